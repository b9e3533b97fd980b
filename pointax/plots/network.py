"""A network's per-site Sky RMS and status.

From a batched :class:`pointax.FitResult` (:func:`pointax.fit_batch`; status from
:func:`pointax.site_statuses`) or a :class:`pointax.analysis.network.NetworkResult`
(:func:`pointax.analysis.network.fit_network`): one bar per site, its Sky RMS in arcsec,
coloured by status (converged, degenerate, failed). A failed site without a Sky RMS is
drawn as a zero-height bar marked with 'x'.

Artists: the bars of each status are patches with gid ``'converged'``,
``'degenerate'`` or ``'failed'``; bar ``k`` is at x = k (site order).
"""

from __future__ import annotations

import math

import numpy as np

from ._mpl import new_figure

__all__ = ["network_figure", "site_rows", "STATUS_COLORS"]

ARCSEC = math.pi / (180.0 * 3600.0)
ARCSEC_PER_MRAD = 1e-3 / ARCSEC

STATUS_COLORS = {"converged": "tab:green", "degenerate": "tab:orange", "failed": "tab:red"}


def site_rows(result, names=None) -> list[tuple[str, str, float, str]]:
    """``[(site, status, Sky RMS arcsec or nan, reason)]`` per site of a batched
    FitResult or a NetworkResult. A PAINT site's RMS is its 'after' error (mrad)
    converted to arcsec."""
    sites = getattr(result, "sites", None)
    if sites is not None:
        rows = []
        for d in sites:
            rms = d.get("sky_rms_arcsec")
            if d.get("format") == "paint":
                mrad = ((d.get("error_mrad") or {}).get("rms") or {}).get("after")
                rms = None if mrad is None else mrad * ARCSEC_PER_MRAD
            rows.append((str(d["site"]), str(d["status"]), math.nan if rms is None else float(rms), str(d.get("reason", ""))))
        return rows
    from ..fitting import site_statuses

    statuses = site_statuses(result)
    rms = np.asarray(result.sky_rms, float).reshape(-1) / ARCSEC
    labels = list(names) if names is not None else [f"site {k + 1}" for k in range(len(statuses))]
    if len(labels) != len(statuses):
        raise ValueError(f"names: {len(labels)} names for {len(statuses)} sites")
    return [(labels[k], s["status"], float(rms[k]) if np.isfinite(rms[k]) else math.nan, s["reason"]) for k, s in enumerate(statuses)]


def network_figure(result, *, names=None, title: str | None = None):
    """Per-site Sky RMS (arcsec) coloured by status: a Figure.

    Args:
        result: a batched :class:`pointax.FitResult` or a
            :class:`pointax.analysis.network.NetworkResult`.
        names: site names for a batched FitResult (default 'site 1', 'site 2', ...).
    """
    rows = site_rows(result, names)
    n = len(rows)
    fig = new_figure(max(6.0, min(0.35 * n + 3.0, 24.0)), 4.8)
    ax = fig.add_subplot()
    x = np.arange(n)
    rms = np.array([r[2] for r in rows])
    status = np.array([r[1] for r in rows])
    for s, color in STATUS_COLORS.items():
        mask = status == s
        if not mask.any():
            continue
        heights = np.where(np.isfinite(rms[mask]), rms[mask], 0.0)
        bars = ax.bar(x[mask], heights, color=color, label=f"{s} ({int(mask.sum())})")
        for patch in bars.patches:
            patch.set_gid(s)
        missing = ~np.isfinite(rms[mask])
        if missing.any():
            ax.plot(x[mask][missing], np.zeros(int(missing.sum())), linestyle="none", marker="x", color=color,
                    markersize=9, gid=f"{s}-no-rms")
    ax.set_xticks(x)
    ax.set_xticklabels([r[0] for r in rows], rotation=60 if n > 8 else 0, ha="right" if n > 8 else "center",
                       fontsize="small")
    ax.set_ylabel("Sky RMS, arcsec")
    ax.set_xlabel("site")
    ax.legend(fontsize="small")
    counts = {s: int(np.sum(status == s)) for s in STATUS_COLORS}
    fig.suptitle(title or f"{n} sites: " + ", ".join(f"{c} {s}" for s, c in counts.items()))
    return fig

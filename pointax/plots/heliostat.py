"""A heliostat calibration's per-sample errors: before, after and leave-one-out.

From :func:`pointax.calibrate_heliostat`'s :class:`pointax.HeliostatCalibration`: for
each sample (in file order) the angle between the measured and the modelled mirror
normal, in mrad, before calibration (nominal kinematics), after it (the fit of all
samples) and left out of it (the fit of the other samples). Samples the robust fit
flagged as outliers are drawn with their own markers.

Artists: on the left axes one ``Line2D`` per (series, kind of sample) with gid
``'<series>-used'`` or ``'<series>-outlier'`` (series 'before', 'after', 'loo'); x is
the sample's 1-based number, y its error in mrad. The right axes show the RMS of each
series over the unflagged samples as bars (gid 'rms-<series>').
"""

from __future__ import annotations

import numpy as np

from ._mpl import new_figure

__all__ = ["heliostat_figure", "SERIES"]

MRAD = 1e-3

SERIES = {
    "before": ("before (nominal)", "tab:gray", "s"),
    "after": ("after (fit of all)", "tab:blue", "o"),
    "loo": ("leave-one-out", "tab:orange", "^"),
}
"""Series -> (label, colour, marker)."""


def heliostat_figure(calibration, *, title: str | None = None):
    """Per-sample errors before, after and leave-one-out (mrad) of a
    :class:`pointax.HeliostatCalibration`, and their RMS: a Figure. Where no
    leave-one-out ran (``calibration.loo_note``), its series and bar are left out and
    the title says so."""
    skipped = getattr(calibration, "loo_note", None)
    series = {k: v for k, v in SERIES.items() if not (k == "loo" and skipped is not None)}
    flagged = np.asarray(calibration.outliers, bool)
    n = flagged.shape[0]
    x = np.arange(1, n + 1, dtype=float)
    fig = new_figure(13.0, 5.0)
    grid = fig.add_gridspec(1, 4)
    ax = fig.add_subplot(grid[0, :3])
    for key, (label, color, marker) in series.items():
        err = np.asarray(getattr(calibration, key), float) / MRAD
        for kind, mask in (("used", ~flagged), ("outlier", flagged)):
            if not mask.any():
                continue
            ax.plot(
                x[mask],
                err[mask],
                linestyle="none",
                marker=marker if kind == "used" else "x",
                markersize=5 if kind == "used" else 7,
                color=color if kind == "used" else "tab:red",
                markeredgecolor=color,
                label=f"{label}" + (" (flagged outlier)" if kind == "outlier" else ""),
                gid=f"{key}-{kind}",
            )
    ax.set_xlabel("sample (file order)")
    ax.set_ylabel("pointing error, mrad")
    ax.set_xticks(x)
    ax.set_xticklabels([str(i) for i in range(1, n + 1)], fontsize="small")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize="small", loc="best")
    ax.set_title("error of each sample: angle between measured and modelled normal", fontsize="medium")

    bar_ax = fig.add_subplot(grid[0, 3])
    for k, (key, (label, color, _)) in enumerate(series.items()):
        rms = calibration.rms(key) / MRAD
        bars = bar_ax.bar([k], [rms], color=color, label=label)
        for patch in bars.patches:
            patch.set_gid(f"rms-{key}")
        bar_ax.text(k, rms, f"{rms:.3f}", ha="center", va="bottom", fontsize="small")
    bar_ax.set_xticks(range(len(series)))
    bar_ax.set_xticklabels(["before", "after", "LOO"][: len(series)])
    bar_ax.set_ylabel("RMS over unflagged samples, mrad")
    bar_ax.set_title("RMS", fontsize="medium")
    n_used = int(np.sum(~flagged))
    note = "" if skipped is None else " (no leave-one-out: too few samples)" if "skipped" in skipped else " (no leave-one-out)"
    fig.suptitle(title or f"heliostat calibration: {n} samples, {n - n_used} flagged{note}")
    return fig

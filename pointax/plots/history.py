"""A run history: each coefficient against time, with error bars and alarms.

From a :class:`pointax.analysis.history.History` (or its :meth:`to_dict`, the JSON of
``pointax history --json``): one panel per coefficient, sharing the time axis (the
decimal year, from each run's MJD; the run number when a run has no time), each run's
value with a one-sigma error bar, and the runs where the coefficient changed beyond
the alarm level from the run before marked in red with the change in sigmas.

Artists: the error bars of each panel have gid ``'runs'``; the alarm markers gid
``'alarm'`` (one point per alarm); panel ``j`` is ``fig.axes[j]``, in the order of the
coefficients.
"""

from __future__ import annotations

import math

import numpy as np

from ._mpl import new_figure

__all__ = ["history_figure", "history_data", "decimal_year"]

_MJD_J2000 = 51544.5
"""MJD of J2000.0 (2000-01-01 12h)."""


def decimal_year(mjd) -> np.ndarray:
    """MJD (days) as a decimal year: ``2000 + (mjd - 51544.5) / 365.25``."""
    return 2000.0 + (np.asarray(mjd, np.float64) - _MJD_J2000) / 365.25


def history_data(history) -> tuple[np.ndarray, str, list[str], np.ndarray, np.ndarray, list[dict]]:
    """What :func:`history_figure` draws: ``(x, x label, names, values, sigmas,
    alarms)``; values and sigmas ``(R, P)`` arcsec (NaN for null), alarms the dicts of
    the JSON."""
    d = history.to_dict() if hasattr(history, "to_dict") else history
    runs = d["runs"]
    if not runs:
        raise ValueError("a history with no runs: nothing to draw")
    names = [t["name"] for t in runs[0]["terms"]]
    times = [r.get("time") for r in runs]
    if all(t is not None for t in times):
        x, label = decimal_year(times), "year (UTC)"
    else:
        x, label = np.arange(1, len(runs) + 1, dtype=np.float64), "run"

    def number(v):
        return math.nan if v is None else float(v)

    values = np.array([[number(t["value_arcsec"]) for t in r["terms"]] for r in runs])
    sigmas = np.array([[number(t["sigma_arcsec"]) for t in r["terms"]] for r in runs])
    return x, label, names, values, sigmas, list(d.get("alarms", []))


def history_figure(history, *, terms=None, title: str | None = None):
    """Each coefficient against time (arcsec, one-sigma error bars), alarms in red.

    Args:
        history: a :class:`pointax.analysis.history.History` or its ``to_dict()``.
        terms: the coefficients to draw (default: every one), by name.
        title: the figure's title (default: how many runs, from when to when).
    """
    x, label, names, values, sigmas, alarms = history_data(history)
    files = [r["file"] for r in (history.to_dict() if hasattr(history, "to_dict") else history)["runs"]]
    chosen = list(names) if terms is None else list(terms)
    unknown = [n for n in chosen if n not in names]
    if unknown:
        raise ValueError(f"terms: {', '.join(unknown)} not fitted (fitted: {' '.join(names)})")
    n = len(chosen)
    fig = new_figure(8.0, max(2.0, 1.6 * n + 1.0))
    axes = fig.subplots(n, 1, sharex=True, squeeze=False)[:, 0]
    for ax, name in zip(axes, chosen):
        j = names.index(name)
        ax.errorbar(x, values[:, j], yerr=np.where(np.isfinite(sigmas[:, j]), sigmas[:, j], 0.0), fmt="o-", color="tab:blue",
                    markersize=4, capsize=3, linewidth=0.8, gid="runs")  # fmt: skip
        hits = [a for a in alarms if a["term"] == name and a["file"] in files]
        if hits:
            rows = [files.index(a["file"]) for a in hits]
            ax.plot(x[rows], values[rows, j], linestyle="none", marker="o", markersize=9, markerfacecolor="none",
                    markeredgecolor="tab:red", markeredgewidth=1.8, gid="alarm")  # fmt: skip
            for a, k in zip(hits, rows):
                z = a.get("change_sigma")
                ax.annotate("" if z is None else f"{z:+.1f}σ", (x[k], values[k, j]), textcoords="offset points",
                            xytext=(6, 6), color="tab:red", fontsize=8)  # fmt: skip
        ax.set_ylabel(f'{name} (")')
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel(label)
    if title is None:
        title = f"{len(files)} runs" + (f", {x[0]:.2f} to {x[-1]:.2f}" if label.startswith("year") else "")
        title += f"; {len(alarms)} alarm{'s' if len(alarms) != 1 else ''}"
    fig.suptitle(title)
    return fig

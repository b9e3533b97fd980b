"""Residual plots: each component against each axis angle, against each other, and
their histograms.

Every point set is one ``Line2D`` (markers, no line) per kind of observation, with
``gid`` ``'used'``, ``'outlier'`` or ``'masked'`` (:meth:`ResidualData.groups`), so that
``line.get_data()`` gives exactly what is drawn: angles in degrees, residuals in the
fit's unit (arcsec for telescopes).
"""

from __future__ import annotations

import numpy as np

from ._mpl import COLORS, LABELS, MARKERS, new_figure
from .data import ResidualData, residual_data

__all__ = [
    "draw_points",
    "draw_scatter",
    "draw_histogram",
    "residual_figure",
    "scatter_figure",
    "histogram_figure",
    "title_of",
]


def title_of(result, extra: str = "") -> str:
    """A figure title: the run's caption, N used and the Sky RMS; for a fit that did
    not converge, 'NOT CONVERGED' first (its residuals are not those of a solution)."""
    from .data import UNIT_SCALE, residual_unit

    unit = residual_unit(result)
    caption = getattr(result, "caption", "") or ""
    rms = float(np.asarray(result.sky_rms)) / UNIT_SCALE[unit]
    converged = getattr(result, "converged", True)
    failed = np.ndim(converged) == 0 and not bool(np.asarray(converged))
    parts = [p for p in ("FIT NOT CONVERGED" if failed else "", caption.strip(), extra) if p]
    parts.append(f"N = {int(np.asarray(result.n_obs))}, Sky RMS = {rms:.3f} {unit}")
    return " - ".join(parts)


def draw_points(ax, data: ResidualData, x: np.ndarray, y: np.ndarray, *, legend: bool = False, size: float = 4.0) -> list:
    """Draw ``y`` against ``x`` (``(n,)`` each), one ``Line2D`` per non-empty kind of
    observation (gid 'used', 'outlier', 'masked'); a zero line. Returns the lines."""
    lines = []
    for group, mask in data.groups():
        if not mask.any():
            continue
        (line,) = ax.plot(
            x[mask],
            y[mask],
            linestyle="none",
            marker=MARKERS[group],
            markersize=size,
            color=COLORS[group],
            markerfacecolor="none" if group == "masked" else COLORS[group],
            label=f"{LABELS[group]} ({int(mask.sum())})",
            gid=group,
        )
        lines.append(line)
    ax.axhline(0.0, color="0.3", linewidth=0.6, gid="zero")
    if legend:
        ax.legend(loc="best", fontsize="small")
    return lines


def _angle_axis(ax, name: str, convention: str | None, source: str) -> None:
    label = f"{name} ({source}"
    if name == "azimuth" and convention:
        label += f", {convention}"
    ax.set_xlabel(label + "), deg")
    if name in ("azimuth", "hour angle", "alpha"):
        ax.set_xticks(np.arange(-360, 361, 90) if name != "azimuth" else np.arange(0, 361, 90))


def residual_axes(fig, data: ResidualData, grid, rows: tuple[int, int], cols: tuple[int, int]) -> list:
    """Fill a 2 x 2 block of ``grid`` (a GridSpec): residual component i (rows) against
    axis angle j (columns), the angles of the raw readings."""
    axes = []
    for i in range(2):
        for j in range(2):
            ax = fig.add_subplot(grid[rows[0] + i, cols[0] + j])
            draw_points(ax, data, data.axis_angles[:, j], data.residuals[:, i], legend=(i == 0 and j == 0))
            ax.set_ylabel(f"{data.names[i]} ({data.symbols[i]}), {data.unit}")
            _angle_axis(ax, data.axis_names[j], data.convention, "reading")
            ax.set_title(f"{data.names[i]} vs {data.axis_names[j]}", fontsize="medium")
            axes.append(ax)
    return axes


def draw_scatter(ax, data: ResidualData, *, legend: bool = True) -> list:
    """The second residual component against the first (equal scales), with a circle
    at the fit's Sky RMS."""
    lines = draw_points(ax, data, data.residuals[:, 0], data.residuals[:, 1], legend=legend)
    ax.axvline(0.0, color="0.3", linewidth=0.6)
    ax.set_aspect("equal", adjustable="datalim")
    if data.used.any() and np.isfinite(data.sky_rms):
        rms = data.sky_rms
        t = np.linspace(0.0, 2 * np.pi, 181)
        ax.plot(rms * np.cos(t), rms * np.sin(t), color="0.4", linestyle="--", linewidth=0.8, gid="rms-circle",
                label=f"Sky RMS {rms:.3g} {data.unit}")
        if legend:
            ax.legend(loc="best", fontsize="small")
    ax.set_xlabel(f"{data.names[0]} ({data.symbols[0]}), {data.unit}")
    ax.set_ylabel(f"{data.names[1]} ({data.symbols[1]}), {data.unit}")
    ax.set_title(f"{data.names[1]} vs {data.names[0]}", fontsize="medium")
    return lines


def histogram_bins(values: np.ndarray, n: int = 20) -> np.ndarray:
    """``n + 1`` bin edges spanning ``values`` (symmetric about 0 when they change sign)."""
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return np.linspace(-1.0, 1.0, n + 1)
    lo, hi = float(finite.min()), float(finite.max())
    if lo < 0 < hi:
        lim = max(-lo, hi)
        lo, hi = -lim, lim
    if hi <= lo:
        lo, hi = lo - 0.5, hi + 0.5
    return np.linspace(lo, hi, n + 1)


def draw_histogram(ax, data: ResidualData, values: np.ndarray, label: str, *, bins: int = 20) -> dict:
    """Histogram of ``values`` (``(n,)``), stacked by kind of observation; each kind's
    bars are patches whose gid is the kind. Returns
    ``{kind: counts}`` and ``'edges'``."""
    edges = histogram_bins(values, bins)
    groups = [(g, m) for g, m in data.groups() if m.any()]
    out = {"edges": edges}
    bottom = np.zeros(len(edges) - 1)
    for group, mask in groups:
        counts, _ = np.histogram(values[mask], bins=edges)
        bars = ax.bar(
            edges[:-1],
            counts,
            width=np.diff(edges),
            bottom=bottom,
            align="edge",
            color=COLORS[group],
            edgecolor="white",
            linewidth=0.5,
            label=f"{LABELS[group]} ({int(mask.sum())})",
        )
        for patch in bars.patches:
            patch.set_gid(group)
        bottom = bottom + counts
        out[group] = counts
    ax.set_xlabel(f"{label}, {data.unit}")
    ax.set_ylabel("observations")
    ax.legend(loc="best", fontsize="small")
    return out


def residual_figure(result, observations, *, outliers=None):
    """Each residual component (rows) against each axis angle (columns), and the two
    components against each other (right): a Figure."""
    data = residual_data(result, observations, outliers)
    fig = new_figure(14.0, 7.0)
    grid = fig.add_gridspec(2, 3)
    residual_axes(fig, data, grid, (0, 1), (0, 1))
    draw_scatter(fig.add_subplot(grid[:, 2]), data)
    fig.suptitle(title_of(result, "residuals (observed - model)"))
    return fig


def scatter_figure(result, observations, *, outliers=None):
    """The second residual component against the first: a Figure."""
    data = residual_data(result, observations, outliers)
    fig = new_figure(6.5, 6.5)
    draw_scatter(fig.add_subplot(), data)
    fig.suptitle(title_of(result))
    return fig


def histogram_figure(result, observations, *, outliers=None, bins: int = 20):
    """Histograms of both residual components and of the on-sky distance: a Figure."""
    data = residual_data(result, observations, outliers)
    fig = new_figure(14.0, 4.5)
    axes = fig.subplots(1, 3)
    for i in range(2):
        draw_histogram(axes[i], data, data.residuals[:, i], f"{data.names[i]} ({data.symbols[i]})", bins=bins)
        axes[i].set_title(data.names[i], fontsize="medium")
    draw_histogram(axes[2], data, data.distance, "on-sky distance", bins=bins)
    axes[2].set_title("on-sky distance (TPOINT's R)", fontsize="medium")
    fig.suptitle(title_of(result, "residual histograms"))
    return fig

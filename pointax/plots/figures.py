"""One fit's figures by kind: :func:`fit_figure`."""

from __future__ import annotations

from ._mpl import new_figure
from .data import residual_data
from .residuals import draw_histogram, draw_scatter, histogram_figure, residual_axes, residual_figure, scatter_figure, title_of
from .skymap import draw_skymap, skymap_figure

__all__ = ["FIT_KINDS", "fit_figure", "summary_figure"]


def summary_figure(result, observations, *, outliers=None):
    """Residual components against both axis angles (left), their scatter and the
    histogram of on-sky distances (middle), the sky map (right): a Figure."""
    data = residual_data(result, observations, outliers)
    fig = new_figure(16.0, 8.0)
    grid = fig.add_gridspec(2, 4)
    residual_axes(fig, data, grid, (0, 1), (0, 1))
    draw_scatter(fig.add_subplot(grid[0, 2]), data)
    draw_skymap(fig.add_subplot(grid[:, 3]), data, legend=False)
    draw_histogram(fig.add_subplot(grid[1, 2]), data, data.distance, "on-sky distance")
    fig.suptitle(title_of(result))
    return fig


def _tpoint9(result, observations, *, outliers=None):
    from .tpoint_panels import tpoint_graph

    return tpoint_graph("A9", result, observations, outliers=outliers)


FIT_KINDS = {
    "summary": summary_figure,
    "residuals": residual_figure,
    "sky": skymap_figure,
    "scatter": scatter_figure,
    "histogram": histogram_figure,
    "tpoint9": _tpoint9,
}
"""Kinds of :func:`fit_figure` -> the function drawing it."""


def fit_figure(result, observations, kind: str = "summary", *, outliers=None):
    """A matplotlib Figure of one fit.

    Args:
        result: a single fit's :class:`pointax.FitResult` (``residuals`` ``(n, 2)``
            radians for every row, masked ones included).
        observations: the fitted :class:`pointax.Observations` (weight 0 = masked),
            or a run with ``.observations``.
        kind: 'summary' (residuals against both axis angles, scatter, histogram, sky
            map), 'residuals' (each component against each axis angle and against
            each other), 'sky' (sky map with residual vectors), 'scatter',
            'histogram' or 'tpoint9' (TPOINT's nine-panel alt-az set, A9).
        outliers: more observations to flag as outliers (0-based indices or a
            boolean mask), drawn like ``result.outliers``.

    Masked and outlier observations are drawn in their own artists (gid 'masked',
    'outlier'; the rest 'used'). Residuals are shown in arcsec (mrad for heliostats).

    Raises:
        ValueError: an unknown ``kind`` (naming the valid ones).
        ImportError: matplotlib is not installed (``pip install 'pointax[plot]'``).
    """
    if kind not in FIT_KINDS:
        raise ValueError(f"unknown plot kind {kind!r}; valid kinds: {', '.join(FIT_KINDS)}")
    return FIT_KINDS[kind](result, observations, outliers=outliers)

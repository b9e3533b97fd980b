"""matplotlib, imported on first use (an optional extra: ``pip install pointax[plot]``).

Figures are :class:`matplotlib.figure.Figure` objects made without pyplot (no global
state, no window): they draw through the non-interactive Agg canvas and are saved
with :func:`pointax.plots.save_figure` or ``fig.savefig``.
"""

from __future__ import annotations

__all__ = ["new_figure", "require_matplotlib", "COLORS", "MARKERS", "LABELS"]

COLORS = {"used": "tab:blue", "outlier": "tab:red", "masked": "0.6"}
"""Colour of each kind of observation (:meth:`ResidualData.groups`)."""

MARKERS = {"used": "o", "outlier": "x", "masked": "s"}
"""Marker of each kind of observation: masked rows as open grey squares."""

LABELS = {"used": "used", "outlier": "outlier", "masked": "masked (weight 0)"}


def require_matplotlib():
    """Import matplotlib (Agg canvas) or raise ImportError saying how to install it."""
    try:
        import matplotlib
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise ImportError(
            "pointax's plots need matplotlib, an optional extra: pip install 'pointax[plot]' "
            "(or pip install 'matplotlib>=3.9')"
        ) from err
    return matplotlib


def new_figure(width: float = 10.0, height: float = 7.0, layout: str | None = "constrained"):
    """A new :class:`matplotlib.figure.Figure` (inches), attached to the Agg canvas."""
    require_matplotlib()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout=layout)
    FigureCanvasAgg(fig)
    return fig

"""Plots of pointing fits (matplotlib, an optional extra: ``pip install 'pointax[plot]'``).

Every function returns a :class:`matplotlib.figure.Figure` made without pyplot (Agg
canvas, no window); :func:`save_figure` writes it as PNG, SVG, PDF or PostScript by
the file's extension. Importing this package imports no matplotlib: each function
imports it when called.

* :func:`fit_figure` (result, observations, kind): one fit's 'summary', 'residuals'
  (each component against each axis angle and against each other), 'sky' (sky map
  with residual vectors: zenith at the centre, North up, East right, a scale arrow),
  'scatter', 'histogram' or 'tpoint9' (TPOINT's A9).
* :func:`tpoint_graph` (command, result, observations): TPOINT's graphics commands by
  name ('G S A', 'GZZ', 'G AM Z', 'GSMAP', 'GHIST', 'A9', ...;
  :mod:`pointax.plots.tpoint_panels` lists every code).
* :func:`heliostat_figure`: a heliostat calibration's per-sample errors before, after
  and leave-one-out (:func:`pointax.calibrate_heliostat`).
* :func:`network_figure`: per-site Sky RMS and status of a batched fit.
* :func:`history_figure`: a run history's coefficients against time, with alarms.
* :func:`families_figure`: a model-family comparison (:func:`pointax.compare`).

Residuals are observed minus model, in arcsec (mrad for heliostats); masked (weight
0) and outlier observations are drawn in their own artists, with gid 'masked' and
'outlier' (the others 'used') and a legend entry each.
"""

from __future__ import annotations

from ..core.lazy import lazy_namespace

__all__ = [
    "fit_figure",
    "tpoint_graph",
    "save_figure",
    "heliostat_figure",
    "network_figure",
    "history_figure",
    "families_figure",
    "residual_data",
    "FIT_KINDS",
    "A9_PANELS",
]

__getattr__, __dir__ = lazy_namespace(
    __name__,
    {
        "fit_figure": "figures",
        "FIT_KINDS": "figures",
        "tpoint_graph": "tpoint_panels",
        "A9_PANELS": "tpoint_panels",
        "save_figure": "save",
        "heliostat_figure": "heliostat",
        "network_figure": "network",
        "history_figure": "history",
        "families_figure": "families",
        "residual_data": "data",
    },
)

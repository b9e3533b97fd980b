"""Least-squares fitting of pointing models: :func:`fit` and what goes with it.

The fit minimises the weighted sum of squared on-sky residuals. A residual is
*observed minus model* in the tangent plane of the observed direction: (cross-elevation,
elevation) in radians, so it is ``(dA cos E, dE)`` for small offsets and has no pole at
the zenith. Statistics follow TPOINT's definitions exactly (unit weights)::

    Sky RMS = sqrt( sum_i |r_i|^2 / N )          N observations
    Popn SD = Sky RMS * sqrt( N / (N - M) )       M fitted parameters
    sigma_j = Sky RMS * sqrt( [(J^T J)^-1]_jj )   J: d r / d parameters

With weights ``w`` they are normalised to mean 1 over the used observations and enter
as ``sqrt(w_i) r_i``; with unit weights this is TPOINT. Observations with weight 0 are
ignored (and may hold NaN).

The code lives in :mod:`pointax.fitting` (one core for the solo, batched,
shared-parameter and leave-one-out fits); this module keeps the names it has always
offered.
"""

from __future__ import annotations

from .fitting.core import LOSSES, SOLVERS
from .fitting.options import FitOptions
from .fitting.residuals import as_observations, check_convention, residuals
from .fitting.result import CORRELATION_WARNING, FitResult
from .fitting.solo import fit, prepare
from .fitting.statistics import DEGENERATE_RCOND, RAYLEIGH_MEDIAN, robust_sigma

__all__ = [
    "fit",
    "FitOptions",
    "FitResult",
    "SOLVERS",
    "LOSSES",
    "residuals",
    "CORRELATION_WARNING",
    "DEGENERATE_RCOND",
    "RAYLEIGH_MEDIAN",
    "robust_sigma",
    "check_options",
    "prepare",
    "as_observations",
    "check_convention",
]


def check_options(solver: str, loss: str, loss_scale: float | None, reject: float) -> FitOptions:
    """Raise ValueError, naming the argument, for a bad solver or robust-loss option
    (returns the :class:`FitOptions` they make)."""
    return FitOptions(solver=solver, loss=loss, loss_scale=loss_scale, reject=reject)

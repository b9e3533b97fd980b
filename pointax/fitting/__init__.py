"""The fitting core: one problem definition, one solver loop, one statistics routine.

* :mod:`~pointax.fitting.options`: :class:`FitOptions`, the fit's options as one object.
* :mod:`~pointax.fitting.residuals`: the residuals a fit minimises (both forms).
* :mod:`~pointax.fitting.core`: the fit, pure JAX, over a mask of free parameters.
* :mod:`~pointax.fitting.statistics`: TPOINT's statistics, for every kind of fit.
* :mod:`~pointax.fitting.structure`: models embedded in a union of terms, so that
  USE / LOSE / FIX / MASK never recompile.
* :mod:`~pointax.fitting.solo`: :func:`fit`, one run.
* :mod:`~pointax.fitting.result`: :class:`FitResult`.
"""

from .core import LOSSES, SOLVERS, fit_core, free_mask, least_squares, restrict, result_from_covariance
from .options import LOSS_NAMES, SOLVER_NAMES, FitOptions
from .residuals import as_observations, check_convention, residuals
from .result import CORRELATION_WARNING, FitResult
from .solo import fit, fit_model, options_from, prepare
from .statistics import (
    DEGENERATE_RCOND,
    RAYLEIGH_MEDIAN,
    Statistics,
    normalised_weights,
    robust_sigma,
    statistics,
    svd_unit_covariance,
)
from .structure import embed

__all__ = [
    "CORRELATION_WARNING",
    "DEGENERATE_RCOND",
    "FitOptions",
    "FitResult",
    "LOSSES",
    "LOSS_NAMES",
    "RAYLEIGH_MEDIAN",
    "SOLVERS",
    "SOLVER_NAMES",
    "Statistics",
    "as_observations",
    "check_convention",
    "embed",
    "fit",
    "fit_core",
    "fit_model",
    "free_mask",
    "least_squares",
    "normalised_weights",
    "options_from",
    "prepare",
    "residuals",
    "restrict",
    "result_from_covariance",
    "robust_sigma",
    "statistics",
    "svd_unit_covariance",
]

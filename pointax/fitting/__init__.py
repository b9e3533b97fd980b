"""The fitting core: one problem definition, one solver loop, one statistics routine.

* :mod:`~pointax.fitting.options`: :class:`FitOptions`, the fit's options as one object.
* :mod:`~pointax.fitting.problem`: the problem definition every fit evaluates: what a
  site's observations fix (one construction, for a site or a chunk of sites), prepared
  once, and one residual family (both forms), evaluated by
  :mod:`~pointax.fitting.fast_evaluation`; its Jacobian for the batched fits:
  :mod:`~pointax.fitting.fast_jacobian`.
* :mod:`~pointax.fitting.residuals`: the plain residuals of the forward model (the
  oracle the problem definition is tested against).
* :mod:`~pointax.fitting.core`: the fit, pure JAX, over a mask of free parameters.
* :mod:`~pointax.fitting.statistics`: TPOINT's statistics, for every kind of fit.
* :mod:`~pointax.fitting.structure`: models embedded in a union of terms, so that
  USE / LOSE / FIX / MASK never recompile.
* :mod:`~pointax.fitting.solo`: :func:`fit`, one run.
* :mod:`~pointax.fitting.result`: :class:`FitResult`.
* :mod:`~pointax.fitting.programs`: traced fits kept on disk (:mod:`jax.export`).

Batched fits (:mod:`pointax.fitting.batch`) run a fixed-step fast pass
(:mod:`pointax.fitting.batch_fast_pass`) on the same problem definition and send the sites it does not settle to :func:`fit_model`; shared-parameter
fits (:mod:`pointax.fitting.shared`) solve the joint problem on it; all of them take their
statistics from :mod:`~pointax.fitting.statistics`.
"""

from ..core.lazy import lazy_namespace

# Public name -> the module that defines it (loaded on first use: the command line reads
# the option names in :mod:`.options` without importing JAX).
_EXPORTS = {
    "LOSSES": "core",
    "ROBUST_LOSSES": "core",
    "FitSettings": "core",
    "SOLVERS": "core",
    "site_statuses": "batch",
    "observation_residuals": "masking",
    "on_sky": "masking",
    "residual_unit": "result",
    "fit_core": "core",
    "free_mask": "core",
    "least_squares": "core",
    "restrict": "core",
    "result_from_covariance": "core",
    "LOSS_NAMES": "options",
    "SOLVER_NAMES": "options",
    "FitOptions": "options",
    "Problem": "problem",
    "define_problem": "problem",
    "as_observations": "residuals",
    "check_convention": "residuals",
    "CORRELATION_WARNING": "result",
    "FitResult": "result",
    "fit": "solo",
    "fit_model": "solo",
    "options_from": "solo",
    "prepare": "solo",
    "DEGENERATE_RCOND": "statistics",
    "RAYLEIGH_MEDIAN": "statistics",
    "Statistics": "statistics",
    "normalised_weights": "statistics",
    "robust_sigma": "statistics",
    "svd_unit_covariance": "statistics",
    "leave_one_out": "statistics",
    "embed": "structure",
    "PooledFit": "pooled",
    "fit_pooled": "pooled",
}

__getattr__, __dir__ = lazy_namespace(__name__, _EXPORTS, ("residuals", "statistics", "structure"))

__all__ = [
    "CORRELATION_WARNING",
    "DEGENERATE_RCOND",
    "FitOptions",
    "FitResult",
    "Problem",
    "define_problem",
    "LOSSES",
    "LOSS_NAMES",
    "RAYLEIGH_MEDIAN",
    "ROBUST_LOSSES",
    "FitSettings",
    "SOLVERS",
    "SOLVER_NAMES",
    "Statistics",
    "as_observations",
    "check_convention",
    "embed",
    "fit",
    "fit_core",
    "fit_model",
    "fit_pooled",
    "PooledFit",
    "free_mask",
    "least_squares",
    "leave_one_out",
    "normalised_weights",
    "options_from",
    "prepare",
    "restrict",
    "result_from_covariance",
    "site_statuses",
    "observation_residuals",
    "on_sky",
    "residual_unit",
    "robust_sigma",
    "svd_unit_covariance",
]

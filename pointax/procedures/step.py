"""TPOINT's FIT: one linearised (Gauss-Newton) adjustment of the current values.

TPOINT's FIT applies the model rigorously at the current coefficients, linearises it
there and solves the linear least-squares problem once: the coefficients change by

    delta = -(J^T W J)^-1 J^T W r(y0)

with ``r`` the residuals (observed minus model, both components, radians), ``J`` their
Jacobian in the free coefficients and ``W`` the weights (0 for masked observations).
It prints each change; users repeat FIT until the changes vanish.

:func:`pointax.fit` iterates to convergence; this is the fitting core's own
Gauss-Newton step (:func:`pointax.fitting.core.gauss_newton_step`, with which every fit
ends), taken once from the current values, on the model embedded in its family's union
of terms (:func:`pointax.fitting.embed`), so that FIT after USE, LOSE, FIX or MASK
compiles nothing new.

Statistics follow TPOINT: Sky RMS and Popn SD from the residuals after the step,
sigmas from the normal equations of the step scaled by that Sky RMS.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..core.precision import float64
from ..fitting import FitResult, embed, restrict
from ..fitting import core
from ..fitting.result import SUCCESSFUL
from ..fitting.solo import prepare
from ..fitting.statistics import normalised_weights
from ..core.model import Model

__all__ = ["Step", "gauss_newton_step"]


@dataclasses.dataclass(frozen=True)
class Step:
    """One FIT.

    Attributes:
        result: the :class:`pointax.FitResult` after the step (``iterations`` 1,
            ``solver`` 'gauss-newton'; ``converged`` means the step is finite).
        changes: ``(M,)`` change of each free parameter, internal units (radians),
            in the order of ``result.names``.
    """

    result: FitResult
    changes: np.ndarray


def _step_core(model: Model, free, obs) -> tuple[FitResult, jax.Array]:
    """One Gauss-Newton step of every ``free`` parameter of ``model`` on the
    :class:`pointax.Observations` ``obs`` (pure JAX).
    Returns a :class:`FitResult` over every parameter and the ``(M,)`` changes."""
    free = jnp.asarray(free, bool)
    used = obs.weight > 0
    step = core.gauss_newton_step(model, free, obs, normalised_weights(obs.weight, used), used, model.values("all"))
    ok = step.finite & step.step_finite
    result = core.fit_result(
        step.model, step.values, step.statistics, step.residuals, used, step.degenerate,
        iterations=1, converged=ok, status=SUCCESSFUL, solver="gauss-newton", every_parameter=True,
    )  # fmt: skip
    return result, step.change


_step_jit = eqx.filter_jit(_step_core)


@float64
def gauss_newton_step(model: Model, observations, weights=None, caption: str = "") -> Step:
    """TPOINT's FIT: one linearised adjustment of ``model``'s free parameters from
    their current values.

    Args:
        model: the model at its current values (fixed parameters stay).
        observations: :class:`pointax.Observations` or a run with ``.observations``.
        weights: optional ``(n,)`` weights replacing the observations' own (0 masks).
        caption: the result's caption.

    Returns:
        A :class:`Step`: the result after the step and each parameter's change.

    Raises:
        ValueError: no observation with a positive weight, weights of the wrong
            shape, or observations in another encoder convention than the model's.
    """
    model, obs = prepare(model, observations, weights)  # float64 NumPy leaves: one compiled step
    embedding = embed(model)
    full, delta = _step_jit(embedding.model, embedding.free, obs)
    result = restrict(full, embedding.index, model, caption, numpy=True)
    return Step(result=result, changes=np.asarray(delta)[np.asarray(embedding.index, int)])

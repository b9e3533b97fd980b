"""Out-of-sample checks of a fit: leave-one-out, all folds in one compiled call."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from ..core.precision import float64
from .core import FitSettings, labelled
from .options import FitOptions
from .residuals import residuals
from .result import FitResult
from .solo import fit_model, options_from, prepare
from ..core.model import Model
from ..core.observations import Observations
from .progress import progress_bar
from ..core.rotations import offset_angle

__all__ = ["leave_one_out", "LeaveOneOut"]


class LeaveOneOut(eqx.Module):
    """Leave-one-out predictions: observation ``i`` predicted by a fit of all the others.

    Attributes:
        offsets: ``(n, 2)`` observed minus predicted for each left-out observation,
            (cross-elevation, elevation) radians; NaN for observations not taken part
            (weight 0).
        errors: ``(n,)`` their norms: the angle between observed and predicted, radians.
        converged: ``(n,)`` whether each fold's fit converged.
        folds: the ``n`` fold fits, stacked along a leading axis (a batched
            :class:`pointax.FitResult`).
    """

    offsets: Float[Array, "n 2"]
    errors: Float[Array, " n"]
    converged: Bool[Array, " n"]
    folds: FitResult

    def rms(self, mask=None) -> float:
        """RMS of :attr:`errors` (radians) over ``mask`` (default: every finite one)."""
        errors = np.asarray(self.errors)
        keep = np.isfinite(errors) if mask is None else np.asarray(mask, bool) & np.isfinite(errors)
        return float(np.sqrt(np.mean(errors[keep] ** 2))) if keep.any() else float("nan")


_BARS: list = []  # the progress bar of the leave-one-out running now, if any


def _fold_done(_=None) -> None:
    if _BARS:
        _BARS[-1].update()


@eqx.filter_jit
def _leave_one_out(model, obs, settings: FitSettings, options: FitOptions, ticks: bool = False):
    n = obs.weight.shape[0]
    masks = 1.0 - jnp.eye(n, dtype=obs.weight.dtype)
    taking_part = obs.weight > 0

    def one_fold(mask):
        fold_obs = eqx.tree_at(lambda o: o.weight, obs, obs.weight * mask)
        fold = fit_model(model, fold_obs, options, settings=settings)
        if ticks:  # a host callback per fold moves the bar while the compiled loop runs
            jax.debug.callback(_fold_done, fold.iterations)
        return fold

    # lax.map rather than vmap: the folds run one after another in one compiled loop.
    # A single fit's body compiles several times faster than the batched one, and each
    # fold then stops at its own step count instead of running as long as the slowest.
    folds = jax.lax.map(one_fold, masks)
    # Fold i's model evaluated on observation i alone (weight 1, so it is not zeroed).
    single = jax.vmap(lambda o, t: Observations(o[None], t[None], convention=obs.convention))(obs.encoder, obs.target)
    offsets = jax.vmap(lambda fold_model, one: residuals(fold_model, one)[0])(folds.model, single)
    offsets = jnp.where(taking_part[:, None], offsets, jnp.nan)
    return offsets, folds


@float64
def leave_one_out(
    model: Model,
    data,
    *,
    solver: str = "lm",
    weights=None,
    fixed: tuple[str, ...] = (),
    max_steps: int = 256,
    rtol: float = 1e-10,
    atol: float = 1e-13,
    loss: str = "linear",
    loss_scale: float | None = None,
    reject: float = 3.0,
    options: FitOptions | None = None,
    progress: bool = False,
) -> LeaveOneOut:
    """Fit ``model`` once per observation with that observation left out, and predict it.

    All ``n`` fits run in one compiled call (a ``lax.map`` over the folds). The keyword
    arguments are those of :func:`pointax.fit`; with a robust ``loss`` each fold finds
    its own outliers, so a left-out gross outlier cannot help predict itself.

    Args:
        model: the model to fit (its current values are every fold's start).
        data: :class:`pointax.Observations` or a run with ``.observations``.
        progress: show a progress bar of the folds on standard error when it is a
            terminal (:func:`pointax.fitting.progress.progress_bar`; the program it runs is
            compiled apart from the silent one's).

    Returns:
        :class:`LeaveOneOut` with each observation's out-of-sample error.

    Raises:
        ValueError: fewer than two observations, or folds with no more residuals
            than free parameters.
    """
    options = options_from(
        options, solver=solver, max_steps=max_steps, rtol=rtol, atol=atol, loss=loss, loss_scale=loss_scale, reject=reject
    )
    model, obs = prepare(model, data, weights, fixed)
    n_used = int(np.sum(np.asarray(obs.weight) > 0))
    if n_used < 2:
        raise ValueError("leave-one-out needs at least two observations with positive weight")
    n_free = len(model.free_parameters)
    if n_free and 2 * (n_used - 1) <= n_free:
        raise ValueError(
            f"leave-one-out: each fold keeps {n_used - 1} observation(s), {2 * (n_used - 1)} residuals for "
            f"{n_free} free parameters: no fold could estimate a sigma (each would be 0); give more than "
            f"{n_free // 2 + 1} observations or fix parameters"
        )
    bar = progress_bar(len(obs.weight), "leave-one-out", "fold", enabled=progress)
    _BARS.append(bar)
    try:
        # The step limit and the robust settings as data: another max_steps, loss or reject
        # runs the same program.
        offsets, folds = _leave_one_out(model, obs, FitSettings.of(options), options.compiled(), bar.active)
        folds = labelled(folds, options)
        jax.block_until_ready(folds.converged)
        jax.effects_barrier()  # every fold's callback has run
    finally:
        _BARS.remove(bar)
        bar.close()
    errors = offset_angle(offsets)
    return LeaveOneOut(offsets=offsets, errors=errors, converged=folds.converged, folds=folds)

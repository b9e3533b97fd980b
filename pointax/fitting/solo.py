"""The fit of one run: :func:`fit`.

The model is embedded in its family's union (:mod:`pointax.fitting.structure`), so a
refit after USE, LOSE, FIX or MASK (other terms, other fixed parameters or values,
other weights) runs the fit already compiled, as does another robust loss, scale or
rejection threshold or another step limit (:class:`pointax.fitting.core.FitSettings`):
only a new term class, mount, residual form, data shape, solver or tolerance compiles
again.
"""

from __future__ import annotations

import functools

import equinox as eqx
import jax
import numpy as np
from jaxtyping import Array, Float

from ..core.padding import pad_rows, power_of_two
from ..core.precision import float64
from ..core.model import Model
from ..core import xla_options
from ..core.observations import Observations
from . import programs
from .core import FitSettings, fit_core, free_mask, labelled, restrict, result_structure
from .options import FitOptions
from .residuals import as_observations, check_convention
from .ranges import wrap_periodic
from .result import FitResult, first_rows, too_little_data
from .structure import embed

__all__ = ["fit", "prepare", "fit_model", "options_from", "check_enough_data"]


def options_from(options: FitOptions | None, **kwargs) -> FitOptions:
    """``options`` if given (then no keyword may differ from its default), else
    :class:`FitOptions` from the keywords."""
    if options is None:
        return FitOptions(**kwargs)
    defaults = FitOptions()
    clash = sorted(k for k, v in kwargs.items() if v != getattr(defaults, k))
    if clash:
        raise ValueError(f"give either options= or the keywords {clash}, not both")
    return options


def fit_model(
    model: Model, obs: Observations, options: FitOptions, caption: str = "", settings: FitSettings | None = None
) -> FitResult:
    """The whole fit of ``model``'s free parameters, pure JAX (jit-, vmap- and
    lax.map-able): :func:`pointax.fitting.core.fit_core` with the model's own fixed
    names as the mask (and ``settings``, the options that are data, as arrays, if
    given), restricted to its free parameters."""
    free = free_mask(model)
    full = fit_core(model, free, obs, options, settings)
    return restrict(full, np.flatnonzero(free), model, caption)


@functools.cache
def _fit_core_jit():
    """:func:`fit_core` compiled in memory (no programs folder), with the faster
    compiler options (:mod:`pointax.core.xla_options`: it compiles in half the time,
    to a smaller executable that runs about as fast)."""

    def run(dynamic, static, options):
        return _fit_program(*eqx.combine(dynamic, static), options)

    return xla_options.jit(run, static_argnums=(1, 2))


def _fit_program(model: Model, free, obs: Observations, settings: FitSettings, options: FitOptions) -> FitResult:
    """:func:`fit_core` with the options last, as the compiled fit takes them (the
    arrays, then the structure: ``options.compiled()``)."""
    return fit_core(model, free, obs, options, settings)


@float64
def fit(
    model: Model,
    data,
    *,
    solver: str = "lm",
    weights: Float[Array, " n"] | None = None,
    fixed: tuple[str, ...] = (),
    max_steps: int = 256,
    rtol: float = 1e-10,
    atol: float = 1e-13,
    caption: str | None = None,
    loss: str = "linear",
    loss_scale: float | None = None,
    reject: float = 3.0,
    options: FitOptions | None = None,
) -> FitResult:
    """Fit the free parameters of ``model`` to pointing observations.

    Args:
        model: a :class:`pointax.Model` (its current values are the starting point; its
            ``fixed`` parameters stay as they are).
        data: :class:`pointax.Observations`, or a run read by :mod:`pointax.io`.
        solver: 'lm' (Levenberg-Marquardt, default), 'gauss-newton' or 'dogleg'.
        weights: optional ``(n,)`` relative weights replacing the observations' own
            (0 masks an observation: it stays in the result's residuals, unused).
        fixed: more parameter names to hold fixed for this fit.
        max_steps: solver step limit; a fit that reaches it reports ``converged=False``.
        rtol, atol: optimistix tolerances on the parameters (radians) and the cost.
        caption: title line for the report (default: the run's caption, if any).
        loss: 'linear' (least squares, default) or a robust loss from
            :data:`pointax.fitting.LOSSES` ('cauchy' is the most forgiving of gross outliers).
        loss_scale: soft margin of the robust loss, radians (default: twice the robust
            standard deviation of the residuals, re-estimated after a first pass).
        reject: with a robust loss, observations whose weighted residual norm exceeds
            ``reject`` robust standard deviations are flagged as ``outliers`` and left
            out of the final least-squares fit that gives values and statistics.
        options: all of the above from ``solver`` to ``reject`` but ``weights``,
            ``fixed`` and ``caption`` as one :class:`pointax.FitOptions` (then leave
            those keywords at their defaults).

    Returns:
        A :class:`FitResult`. A fit that fails to converge does not raise: check
        ``result.converged`` (the report and ``warnings()`` say why).

    Raises:
        ValueError: for bad input, e.g. no more residuals (two per observation) than
            free parameters, where every sigma would be 0 (:func:`check_enough_data`).

    Changing the terms, the fixed parameters or their values, or the weights does not
    compile the fit again (:mod:`pointax.fitting.structure`), nor does another robust
    loss, ``loss_scale`` or ``reject`` (only least squares against robust does).
    """
    options = options_from(
        options, solver=solver, max_steps=max_steps, rtol=rtol, atol=atol, loss=loss, loss_scale=loss_scale, reject=reject
    )
    model, obs = prepare(model, data, weights, fixed)
    check_enough_data(model, obs)
    if caption is None:
        caption = getattr(data, "caption", "") or ""
    embedding = embed(model)
    n = len(obs)
    padded = pad_observations(obs, fit_bucket(n))
    # The step limit and the robust settings are data: another max_steps, loss, scale or
    # reject runs the same program.
    args = (embedding.model, embedding.free, padded, FitSettings.of(options))
    if programs.directory() is not None:  # traced programs kept on disk
        full = programs.call("fit_core", _fit_program, args, options.compiled(), result_structure, fast_compile=True)
    else:
        dynamic, static = eqx.partition(args, eqx.is_array)
        full = _fit_core_jit()(dynamic, static, options.compiled())
    full = first_rows(jax.tree.map(lambda x: np.asarray(x) if isinstance(x, jax.Array) else x, labelled(full, options)), n)
    # An encoder zero that ended a turn away is reported in its range (same model).
    return wrap_periodic(restrict(full, embedding.index, model, caption, numpy=True))


def fit_bucket(n: int) -> int:
    """Rows :func:`fit` compiles for a run of ``n`` observations: the next power of two,
    at least 16. Runs of 80 and 83 stars then share one compiled (and stored) fit, so
    tonight's run is not compiled again because it has a few more stars than last
    night's; the padding costs microseconds of solving, a new size seconds of compiling."""
    return power_of_two(n, 16)


def pad_observations(obs: Observations, rows: int) -> Observations:
    """``obs`` with rows added up to ``rows``: copies of the first observation (a real
    direction, finite readings) at weight 0, so they never enter the fit."""
    n = len(obs)
    if rows <= n:
        return obs
    # The arrays replaced, not the observations built again: ``obs`` was checked when it
    # was made, and a second check would warn again, counting the padding rows.
    return eqx.tree_at(
        lambda o: (o.encoder, o.target, o.weight, o.readings),
        obs,
        (
            pad_rows(obs.encoder, rows),
            pad_rows(obs.target, rows),
            np.concatenate([np.asarray(obs.weight), np.zeros(rows - n)]),
            {k: pad_rows(v, rows) for k, v in obs.readings.items()},
        ),
    )


def prepare(model: Model, data, weights=None, fixed: tuple[str, ...] = ()) -> tuple[Model, Observations]:
    """Check and convert :func:`fit`'s inputs: observations (with ``weights``) in the
    model's convention, ``fixed`` names held, parameters and data as float64 NumPy
    arrays (traced by ``jit``, not baked in; NumPy so that nothing small is compiled)."""
    obs = as_observations(data)
    check_convention(model, obs)
    obs = obs.only_readings(model.readings)
    if weights is not None:
        weights = np.asarray(weights, np.float64)
        if weights.shape != (len(obs),):
            raise ValueError(f"weights must have shape ({len(obs)},), got {weights.shape}")
        if np.any(weights < 0) or not np.all(np.isfinite(weights)):
            raise ValueError("weights must be finite and non-negative")
        obs = obs.with_weight(weights)  # readings kept
    if fixed:
        model = model.fix(*fixed)
    if not np.any(np.asarray(obs.weight) > 0):
        raise ValueError("no observation has a positive weight: nothing to fit")
    params = model.parameters
    model = model.replace_parameters(params, [_host(getattr(model.terms[p.term], p.field)) for p in params])
    obs = jax.tree.map(_host, obs)
    return model, obs


def check_enough_data(model: Model, obs: Observations) -> None:
    """Refuse a fit with no more residuals (two per used observation) than free
    parameters: it would pass through every point, and every sigma would be 0.

    Raises:
        ValueError: naming the counts and what to do (:func:`too_little_data`).
    """
    problem = too_little_data(int(np.sum(np.asarray(obs.weight) > 0)), model.free_parameters)
    if problem:
        raise ValueError(problem)


def _host(x) -> np.ndarray:
    return np.asarray(x, np.float64)

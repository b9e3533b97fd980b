"""The fast pass of :func:`pointax.fit_batch`: a fixed number of Gauss-Newton steps for
every site of a chunk in one compiled call, then each site's statistics and whether it
must go on to the full loop (:func:`pointax.fit`'s optimistix solver).

The problem is the solo fit's (:mod:`pointax.fitting.problem`: :func:`site_data` for
the whole chunk and the residual family), with the Jacobian columns of
:mod:`pointax.fitting.fast_jacobian` and the normal equations of
:mod:`pointax.fitting.normal_equations`, written out so that they vectorise across
sites. Each step is the linearisation the statistics need, so the last one serves
both: no solver state is read.
"""

from __future__ import annotations

import collections
import contextlib
import dataclasses
import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from ..core import xla_options
from ..core.model import Model
from ..core.mounts import SphericalMount
from ..core.term import Term
from . import normal_equations, programs
from .core import fit_result_structure, result_from_covariance, within_tolerances
from .fast_jacobian import residuals_and_columns
from .problem import SiteData, is_affine, site_data, site_residuals
from .result import FitResult

__all__ = [
    "SUSPECT_PIVOT",
    "DEFAULT_STEPS",
    "TPOINT_START_STEPS",
    "TPOINT_START_CHORDS",
    "DEFAULT_CHUNK",
    "SKY_FORM_CHUNK",
    "fast_pass",
    "FastPass",
    "Linearisation",
    "gauss_newton_step",
    "fixed_steps_fits",
    "finish",
    "starts_in_tpoint_form",
    "uses_fast_compile_options",
    "default_chunk_size",
    "compiled",
    "first_call",
    "PROGRAMS",
]

SUSPECT_PIVOT = 1e-8
"""A relative Cholesky pivot of the normal matrix below this sends a site to the exact
(SVD) statistics of the full loop: its parameters may be nearly indistinguishable."""

DEFAULT_STEPS = 5
"""Gauss-Newton steps of the fast pass for models not affine in their parameters (the
fewest that take the library's models from a start within a few tenths of a degree to
float64 precision, ``benchmarks/batch_fit_notes.md``)."""

TPOINT_START_STEPS = 1
"""Exact (sky form) Gauss-Newton steps after the TPOINT-form start (:func:`starts_in_tpoint_form`)."""

TPOINT_START_CHORDS = 2
"""Chord steps after them (:func:`finish`)."""

DEFAULT_CHUNK = 1024
"""Sites per compiled call of :func:`pointax.fit_batch` by default (the working set
stays in the CPU's caches)."""

SKY_FORM_CHUNK = 512
"""Sites per compiled call for the exact (sky) form with sky offsets: its fixed point
carries every parameter's derivative per observation, a larger working set per site."""


PROGRAMS: collections.Counter = collections.Counter()
"""Programs of the batched fit met in this process, per function name (one per model
structure, options and shape: a test's compilation counter)."""

_SEEN: set = set()


def first_call(name: str, args, statics=()) -> bool:
    """Whether this is the first call in this process of the compiled ``name`` with
    arguments of this structure and these shapes (then it is traced and compiled, or
    read from JAX's persistent cache): for :func:`pointax.fit_batch`'s "compiling"
    notice and :data:`PROGRAMS`. Computed from the pytree structure and shapes, without
    tracing."""
    try:
        leaves, treedef = jax.tree.flatten(args)
        shapes = tuple((np.shape(x), _dtype(x)) for x in leaves)
        key = (name, treedef, shapes, statics, bool(jax.config.jax_enable_x64))
        hash(key)
    except TypeError:  # a structure without a hash: say so every time
        return True
    if key in _SEEN:
        return False
    _SEEN.add(key)
    PROGRAMS[name] += 1
    return True


@functools.cache
def compiled(fn, static_argnames: tuple[str, ...] = (), fast_options: bool = True):
    """``fn`` compiled with :func:`pointax.core.xla_options.jit` (one per function and options)."""
    return xla_options.jit(fn, fast_options, static_argnames=static_argnames)


class Linearisation(eqx.Module):
    """One site's Gauss-Newton step (:func:`gauss_newton_step`): the point ``y`` it
    linearised at, the weighted residuals ``rw`` and the Jacobian's columns ``cols``
    there, the Cholesky factor ``low`` of ``J^T J`` (``(m, m)``) with its relative
    ``pivots``, and the ``update`` it makes."""

    y: Array
    rw: tuple[Array, Array]
    cols: list
    low: Array
    pivots: Array
    update: Array


def gauss_newton_step(model: Model, y, data: SiteData) -> Linearisation:
    """One site's Gauss-Newton step from ``y``: the residuals and Jacobian columns of
    :func:`pointax.fitting.fast_jacobian.residuals_and_columns`, the normal equations
    solved by the written-out Cholesky factorisation of
    :mod:`pointax.fitting.normal_equations` (it vectorises across sites)."""
    params = model.free_parameters
    rw, cols = residuals_and_columns(model.replace_parameters(params, [y[k] for k in range(len(params))]), data, params)
    low, pivots = _factor(cols)
    update = -normal_equations.solve(low, [normal_equations.inner(c, rw) for c in cols])
    m = len(cols)
    dense = jnp.stack([jnp.stack([jnp.asarray(low[i][j], y.dtype) for j in range(m)]) for i in range(m)]) if m else jnp.zeros((0, 0))
    return Linearisation(y, rw, cols, dense, pivots, update)


def fixed_steps_fits(
    model: Model, y0, data: SiteData, steps: int, rtol: float, atol: float, chords: int = 0
) -> tuple[FitResult, Array]:
    """A chunk of sites (``y0 (S, M)``, ``data`` with a leading site axis): exactly
    ``steps`` Gauss-Newton steps for every site (:func:`gauss_newton_step`), then
    :func:`finish` (with ``chords`` chord steps). Returns the batched ``(FitResult, suspect)``.

    A fixed count, not a solver's loop: under ``vmap`` every site would run as long as
    the slowest anyway, and the last step's linearisation is the statistics' (a solver
    keeps it in its private state). The loop runs over the whole chunk and ``vmap`` acts
    inside it, one traced step (unrolled, it compiles several times longer and runs no
    faster)."""
    step = jax.vmap(lambda y, d: gauss_newton_step(model, y, d))
    if steps <= 1:
        last = step(y0, data)
    else:
        shapes = jax.eval_shape(step, y0, data)
        start = jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), shapes)
        start = eqx.tree_at(lambda s: s.y, start, y0)
        last = jax.lax.fori_loop(0, steps, lambda _, lin: step(lin.y + lin.update, data), start)
    return jax.vmap(lambda lin, d: finish(model, lin, d, steps, rtol, atol, chords))(last, data)


def finish(model: Model, last: Linearisation, data: SiteData, steps: int, rtol: float, atol: float, chords: int = 0
) -> tuple[FitResult, Array]:  # fmt: skip
    """One site after the fixed steps, from the ``last`` one: its update, the
    convergence test and the statistics.

    With ``chords``, that many chord steps follow: Gauss-Newton updates from the
    residuals evaluated afresh and the same Jacobian and Cholesky factor (a model
    evaluation each, without derivatives: a fraction of a step). They converge linearly
    at a rate of the relative change of the Jacobian over the last update, so two of
    them finish what one Gauss-Newton step from a good start leaves, and the
    convergence test is made on the last one.

    Converged when the last update and the change of the residuals it made are within
    the tolerances (optimistix's Cauchy test) and everything is finite. When the
    residuals are affine in the parameters (:func:`pointax.fitting.problem.is_affine`)
    the Jacobian is the same everywhere, so the test is made on the update still to come
    (from the final residuals), exact after a single step. The covariance comes from the
    last step's Cholesky factor of ``J^T J``; ``suspect`` marks sites whose factor is
    near-singular, for an exact (SVD) second look.
    """
    params = model.free_parameters
    m = len(params)
    cols, update, pivots = last.cols, last.update, last.pivots
    low = normal_equations.factor_entries(last.low)
    y = last.y + update
    # The residuals at the final point from those at the last linearisation and its
    # Jacobian: exact for affine models, and for the others wrong by the square of the
    # last update (a site whose update is not below the tolerances goes to the full loop
    # anyway); evaluating the model once more would cost a good part of a step.
    step_change = _along(cols, update)
    rw = tuple(b + dc for b, dc in zip(last.rw, step_change))  # 0 where unused
    for _ in range(chords):
        rw = site_residuals(model.replace_parameters(params, [y[k] for k in range(m)]), data)
        update = -normal_equations.solve(low, [normal_equations.inner(c, rw) for c in cols])
        y = y + update
        step_change = _along(cols, update)
        rw = tuple(b + dc for b, dc in zip(rw, step_change))
    safe_w = jnp.where(data.sqrt_weight > 0, data.sqrt_weight, 1.0)
    r = jnp.stack([jnp.where(data.used, x / safe_w, 0.0) for x in rw], axis=-1)
    if is_affine(model):
        # The same Jacobian everywhere: the update still to come, from the final residuals.
        update = normal_equations.solve(low, [normal_equations.inner(c, rw) for c in cols])
        f_change = _along(cols, update)
    else:
        f_change = step_change
    fitted = model.replace_parameters(params, [y[k] for k in range(m)])
    # Per residual component (a concatenation would copy every column once more).
    small = jnp.all(within_tolerances(update, y, rtol, atol))
    for change, now in zip(f_change, rw):
        small = small & jnp.all(within_tolerances(change, now, rtol, atol))
    suspect = ~jnp.all(pivots > SUSPECT_PIVOT) if m else jnp.asarray(False)
    unit_cov = normal_equations.inverse(low) if m else jnp.zeros((0, 0))
    result = result_from_covariance(
        fitted, y, unit_cov, r, jnp.stack(rw, axis=-1), data.used, steps + chords, small, "gauss-newton"
    )
    return result, suspect


def _factor(cols: list):
    """The Cholesky factor of ``J^T J`` as nested lists of entries, and its relative
    pivots, from J's columns (``jnp.linalg`` above
    :data:`pointax.fitting.normal_equations.MAX_UNROLLED` unknowns, as
    ``jnp.linalg.cholesky``)."""
    if len(cols) > normal_equations.MAX_UNROLLED:
        j = jnp.stack([jnp.concatenate([jnp.ravel(x) for x in jax.tree.leaves(c)]) for c in cols], axis=-1)
        a = j.T @ j
        low = jnp.linalg.cholesky(a)
        return normal_equations.factor_entries(low), jnp.diagonal(low) ** 2 / jnp.diagonal(a)
    return normal_equations.cholesky(normal_equations.normal_matrix(cols))


def _along(cols: list, update) -> list:
    """``J @ update`` as the two residual components, from J's columns (0 with no column)."""
    return [sum(update[k] * c[i] for k, c in enumerate(cols)) if cols else 0.0 for i in range(2)]


def uses_fast_compile_options(model: Model) -> bool:
    """Whether the fast pass compiles ``model``'s fit with
    :data:`pointax.core.xla_options.FAST_COMPILE_OPTIONS`: not for the exact (sky)
    residual form with sky offsets, whose fixed-point iterations run faster with XLA's
    default emitters and compile no slower."""
    return not sky_form_with_sky_offsets(model)


def sky_form_with_sky_offsets(model: Model) -> bool:
    """Whether ``model`` is fitted in the exact (sky) form and some term has a sky offset
    (then the form solves a fixed point per observation)."""
    return model.residual_form == "sky" and any(
        type(t).sky_offset is not Term.sky_offset or type(t).sky_offset_at is not Term.sky_offset_at for t in model.terms
    )


def default_chunk_size(model: Model) -> int:
    """:func:`pointax.fit_batch`'s chunk size for ``model`` (``chunk_size='auto'``)."""
    return SKY_FORM_CHUNK if sky_form_with_sky_offsets(model) else DEFAULT_CHUNK


def starts_in_tpoint_form(model: Model) -> bool:
    """Whether the fast pass starts the exact (sky) form's fit of ``model`` from the
    solution of its TPOINT form: a model with sky offsets (else the sky form is the
    chain alone) on a mount with spherical angles (which TPOINT's form needs) whose
    free parameters are all in linear sky-offset terms, so that one step solves the
    TPOINT form. (With a free rotation term, one step of the TPOINT form can leave too
    much for one exact step and two chords.)"""
    return (
        model.residual_form == "sky"
        and isinstance(model.mount, SphericalMount)
        and sky_form_with_sky_offsets(model)
        and all(model.terms[p.term].linear_sky_offset for p in model.free_parameters)
    )


def _site_data_and_fits(model, y0, obs, steps: int, rtol: float, atol: float, tpoint_start: bool = False):
    """The site data of a chunk and :func:`fixed_steps_fits` on them (one computation)."""
    if tpoint_start:
        # TPOINT's form of the same model is linear in the library's terms: one step
        # solves it, and its solution is within the square of the corrections of the
        # exact form's, so one exact step and two chord steps finish the fit.
        start = model.with_residual_form("tpoint")
        first, _ = fixed_steps_fits(start, y0, site_data(start, obs), 1, rtol, atol)
        y0 = jnp.where(jnp.all(jnp.isfinite(first.values), axis=-1, keepdims=True), first.values, y0)
        result, suspect = fixed_steps_fits(model, y0, site_data(model, obs), steps, rtol, atol, TPOINT_START_CHORDS)
        return dataclasses.replace(result, iterations=result.iterations + 1), suspect  # the start's step counts
    return fixed_steps_fits(model, y0, site_data(model, obs), steps, rtol, atol)


def fast_pass(
    model: Model, values, obs, steps: int, rtol: float, atol: float, notice=None
) -> tuple[FitResult, Array]:
    """The fast pass over one chunk (``values (S, M)``, ``obs`` with a leading site axis):
    the site data, then :func:`fixed_steps_fits`; the batched ``(FitResult, suspect)``.
    :class:`FastPass` does the same for the many chunks of one batch.

    ``notice``: ``notice()`` gives a context that the first call of a program (a
    compilation, :func:`first_call`) runs in, e.g. a progress bar's activity."""
    return FastPass(model, steps, rtol, atol)(values, obs, notice)


class FastPass:
    """The fast pass (:func:`fast_pass`) of one model and settings, set up once for the
    chunks of a :func:`pointax.fit_batch` call: the program and its compiler options are
    chosen once, and the first-call check (:func:`first_call`) runs once per chunk
    shape, not once per chunk (the Python between chunks takes a core from the fits).

    With more than one step (or the TPOINT-form start), one compiled call: the step loop
    takes the site data as arrays, so XLA computes each of them once. With one step
    (affine models) there is no loop, and inside one computation XLA on the CPU
    recomputes the data's arctangents, sines and cosines in every fusion that uses them,
    so the site data are a call of their own and handed over as arrays."""

    def __init__(self, model: Model, steps: int, rtol: float, atol: float):
        self.model, self.steps, self.rtol, self.atol = model, int(steps), rtol, atol
        self.fast = uses_fast_compile_options(model)
        self.tpoint_start = starts_in_tpoint_form(model)
        self._checked: set = set()

    def __call__(self, values, obs, notice=None) -> tuple[FitResult, Array]:
        """The fast pass over one chunk (as :func:`fast_pass`)."""
        model, steps, rtol, atol = self.model, self.steps, self.rtol, self.atol
        shape = (np.shape(values), np.shape(obs.encoder), _dtype(values), _dtype(obs.encoder), obs.convention, tuple(obs.readings))
        first = False
        if shape not in self._checked:  # every other leaf's shape follows from these
            self._checked.add(shape)
            statics = (steps, rtol, atol, self.fast, self.tpoint_start)
            first = first_call("fast_pass", (model, values, obs), statics)
        with notice() if first and notice is not None else contextlib.nullcontext():
            return self._run(values, obs)

    def _run(self, values, obs) -> tuple[FitResult, Array]:
        model, steps, rtol, atol, fast = self.model, self.steps, self.rtol, self.atol, self.fast
        if (steps > 1 or self.tpoint_start) and programs.directory() is not None:
            # Stored programs (jax.export): a later process does not trace this fit again
            # (tracing it costs more than loading its compiled code, benchmarks/network_scale.py).
            static = (steps, float(rtol), float(atol), bool(self.tpoint_start))
            return programs.call("batch_fast_pass", _stored_fast_pass, (model, values, obs), static, _fast_pass_structure, fast)
        statics = ("steps", "rtol", "atol")
        if steps > 1 or self.tpoint_start:
            return compiled(_site_data_and_fits, statics + ("tpoint_start",), fast)(
                model, values, obs, steps=steps, rtol=rtol, atol=atol, tpoint_start=self.tpoint_start
            )
        data = compiled(site_data, (), fast)(model, obs)
        return compiled(fixed_steps_fits, statics, fast)(model, values, data, steps=steps, rtol=rtol, atol=atol)


def _dtype(x) -> str:
    """The name of ``x``'s dtype (an array's, or NumPy's for a Python number)."""
    dtype = getattr(x, "dtype", None)
    return str(dtype if dtype is not None else np.asarray(x).dtype)


def _stored_fast_pass(model, values, obs, static):
    """:func:`_site_data_and_fits` in :func:`pointax.fitting.programs.call`'s form."""
    steps, rtol, atol, tpoint_start = static
    return _site_data_and_fits(model, values, obs, steps, rtol, atol, tpoint_start)


def _fast_pass_structure(model, values, obs, static):
    """The pytree structure of :func:`_site_data_and_fits`'s ``(FitResult, suspect)``,
    built without tracing (checked by :mod:`pointax.fitting.programs` before storing)."""
    return jax.tree_util.treedef_tuple([fit_result_structure(model, model.free_parameters), jax.tree.structure(0)])

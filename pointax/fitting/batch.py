"""Fits of many sites in one compiled call: the same model structure, per-site data
and parameters, per-site status.

    batch = px.stack_observations([obs_site_1, obs_site_2, ...])   # ragged -> padded
    result = px.fit_batch(model, batch)                            # FitResult, leading axis = site
    result.converged                                               # (S,) per site
    px.site_result(result, 7).report()                             # one site's report

Every site first gets a fixed number of optimistix Gauss-Newton steps on the structured
evaluation of :mod:`pointax.fitting.fast_evaluation` (``jax.vmap`` over sites, chunks of sites per compiled
call); a site that does not converge there is refitted with :func:`pointax.fit`'s full
loop. A site whose data are bad (NaN in a used row, degenerate geometry, wild outliers)
or whose fit diverges is flagged by its own ``converged`` and ``message`` and changes
nothing for the others. Padding rows carry weight 0 and do not enter any statistic.
Parameters shared by all sites: :func:`pointax.fit_shared`.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from . import normal_equations
from ..core.precision import float64
from . import xla_options
from .core import result_from_covariance
from .options import FitOptions
from .ranges import range_warning, wrap_periodic
from .residuals import check_convention
from .result import FitResult, too_few_residuals
from .solo import fit_model, options_from
from ..core.model import Model
from ..core.mounts import SphericalMount
from .normal_equations import CholeskyGaussNewton
from ..core.term import Term
from ..core.observations import Observations
from .fast_evaluation import (
    SiteData,
    is_affine,
    observed_point,
    site_geometry,
    site_residuals,
    with_sky_basis,
)
from .fast_jacobian import residual_function

SUSPECT_PIVOT = 1e-8
"""A relative Cholesky pivot of the normal matrix below this sends a site to the exact
(SVD) statistics of the full loop: its parameters may be nearly indistinguishable."""

DEFAULT_STEPS = 5
"""Gauss-Newton steps of :func:`fit_batch`'s fast pass for models not affine in their
parameters (with 4, 11 of 4,000 turntables went on to the full loop; with 3, all)."""

__all__ = ["stack_observations", "batched_observations", "fit_batch", "site_result", "site_statuses"]


def stack_observations(sites: Sequence[Observations], n_obs: int | None = None) -> Observations:
    """Pad per-site observations to a common length and stack them: ``(S, N, ...)``.

    Padding rows have weight 0 (they never enter a fit) and hold a harmless direction.

    Args:
        sites: one :class:`pointax.Observations` per site, all in one convention.
        n_obs: rows per site after padding (default: the longest site).

    Raises:
        ValueError: no sites, mixed conventions, or a site longer than ``n_obs``.
    """
    if not sites:
        raise ValueError("no sites to stack")
    conventions = {s.convention for s in sites}
    if len(conventions) > 1:
        raise ValueError(f"sites mix encoder conventions {sorted(map(str, conventions))}")
    longest = max(len(s) for s in sites)
    n = longest if n_obs is None else int(n_obs)
    if n < longest:
        raise ValueError(f"n_obs={n} is shorter than the longest site ({longest} observations)")
    encoder = np.zeros((len(sites), n, 2))
    target = np.tile(np.array([0.0, 1.0, 0.0]), (len(sites), n, 1))
    weight = np.zeros((len(sites), n))
    for k, s in enumerate(sites):
        m = len(s)
        encoder[k, :m] = np.asarray(s.encoder)
        target[k, :m] = np.asarray(s.target)
        weight[k, :m] = np.asarray(s.weight)
    return batched_observations(encoder, target, weight, conventions.pop())


def batched_observations(encoder, target, weight, convention) -> Observations:
    """An Observations pytree with a leading site axis (bypasses the 2-D shape checks)."""
    obs = Observations(encoder[0], target[0], weight[0], convention)
    return eqx.tree_at(lambda o: (o.encoder, o.target, o.weight), obs, (encoder, target, weight))


def site_result(result: FitResult, site: int) -> FitResult:
    """One site's :class:`pointax.FitResult` out of a batched one (report, table, ...)."""
    # x[site, ...] keeps 0-d arrays (x[site] of a NumPy leaf would be a NumPy scalar).
    return jax.tree.map(lambda x: x[site, ...], result)


def site_statuses(result: FitResult) -> list[dict[str, str]]:
    """Per site of a batched result: ``{"status": ..., "reason": ...}`` with status
    ``"converged"``, ``"degenerate"`` (converged, but some parameters cannot be told
    apart: the reason names them) or ``"failed"`` (the reason says why: too few
    observations for the free parameters, as :func:`pointax.fit` refuses them, or why
    the solver stopped). A converged site whose values lie outside their declared ranges
    (:mod:`pointax.fitting.ranges`: an equivalent solution in another branch) keeps its
    status, with the reason saying so."""
    out = []
    for k in range(int(np.shape(result.converged)[0])):
        one = site_result(result, k)
        degenerate = [n for n, d in zip(one.names, np.asarray(one.degenerate)) if d]
        if not bool(one.converged):
            out.append({"status": "failed", "reason": one.message})
        elif degenerate:
            out.append({"status": "degenerate", "reason": "cannot be told apart: " + ", ".join(degenerate)})
        else:
            out.append({"status": "converged", "reason": range_warning(np.asarray(one.values), one.model.free_parameters)})
    return out


def check_batch(observations) -> None:
    """Raise ValueError unless ``observations`` is a batch ``(S, N, ...)``."""
    if not isinstance(observations, Observations) or np.ndim(observations.encoder) != 3:
        raise ValueError("observations must be a batch of shape (S, N, ...): build it with pointax.stack_observations")


def start_values(model: Model, n_sites: int, values, what: str = "free parameters") -> np.ndarray:
    """``(S, M)`` starting values of ``model``'s free parameters per site, float64: the
    model's own values for every site when ``values`` is None; ValueError for a wrong shape."""
    n_free = len(model.free_parameters)
    if values is None:
        values = np.broadcast_to(np.asarray(model.values("free"), np.float64), (n_sites, n_free))
    values = np.asarray(values, np.float64)
    if values.shape != (n_sites, n_free):
        raise ValueError(f"values must have shape ({n_sites}, {n_free}) (sites, {what}), got {values.shape}")
    return values


def _fixed_steps_fits(model: Model, y0, data: SiteData, steps: int, rtol: float, atol: float, chords: int = 0):
    """A chunk of sites (``y0 (S, M)``, ``data`` with a leading site axis): exactly
    ``steps`` optimistix Gauss-Newton steps for every site (no early exit: under ``vmap``
    every site would run as long as the slowest anyway) with the structured residuals
    of :mod:`pointax.fitting.fast_evaluation` and the :class:`NormalCholesky` solver
    (:class:`pointax.fitting.normal_equations.CholeskyGaussNewton`, which keeps the last Cholesky
    factor for the statistics), then the statistics
    (:func:`_finish`, with ``chords`` chord steps). Returns the batched ``(FitResult, suspect)``.

    The loop runs over the whole chunk and ``vmap`` acts inside it: vmapping the loop
    instead made JAX batch its body twice while tracing (once more for every carried
    value that starts the same for all sites), 0.35 s of the first call.
    """
    params = model.free_parameters
    fn = residual_function(params)
    solver = CholeskyGaussNewton(rtol=rtol, atol=atol)

    def with_aux(y, a):
        return fn(y, a), None

    n = data.used.shape[-1]
    f_struct = (jax.ShapeDtypeStruct((n,), y0.dtype), jax.ShapeDtypeStruct((n,), y0.dtype))
    # The initial state for one site, broadcast to all sites, with each site's start as
    # y_eval (where the first step evaluates; the rest of the state depends on the start
    # only through its shape). optimistix's init traces the linearisation for its shapes,
    # and under vmap JAX batched that trace too: 0.1 s of a fresh process's first call.
    one_site = jax.tree.map(lambda x: x[0], (y0, data))
    state = solver.init(with_aux, one_site[0], (model, one_site[1]), {}, f_struct, None, frozenset())
    n_sites = y0.shape[0]
    state = jax.tree.map(lambda x: jnp.broadcast_to(x, (n_sites, *x.shape)) if eqx.is_array(x) else x, state)
    state = eqx.tree_at(lambda s: s.y_eval, state, y0)
    # optimistix's own steps in a fixed-count loop (one traced step: compiles once; an
    # unrolled loop compiled 2-3x longer and ran no faster, see benchmarks/batch_fit_notes.md).
    dynamic, static = eqx.partition(state, eqx.is_array)

    def one_step(y, dynamic, d):
        y, state, _ = solver.step(with_aux, y, (model, d), {}, eqx.combine(dynamic, static), frozenset())
        return y, eqx.filter(state, eqx.is_array)

    def body(_, carry):
        return jax.vmap(one_step)(*carry, data)

    y, dynamic = jax.lax.fori_loop(0, steps, body, (y0, dynamic))
    finish = lambda y, dynamic, d: _finish(model, y, eqx.combine(dynamic, static), d, steps, rtol, atol, chords)  # noqa: E731
    return jax.vmap(finish)(y, dynamic, data)


def _finish(
    model: Model, y, state, data: SiteData, steps: int, rtol: float, atol: float, chords: int = 0
) -> tuple[FitResult, Array]:
    """One site after the fixed steps (``y``: the last accepted point, ``state`` the
    solver's): the convergence test and the statistics.

    With ``chords``, that many chord steps follow: Gauss-Newton updates from the
    residuals evaluated afresh and the last step's Jacobian and Cholesky factor (a
    model evaluation each, without derivatives: a fraction of a step). They converge
    linearly at a rate of the relative change of the Jacobian over the last update,
    so two of them finish what one Gauss-Newton step from a good start leaves, and the
    convergence test is made on the last one.

    Converged when the last update and the change of the residuals it made are within
    the tolerances (optimistix's Cauchy test) and everything is finite. When the
    residuals are affine in the parameters (:func:`pointax.fitting.fast_evaluation.is_affine`) the
    Jacobian is the same everywhere, so the test is made on the update still to come
    (from the final residuals), exact after a single step. The covariance comes from the
    Cholesky factor of ``J^T J`` that the last step computed (the solver's descent keeps
    it: factorising again here cost 0.2 s of compilation); ``suspect`` marks sites whose
    factor is near-singular, for an exact (SVD) second look.
    """
    params = model.free_parameters
    m = len(params)
    # optimistix evaluates at y_eval and accepts y one step later: y_eval holds the last
    # update, made from the residuals and Jacobian at y.
    update = state.y_eval - y
    y = state.y_eval
    cols = normal_equations.columns(state.f_info.jac)
    # The residuals at the final point from those at y and the Jacobian there: exact for
    # affine models, and for the others wrong by the square of the last update (a site
    # whose update is not below the tolerances goes to the full loop anyway). Evaluating
    # the model once more cost a sixth of a step and 0.3 s of compilation.
    step_change = _along(cols, update)
    rw = tuple(b + dc for b, dc in zip(state.f_info.residual, step_change))  # 0 where unused
    safe_w = jnp.where(data.sqrt_weight > 0, data.sqrt_weight, 1.0)
    r = jnp.stack([jnp.where(data.used, x / safe_w, 0.0) for x in rw], axis=-1)
    # The covariance from the last step's Jacobian and its factor (at the point before the
    # last update, which is below the tolerances: the difference is of the order of that
    # update).
    low, pivots = normal_equations.factor_entries(state.descent_state.low), state.descent_state.pivots
    for _ in range(chords):
        rw = site_residuals(model.replace_parameters(params, [y[k] for k in range(m)]), data)
        update = -normal_equations.solve(low, [normal_equations.inner(c, rw) for c in cols])
        y = y + update
        step_change = _along(cols, update)
        rw = tuple(b + dc for b, dc in zip(rw, step_change))
    if chords:
        r = jnp.stack([jnp.where(data.used, x / safe_w, 0.0) for x in rw], axis=-1)
    if is_affine(model):
        # The same Jacobian everywhere: the update still to come, from the final residuals.
        update = normal_equations.solve(low, [normal_equations.inner(c, rw) for c in cols])
        f_change = _along(cols, update)
    else:
        f_change = step_change
    fitted = model.replace_parameters(params, [y[k] for k in range(m)])
    # Per residual component (a concatenation would copy every column once more).
    small = jnp.all(jnp.abs(update) <= atol + rtol * jnp.abs(y))
    for change, now in zip(f_change, rw):
        small = small & jnp.all(jnp.abs(change) <= atol + rtol * jnp.abs(now))
    suspect = ~jnp.all(pivots > SUSPECT_PIVOT) if m else jnp.asarray(False)
    unit_cov = normal_equations.inverse(low) if m else jnp.zeros((0, 0))
    result = result_from_covariance(
        fitted, y, unit_cov, r, jnp.stack(rw, axis=-1), data.used, steps + chords, small, "gauss-newton"
    )
    return result, suspect


def _along(cols: list, update) -> list:
    """``J @ update`` as the two residual components, from J's columns (0 with no column)."""
    return [sum(update[k] * c[i] for k, c in enumerate(cols)) if cols else 0.0 for i in range(2)]


@functools.cache
def _compiled(fn, static_argnames: tuple[str, ...] = (), fast_options: bool = True):
    return xla_options.jit(fn, fast_options, static_argnames=static_argnames)


def uses_fast_compile_options(model: Model) -> bool:
    """Whether the fast path compiles ``model``'s fit with :data:`pointax.fitting.xla_options.FAST_COMPILE_OPTIONS`:
    not for the exact (sky) residual form with sky offsets, whose fixed-point iterations
    ran twice as fast with XLA's default emitters (8 TPOINT terms, 1,024 sites: 0.51
    against 1.05 s per call) and compiled no slower."""
    return not _sky_form_with_sky_offsets(model)


def _sky_form_with_sky_offsets(model: Model) -> bool:
    """Whether ``model`` is fitted in the exact (sky) form and some term has a sky offset
    (then the form solves a fixed point per observation)."""
    return model.residual_form == "sky" and any(
        type(t).sky_offset is not Term.sky_offset or type(t).sky_offset_at is not Term.sky_offset_at for t in model.terms
    )


def _site_data_batch(model, obs) -> SiteData:
    """:func:`pointax.fitting.fast_evaluation.site_data` for a chunk (a leading site axis), with the
    observed point for the whole chunk at once (so the mount's pole check is one test)."""
    data, target = jax.vmap(lambda o: site_geometry(model, o))(obs)
    if target is None:
        return data
    point = observed_point(model, data, target)
    return jax.vmap(lambda d, p: with_sky_basis(model, d, p))(data, point)


def _site_data_and_fits(model, y0, obs, steps: int, rtol: float, atol: float, tpoint_start: bool = False):
    if tpoint_start:
        # TPOINT's form of the same model is linear in the library's terms: one step
        # solves it, and its solution is within the square of the corrections of the
        # exact form's, so one exact step and two chord steps finish the fit, where
        # five exact steps from the start values cost several times as much
        # (benchmarks/batch_fit_notes.md).
        start = model.with_residual_form("tpoint")
        first, _ = _fixed_steps_fits(start, y0, _site_data_batch(start, obs), 1, rtol, atol)
        y0 = jnp.where(jnp.all(jnp.isfinite(first.values), axis=-1, keepdims=True), first.values, y0)
        result, suspect = _fixed_steps_fits(model, y0, _site_data_batch(model, obs), steps, rtol, atol, TPOINT_START_CHORDS)
        return dataclasses.replace(result, iterations=result.iterations + 1), suspect  # the start's step counts
    return _fixed_steps_fits(model, y0, _site_data_batch(model, obs), steps, rtol, atol)


TPOINT_START_STEPS = 1
"""Exact (sky form) Gauss-Newton steps after the TPOINT-form start (:func:`starts_in_tpoint_form`)."""

TPOINT_START_CHORDS = 2
"""Chord steps after them (:func:`_finish`)."""


DEFAULT_CHUNK = 1024
"""Sites per compiled call of :func:`fit_batch` by default."""

SKY_FORM_CHUNK = 512
"""Sites per compiled call for the exact (sky) form with sky offsets: its fixed point
carries every parameter's derivative per observation, a larger working set per site
(1,024 sites per chunk ran at two thirds of the rate of 512 or 256,
``benchmarks/batch_fit_notes.md``)."""


def default_chunk_size(model: Model) -> int:
    """:func:`fit_batch`'s chunk size for ``model`` (``chunk_size='auto'``)."""
    return SKY_FORM_CHUNK if _sky_form_with_sky_offsets(model) else DEFAULT_CHUNK


def starts_in_tpoint_form(model: Model) -> bool:
    """Whether the fast pass starts the exact (sky) form's fit of ``model`` from the
    solution of its TPOINT form: a model with sky offsets (else the sky form is the
    chain alone) on a mount with spherical angles (which TPOINT's form needs) whose
    free parameters are all in linear sky-offset terms, so that one step solves the
    TPOINT form. (With a free rotation term, say a wobble started 5 deg off in phase,
    one step of the TPOINT form leaves too much for one exact step and two chords, and
    every site went to the full loop where five exact steps had converged.)"""
    return (
        model.residual_form == "sky"
        and isinstance(model.mount, SphericalMount)
        and _sky_form_with_sky_offsets(model)
        and all(model.terms[p.term].linear_sky_offset for p in model.free_parameters)
    )


def _fit_sites_fixed(model, values, obs, steps, rtol, atol):
    """The fast pass over one chunk: the site data, then :func:`_fixed_steps_fits`.

    With more than one step, one compiled call: the step loop takes the site data as
    arrays, so XLA computes each of them once, and one module compiles faster than two
    (compiled alone: 1.5-1.8 against 2.0-2.1 s for 1,024 turntables). With one step (affine models) there is no loop, and inside one computation XLA
    on the CPU recomputes the data's arctangents, sines and cosines in every fusion that
    uses them (measured: 136 copies, 20 M transcendentals per 4,000 sites; the TPOINT
    fit 6.3-9 against 5.4-5.8 ms per 1,024 sites), so the site data are a call of their
    own and handed over as arrays."""
    statics = ("steps", "rtol", "atol")
    fast = uses_fast_compile_options(model)
    tpoint_start = starts_in_tpoint_form(model)
    if steps > 1 or tpoint_start:
        return _compiled(_site_data_and_fits, statics + ("tpoint_start",), fast)(
            model, values, obs, steps=steps, rtol=rtol, atol=atol, tpoint_start=tpoint_start
        )
    data = _compiled(_site_data_batch, (), fast)(model, obs)
    return _compiled(_fixed_steps_fits, statics, fast)(model, values, data, steps=steps, rtol=rtol, atol=atol)


def _fit_sites(model, values, obs, options: FitOptions, active=None):
    """The full loop (:func:`pointax.fitting.fit_model`, the solo fit) for every site
    ``active`` marks (default all; padding sites are skipped, not fitted), one site after
    another (``lax.map``): their step counts differ, and under ``vmap`` each ran as long
    as the slowest. Compiled with the solo fit's compiler options
    (:mod:`pointax.fitting.xla_options`): 64 sites of the wobble example (every site
    leaves the fast pass) took 0.38 s with them against 1.17 s (compiled in 5.4 against
    6.9 s), where a Python loop of ``px.fit`` took 0.56 s; under ``vmap`` 1.7 s."""
    if active is None:
        active = np.ones(np.shape(values)[0], bool)
    dynamic, static = eqx.partition((model, values, obs, np.asarray(active)), eqx.is_array)
    return _compiled(_full_loop, ("static", "options"))(dynamic, static, options)


def _full_loop(dynamic, static, options: FitOptions):
    """:func:`_fit_sites`'s loop; ``dynamic`` and ``static``: ``(model, values, obs,
    active)`` partitioned into arrays and the rest."""
    model, values, obs, active = eqx.combine(dynamic, static)

    def one(args):
        y, site_obs = args
        return fit_model(model.with_values(y, "free"), site_obs, options)

    shapes = jax.eval_shape(one, jax.tree.map(lambda x: x[0], (values, obs)))

    def maybe(args):
        is_active, y, site_obs = args
        skip = lambda a: jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), shapes)  # noqa: E731
        return jax.lax.cond(is_active, one, skip, (y, site_obs))

    return jax.lax.map(maybe, (active, values, obs))


def _power_of_two(n: int) -> int:
    """The smallest power of two >= ``n`` (``n >= 1``)."""
    return 1 << (int(n) - 1).bit_length()


def _pad_sites(tree, size: int):
    """Pad the leading (site) axis of every leaf to ``size`` with copies of site 0, and
    hand the leaves to JAX in one ``device_put`` (``jnp.asarray`` would compile a small
    program per new shape). They may share memory with the NumPy arrays: nothing here
    writes to those while the fits that read them run."""

    def pad(x):
        x = np.asarray(x)
        if x.shape[0] < size:
            x = np.concatenate([x, np.repeat(x[:1], size - x.shape[0], axis=0)])
        return x

    return jax.device_put(jax.tree.map(pad, tree), may_alias=True)


def _host(x) -> np.ndarray:
    return np.asarray(x, np.float64)


def _first_sites(tree, n: int):
    """The first ``n`` sites of every leaf, as NumPy arrays."""
    return jax.tree.map(lambda x: np.asarray(x)[:n], tree)


def _take_sites(tree, index):
    return jax.tree.map(lambda x: np.asarray(x)[index], tree)


def _put_sites(tree, index, part):
    """``tree`` with the sites ``index`` replaced by ``part`` (numpy, on the host)."""

    def put(x, y):
        x = np.array(x)
        x[index] = np.asarray(y)[: len(index)]
        return x

    return jax.tree.map(put, tree, part)


@float64
def fit_batch(
    model: Model,
    observations: Observations,
    *,
    values: Float[ArrayLike, "S M"] | None = None,
    steps: int | None = None,
    solver: str = "lm",
    max_steps: int = 256,
    rtol: float = 1e-10,
    atol: float = 1e-13,
    loss: str = "linear",
    loss_scale: float | None = None,
    reject: float = 3.0,
    chunk_size: int | str | None = "auto",
    progress: Callable[[int, int], None] | None = None,
    options: FitOptions | None = None,
) -> FitResult:
    """Fit ``model`` to every site of a batch, each with its own parameters.

    How (least squares, ``loss="linear"``): every site first gets ``steps`` Gauss-Newton
    steps, all sites in one compiled call with no per-site loop or branch (optimistix's
    Gauss-Newton with the structured residuals of :mod:`pointax.fitting.fast_evaluation` and the
    :class:`pointax.fitting.normal_equations.NormalCholesky` solver). A site whose last step
    does not meet the tolerances (optimistix's Cauchy test with ``rtol``, ``atol``), or
    whose normal matrix is near-singular, is then fitted again from its start with the
    full ``solver`` loop (:func:`pointax.fit`'s algorithm, SVD statistics): so every
    converged site meets the same tolerances as a solo :func:`pointax.fit`, and a bad
    site gets a solo fit's diagnosis. ``steps=0`` sends every site through the full
    loop; robust losses always use it. The exact (sky) form of a model with sky
    offsets on a mount with spherical angles starts from the one-step solution of its
    TPOINT form, and its exact steps end with two chord steps
    (:func:`starts_in_tpoint_form`): 4 times the rate of five exact steps from the
    start values (``benchmarks/batch_fit_notes.md``).

    Args:
        model: the model (structure, fixed parameters and default starting values).
        observations: ``(S, N, ...)`` observations from :func:`stack_observations`.
        values: ``(S, M)`` starting values of the free parameters per site (default:
            the model's values for every site).
        steps: Gauss-Newton steps of the fast first pass (0: none). Default: 1 when the
            residuals are affine in the free parameters (``residual_form="tpoint"`` with
            only TPOINT linear-form terms free, :func:`pointax.fitting.fast_evaluation.is_affine`: one step
            is the solution, and the check needs no second), 1 after the TPOINT-form
            start (:func:`starts_in_tpoint_form`), else 5 (they take a start within a
            few tenths of a degree to float64 precision).
        solver, max_steps, rtol, atol, loss, loss_scale, reject: as in :func:`pointax.fit`.
        chunk_size: sites per compiled call (``None``: all at once; 'auto', the
            default: :func:`default_chunk_size`). Chunks bound the memory and keep the
            working set in the CPU's caches (1,024 sites per chunk ran 1.4x faster
            than 4,096, see ``benchmarks/batch_fit_notes.md``);
            every chunk has the same shape (the last is padded), so one compilation
            serves them all. A batch smaller than a chunk is padded to the next power
            of two: batches of 100 and of 101 sites share one compilation.
        progress: called as ``progress(sites_done, sites_total)`` after each chunk.
        options: ``solver`` to ``reject`` as one :class:`pointax.FitOptions` (then
            leave those keywords at their defaults).

    Returns:
        A :class:`pointax.FitResult` whose arrays have a leading site axis; per site:
        values, sigmas, statistics, iterations (both passes), ``converged`` and, through
        :func:`site_result`, its report and ``message``. ``solver`` names the full loop's
        solver.
    """
    options = options_from(
        options, solver=solver, max_steps=max_steps, rtol=rtol, atol=atol, loss=loss, loss_scale=loss_scale, reject=reject
    )
    solver, rtol, atol = options.solver, options.rtol, options.atol
    check_batch(observations)
    if steps is None:
        steps = 1 if is_affine(model) else TPOINT_START_STEPS if starts_in_tpoint_form(model) else DEFAULT_STEPS
    if int(steps) < 0:
        raise ValueError(f"steps must be >= 0, got {steps!r}")
    check_convention(model, observations)
    n_sites = observations.encoder.shape[0]
    values = start_values(model, n_sites, values)
    # Parameters as float64 arrays (host-side: no small computations to compile).
    model = model.replace_parameters(model.parameters, [_host(getattr(model.terms[p.term], p.field)) for p in model.parameters])
    fast = int(steps) > 0 and not options.robust
    site_obs = batched_observations(
        np.asarray(observations.encoder, np.float64),
        np.asarray(observations.target, np.float64),
        np.asarray(observations.weight, np.float64),
        observations.convention,
    )
    if isinstance(chunk_size, str):
        if chunk_size != "auto":
            raise ValueError(f"chunk_size must be a number of sites, None or 'auto', got {chunk_size!r}")
        chunk_size = default_chunk_size(model)
    size = n_sites if chunk_size is None else min(max(1, int(chunk_size)), _power_of_two(n_sites))
    chunks = [(start, min(start + size, n_sites)) for start in range(0, n_sites, size)]

    def chunk_inputs(start, stop):
        return _pad_sites(values[start:stop], size), _pad_sites(_take_sites(site_obs, slice(start, stop)), size)

    results = []
    if fast:
        # Dispatch every chunk first (JAX runs them asynchronously), then look at them:
        # checking each chunk before dispatching the next would leave the CPU idle.
        pending = []
        for start, stop in chunks:
            y0, obs = chunk_inputs(start, stop)
            pending.append((start, stop, y0, obs, _fit_sites_fixed(model, y0, obs, int(steps), rtol, atol)))
        for start, stop, y0, obs, (out, suspect) in pending:
            n = stop - start
            again = np.flatnonzero(~np.asarray(out.converged)[:n] | np.asarray(suspect)[:n])
            if again.size:
                # Few sites: pad to a power of two so that few shapes are compiled.
                pad = max(8, _power_of_two(again.size))
                redo = _fit_sites(
                    model,
                    _pad_sites(np.asarray(y0)[again], pad),
                    _pad_sites(_take_sites(obs, again), pad),
                    options,
                    active=np.arange(pad) < again.size,
                )
                # (the solver's name is static: one name for the batch, set at the end)
                fast_steps = np.asarray(out.iterations)[again]
                redo = dataclasses.replace(redo, iterations=redo.iterations + _pad_sites(fast_steps, pad), solver=out.solver)
                out = _put_sites(out, again, redo)
            results.append(_first_sites(out, n))
            if progress is not None:
                progress(stop, n_sites)
    else:
        for start, stop in chunks:
            y0, obs = chunk_inputs(start, stop)
            out = _fit_sites(model, y0, obs, options, active=np.arange(size) < stop - start)
            results.append(_first_sites(out, stop - start))
            if progress is not None:
                progress(stop, n_sites)
    # Assembled on the host: JAX's slicing and concatenation (and jnp.asarray) would each
    # compile a small computation per result field on the first call (0.6 s measured).
    result = jax.tree.map(lambda *xs: np.concatenate(xs), *results)
    # A site with no more residuals than free parameters fits every point, with every
    # sigma 0: refused, as px.fit refuses it (the reason: FitResult.message).
    too_few = too_few_residuals(result.n_obs, len(model.free_parameters))
    result = dataclasses.replace(result, converged=np.asarray(result.converged) & ~too_few, solver=solver)
    # An encoder zero that ended a turn away is reported in its range (same model).
    return wrap_periodic(jax.device_put(result, may_alias=True))

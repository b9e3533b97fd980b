"""Fits of many sites in one compiled call: the same model structure, per-site data
and parameters, per-site status.

    batch = px.stack_observations([obs_site_1, obs_site_2, ...])   # ragged -> padded
    result = px.fit_batch(model, batch)                            # FitResult, leading axis = site
    result.converged                                               # (S,) per site
    px.site_result(result, 7).report()                             # one site's report

Every site first gets the fast pass (:mod:`pointax.fitting.batch_fast_pass`: a fixed
number of optimistix Gauss-Newton steps on the solo fit's problem definition,
``jax.vmap`` over sites, chunks of sites per compiled call); a site that does not converge there is refitted with :func:`pointax.fit`'s full
loop. A site whose data are bad (NaN in a used row, degenerate geometry, wild outliers)
or whose fit diverges is flagged by its own ``converged`` and ``message`` and changes
nothing for the others. Padding rows carry weight 0 and do not enter any statistic.
Parameters shared by all sites: :func:`pointax.fit_shared`.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike, Float

from ..core.model import Model
from ..core.observations import Observations
from ..core.padding import pad_rows, power_of_two
from ..core.precision import float64
from .batch_fast_pass import (
    DEFAULT_STEPS,
    TPOINT_START_STEPS,
    FastPass,
    compiled,
    default_chunk_size,
    first_call,
    starts_in_tpoint_form,
)
from . import programs
from .core import FitSettings, fit_result_structure, labelled
from .batch_records import site_result, site_statuses
from .options import FitOptions
from .problem import is_affine
from .progress import activity, progress_bar
from .ranges import wrap_periodic
from .residuals import check_convention
from .result import PER_ROW_FIELDS, FitResult, too_few_residuals
from .solo import fit_model, options_from

__all__ = ["stack_observations", "batched_observations", "fit_batch", "site_result", "site_statuses", "observation_bucket"]

COMPILING = "compiling the batched fit (first call for this model and size)"
"""What a progress bar says while :func:`fit_batch` compiles its fast pass."""

COMPILING_FULL = "compiling the full fit for the sites the fast pass left (first call for this model and size)"
"""... and while it compiles the full loop."""


def observation_bucket(n: int) -> int:
    """Rows per site for sites of up to ``n`` observations (:func:`stack_observations`'s
    default): ``n`` rounded up to 8, 9, ..., 16, 18, ..., 32, 36, ... (8 to 15 times a
    power of two), so that networks whose longest sites differ share a few compiled
    shapes while at most an eighth of the rows are padding (a quarter cost the batched
    refits of 60-observation sites about 10%, padded to 64)."""
    n = max(int(n), 8)
    step = 1 << max(n.bit_length() - 4, 0)  # n lies in [8 step, 16 step)
    return -(-n // step) * step


def stack_observations(sites: Sequence[Observations], n_obs: int | None = None) -> Observations:
    """Pad per-site observations to a common length and stack them: ``(S, N, ...)``.

    Padding rows have weight 0 (they never enter a fit) and hold a harmless direction.

    Args:
        sites: one :class:`pointax.Observations` per site, all in one convention.
        n_obs: rows per site after padding (default: the longest site's
            :func:`observation_bucket`, so that networks whose longest sites differ
            share a few compiled shapes).

    Raises:
        ValueError: no sites, mixed conventions, or a site longer than ``n_obs``.
    """
    if not sites:
        raise ValueError("no sites to stack")
    conventions = {s.convention for s in sites}
    if len(conventions) > 1:
        raise ValueError(f"sites mix encoder conventions {sorted(map(str, conventions))}")
    longest = max(len(s) for s in sites)
    n = observation_bucket(longest) if n_obs is None else int(n_obs)
    if n < longest:
        raise ValueError(f"n_obs={n} is shorter than the longest site ({longest} observations)")
    encoder = np.zeros((len(sites), n, 2))
    target = np.tile(np.array([0.0, 1.0, 0.0]), (len(sites), n, 1))
    weight = np.zeros((len(sites), n))
    names = sorted({name for s in sites for name in s.readings})  # a reading a site lacks: NaN (not recorded)
    readings = {name: np.full((len(sites), n), np.nan) for name in names}
    for k, s in enumerate(sites):
        m = len(s)
        encoder[k, :m] = np.asarray(s.encoder)
        target[k, :m] = np.asarray(s.target)
        weight[k, :m] = np.asarray(s.weight)
        for name, value in s.readings.items():
            readings[name][k, :m] = np.asarray(value)
    return batched_observations(encoder, target, weight, conventions.pop(), readings)


def batched_observations(encoder, target, weight, convention, readings=None) -> Observations:
    """An Observations pytree with a leading site axis (bypasses the 2-D shape checks);
    ``readings``: name -> ``(S, N)`` auxiliary readings."""
    readings = dict(readings or {})
    obs = Observations(encoder[0], target[0], weight[0], convention, {k: v[0] for k, v in readings.items()})
    return eqx.tree_at(lambda o: (o.encoder, o.target, o.weight, o.readings), obs, (encoder, target, weight, readings))


def host_batch(observations: Observations) -> Observations:
    """A batch ``(S, N, ...)`` of observations with every array, readings included, as a
    float64 NumPy array (:func:`batched_observations`): the batched fits' host-side input
    (``observations`` itself when they are already)."""
    arrays = (observations.encoder, observations.target, observations.weight, *observations.readings.values())
    if all(type(x) is np.ndarray and x.dtype == np.float64 for x in arrays):
        return observations
    return batched_observations(
        np.asarray(observations.encoder, np.float64),
        np.asarray(observations.target, np.float64),
        np.asarray(observations.weight, np.float64),
        observations.convention,
        {k: np.asarray(v, np.float64) for k, v in observations.readings.items()},
    )


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


def _fit_sites(model, values, obs, options: FitOptions, active=None):
    """The full loop (:func:`pointax.fitting.fit_model`, the solo fit) for every site
    ``active`` marks (default all; padding sites are skipped, not fitted), one site after
    another (``lax.map``): their step counts differ, and under ``vmap`` each would run as
    long as the slowest. Compiled with the solo fit's compiler options
    (:mod:`pointax.core.xla_options`), which run it faster (``benchmarks/batch_fit_notes.md``)."""
    if active is None:
        active = np.ones(np.shape(values)[0], bool)
    # The step limit and the robust settings are data (another limit, loss or reject: no
    # compilation), the rest of the options structure; the result is labelled with the
    # options' own loss.
    args = (model, values, obs, np.asarray(active), FitSettings.of(options))
    if programs.directory() is not None:
        # Stored programs (jax.export): a later process does not trace the full loop again
        # (tracing it costs more than loading its compiled code, benchmarks/network_scale.py).
        out = programs.call("batch_full_loop", _stored_full_loop, args, options.compiled(), _full_loop_structure, fast_compile=True)
    else:
        dynamic, static = eqx.partition(args, eqx.is_array)
        out = compiled(_full_loop, ("static", "options"))(dynamic, _Static(static), options.compiled())
    return labelled(out, options)


def _stored_full_loop(model, values, obs, active, settings, options: FitOptions):
    """:func:`_full_loop` in :func:`pointax.fitting.programs.call`'s form."""
    dynamic, static = eqx.partition((model, values, obs, active, settings), eqx.is_array)
    return _full_loop(dynamic, _Static(static), options)


def _full_loop_structure(model, values, obs, active, settings, options: FitOptions):
    """The pytree structure of :func:`_full_loop`'s result (a batched
    :func:`pointax.fitting.fit_model` result), built without tracing."""
    return fit_result_structure(model, model.free_parameters, options)


class _Static:
    """The non-array part of a pytree as a hashable static argument (its structure and
    leaves: a module holding a dict, such as the observations' readings, has no hash)."""

    def __init__(self, tree):
        self.leaves, self.treedef = jax.tree.flatten(tree)

    def __hash__(self):
        return hash((self.treedef, tuple(self.leaves)))

    def __eq__(self, other):
        return isinstance(other, _Static) and (self.treedef, self.leaves) == (other.treedef, other.leaves)

    def tree(self):
        return jax.tree.unflatten(self.treedef, self.leaves)


def _full_loop(dynamic, static: _Static, options: FitOptions):
    """:func:`_fit_sites`'s loop; ``dynamic`` and ``static``: ``(model, values, obs,
    active, settings)`` partitioned into arrays and the rest."""
    model, values, obs, active, settings = eqx.combine(dynamic, static.tree())

    def one(args):
        y, site_obs = args
        return fit_model(model.with_values(y, "free"), site_obs, options, settings=settings)

    shapes = jax.eval_shape(one, jax.tree.map(lambda x: x[0], (values, obs)))

    def maybe(args):
        is_active, y, site_obs = args
        skip = lambda a: jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), shapes)  # noqa: E731
        return jax.lax.cond(is_active, one, skip, (y, site_obs))

    return jax.lax.map(maybe, (active, values, obs))


def _site_lengths(weight) -> np.ndarray:
    """``(S,)`` rows per site up to its last used one (weight > 0): the rest are padding."""
    used = np.asarray(weight) > 0
    return np.where(used.any(axis=1), used.shape[1] - np.argmax(used[:, ::-1], axis=1), 0)


def _chunk_plan(weight, size: int, n_rows: int | None = None) -> list[tuple[np.ndarray, int]]:
    """``(site indices, rows)`` per compiled call of :func:`fit_batch`, from the batch's
    ``(S, N)`` weights (rows of weight 0 after a site's last used one are padding).

    Every chunk gets the batch's ``n_rows`` (default: the longest site's
    :func:`observation_bucket`), in site order; except that in a batch of several chunks, the sites
    that fit in half those rows (a quarter, ...) get chunks of their own with those
    rows when they fill at least two chunks (a further compilation must pay for
    itself): sites of very different sizes do not all pay for the largest."""
    weight = np.asarray(weight)
    n_sites = weight.shape[0]
    lengths = None
    if n_rows is None:
        lengths = _site_lengths(weight)
    top = int(n_rows) if n_rows is not None else observation_bucket(lengths.max() if n_sites else 0)
    if n_sites <= size:
        return [(np.arange(n_sites), top)]
    one_size = [(np.arange(start, min(start + size, n_sites)), top) for start in range(0, n_sites, size)]
    if top % 2 or top // 2 < 8:
        return one_size
    # The sites that fit in half the rows include those of every smaller level: fewer
    # than two chunks of them, and every group joins the next larger (a quick test
    # before the sites' lengths, which cost batched refits time).
    if n_sites - np.count_nonzero(np.any(weight[:, top // 2 :] > 0, axis=1)) < 2 * size:
        return one_size
    lengths = _site_lengths(weight) if lengths is None else lengths
    order = np.argsort(lengths, kind="stable")
    rows = np.full(n_sites, top)
    level = top
    while level % 2 == 0 and level // 2 >= 8:
        level //= 2
        rows = np.where(lengths <= level, level, rows)
    levels = sorted(set(rows.tolist()))
    for k, level in enumerate(levels[:-1]):  # small groups join the next larger one
        if np.sum(rows == level) < 2 * size:
            rows[rows == level] = levels[k + 1]
    if np.all(rows == top):
        return one_size
    chunks = []
    for level in sorted(set(rows.tolist())):
        members = order[rows[order] == level]
        chunks += [(members[start : start + size], level) for start in range(0, len(members), size)]
    return chunks


def _rows_to(obs: Observations, rows: int) -> Observations:
    """``obs`` (a leading site axis) with ``rows`` rows per site: cut (the rows beyond are
    unused) or padded as :func:`stack_observations` pads (weight 0)."""
    n = obs.encoder.shape[1]
    if rows == n:
        return obs
    if rows < n:
        return jax.tree.map(lambda x: np.asarray(x)[:, :rows], obs)
    pad = lambda x: np.concatenate([x, np.zeros((x.shape[0], rows - n) + x.shape[2:], x.dtype)], axis=1)  # noqa: E731
    out = jax.tree.map(lambda x: pad(np.asarray(x)), obs)
    target = np.array(out.target)
    target[:, n:] = [0.0, 1.0, 0.0]
    return eqx.tree_at(lambda o: o.target, out, target)


def _rows_back(result: FitResult, rows: int) -> FitResult:
    """A chunk's result with ``rows`` rows per site in its per-row fields, as the fit of
    the batch's own rows gives them: rows beyond are unused (residual 0, not used, no
    outlier; leave-one-out residual 0, NaN where the site has none, as the fast pass)."""
    n = np.shape(result.used)[1]
    if n == rows:
        return result
    fields = lambda r: [getattr(r, f) for f in PER_ROW_FIELDS]  # noqa: E731
    if n > rows:
        return eqx.tree_at(fields, result, [np.asarray(x)[:, :rows] for x in fields(result)])
    loo = np.asarray(result.loo_residuals)
    none = np.all(np.isnan(loo), axis=(1, 2))[:, None, None]
    extra = rows - n
    fill = {
        "residuals": np.zeros((loo.shape[0], extra, 2)),
        "used": np.zeros((loo.shape[0], extra), bool),
        "loo_residuals": np.where(none, np.nan, np.zeros((loo.shape[0], extra, 2))),
        "outliers": np.zeros((loo.shape[0], extra), bool),
    }
    grown = []
    for name, x in zip(PER_ROW_FIELDS, fields(result)):
        x = np.asarray(x)
        grown.append(np.concatenate([x, fill[name].astype(x.dtype)], axis=1))
    return eqx.tree_at(fields, result, grown)


def _pad_sites(tree, size: int):
    """Pad the leading (site) axis of every leaf to ``size`` with copies of site 0. The
    leaves stay NumPy arrays: a compiled function takes them as they are, in its C++
    dispatch, at about half the host's time per chunk of a ``jax.device_put`` first
    (``benchmarks/batch_fit_notes.md``), and ``jnp.asarray`` would compile a small
    program per new shape."""
    return jax.tree.map(lambda x: pad_rows(x, size), tree)


def _host(x) -> np.ndarray:
    return np.asarray(x, np.float64)


def _first_sites(tree, n: int) -> tuple[list[np.ndarray], object]:
    """The first ``n`` sites of every leaf of ``tree`` as NumPy arrays, and the tree's
    structure: the chunks' results are kept as leaves and put together once (a pytree
    per chunk would build every chunk's result and model again)."""
    leaves, structure = jax.tree.flatten(tree)
    return [np.asarray(x)[:n] for x in leaves], structure


def _take_sites(tree, index):
    """The sites ``index`` of every leaf (NumPy); a run of consecutive sites as a slice,
    a view: copying a chunk's observations on every call costs batched refits time."""
    index = np.asarray(index)
    if index.size and index[-1] - index[0] == index.size - 1 and np.all(np.diff(index) == 1):
        index = slice(int(index[0]), int(index[-1]) + 1)
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
    progress: bool | Callable[[int, int], None] | None = None,
    options: FitOptions | None = None,
) -> FitResult:
    """Fit ``model`` to every site of a batch, each with its own parameters.

    How (least squares, ``loss="linear"``): every site first gets ``steps`` Gauss-Newton
    steps, all sites in one compiled call with no per-site loop or branch
    (:mod:`pointax.fitting.batch_fast_pass`). A site whose last step
    does not meet the tolerances (optimistix's Cauchy test with ``rtol``, ``atol``), or
    whose normal matrix is near-singular, is then fitted again from its start with the
    full ``solver`` loop (:func:`pointax.fit`'s algorithm, SVD statistics): so every
    converged site meets the same tolerances as a solo :func:`pointax.fit`, and a bad
    site gets a solo fit's diagnosis. ``steps=0`` sends every site through the full
    loop; robust losses always use it. The exact (sky) form of a model with sky
    offsets on a mount with spherical angles starts from the one-step solution of its
    TPOINT form, and its exact steps end with two chord steps
    (:func:`pointax.fitting.batch_fast_pass.starts_in_tpoint_form`), several times the
    rate of five exact steps from the start values (``benchmarks/batch_fit_notes.md``).

    Args:
        model: the model (structure, fixed parameters and default starting values).
        observations: ``(S, N, ...)`` observations from :func:`stack_observations`.
        values: ``(S, M)`` starting values of the free parameters per site (default:
            the model's values for every site).
        steps: Gauss-Newton steps of the fast first pass (0: none). Default: 1 when the
            residuals are affine in the free parameters (``residual_form="tpoint"`` with
            only TPOINT linear-form terms free, :func:`pointax.fitting.problem.is_affine`: one step
            is the solution, and the check needs no second), 1 after the TPOINT-form
            start, else 5 (they take a start within a
            few tenths of a degree to float64 precision).
        solver, max_steps, rtol, atol, loss, loss_scale, reject: as in :func:`pointax.fit`.
        chunk_size: sites per compiled call (``None``: all at once; 'auto', the
            default: :func:`pointax.fitting.batch_fast_pass.default_chunk_size`). Chunks
            bound the memory and keep the working set in the CPU's caches;
            every chunk has the same shape (the last is padded), so one compilation
            serves them all. A batch smaller than a chunk is padded to the next power
            of two: batches of 100 and of 101 sites share one compilation. The rows
            per site are the batch's (:func:`stack_observations` pads them to a few
            bucketed lengths, :func:`observation_bucket`, so that batches whose longest
            sites differ share a few compilations; padding arrays of an exact length
            again would cost every call copies and rows to fit); in
            a batch of several chunks, sites that fit in half the rows (a quarter, ...)
            get chunks of their own when they fill two or more (results in site order).
        progress: ``True`` for a progress bar on standard error when it is a terminal
            (it names a compilation while it lasts), or a callable called as
            ``progress(sites_done, sites_total)`` after each chunk (a
            :class:`pointax.fitting.progress.Progress` also shows the compilations).
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
    observations = observations.only_readings(model.readings)
    n_sites = observations.encoder.shape[0]
    values = start_values(model, n_sites, values)
    # Parameters as float64 arrays (host-side: no small computations to compile).
    model = model.replace_parameters(model.parameters, [_host(getattr(model.terms[p.term], p.field)) for p in model.parameters])
    fast = int(steps) > 0 and not options.robust
    site_obs = host_batch(observations)
    if isinstance(chunk_size, str):
        if chunk_size != "auto":
            raise ValueError(f"chunk_size must be a number of sites, None or 'auto', got {chunk_size!r}")
        chunk_size = default_chunk_size(model)
    size = n_sites if chunk_size is None else min(max(1, int(chunk_size)), power_of_two(n_sites))
    n_rows = observations.encoder.shape[1]
    chunks = _chunk_plan(site_obs.weight, size, n_rows)
    bar = progress_bar(n_sites, "fitting", "site", enabled=True) if progress is True else None
    report = bar if bar is not None else (progress or None)

    def chunk_inputs(index, rows):
        return _pad_sites(values[index], size), _pad_sites(_rows_to(_take_sites(site_obs, index), rows), size)

    def full_loop(y0, obs, active):
        # Padded to a power of two: few shapes to compile.
        first = first_call("full_loop", (model, y0, obs), options.compiled())
        with activity(report, COMPILING_FULL) if first else contextlib.nullcontext():
            return _fit_sites(model, y0, obs, options, active=active)

    results, done = [], 0

    def keep(index, out):
        # A chunk's sites as NumPy leaves (with their structure), with the batch's rows.
        nonlocal done
        leaves, structure = _first_sites(_rows_back(out, n_rows), len(index))
        results.append((index, structure, leaves))
        done += len(index)
        if report is not None:
            report(done, n_sites)

    try:
        if fast:
            # Dispatch every chunk first (JAX runs them asynchronously), then look at them:
            # checking each chunk before dispatching the next would leave the CPU idle.
            pending, fast_pass = [], FastPass(model, int(steps), rtol, atol)
            notice = lambda: activity(report, COMPILING)  # noqa: E731
            for index, rows in chunks:
                y0, obs = chunk_inputs(index, rows)
                pending.append((index, y0, obs, fast_pass(y0, obs, notice)))
            for index, y0, obs, (out, suspect) in pending:
                n = len(index)
                again = np.flatnonzero(~np.asarray(out.converged)[:n] | np.asarray(suspect)[:n])
                if again.size:
                    pad = power_of_two(again.size, 8)
                    redo = full_loop(
                        _pad_sites(np.asarray(y0)[again], pad), _pad_sites(_take_sites(obs, again), pad), np.arange(pad) < again.size
                    )
                    # (the solver's name is static: one name for the batch, set at the end)
                    fast_steps = np.asarray(out.iterations)[again]
                    redo = dataclasses.replace(redo, iterations=np.asarray(redo.iterations) + pad_rows(fast_steps, pad), solver=out.solver)
                    out = _put_sites(out, again, redo)
                keep(index, out)
        else:
            for index, rows in chunks:
                y0, obs = chunk_inputs(index, rows)
                out = full_loop(y0, obs, np.arange(size) < len(index))
                keep(index, out)
    finally:
        if bar is not None:
            bar.close()
    order = np.concatenate([index for index, _, _ in results])
    # Assembled on the host: JAX's slicing and concatenation (and jnp.asarray) would each
    # compile a small computation per result field on the first call.
    leaves = [np.concatenate(parts) for parts in zip(*(part for _, _, part in results))]
    if not np.array_equal(order, np.arange(n_sites)):  # chunks by size: back to site order
        leaves = [x[np.argsort(order, kind="stable")] for x in leaves]
    result = jax.tree.unflatten(results[0][1], leaves)
    # A site with no more residuals than free parameters fits every point, with every
    # sigma 0: refused, as px.fit refuses it (the reason: FitResult.message).
    too_few = too_few_residuals(result.n_obs, len(model.free_parameters))
    result = dataclasses.replace(result, converged=np.asarray(result.converged) & ~too_few, solver=solver)
    # An encoder zero that ended a turn away is reported in its range (same model).
    return wrap_periodic(jax.device_put(result, may_alias=True))

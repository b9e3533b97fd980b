"""Batched fits spread over a Dask cluster: sites in chunks, each worker runs the
compiled batched fit on its chunks.

    from dask.distributed import Client
    client = Client("tcp://scheduler:8786")                 # or Client(LocalCluster(...))
    result = px.distributed.fit_batch_distributed(
        model, batch, client=client, chunk_size=2000, values=starts
    )

The sites are cut into chunks of ``chunk_size`` (the last one padded with copies of
its first site, exactly as :func:`pointax.fit_batch` pads its chunks), each chunk is a
Dask task that runs :func:`pointax.fit_batch` on a worker, and the results are
gathered and concatenated in site order. Every chunk has one shape, so each worker
compiles the fit once and reuses it for every further chunk it gets. The result is
``px.fit_batch(model, batch, chunk_size=chunk_size, ...)`` computed elsewhere: the same
inputs go through the same compiled program, so the arrays are identical bit for bit
when workers and client run the same versions of jax/jaxlib on the same kind of CPU.

Needs ``dask[distributed]`` (``pip install "pointax[distributed]"``) here and on every
worker, with pointax installed there too; workers switch JAX's float64 mode on for the
duration of each task themselves.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike, Float

from ..core.precision import float64
from .batch import batched_observations, check_batch, fit_batch, host_batch, start_values
from .options import FitOptions
from .result import FitResult
from ..core.model import Model
from ..core.observations import Observations

__all__ = ["fit_batch_distributed", "fit_chunks_distributed", "site_summary", "SUMMARY_FIELDS"]


def _dask():
    try:
        import distributed
    except ImportError:  # pragma: no cover - exercised only without the extra
        raise ImportError(
            'pointax.fitting.distributed needs Dask distributed: pip install "dask[distributed]" '
            '(or the "distributed" extra of pointax)'
        ) from None
    return distributed


def _to_numpy(tree):
    """Array leaves as NumPy arrays (float64 kept whatever the receiver's JAX mode)."""
    return jax.tree.map(lambda x: np.asarray(x) if eqx.is_array(x) else x, tree)


@float64
def _fit_chunk(model: Model, encoder, target, weight, convention, readings, values, options: dict[str, Any]) -> FitResult:
    """One Dask task: :func:`pointax.fit_batch` on one chunk (readings: name -> ``(S, N)``),
    arrays back as NumPy."""
    obs = batched_observations(encoder, target, weight, convention, readings)
    result = fit_batch(model, obs, values=values, **options)
    return _to_numpy(result)


@float64
def fit_batch_distributed(
    model: Model,
    observations: Observations,
    *,
    client,
    chunk_size: int,
    values: Float[ArrayLike, "S M"] | None = None,  # noqa: F722
    progress: Callable[[int, int], None] | None = None,
    retries: int = 0,
    timeout: float | None = None,
    **options: Any,
) -> FitResult:
    """:func:`pointax.fit_batch` with the chunks of sites run as tasks on a Dask cluster.

    Args:
        model: the model (structure, fixed parameters, default starting values).
        observations: ``(S, N, ...)`` observations from :func:`pointax.stack_observations`.
        client: a ``distributed.Client``, or a scheduler address such as
            ``"tcp://scheduler:8786"`` (a client is then opened and closed here).
        chunk_size: sites per task. Every task has this many sites (the last is padded),
            so each worker compiles once; pick it so that one chunk takes seconds, not
            milliseconds (scheduling costs about a millisecond per task).
        values: ``(S, M)`` starting values of the free parameters per site (default: the
            model's values for every site).
        progress: called as ``progress(sites_done, sites_total)`` in the client process
            as each chunk comes back (chunks may finish in any order).
        retries: times Dask may rerun a chunk whose worker died.
        timeout: seconds to wait for all chunks (default: no limit); past it the
            outstanding chunks are cancelled and ``TimeoutError`` is raised (a cluster
            without live workers would otherwise wait for ever).
        **options: further keyword arguments of :func:`pointax.fit_batch` (``solver``,
            ``max_steps``, ``rtol``, ``atol``, ``loss``, ...), passed to every worker.

    Returns:
        A :class:`pointax.FitResult` with a leading site axis, in site order: the arrays
        ``px.fit_batch(model, observations, values=values, chunk_size=chunk_size,
        **options)`` gives.

    Raises:
        ValueError: bad batch, chunk size, values shape or option; TypeError: an option
            :func:`pointax.fit_batch` does not take. An exception raised inside a task
            is re-raised here, with a note naming the chunk's sites.
    """
    distributed = _dask()
    try:
        inspect.signature(fit_batch).bind(model, observations, values=values, **options)
    except TypeError as err:
        raise TypeError(f"fit_batch_distributed: {err}") from None
    names = ("solver", "max_steps", "rtol", "atol", "loss", "loss_scale", "reject")
    if options.get("options") is None:
        FitOptions(**{k: options[k] for k in names if k in options})  # checked before any chunk is sent
    check_batch(observations)
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, (int, np.integer)) or chunk_size < 1:
        raise ValueError(f"chunk_size must be a positive number of sites, got {chunk_size!r}")
    host = host_batch(observations.only_readings(model.readings))
    encoder, target, weight = host.encoder, host.target, host.weight
    n_sites = encoder.shape[0]
    values = start_values(model, n_sites, values)
    size = max(1, min(int(chunk_size), n_sites))
    shipped_model = _to_numpy(model)

    own_client = isinstance(client, str)
    if own_client:
        client = distributed.Client(client)
    try:
        futures = {}
        for start in range(0, n_sites, size):
            stop = min(start + size, n_sites)
            pad = size - (stop - start)

            def chunk(x, start=start, stop=stop, pad=pad):
                # As fit_batch: the last chunk is padded with copies of its first site.
                part = x[start:stop]
                if pad:
                    part = np.concatenate([part, np.repeat(part[:1], pad, axis=0)])
                return np.ascontiguousarray(part)

            future = client.submit(
                _fit_chunk,
                shipped_model,
                chunk(encoder),
                chunk(target),
                chunk(weight),
                observations.convention,
                {name: chunk(x) for name, x in host.readings.items()},
                chunk(values),
                options,
                pure=False,
                retries=retries,
            )
            futures[future] = (start, stop)
        parts: dict[int, FitResult] = {}
        done = 0
        try:
            for future in distributed.as_completed(list(futures), timeout=timeout):
                start, stop = futures[future]
                try:
                    part = future.result()
                except Exception as err:
                    err.add_note(f"fit_batch_distributed: raised by the chunk of sites {start}..{stop - 1}")
                    raise
                parts[start] = jax.tree.map(lambda x: x[: stop - start], part)
                done += stop - start
                if progress is not None:
                    progress(done, n_sites)
        except TimeoutError as err:
            if getattr(err, "__notes__", None):  # raised by a task, not by the wait
                raise
            missing = len(futures) - len(parts)
            raise TimeoutError(
                f"fit_batch_distributed: {missing} of {len(futures)} chunks not back after {timeout} s "
                f"({len(client.scheduler_info().get('workers', {}))} workers connected)"
            ) from None
        finally:
            for future in futures:
                if not future.done():
                    future.cancel()
    finally:
        if own_client:
            client.close()
    ordered = [parts[k] for k in sorted(parts)]
    merged = ordered[0] if len(ordered) == 1 else jax.tree.map(lambda *xs: np.concatenate(xs), *ordered)
    return jax.tree.map(jnp.asarray, merged)


SUMMARY_FIELDS = ("values", "sigmas", "sky_rms", "n_obs", "iterations", "converged")
"""What :func:`site_summary` keeps of a batched result: per site, no per-observation rows."""


def site_summary(result: FitResult) -> dict[str, np.ndarray]:
    """The per-site fields :data:`SUMMARY_FIELDS` of a batched result as NumPy arrays
    (``values``, ``sigmas``: ``(S, M)`` radians; ``sky_rms``: ``(S,)`` radians;
    ``n_obs``, ``iterations``: ``(S,)``; ``converged``: ``(S,)`` bool): a few numbers per
    site where the full result carries every observation's residuals."""
    return {name: np.asarray(getattr(result, name)) for name in SUMMARY_FIELDS}


@float64
def _fit_source_chunk(model: Model, source: Callable, k: int, summary: Callable, options: dict[str, Any]):
    """One Dask task of :func:`fit_chunks_distributed`: chunk ``k`` read (or made) on
    the worker, fitted, summarised."""
    chunk = source(k)
    observations, values = chunk if isinstance(chunk, tuple) else (chunk, None)
    result = fit_batch(model, observations, values=values, **options)
    return summary(_to_numpy(result))


@float64
def fit_chunks_distributed(
    model: Model,
    source: Callable[[int], Any],
    n_chunks: int,
    *,
    client,
    summary: Callable[[FitResult], Any] = site_summary,
    on_chunk: Callable[[int, Any], None] | None = None,
    max_in_flight: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    retries: int = 0,
    **options: Any,
) -> dict[str, np.ndarray] | None:
    """Fit a network too large for one machine's memory: each chunk of sites is read
    (or made) by ``source(k)`` on a worker, fitted there with :func:`pointax.fit_batch`,
    and only its ``summary`` comes back.

    Memory is bounded by the chunk size: a worker holds one chunk's observations and
    result at a time (with ``nthreads`` 1), at most ``max_in_flight`` chunks are
    submitted at once, and the client keeps the summaries (a few numbers per site) or,
    with ``on_chunk``, hands each one on and keeps nothing.

    Args:
        model: the model (structure, fixed parameters, default starting values).
        source: ``source(k)`` for ``k`` in ``range(n_chunks)``: ``(observations,
            values)`` or ``observations`` alone (``(S, N, ...)``, e.g. from
            :func:`pointax.stack_observations`; ``values (S, M)`` starting values or
            None), run on the worker. A module-level function (or
            ``functools.partial`` of one) that workers can import: it reads the chunk's
            files, or simulates it. Give every chunk the same number of sites and rows
            so that each worker compiles once.
        n_chunks: number of chunks.
        client: a ``distributed.Client`` or a scheduler address.
        summary: ``summary(result)`` of a chunk's :class:`pointax.FitResult` (NumPy
            arrays), run on the worker (default :func:`site_summary`).
        on_chunk: ``on_chunk(k, summary)`` as each chunk comes back (any order); then
            nothing is kept and None is returned.
        max_in_flight: chunks submitted at once (default: twice the cluster's threads).
        progress: ``progress(chunks_done, n_chunks)`` as chunks come back.
        retries: times Dask may rerun a chunk whose worker died.
        **options: further keyword arguments of :func:`pointax.fit_batch`.

    Returns:
        Without ``on_chunk``: the summaries' fields concatenated in chunk order (for
        :func:`site_summary`: a dict of arrays with one row per site); else None.
    """
    distributed = _dask()
    if isinstance(n_chunks, bool) or int(n_chunks) < 1:
        raise ValueError(f"n_chunks must be a positive number, got {n_chunks!r}")
    try:
        inspect.signature(fit_batch).bind(model, None, **options)
    except TypeError as err:
        raise TypeError(f"fit_chunks_distributed: {err}") from None
    own_client = isinstance(client, str)
    if own_client:
        client = distributed.Client(client)
    shipped_model = _to_numpy(model)
    kept: dict[int, Any] = {}
    where: dict = {}  # future -> chunk, for those submitted and not yet back
    try:
        if max_in_flight is None:
            threads = sum(w.get("nthreads", 1) for w in client.scheduler_info().get("workers", {}).values())
            max_in_flight = 2 * max(threads, 1)
        todo = iter(range(int(n_chunks)))
        running = distributed.as_completed()

        def submit() -> None:
            k = next(todo, None)
            if k is not None:
                future = client.submit(
                    _fit_source_chunk, shipped_model, source, k, summary, options, pure=False, retries=retries
                )
                where[future] = k
                running.add(future)

        for _ in range(max(1, int(max_in_flight))):
            submit()
        done = 0
        for future in running:
            k = where.pop(future)
            try:
                part = future.result()
            except Exception as err:
                err.add_note(f"fit_chunks_distributed: raised by chunk {k}")
                raise
            future.release()
            submit()
            if on_chunk is not None:
                on_chunk(k, part)
            else:
                kept[k] = part
            done += 1
            if progress is not None:
                progress(done, int(n_chunks))
    finally:
        for future in where:
            future.cancel()
        if own_client:
            client.close()
    if on_chunk is not None:
        return None
    ordered = [kept[k] for k in sorted(kept)]
    return jax.tree.map(lambda *xs: np.concatenate(xs), *ordered)

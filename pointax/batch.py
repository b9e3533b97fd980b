"""Fits of many sites in one compiled call: the same model structure, per-site data
and parameters, per-site status.

    batch = px.stack_observations([obs_site_1, obs_site_2, ...])   # ragged -> padded
    result = px.fit_batch(model, batch)                            # FitResult, leading axis = site
    result.converged                                               # (S,) per site
    px.site_result(result, 7).report()                             # one site's report

Each site is the pure fit of :func:`pointax.fit` (``jax.vmap`` over sites): a site whose
data are bad (NaN in a used row, degenerate geometry, wild outliers) or whose fit
diverges is flagged by its own ``converged`` and ``message`` and changes nothing for
the others. Padding rows carry weight 0 and do not enter any statistic.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike, Float

from ._x64 import float64
from .fit import FitResult, _check_convention, _fit, check_options
from .model import Model
from .observations import Observations

__all__ = ["stack_observations", "fit_batch", "site_result", "site_statuses"]


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
    return _batched(encoder, target, weight, conventions.pop())


def _batched(encoder, target, weight, convention) -> Observations:
    """An Observations pytree with a leading site axis (bypasses the 2-D shape checks)."""
    obs = Observations(encoder[0], target[0], weight[0], convention)
    return eqx.tree_at(lambda o: (o.encoder, o.target, o.weight), obs, (encoder, target, weight))


def site_result(result: FitResult, site: int) -> FitResult:
    """One site's :class:`pointax.FitResult` out of a batched one (report, table, ...)."""
    return jax.tree.map(lambda x: x[site], result)


def site_statuses(result: FitResult) -> list[dict[str, str]]:
    """Per site of a batched result: ``{"status": ..., "reason": ...}`` with status
    ``"converged"``, ``"degenerate"`` (converged, but some parameters cannot be told
    apart: the reason names them) or ``"failed"`` (the reason says why)."""
    out = []
    for k in range(int(np.shape(result.converged)[0])):
        one = site_result(result, k)
        degenerate = [n for n, d in zip(one.names, np.asarray(one.degenerate)) if d]
        if not bool(one.converged):
            out.append({"status": "failed", "reason": one.message})
        elif degenerate:
            out.append({"status": "degenerate", "reason": "cannot be told apart: " + ", ".join(degenerate)})
        else:
            out.append({"status": "converged", "reason": ""})
    return out


@eqx.filter_jit
def _fit_sites(model, values, obs, solver, max_steps, rtol, atol, loss, loss_scale, reject):
    def one(y, site_obs):
        return _fit(model.with_values(y, "free"), site_obs, solver, max_steps, rtol, atol, "", loss, loss_scale, reject)

    return jax.vmap(one)(values, obs)


@float64
def fit_batch(
    model: Model,
    observations: Observations,
    *,
    values: Float[ArrayLike, "S M"] | None = None,
    solver: str = "lm",
    max_steps: int = 256,
    rtol: float = 1e-10,
    atol: float = 1e-13,
    loss: str = "linear",
    loss_scale: float | None = None,
    reject: float = 3.0,
    chunk_size: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> FitResult:
    """Fit ``model`` to every site of a batch, each with its own parameters.

    Args:
        model: the model (structure, fixed parameters and default starting values).
        observations: ``(S, N, ...)`` observations from :func:`stack_observations`.
        values: ``(S, M)`` starting values of the free parameters per site (default:
            the model's values for every site).
        solver, max_steps, rtol, atol, loss, loss_scale, reject: as in :func:`pointax.fit`.
        chunk_size: sites per compiled call (default: all at once). Chunks bound the
            memory; every chunk has the same shape (the last is padded), so one
            compilation serves them all.
        progress: called as ``progress(sites_done, sites_total)`` after each chunk.

    Returns:
        A :class:`pointax.FitResult` whose arrays have a leading site axis; per site:
        values, sigmas, statistics, iterations, ``converged`` and, through
        :func:`site_result`, its report and ``message``.
    """
    check_options(solver, loss, loss_scale, reject)
    if not isinstance(observations, Observations) or np.ndim(observations.encoder) != 3:
        raise ValueError("observations must be a batch of shape (S, N, ...): build it with pointax.stack_observations")
    _check_convention(model, observations)
    n_sites = observations.encoder.shape[0]
    n_free = len(model.free_parameters)
    if values is None:
        values = np.broadcast_to(np.asarray(model.values("free"), np.float64), (n_sites, n_free))
    values = np.asarray(values, np.float64)
    if values.shape != (n_sites, n_free):
        raise ValueError(f"values must have shape ({n_sites}, {n_free}) (sites, free parameters), got {values.shape}")
    model = model.with_values(model.values())
    encoder = np.asarray(observations.encoder, np.float64)
    target = np.asarray(observations.target, np.float64)
    weight = np.asarray(observations.weight, np.float64)
    size = n_sites if chunk_size is None else max(1, min(int(chunk_size), n_sites))
    results = []
    for start in range(0, n_sites, size):
        stop = min(start + size, n_sites)
        pad = size - (stop - start)

        def chunk(x):
            # The last chunk is padded with copies of its first site (results dropped),
            # so every chunk has one shape and one compilation.
            part = x[start:stop]
            if pad:
                part = np.concatenate([part, np.repeat(part[:1], pad, axis=0)])
            return jnp.asarray(part)

        obs = _batched(chunk(encoder), chunk(target), chunk(weight), observations.convention)
        out = _fit_sites(model, chunk(values), obs, solver, max_steps, rtol, atol, loss, loss_scale, reject)
        results.append(jax.tree.map(lambda x: x[: stop - start], out))
        if progress is not None:
            progress(stop, n_sites)
    if len(results) == 1:
        return results[0]
    return jax.tree.map(lambda *xs: jnp.concatenate(xs), *results)

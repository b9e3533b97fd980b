"""TPOINT's statistics of a least-squares fit, in one place for every kind of fit.

With ``r_i`` the residuals of the used observations times the square roots of their
weights (normalised to mean 1), ``N`` the number used and ``M`` the number of fitted
parameters (DESIGN.md, checked against real TPOINT output)::

    Sky RMS = sqrt( sum_i |r_i|^2 / N )
    Popn SD = Sky RMS * sqrt( N / (N - M) )        (undefined, inf, when N <= M)
    sigma_j = Sky RMS * sqrt( [(J^T J)^-1]_jj )    J: d r / d parameters

:func:`statistics` takes ``(J^T J)^-1`` however a fit obtained it: from the Jacobian's
SVD (:func:`svd_unit_covariance`, the solo fit, which also finds parameters the data
cannot tell apart) or from a Cholesky factor (the batched fast path, the
shared-parameter fit).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

__all__ = [
    "Statistics",
    "statistics",
    "svd_unit_covariance",
    "robust_sigma",
    "normalised_weights",
    "DEGENERATE_RCOND",
    "RAYLEIGH_MEDIAN",
]

DEGENERATE_RCOND = 1e-10
"""Singular values of the Jacobian below this fraction of the largest count as zero:
the parameters that share such a direction cannot be told apart by the data."""

RAYLEIGH_MEDIAN = math.sqrt(2 * math.log(2))
"""Median of the norm of a 2-D Gaussian offset with unit standard deviation per axis."""


class Statistics(NamedTuple):
    """TPOINT's statistics of a fit (see the module's docstring)."""

    n_obs: Array
    sky_rms: Array
    popn_sd: Array
    covariance: Array
    sigmas: Array
    correlation: Array


def normalised_weights(weight: Float[Array, " n"], used: Bool[Array, " n"]) -> Float[Array, " n"]:
    """Weights of the ``used`` rows scaled to mean 1 over them; 0 elsewhere."""
    weight = jnp.where(used, weight, 0.0)
    return weight * jnp.sum(used) / jnp.sum(weight)


def statistics(
    weighted: Float[Array, "n 2"],
    used: Bool[Array, " n"],
    n_free: Int[Array, ""] | int,
    unit_covariance: Float[Array, "m m"],
    degenerate: Bool[Array, " m"] | None = None,
    scale: Float[Array, ""] | None = None,
) -> Statistics:
    """TPOINT's statistics of a fit (pure JAX; ``vmap`` over sites).

    Args:
        weighted: ``(n, 2)`` residuals times the square roots of the normalised weights,
            0 for unused observations.
        used: ``(n,)`` the observations the fit used.
        n_free: ``M``, the number of fitted parameters (may be traced).
        unit_covariance: ``(J^T J)^-1`` of the weighted residuals, ``(m, m)``.
        degenerate: ``(m,)`` parameters the data cannot determine: their sigma is inf and
            their correlations NaN (default: none).
        scale: the standard deviation the covariance is scaled by (default: this fit's
            Sky RMS, as TPOINT's sigmas).
    """
    n_obs = jnp.sum(used)
    sky_rms = jnp.sqrt(jnp.sum(weighted**2) / n_obs)
    popn_sd = jnp.where(n_obs > n_free, sky_rms * jnp.sqrt(n_obs / jnp.maximum(n_obs - n_free, 1)), jnp.inf)
    cov = unit_covariance * (sky_rms if scale is None else scale) ** 2
    if degenerate is None:
        degenerate = jnp.zeros(cov.shape[:1], bool)
    sigmas = jnp.where(degenerate, jnp.inf, jnp.sqrt(jnp.diag(cov)))
    safe = jnp.where(degenerate | (sigmas == 0), 1.0, sigmas)
    corr = cov / (safe[:, None] * safe[None, :])
    corr = jnp.where(degenerate[:, None] | degenerate[None, :], jnp.nan, corr)
    return Statistics(n_obs, sky_rms, popn_sd, cov, sigmas, corr)


def svd_unit_covariance(
    jac: Float[Array, "k m"], free: Bool[Array, " m"] | None = None
) -> tuple[Float[Array, "m m"], Bool[Array, " m"]]:
    """``(J^T J)^-1`` from the SVD of the Jacobian, and the degenerate parameters.

    Singular values below :data:`DEGENERATE_RCOND` of the largest count as zero; a
    parameter is degenerate when it takes part in such a direction.

    Args:
        jac: ``(k, m)`` Jacobian of the weighted residuals.
        free: ``(m,)`` which columns are fitted (default: all). The others (fixed
            parameters, whose columns are zero) are given a column of their own,
            orthogonal to the rest and as long as the longest, so that they neither
            count as degenerate nor change the free block: their rows and columns of the
            result are to be ignored.
    """
    m = jac.shape[1]
    if m == 0:
        return jnp.zeros((0, 0)), jnp.zeros((0,), bool)
    if free is not None:
        norm = jnp.sqrt(jnp.max(jnp.sum(jac**2, axis=0)))
        norm = jnp.where(norm > 0, norm, 1.0)
        jac = jnp.concatenate([jac * free, jnp.diag(jnp.where(free, 0.0, norm))], axis=0)
    _, s, vt = jnp.linalg.svd(jac, full_matrices=False)
    small = s <= DEGENERATE_RCOND * s[0]
    inv_s2 = jnp.where(small, 0.0, 1.0 / jnp.where(small, 1.0, s) ** 2)
    unit_cov = (vt.T * inv_s2) @ vt
    degenerate = jnp.any(small[:, None] & (jnp.abs(vt) > 0.1), axis=0)
    if free is not None:
        degenerate = degenerate & free
    return unit_cov, degenerate


def robust_sigma(r: Float[Array, "n 2"], used: Bool[Array, " n"]) -> Float[Array, ""]:
    """Robust per-axis standard deviation of 2-D residuals: the median residual norm
    over the ``used`` observations divided by its Gaussian expectation
    (:data:`RAYLEIGH_MEDIAN` sigma); insensitive to up to half the rows being wild."""
    z = jnp.sum(jnp.where(used[:, None], r, 0.0) ** 2, axis=-1)
    norm = jnp.where(used, jnp.sqrt(jnp.where(used, z, 1.0)), jnp.nan)
    return jnp.nanmedian(norm) / RAYLEIGH_MEDIAN

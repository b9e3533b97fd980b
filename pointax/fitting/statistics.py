"""TPOINT's statistics of a least-squares fit, in one place for every kind of fit.

With ``r_i`` the residuals of the used observations times the square roots of their
weights (normalised to mean 1), ``N`` the number used and ``M`` the number of fitted
parameters (DESIGN.md, checked against real TPOINT output)::

    Sky RMS = sqrt( sum_i |r_i|^2 / N )
    Popn SD = Sky RMS * sqrt( N / (N - M) )        (undefined, inf, when N <= M)
    sigma_j = Sky RMS * sqrt( [(J^T J)^-1]_jj )    J: d r / d parameters
    LOO RMS = sqrt( sum_i |e_i|^2 / N ),  e_i = (I - H_ii)^-1 r_i      (leave-one-out)

``H = J (J^T J)^-1 J^T`` is the hat matrix of the weighted linearised problem at the
solution and ``H_ii`` its 2x2 block of star ``i`` (both its residual components): ``e_i``
is exactly the residual star ``i`` would have in the fit of the linearised problem with
that star left out (the leave-one-out identity for a block of rows), so the
out-of-sample figure costs no refit. It is exact for residuals affine in the
parameters (TPOINT's residual form with TPOINT-form terms) and equal to refits to the
linearisation error otherwise. A star the fit did not use (weight 0, masked or
rejected) is already left out: its leave-one-out residual is its residual.

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
    "leave_one_out",
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
    loo_residuals: Array
    loo_rms: Array


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
    jac: Float[Array, "k m"] | None = None,
    residuals: Float[Array, "n 2"] | None = None,
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
        jac: ``(2n, m)`` Jacobian of ``weighted`` (flattened row by row: star ``i``'s
            rows are ``2i`` and ``2i + 1``) at the solution, columns of fixed
            parameters zero, for the leave-one-out figures (:func:`leave_one_out`);
            without it they are NaN.
        residuals: ``(n, 2)`` unweighted residuals (default: ``weighted``), for the
            leave-one-out residuals of the stars not used.
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
    if jac is None:
        loo = jnp.full(weighted.shape, jnp.nan)
        loo_rms = jnp.asarray(jnp.nan, weighted.dtype)
    else:
        loo, loo_rms = leave_one_out(weighted, used, jac, unit_covariance, residuals)
    return Statistics(n_obs, sky_rms, popn_sd, cov, sigmas, corr, loo, loo_rms)


def leave_one_out(
    weighted: Float[Array, "n 2"],
    used: Bool[Array, " n"],
    jac: Float[Array, "k m"],
    unit_covariance: Float[Array, "m m"],
    residuals: Float[Array, "n 2"] | None = None,
) -> tuple[Float[Array, "n 2"], Float[Array, ""]]:
    """Leave-one-out residuals and their RMS from the hat matrix, with no refit.

    For each used star ``i``, ``e_i = (I - H_ii)^-1 r_i`` with ``r_i`` its two weighted
    residuals and ``H_ii = J_i (J^T J)^-1 J_i^T`` its 2x2 block of the hat matrix: the
    residual star ``i`` has in the least-squares fit of the linearised problem without
    it (both components left out together). The RMS is over the used stars, as the
    Sky RMS: ``sqrt(sum_i |e_i|^2 / N)``. A star that alone fixes a parameter
    (``I - H_ii`` singular) makes it infinite.

    Args:
        weighted: ``(n, 2)`` residuals times the square roots of the normalised weights.
        used: ``(n,)`` the stars the fit used.
        jac: ``(2n, m)`` Jacobian of ``weighted`` flattened row by row; columns of fixed
            parameters zero.
        unit_covariance: ``(J^T J)^-1`` (a pseudo-inverse where parameters are degenerate).
        residuals: ``(n, 2)`` unweighted residuals: the leave-one-out residuals of the
            stars not used (default: ``weighted``, 0 there).

    Returns:
        ``(n, 2)`` leave-one-out residuals, unweighted (radians), and their weighted RMS.
    """
    n = weighted.shape[0]
    if n == 0:
        return jnp.zeros((0, 2)), jnp.asarray(jnp.nan)
    rows = jac.reshape(n, 2, -1)
    block = jnp.einsum("nam,mk,nbk->nab", rows, unit_covariance, rows)  # H_ii, (n, 2, 2)
    a, b = 1.0 - block[:, 0, 0], -block[:, 0, 1]
    c, d = -block[:, 1, 0], 1.0 - block[:, 1, 1]
    det = a * d - b * c
    x, y = weighted[:, 0], weighted[:, 1]
    singular = det <= 1e-12
    inv_det = 1.0 / jnp.where(singular, 1.0, det)
    e = jnp.stack([(d * x - b * y) * inv_det, (a * y - c * x) * inv_det], axis=-1)
    e = jnp.where(singular[:, None] & (jnp.abs(weighted) > 0), jnp.inf, jnp.where(singular[:, None], 0.0, e))
    e = jnp.where(used[:, None], e, 0.0)
    n_obs = jnp.sum(used)
    loo_rms = jnp.sqrt(jnp.sum(e**2) / n_obs)
    # Unweighted: e_i / sqrt(w_i) (the weighted residual over the plain one).
    plain = weighted if residuals is None else residuals
    scale = jnp.sqrt(jnp.sum(weighted**2, axis=-1) / jnp.maximum(jnp.sum(plain**2, axis=-1), 1e-300))
    unweighted = jnp.where((scale > 0)[:, None], e / jnp.where(scale > 0, scale, 1.0)[:, None], e)
    loo = jnp.where(used[:, None], unweighted, plain)
    return loo, loo_rms


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

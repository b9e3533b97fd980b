"""Every statistic pointax reports of a fit, in one module: TPOINT's for every kind of
fit (solo, batched, shared-parameter), and the model comparison's.

TPOINT's statistics (:func:`statistics`, the one routine every fit calls). With ``r_i``
the residuals of the used observations times the square roots of their weights
(normalised to mean 1, :func:`normalised_weights`), ``N`` the number used and ``M`` the
number of fitted parameters (DESIGN.md)::

    Sky RMS = sqrt( sum_i |r_i|^2 / N )                                  sky_rms()
    Popn SD = Sky RMS * sqrt( N / (N - M) )     (inf when N <= M)        popn_sd()
    sigma_j = Sky RMS * sqrt( [(J^T J)^-1]_jj )    J: d r / d parameters
    LOO RMS = sqrt( sum_i |e_i|^2 / N ),  e_i = (I - H_ii)^-1 r_i        leave_one_out()

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

The model comparison's figures (:func:`pointax.compare`, :func:`pointax.build_model`),
which are not TPOINT's and differ from them on purpose:

* :func:`axis_rms`: per-axis and total RMS of the level-mount paper (Li, Li & Liu,
  Laser & Infrared 47(5) 2017, eqs 21-23), with ``n - 1`` in the denominator (not
  TPOINT's ``N``, nor ``N - M``), per axis;
* :func:`information_criteria`: AIC and BIC of a least-squares fit;
* :func:`significance`: ``value / sigma`` of each fitted parameter.

A fit's residual at every observation (masked and rejected ones included), in the fit's
own residual form, comes from :func:`pointax.fitting.masking.observation_residuals`.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, NamedTuple

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from ..core.units import ARCSEC

__all__ = [
    "Statistics",
    "statistics",
    "sky_rms",
    "popn_sd",
    "svd_unit_covariance",
    "leave_one_out",
    "robust_sigma",
    "normalised_weights",
    "DEGENERATE_RCOND",
    "RAYLEIGH_MEDIAN",
    "AxisRMS",
    "axis_rms",
    "information_criteria",
    "significance",
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


def sky_rms(weighted: Float[Array, "n 2"], used: Bool[Array, " n"]) -> Float[Array, ""]:
    """TPOINT's Sky RMS, ``sqrt(sum_i |r_i|^2 / N)`` over the ``N`` used observations.

    Args:
        weighted: ``(n, 2)`` residuals times the square roots of the normalised weights
            (:func:`normalised_weights`; plain residuals when every weight is equal);
            the rows not ``used`` are left out.
        used: ``(n,)`` the observations the fit used.
    """
    weighted = jnp.where(used[..., None], weighted, 0.0)
    return jnp.sqrt(jnp.sum(weighted**2, axis=(-2, -1)) / jnp.sum(used, axis=-1))


def popn_sd(sky_rms: Float[Array, ""], n_obs: Int[Array, ""] | int, n_free: Int[Array, ""] | int) -> Float[Array, ""]:
    """TPOINT's Popn SD, ``Sky RMS * sqrt(N / (N - M))`` for ``N`` observations used and
    ``M`` fitted parameters: the Sky RMS corrected for the degrees of freedom the fit
    took; inf when ``N <= M`` (TPOINT prints it as undefined)."""
    n_obs = jnp.asarray(n_obs)
    return jnp.where(n_obs > n_free, sky_rms * jnp.sqrt(n_obs / jnp.maximum(n_obs - n_free, 1)), jnp.inf)


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
    rms = sky_rms(weighted, used)
    cov = unit_covariance * (rms if scale is None else scale) ** 2
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
    return Statistics(n_obs, rms, popn_sd(rms, n_obs, n_free), cov, sigmas, corr, loo, loo_rms)


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


# ----------------------------------------------------------- the model comparison's figures


@dataclasses.dataclass(frozen=True)
class AxisRMS:
    """Per-axis and total RMS of one set of residuals (the level-mount paper's eqs
    21-23, :func:`axis_rms`), radians.

    Attributes:
        axis1, axis2: ``sqrt(sum d^2 / (n - 1))`` per axis.
        total: ``sqrt(axis1^2 + axis2^2)``.
        n: number of residuals (stars).
    """

    axis1: float
    axis2: float
    total: float
    n: int

    def arcsec(self) -> dict[str, Any]:
        """The three figures in arcsec, and ``n``."""
        return {"axis1": self.axis1 / ARCSEC, "axis2": self.axis2 / ARCSEC, "total": self.total / ARCSEC, "n": self.n}


def axis_rms(residuals: Float[np.ndarray, "n 2"], cos_axis2: Float[np.ndarray, " n"] | None = None) -> AxisRMS:
    """The level-mount paper's per-axis and total RMS (Li, Li & Liu 2017, eqs 21-23)
    of ``(n, 2)`` residuals (radians): not TPOINT's Sky RMS (:func:`sky_rms`), which
    divides the sum over both axes by ``N``; this divides each axis's sum by ``n - 1``::

        sigma_1 = sqrt( sum_i d1_i^2 / (n - 1) ),  sigma_2 = sqrt( sum_i d2_i^2 / (n - 1) )
        sigma   = sqrt( sigma_1^2 + sigma_2^2 )

    Args:
        residuals: ``(n, 2)`` observed minus model, (cross-axis, second axis) radians,
            as :func:`pointax.residuals` gives them (unweighted; every row counts).
        cos_axis2: ``(n,)`` cosine of each star's second-axis angle. Given, the first
            column is divided by it (the residual of the first-axis angle, the paper's
            ``DL``, to first order); ``None`` keeps the cross-axis offset on the sky.

    Returns:
        :class:`AxisRMS` (NaN for fewer than 2 rows).
    """
    r = np.asarray(residuals, np.float64).reshape(-1, 2)
    d1 = r[:, 0] if cos_axis2 is None else r[:, 0] / np.asarray(cos_axis2, np.float64)
    n = r.shape[0]
    if n < 2:
        return AxisRMS(math.nan, math.nan, math.nan, n)
    s1 = math.sqrt(float(np.sum(d1**2)) / (n - 1))
    s2 = math.sqrt(float(np.sum(r[:, 1] ** 2)) / (n - 1))
    return AxisRMS(s1, s2, math.hypot(s1, s2), n)


def information_criteria(residuals: Float[np.ndarray, "n 2"], n_params: int) -> tuple[float, float, float]:
    """``(ln L, AIC, BIC)`` of a least-squares fit from its ``(n, 2)`` residuals (radians)
    and its number of fitted parameters ``m``. The likelihood: the ``2n`` residual
    components, in arcsec, are independent Gaussians with one common variance, set to
    its maximum-likelihood value ``s^2 = RSS / (2n)`` (least squares is then the
    maximum-likelihood fit)::

        ln L = -n ( ln(2 pi s^2) + 1 ),   k = m + 1  (the variance counts)
        AIC = 2k - 2 ln L,                BIC = k ln(2n) - 2 ln L

    Only differences between models fitted to the same observations mean anything."""
    r = np.asarray(residuals, np.float64).reshape(-1) / ARCSEC
    n_components = r.size
    variance = float(np.sum(r**2)) / n_components
    log_l = -0.5 * n_components * (math.log(2 * math.pi * variance) + 1.0)
    k = n_params + 1
    return log_l, 2 * k - 2 * log_l, k * math.log(n_components) - 2 * log_l


def significance(values: Float[np.ndarray, " m"], sigmas: Float[np.ndarray, " m"]) -> np.ndarray:
    """``value / sigma`` of each fitted parameter (TPOINT's sigma, :func:`statistics`);
    0 for a parameter the data cannot determine (sigma inf) or whose sigma is 0."""
    values, sigmas = np.asarray(values, np.float64), np.asarray(sigmas, np.float64)
    good = np.isfinite(sigmas) & (sigmas > 0)
    return np.where(good, values / np.where(good, sigmas, 1.0), 0.0)

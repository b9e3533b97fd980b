"""Predicted pointing accuracy: how well a model's pointing is known, direction by
direction, before (or after) a run.

With ``C`` the covariance of the model's free parameters (a fit's, or that a planned
run would give: ``C = M^-1``, ``M = sum_i J_i^T W_i J_i`` the information matrix of the
observations, ``J_i`` the ``(2, p)`` Jacobian of observation ``i``'s pointing with
respect to the parameters, ``W_i = diag(1 / sigma^2)`` the noise), a pointing model
fitted from those data errs at a direction ``d`` by ``J(d) dy``, ``dy ~ N(0, C)``: its
covariance there is ``J(d) C J(d)^T`` (2 x 2, in the tangent plane of the mount frame:
the fit residuals' axes). :class:`PredictedAccuracy` gives

* ``axes(d)``: the standard deviation along the two axes,
* ``total(d)`` (and calling it): ``sqrt(trace J C J^T)``, the RMS length of the 2-D
  pointing error (as TPOINT's Sky RMS counts both axes),
* ``summary()``: over the visible sky (:func:`sky_grid`, equal-area), the RMS of the
  total, ``sqrt(mean_d trace(J C J^T)) = sqrt(trace(G C))`` with ``G`` the sky-averaged
  ``J^T J``, and its maximum; and the predicted *median* over runs of the sky RMS a fit
  reaches (the RMS over runs is the first; the median is lower when few parameter
  combinations dominate, see :meth:`PredictedAccuracy.summary`),
* ``skymap()``: a polar map of ``total`` (zenith at centre, North up, East right, as
  :mod:`pointax.plots.skymap`).

Linear theory: exact for models linear in their parameters (TPOINT's linear terms) and
to first order otherwise; noise Gaussian and known. Checked against a Monte Carlo of
refits in ``tests/test_planning.py`` and ``benchmarks/planning.py``.
"""

from __future__ import annotations

import dataclasses
import math

import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike, Float

from ..core.precision import float64
from ..core.model import Model
from ..core.units import ARCSEC, directions_enu
from .jacobian import pointing_jacobian, readings_for

__all__ = [
    "PredictedAccuracy",
    "predicted_accuracy",
    "information_matrix",
    "sky_grid",
    "sky_average",
    "noise_weights",
    "invert_information",
    "SKY_GRID_POINTS",
    "SKY_MIN_ELEVATION_DEG",
    "SKY_MAX_ELEVATION_DEG",
]

SKY_GRID_POINTS = 512
"""Points of the default :func:`sky_grid` (about one per 40 square degrees above 20 deg;
a power of two, the batch size the compiled evaluations are padded to)."""
SKY_MIN_ELEVATION_DEG = 20.0
"""Lowest elevation of the default visible sky."""
SKY_MAX_ELEVATION_DEG = 85.0
"""Highest elevation of the default visible sky (an alt-az mount's CA and NPAE terms
grow as sec E and tan E near the zenith, where no telescope is pointed)."""


def sky_grid(
    n: int = SKY_GRID_POINTS,
    min_elevation_deg: float = SKY_MIN_ELEVATION_DEG,
    max_elevation_deg: float = SKY_MAX_ELEVATION_DEG,
) -> Float[np.ndarray, "n 3"]:
    """``(n, 3)`` ENU directions spread evenly (equal area: a Fibonacci lattice) over the
    sky between two elevations (degrees). Every point stands for the same solid angle,
    so a plain mean over them is a sky average."""
    n = int(n)
    if n < 1:
        raise ValueError(f"n must be at least 1, got {n}")
    lo, hi = math.radians(min_elevation_deg), math.radians(max_elevation_deg)
    if not (-math.pi / 2 <= lo < hi <= math.pi / 2):
        raise ValueError(f"need -90 <= min_elevation_deg < max_elevation_deg <= 90, got {min_elevation_deg}, {max_elevation_deg}")
    k = np.arange(n) + 0.5
    z = math.sin(lo) + (math.sin(hi) - math.sin(lo)) * k / n
    az = np.mod(k * math.pi * (3.0 - math.sqrt(5.0)), 2 * math.pi)
    c = np.sqrt(1.0 - z**2)
    return np.stack([np.sin(az) * c, np.cos(az) * c, z], axis=-1)


def noise_weights(noise) -> np.ndarray:
    """``(2,)`` inverse standard deviations from ``noise``: radians, one value or ``(axis
    1, axis 2)`` in the mount frame's tangent plane (as :func:`pointax.core.simulate`)."""
    from ..core.units import angles_in_radians

    sigma = np.broadcast_to(np.asarray(angles_in_radians(noise, "noise"), np.float64), (2,))
    if not np.all(np.isfinite(sigma) & (sigma > 0)):
        raise ValueError(f"noise must be positive and finite (radians), got {noise!r}")
    return 1.0 / sigma


def information_matrix(jacobian: Float[ArrayLike, "n 2 p"], noise) -> Float[np.ndarray, "p p"]:
    """``M = sum_i J_i^T W J_i`` for Jacobians ``(n, 2, p)`` and ``noise`` (radians, one
    value or one per axis)."""
    a = np.asarray(jacobian) * noise_weights(noise)[None, :, None]
    return np.einsum("nip,niq->pq", a, a)


def sky_average(model: Model, sky=None) -> tuple[Float[np.ndarray, "p p"], Float[np.ndarray, "m 3"]]:
    """``G = mean_d J(d)^T J(d)`` over the sky directions ``sky`` (default
    :func:`sky_grid`) the model reaches, and those directions."""
    sky = sky_grid() if sky is None else np.asarray(directions_enu(sky, "sky"), np.float64).reshape(-1, 3)
    readings, ok = readings_for(model, sky)
    if not ok.any():
        raise ValueError("the model reaches none of the sky directions")
    jac, _ = pointing_jacobian(model, readings[ok])
    jac = np.asarray(jac)
    return np.einsum("nip,niq->pq", jac, jac) / jac.shape[0], sky[ok]


def _free_covariance(result) -> tuple[Model, np.ndarray]:
    model = result.model
    cov = np.asarray(result.covariance, np.float64)
    p = len(model.free_parameters)
    if cov.shape == (p, p):
        return model, cov
    if cov.shape == (len(model.parameters),) * 2:
        keep = np.array([q.name not in model.fixed for q in model.parameters])
        return model, cov[np.ix_(keep, keep)]
    raise ValueError(f"covariance of shape {cov.shape} does not match the model's {p} free parameters")


@dataclasses.dataclass(frozen=True, eq=False)
class PredictedAccuracy:
    """The predicted pointing accuracy of a model whose free parameters have the
    covariance ``covariance`` (``(p, p)``, internal units; see the module).

    Attributes:
        model: the model (its free parameters, in order, are those of ``covariance``).
        covariance: ``(p, p)`` covariance of the free parameters.
        observations: ``(k, 3)`` ENU directions of the observations it came from, if
            known (drawn on :meth:`skymap`).
        sky: ``(m, 3)`` ENU directions a plan was judged over (:attr:`Plan.sky`: for
            a sun plan, the sun's path), or None (:func:`sky_grid`): the figures of
            :meth:`skymap`'s title are ``summary(sky)``, those of the plan's table.
        sky_name: what ``sky`` is ('grid', 'path', 'sun path' or 'given'; None: the
            grid), named in the sky map's title.
    """

    model: Model
    covariance: Float[np.ndarray, "p p"]
    observations: Float[np.ndarray, "k 3"] | None = None
    sky: Float[np.ndarray, "m 3"] | None = None
    sky_name: str | None = None

    @float64
    def axes(self, directions) -> Float[np.ndarray, "n 2"]:
        """``(n, 2)`` standard deviations (radians) of the pointing error along the two
        axes of the mount frame's tangent plane at ``directions`` (``(n, 3)`` ENU, or a
        ``SkyCoord`` / Quantity); NaN where the model cannot point."""
        var, ok = self._variance(directions)
        out = np.sqrt(np.maximum(np.stack([var[:, 0, 0], var[:, 1, 1]], axis=-1), 0.0))
        return np.where(ok[:, None], out, np.nan)

    @float64
    def total(self, directions) -> Float[np.ndarray, " n"]:
        """``(n,)`` RMS length (radians) of the 2-D pointing error at ``directions``:
        ``sqrt(trace(J C J^T))``; NaN where the model cannot point."""
        var, ok = self._variance(directions)
        return np.where(ok, np.sqrt(np.maximum(var[:, 0, 0] + var[:, 1, 1], 0.0)), np.nan)

    __call__ = total

    def _variance(self, directions):
        d = np.asarray(directions_enu(directions, "directions"), np.float64).reshape(-1, 3)
        readings, ok = readings_for(self.model, d)
        jac, _ = pointing_jacobian(self.model, np.where(ok[:, None], readings, readings[np.argmax(ok)]))
        jac = jnp.asarray(jac)
        var = jnp.einsum("nip,pq,njq->nij", jac, jnp.asarray(self.covariance), jac)
        return np.asarray(var), ok

    @float64
    def summary(self, sky=None, *, quantiles: int = 4000, seed: int = 0) -> dict:
        """Figures over the visible sky (``sky``: ``(m, 3)`` ENU directions, default
        :func:`sky_grid`; a plan's own figures are ``summary(self.sky)``), in arcseconds:

        * ``rms_arcsec``: ``sqrt(trace(G C))``, the RMS over the sky (and over runs) of
          the pointing error of a fitted model;
        * ``max_arcsec``: the largest ``total`` over the sky;
        * ``median_rms_arcsec``: the median over runs of one run's sky RMS
          (``sqrt(dy^T G dy)``, ``dy ~ N(0, C)``; from ``quantiles`` draws with ``seed``):
          what the median of a Monte Carlo of refits is to be compared with;
        * ``n_sky``: the number of sky directions the model reaches.
        """
        g, sky_ok = sky_average(self.model, sky)
        c = np.asarray(self.covariance)
        rms = math.sqrt(max(float(np.trace(g @ c)), 0.0))
        tot = self.total(sky_ok)
        # One run's mean square over the sky is dy^T G dy: a weighted sum of chi-squares
        # with the eigenvalues of C^1/2 G C^1/2 as weights.
        w, v = np.linalg.eigh(c)
        half = (v * np.sqrt(np.maximum(w, 0.0))) @ v.T
        lam = np.clip(np.linalg.eigvalsh(half @ g @ half), 0.0, None)
        z = np.random.default_rng(seed).standard_normal((int(quantiles), lam.size))
        median = float(np.median(np.sqrt(z**2 @ lam)))
        return {
            "rms_arcsec": rms / ARCSEC,
            "max_arcsec": float(np.nanmax(tot)) / ARCSEC,
            "median_rms_arcsec": median / ARCSEC,
            "n_sky": int(sky_ok.shape[0]),
        }

    def skymap(self, *, resolution_deg: float = 2.0, min_elevation_deg: float = SKY_MIN_ELEVATION_DEG,
               max_elevation_deg: float = SKY_MAX_ELEVATION_DEG, title: str | None = None, ax=None):  # fmt: skip
        """A polar sky map of the predicted pointing error (``total``, arcsec): zenith at
        the centre, North up, East right (:mod:`pointax.plots.skymap`'s projection), the
        observations as dots. Returns a :class:`matplotlib.figure.Figure` (``ax``'s
        figure when an axes is given)."""
        from .skymap import accuracy_skymap

        return accuracy_skymap(self, resolution_deg=resolution_deg, min_elevation_deg=min_elevation_deg,
                               max_elevation_deg=max_elevation_deg, title=title, ax=ax)  # fmt: skip


@float64
def predicted_accuracy(
    source,
    *,
    readings: Float[ArrayLike, "n 2"] | None = None,
    directions: Float[ArrayLike, "n 3"] | None = None,
    noise=None,
    covariance: Float[ArrayLike, "p p"] | None = None,
) -> PredictedAccuracy:
    """The predicted pointing accuracy of a fitted model, or of a planned run.

    Args:
        source: a :class:`pointax.FitResult` (its model and covariance: TPOINT's, scaled
            by the fit's Sky RMS), or a :class:`pointax.Model` with either
            ``covariance`` or planned observations and ``noise``.
        readings: ``(n, 2)`` planned raw readings, or
        directions: ``(n, 3)`` planned ENU directions (read through the model's
            inverse, :func:`pointax.planning.readings_for`), or a
            :class:`pointax.Observations` (its readings and directions).
        noise: expected measurement noise, radians on the sky (one value, or one per
            axis of the mount frame's tangent plane), for planned observations.
        covariance: ``(p, p)`` covariance of the model's free parameters, given directly.

    Raises:
        ValueError: nothing to take a covariance from, or observations that do not
            determine every free parameter (singular information matrix).
    """
    if hasattr(source, "covariance") and hasattr(source, "model") and not isinstance(source, Model):
        model, cov = _free_covariance(source)
        return PredictedAccuracy(model, cov)
    if not isinstance(source, Model):
        raise TypeError(f"expected a pointax.Model or FitResult, got {type(source).__name__}")
    model = source
    p = len(model.free_parameters)
    if covariance is not None:
        cov = np.asarray(covariance, np.float64)
        if cov.shape != (p, p):
            raise ValueError(f"covariance must be ({p}, {p}) for the model's free parameters, got {cov.shape}")
        return PredictedAccuracy(model, cov)
    if noise is None:
        raise ValueError("give noise (radians, e.g. px.arcsec(2)) with planned readings or directions")
    if hasattr(directions, "encoder") and hasattr(directions, "target"):
        readings, directions = np.asarray(directions.encoder), np.asarray(directions.target)
    if readings is None:
        if directions is None:
            raise ValueError("give readings, directions or a covariance")
        d = np.asarray(directions_enu(directions, "directions"), np.float64).reshape(-1, 3)
        readings, ok = readings_for(model, d)
        if not ok.all():
            raise ValueError(f"the model cannot point at {int((~ok).sum())} of the planned directions")
    jac, where = pointing_jacobian(model, readings)
    m = information_matrix(jac, noise)
    cov = invert_information(m)
    return PredictedAccuracy(model, cov, np.asarray(where))


def invert_information(m: Float[np.ndarray, "p p"]) -> Float[np.ndarray, "p p"]:
    """The covariance ``M^-1`` of an information matrix ``M`` ``(p, p)`` (inverted
    after scaling by its diagonal); ValueError if it is singular relative to its
    diagonal (parameters the observations cannot tell apart)."""
    scale = np.sqrt(np.clip(np.diag(m), 1e-300, None))
    mn = m / scale[:, None] / scale[None, :]
    w = np.linalg.eigvalsh(mn)
    if w[0] <= 1e-12 * max(w[-1], 1e-300):
        raise ValueError("the observations do not determine every free parameter (singular information matrix)")
    return np.linalg.inv(mn) / scale[:, None] / scale[None, :]

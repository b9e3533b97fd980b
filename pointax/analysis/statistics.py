"""The figures a model comparison reports: per-axis RMS (the level-mount paper's eqs
21-23) and the information criteria of a least-squares fit.

Every figure is computed from residuals *observed minus model* in the tangent plane
(:func:`pointax.residuals`):

* *Per-axis and total RMS*, the level-mount paper's eqs 21-23 (Li, Li & Liu, Laser &
  Infrared 47(5) 2017), which divide by ``n - 1`` (``n`` the number of stars in the set,
  not ``n - m``)::

      sigma_1 = sqrt( sum_i d1_i^2 / (n - 1) ),  sigma_2 = sqrt( sum_i d2_i^2 / (n - 1) )
      sigma   = sqrt( sigma_1^2 + sigma_2^2 )

  With ``per_axis="angle"`` (the paper's eq 20: ``DL = L - L0``; the default on an X-Y
  mount) ``d1`` is the residual of the first axis *angle*, the cross-axis residual
  divided by ``cos a2`` (``a2`` the star's second-axis angle: B, elevation,
  declination), to first order in the residual; with ``per_axis="sky"`` it is the cross-axis offset on the sky
  (TPOINT's ``dA cos E``; the default on other mounts, where ``DA`` grows as ``sec E``
  towards the zenith). ``d2`` is the second-axis residual in both.
* *Sky RMS*, TPOINT's ``sqrt(sum |r_i|^2 / n)`` (:class:`pointax.FitResult`).
* *AIC and BIC* of the in-sample fit. The likelihood: the ``2n`` sky residual components
  (cross-axis and second-axis, arcsec) are independent Gaussians with one common
  variance, set to its maximum-likelihood value ``s^2 = RSS / (2n)``; least squares is
  then the maximum-likelihood fit, and ::

      ln L = -n ( ln(2 pi s^2) + 1 ),   k = m + 1  (m fitted parameters, plus s^2)
      AIC = 2k - 2 ln L,                BIC = k ln(2n) - 2 ln L

  Only differences between families fitted to the same stars mean anything.
* *Significance* of each fitted parameter: ``value / sigma`` with TPOINT's sigma; 0 for
  a parameter the data cannot determine (infinite sigma).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from jaxtyping import Float

from ..core.mounts import Mount, SphericalMount, XYMount
from ..core.observations import Observations
from ..core.units import ARCSEC

__all__ = [
    "PER_AXIS",
    "AxisRMS",
    "axis_rms",
    "information_criteria",
    "resolve_per_axis",
    "second_axis_cosines",
    "finite_or_none",
]

PER_AXIS = ("angle", "sky")
"""What the per-axis RMS measures on the first axis: its angle (the paper's ``DL``) or
the cross-axis offset on the sky (TPOINT's ``dA cos E``)."""


@dataclasses.dataclass(frozen=True)
class AxisRMS:
    """Per-axis and total RMS of one set of residuals (the paper's eqs 21-23), radians.

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
    """The level-mount paper's eqs 21-23 for ``(n, 2)`` sky residuals (radians).

    Args:
        residuals: ``(n, 2)`` observed minus model, (cross-axis, second axis) radians,
            as :func:`pointax.residuals` gives them.
        cos_axis2: ``(n,)`` cosine of each star's second-axis angle. Given, the first
            column is divided by it (the residual of the first axis angle, the paper's
            ``DL``); ``None`` keeps the cross-axis offset on the sky.

    Returns:
        :class:`AxisRMS` with ``n - 1`` in the denominators (NaN for fewer than 2 rows).
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
    """``(ln L, AIC, BIC)`` of a least-squares fit from its ``(n, 2)`` sky residuals
    (radians) and its number of fitted parameters (see the module docstring: Gaussian
    residual components in arcsec with the maximum-likelihood common variance; the
    variance counts as a parameter)."""
    r = np.asarray(residuals, np.float64).reshape(-1) / ARCSEC
    n_components = r.size
    variance = float(np.sum(r**2)) / n_components
    log_l = -0.5 * n_components * (math.log(2 * math.pi * variance) + 1.0)
    k = n_params + 1
    return log_l, 2 * k - 2 * log_l, k * math.log(n_components) - 2 * log_l


def resolve_per_axis(mount: Mount, per_axis: str | None) -> str:
    """``per_axis``, or its default for ``mount`` when None: the paper's axis angles on
    an X-Y mount, TPOINT's sky offsets elsewhere."""
    if per_axis is None:
        return "angle" if isinstance(mount, XYMount) else "sky"
    return per_axis


def second_axis_cosines(mount: Mount, obs: Observations, per_axis: str) -> np.ndarray | None:
    """cos of each target's second-axis angle in the mount frame (None for 'sky'): the
    ``cos_axis2`` of :func:`axis_rms`.

    Raises:
        ValueError: an unknown ``per_axis``, or 'angle' on a mount without spherical
            axis angles.
    """
    if per_axis not in PER_AXIS:
        raise ValueError(f"per_axis must be one of {PER_AXIS}, got {per_axis!r}")
    if per_axis == "sky":
        return None
    if not isinstance(mount, SphericalMount):
        raise ValueError(
            f"per_axis='angle' needs a mount with perpendicular axes (alt-az, X-Y, equatorial); "
            f"a {type(mount).__name__} has no first-axis angle residual: use per_axis='sky'"
        )
    t = np.asarray(obs.target) @ np.asarray(mount.frame)
    return np.hypot(t[:, 0], t[:, 1])


def finite_or_none(x) -> float | None:
    """``float(x)``, or None where it is not finite (JSON has no inf or NaN)."""
    x = float(x)
    return x if math.isfinite(x) else None

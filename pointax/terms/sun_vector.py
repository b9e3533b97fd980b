"""Error terms of the sun-vector turntable model (Acta Optica Sinica 39(11) 1128001).

The paper's high-precision model of a mirror turntable (:class:`pointax.TurntableMount`)::

    S = Rx(mu0) . Ry(nu0) . Rz'(alpha0 - alpha) . Ry(omega0) . Rx(beta - beta0) . (0, 1, 0)

=========  ==========================================  ============================
parameter  meaning                                     place in the chain
=========  ==========================================  ============================
mu0        level tilt of the azimuth axis about East   ``Rx(mu0)``, base
nu0        level tilt of the azimuth axis about North  ``Ry(nu0)``, base
omega0     non-perpendicularity of the pitch axis      ``Ry(omega0)``, between axes
alpha0     azimuth encoder zero                        ``alpha - alpha0``
beta0      pitch encoder zero                          ``beta - beta0``
=========  ==========================================  ============================

All five are exact rotations (no small-angle approximation). The paper's simplified
model keeps only the two encoder zeros. Parameters are shown in degrees, as the paper
gives them.
"""

from __future__ import annotations

import numpy as np

from ..core.rotations import rot_x, rot_y
from ..core.term import Term, angle_pair, param

__all__ = [
    "TiltEast",
    "TiltNorth",
    "NonPerpendicularity",
    "AzimuthZero",
    "PitchZero",
    "TURNTABLE_TERMS",
    "TURNTABLE_MODELS",
    "estimate_zeros",
]


SMALL_ANGLE = (-np.radians(20.0), np.radians(20.0))
"""Where the turntable's tilts and non-perpendicularity lie in a sound fit (radians):
mechanical errors of a fraction of a degree. The model has an exact twin, ``alpha0 + 180
deg``, ``beta0 - 180 deg``, ``omega0 -> 180 deg - omega0``, which a fit started far from
the encoder zeros can reach; its ``omega0`` lies outside this range and is flagged."""


class TiltEast(Term):
    """``mu0``: tilt of the azimuth axis about East, ``Rx(mu0)`` before the axes."""

    mu0: float = param(0.0, unit="deg", expected=SMALL_ANGLE)

    @property
    def name(self) -> str:
        return "mu0"

    def base_rotation(self, angles):
        return rot_x(self.mu0)


class TiltNorth(Term):
    """``nu0``: tilt of the azimuth axis about North, ``Ry(nu0)`` before the axes."""

    nu0: float = param(0.0, unit="deg", expected=SMALL_ANGLE)

    @property
    def name(self) -> str:
        return "nu0"

    def base_rotation(self, angles):
        return rot_y(self.nu0)


class NonPerpendicularity(Term):
    """``omega0``: the pitch axis is not perpendicular to the azimuth axis,
    ``Ry(omega0)`` between the two axes."""

    omega0: float = param(0.0, unit="deg", expected=SMALL_ANGLE)

    @property
    def name(self) -> str:
        return "omega0"

    def axes_rotation(self, angles):
        return rot_y(self.omega0)


class AzimuthZero(Term):
    """``alpha0``: azimuth encoder reading at the model's zero (``alpha - alpha0``)."""

    alpha0: float = param(0.0, unit="deg", period=2 * np.pi)

    @property
    def name(self) -> str:
        return "alpha0"

    def encoder_offset(self, encoder):
        return angle_pair(-self.alpha0, 0.0)


class PitchZero(Term):
    """``beta0``: pitch encoder reading at zero elevation (``beta - beta0``)."""

    beta0: float = param(0.0, unit="deg", period=2 * np.pi)

    @property
    def name(self) -> str:
        return "beta0"

    def encoder_offset(self, encoder):
        return angle_pair(0.0, -self.beta0)


TURNTABLE_TERMS: dict[str, type[Term]] = {
    "mu0": TiltEast,
    "nu0": TiltNorth,
    "omega0": NonPerpendicularity,
    "alpha0": AzimuthZero,
    "beta0": PitchZero,
}
"""Paper symbol -> term class, in the order of the paper's chain."""

TURNTABLE_MODELS: dict[str, tuple[str, ...]] = {
    "full": ("mu0", "nu0", "omega0", "alpha0", "beta0"),
    "simple": ("alpha0", "beta0"),
}
"""The paper's high-precision (five-parameter) and simplified (two-parameter) models."""


def estimate_zeros(encoder, target) -> tuple[float, float]:
    """Starting values of ``(alpha0, beta0)`` (radians) from observations, assuming an
    otherwise perfect turntable: ``alpha0 = circular mean(alpha + azimuth)`` and
    ``beta0 = circular mean(beta - elevation)``. Least-squares fits need them: the zeros
    are often far (tens of degrees) from 0.

    Args:
        encoder: ``(n, 2)`` raw readings ``(alpha, beta)``, radians.
        target: ``(n, 3)`` observed directions, ENU unit vectors.
    """
    encoder = np.asarray(encoder, np.float64)
    target = np.asarray(target, np.float64)
    azimuth = np.arctan2(target[:, 0], target[:, 1])
    elevation = np.arctan2(target[:, 2], np.hypot(target[:, 0], target[:, 1]))

    def circular_mean(x):
        return float(np.arctan2(np.mean(np.sin(x)), np.mean(np.cos(x))) % (2 * np.pi))

    return circular_mean(encoder[:, 0] + azimuth), circular_mean(encoder[:, 1] - elevation)

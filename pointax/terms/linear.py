"""The base classes of TPOINT's terms in linear form (:class:`LinearTerm`,
:class:`LatitudeTerm`), the error for TPOINT names pointax cannot build yet
(:class:`NotYetInPointax`) and TPOINT's internal azimuth (:func:`tpoint_azimuth`).
Re-exported by :mod:`pointax.terms.tpoint_terms`; kept apart so that every module of terms
can import them without importing the others."""

from __future__ import annotations

import math
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from ..core.term import SkyPoint, Term, angle_pair, param

__all__ = ["NotYetInPointax", "tpoint_azimuth", "LinearTerm", "LatitudeTerm"]


class NotYetInPointax(ValueError):
    """A name TPOINT knows (one of its terms, or a generated name it accepts) that pointax
    cannot build yet: the message says why (no public definition, auxiliary readings
    pointax's data do not carry, a conversion that needs the site's latitude, ...).
    A ``ValueError``, distinct from the one for an unknown name."""


def tpoint_azimuth(sin_az, cos_az):
    """TPOINT's internal azimuth ``A_T = 180 deg - A`` in (-pi, pi] (South 0, East +pi/2
    for a file counting North through East), from the sine and cosine of ``A``, the
    azimuth as the data count it. Wallace's ``tptPtpre`` computes it with ``atan2``, so
    polynomials in azimuth are discontinuous at ``A_T = +-180 deg`` as TPOINT's."""
    return jnp.arctan2(sin_az, -cos_az)


class LinearTerm(Term):
    """A TPOINT-style term: ``coef * basis(A, E)`` added to (A, E) at the sky position."""

    coef: float = param(0.0)
    linear_sky_offset: ClassVar[bool] = True
    linear_by_construction: ClassVar[bool] = True
    neutral_at_zero: ClassVar[bool | None] = True

    def basis(self, p: SkyPoint) -> tuple:
        """(dA, dE) per radian of coefficient at ``p`` (its angles and their sines and
        cosines): observed minus raw, TPOINT's sign."""
        raise NotImplementedError

    def sky_offset_at(self, point: SkyPoint):
        return self.coef * angle_pair(*self.basis(point))

    def sky_offset(self, angles):
        return self.sky_offset_at(SkyPoint.at(angles))


class LatitudeTerm(LinearTerm):
    """A linear equatorial term whose basis needs the site's latitude (static, radians)."""

    latitude: float | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        if self.latitude is None:
            raise ValueError(
                f"equatorial term {type(self).__name__} needs the site's latitude: build it with "
                f"latitude=<radians> (e.g. pointax.terms.tpoint({type(self).__name__!r}, mount='equatorial', "
                "latitude=pointax.deg(33.36)))"
            )
        lat = float(self.latitude)
        if not (math.isfinite(lat) and abs(lat) <= math.pi / 2 + 1e-12):
            raise ValueError(
                f"equatorial term {type(self).__name__}: latitude {lat!r} rad is not within [-pi/2, pi/2] "
                "(give it in radians)"
            )

    @property
    def _trig_lat(self):
        return math.sin(self.latitude), math.cos(self.latitude)

"""TPOINT's alt-az terms as exact rotations and encoder corrections.

Same names, parameters and signs as :mod:`pointax.terms.tpoint_terms`: to first order in the
coefficients each rigorous term equals its linear form (a test checks this), but the
rigorous form is exact at any size and has no pole at the zenith. Where the linear form
is already exact (elevation terms, azimuth zero point) the physical form is kept.

Geometry (mount frame, see :class:`pointax.AltAzMount`)::

    d = [AN, AW tilts] . Rz(-A) . [NPAE] . Rx(E) . [CA] . (0, 1, 0)

NRX, NRY, CRX, CRY, FLOP, TFP, ANL, AWL, CAL, NPAEL and TXL
(:mod:`pointax.terms.tpoint_special`) keep their linear form.

Encoder terms (IA, IE, ACEC, ACES, ECEC, ECES, PAA1, PEE1) correct the encoder angles
and are evaluated at the raw encoder reading, which is where an encoder error lives.
Harmonic terms in this form (:class:`pointax.terms.harmonic.RigorousHarmonic`) follow the
same pattern: azimuth and elevation harmonics are encoder corrections, cross-elevation
harmonics turn the boresight as CA does.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..core.rotations import rot_x, rot_y, rot_z
from ..core.term import Term, angle_pair, param
from . import _TPOINT_ALTAZ_NAMES
from .linear import tpoint_azimuth
from .tpoint_terms import TF, TX  # noqa: F401  (in RIGOROUS_TERMS through globals(): TF and TX have one form)
from .tpoint_special import SPECIAL_ALTAZ_TERMS

__all__ = [*_TPOINT_ALTAZ_NAMES, "RIGOROUS_TERMS"]


class _RigorousTerm(Term):
    """A rigorous term of one coefficient: at 0 it adds a zero correction or turns by
    the identity rotation, exactly, so a fit may carry it switched off for a model that
    lacks it (:mod:`pointax.fitting.structure`) without probing it, and a change of
    terms compiles nothing (the library's claims are checked by the tests)."""

    coef: float = param(0.0)
    neutral_at_zero = True


class _EncoderTerm(_RigorousTerm):
    """``coef * (f_A, f_E)(raw encoder)`` added to the encoder angles."""

    def encoder_basis(self, az, el) -> tuple:
        raise NotImplementedError

    def encoder_offset(self, encoder):
        return self.coef * angle_pair(*self.encoder_basis(encoder[0], encoder[1]))


class IA(_EncoderTerm):
    """Azimuth encoder zero point: true azimuth = encoder - IA."""

    def encoder_basis(self, az, el):
        return -1.0, 0.0


class IE(_EncoderTerm):
    """Elevation encoder zero point: true elevation = encoder + IE."""

    def encoder_basis(self, az, el):
        return 0.0, 1.0


class ACEC(_EncoderTerm):
    """Azimuth encoder eccentricity, cosine component: azimuth + ACEC cos(A_encoder)."""

    def encoder_basis(self, az, el):
        return jnp.cos(az), 0.0


class ACES(_EncoderTerm):
    """Azimuth encoder eccentricity, sine component: azimuth - ACES sin(A_encoder)."""

    def encoder_basis(self, az, el):
        return -jnp.sin(az), 0.0


class ECEC(_EncoderTerm):
    """Elevation encoder eccentricity, cosine component: elevation + ECEC cos(E_encoder)."""

    def encoder_basis(self, az, el):
        return 0.0, jnp.cos(el)


class ECES(_EncoderTerm):
    """Elevation encoder eccentricity, sine component: elevation + ECES sin(E_encoder)."""

    def encoder_basis(self, az, el):
        return 0.0, jnp.sin(el)


class PAA1(_EncoderTerm):
    """Azimuth encoder scale error: azimuth - PAA1 * A_T(encoder), ``A_T = 180 deg - A``
    in (-180, 180] deg, radians (TPOINT's polynomial variable, as the linear PAA1)."""

    def encoder_basis(self, az, el):
        return -tpoint_azimuth(jnp.sin(az), jnp.cos(az)), 0.0


class PEE1(_EncoderTerm):
    """Elevation encoder scale error: elevation + PEE1 * E_encoder (radians)."""

    def encoder_basis(self, az, el):
        return 0.0, el


class CA(_RigorousTerm):
    """Collimation: the boresight turned by ``-CA`` towards increasing azimuth, about
    the tube's axis perpendicular to the elevation axis; a cross-elevation offset of
    exactly ``-CA`` at every elevation (linear form ``dA = -CA sec E``)."""

    def boresight_rotation(self, angles):
        return rot_z(self.coef)


class NPAE(_RigorousTerm):
    """Elevation axis tilted by ``-NPAE`` from perpendicular to the azimuth axis, a
    rotation about the horizontal axis perpendicular to the elevation axis (linear
    form ``dA = -NPAE tan E``)."""

    def axes_rotation(self, angles):
        return rot_y(-self.coef)


class AN(_RigorousTerm):
    """Azimuth axis tilted by AN towards azimuth 0, a rotation by ``-AN`` about the
    mount frame's x axis (linear form ``dA = -AN sin A tan E``, ``dE = -AN cos A``)."""

    def base_rotation(self, angles):
        return rot_x(-self.coef)


class AW(_RigorousTerm):
    """Azimuth axis tilted by AW towards azimuth 270 deg, a rotation by ``-AW`` about
    the mount frame's y axis (linear form ``dA = -AW cos A tan E``, ``dE = +AW sin A``)."""

    def base_rotation(self, angles):
        return rot_y(-self.coef)


RIGOROUS_TERMS: dict[str, type[Term]] = {
    **{name: globals()[name] for name in _TPOINT_ALTAZ_NAMES},
    **SPECIAL_ALTAZ_TERMS,
}
"""TPOINT name -> rigorous-form term class (:mod:`pointax.terms.tpoint_special`'s terms:
their linear form)."""

"""TPOINT's alt-az terms in TPOINT's own linear form.

Each term is ``coefficient x basis function`` added to the pointing in azimuth and
elevation, evaluated at the corrected (sky) position, exactly as TPOINT defines it.
With ``A``, ``E`` the azimuth and elevation *as the data count them* (the mount's
azimuth convention) and ``dA``, ``dE`` = observed minus raw encoder, the basis
functions are (checked against real TPOINT output, see ``tests/test_conformance.py``):

=======  =========================  =====================  ==========================
TPOINT   dA (observed - raw)        dE (observed - raw)    katpoint (same sign = +)
=======  =========================  =====================  ==========================
IA       -1                         0                      P1 = +IA
IE       0                          +1                     P7 = -IE
CA       -sec E                     0                      P4 = -CA
NPAE     -tan E                     0                      P3 = +NPAE
AN       -sin A tan E               -cos A                 P5 = +AN
AW       -cos A tan E               +sin A                 P6 = -AW
TF       0                          -cos E                 P8 = +TF
TX       0                          -cot E                 none
ACEC     +cos A                     0                      P13 = -ACEC
ACES     -sin A                     0                      P14 = +ACES
ECEC     0                          +cos E                 P8 = -ECEC (ECEC = -TF)
ECES     0                          +sin E                 P11 = -ECES
PAA1     -A (radians)               0                      P12 = +PAA1 (unitless)
PEE1     0                          +E (radians)           P9 = -PEE1 (unitless)
=======  =========================  =====================  ==========================

katpoint's relations are derived from its formulas (``katpoint.PointingModel``, whose
offsets are raw minus observed on North-through-East azimuth), not from its docstrings,
which disagree among themselves.

What is verified: IA, IE, CA, NPAE, AN, AW, TF and TX reproduce a real TPOINT fit of
the MMT run to 0.003" (``tests/test_conformance.py``). The centring terms follow from
TPOINT's identities ACEC = HACA1, ACES = HASA1, ECEC = HECE1, ECES = HESE1 and the
harmonic-term conventions checked against a published TPOINT fit (the azimuth inside
them is 180 deg - A, the sign is -coef for A and +coef for E terms), which give the
signs above. The polynomial terms PAA1 and PEE1 follow TPOINT's sign rule for A and E
terms; neither they nor the centring terms have yet been checked against TPOINT
output.

All coefficients are in radians internally and shown in arcseconds. The sign rule is
TPOINT's: a positive azimuth coefficient makes the mount point at *smaller* azimuth
than its encoder says (``dA = -coef * f``), a positive elevation coefficient at
*larger* elevation (``dE = +coef * f``).

The linear form is what TPOINT fits; it has poles where ``tan E`` or ``sec E`` do (at
the zenith). :mod:`pointax.terms.rigorous` gives the same physics as exact rotations.
TPOINT's harmonic terms (``HACA2``, ``HSCA5CE8``, ...) are generated from their names by
:mod:`pointax.terms.harmonic`; :func:`pointax.terms.tpoint` builds both kinds by name.
"""

from __future__ import annotations

from typing import ClassVar

from .base import SkyPoint, Term, angle_pair, param

__all__ = [
    "LinearTerm",
    "IA",
    "IE",
    "CA",
    "NPAE",
    "AN",
    "AW",
    "TF",
    "TX",
    "ACEC",
    "ACES",
    "ECEC",
    "ECES",
    "PAA1",
    "PEE1",
    "LINEAR_TERMS",
]


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


class IA(LinearTerm):
    """Azimuth index error: the azimuth encoder zero point. ``dA = -IA``.
    katpoint: P1 = +IA."""

    def basis(self, p):
        return -1.0, 0.0


class IE(LinearTerm):
    """Elevation index error: the elevation encoder zero point. ``dE = +IE``.

    katpoint: P7 = -IE.
    """

    def basis(self, p):
        return 0.0, 1.0


class CA(LinearTerm):
    """Left-right collimation error: the optical axis is not perpendicular to the
    elevation axis, a constant cross-elevation offset. ``dA = -CA sec E``.

    katpoint: P4 = -CA.
    """

    def basis(self, p):
        return -1.0 / p.cos_el, 0.0


class NPAE(LinearTerm):
    """Non-perpendicularity of the azimuth and elevation axes. ``dA = -NPAE tan E``.

    katpoint: P3 = +NPAE.
    """

    def basis(self, p):
        return -p.tan_el, 0.0


class AN(LinearTerm):
    """Azimuth axis tilted towards azimuth 0 (North in the N-E convention).
    ``dA = -AN sin A tan E``, ``dE = -AN cos A``.

    katpoint: P5 = +AN.
    """

    def basis(self, p):
        return -p.sin_az * p.tan_el, -p.cos_az


class AW(LinearTerm):
    """Azimuth axis tilted towards azimuth 270 deg (West in the N-E convention).
    ``dA = -AW cos A tan E``, ``dE = +AW sin A``.

    katpoint: P6 = -AW.
    """

    def basis(self, p):
        return -p.cos_az * p.tan_el, p.sin_az


class TF(LinearTerm):
    """Tube flexure (Hooke's law): the tube sags by ``TF cos E``. ``dE = -TF cos E``.

    katpoint: P8 = +TF. An elevation change is already exact, so this is
    also the rigorous form.
    """

    def basis(self, p):
        return 0.0, -p.cos_el


class TX(LinearTerm):
    """Tube flexure, tan Z law (a sag proportional to the tangent of the zenith
    distance). ``dE = -TX cot E``. No katpoint equivalent."""

    def basis(self, p):
        return 0.0, -p.cos_el / p.sin_el


class ACEC(LinearTerm):
    """Azimuth centring error, cosine component: the azimuth encoder disc is off
    centre (encoder eccentricity). ``dA = +ACEC cos A`` (TPOINT's HACA1, which is
    ``-coef cos(180 deg - A)``). katpoint: P13 = -ACEC."""

    def basis(self, p):
        return p.cos_az, 0.0


class ACES(LinearTerm):
    """Azimuth centring error, sine component. ``dA = -ACES sin A`` (TPOINT's HASA1,
    ``-coef sin(180 deg - A)``). katpoint: P14 = +ACES."""

    def basis(self, p):
        return -p.sin_az, 0.0


class ECEC(LinearTerm):
    """Elevation centring error, cosine component (elevation encoder eccentricity).
    ``dE = +ECEC cos E`` (TPOINT's HECE1; the same function as TF with the opposite
    sign, so never fit both). katpoint: P8 = -ECEC."""

    def basis(self, p):
        return 0.0, p.cos_el


class ECES(LinearTerm):
    """Elevation centring error, sine component. ``dE = +ECES sin E`` (TPOINT's HESE1).
    katpoint: P11 = -ECES."""

    def basis(self, p):
        return 0.0, p.sin_el


class PAA1(LinearTerm):
    """Azimuth encoder scale error: first-order polynomial in azimuth.
    ``dA = -PAA1 * A`` with A in radians (on the encoder's branch of azimuth).
    katpoint: P12 = +PAA1 (dimensionless there)."""

    def basis(self, p):
        return -p.az, 0.0


class PEE1(LinearTerm):
    """Elevation encoder scale error: first-order polynomial in elevation.
    ``dE = +PEE1 * E`` with E in radians. katpoint: P9 = -PEE1 (dimensionless there)."""

    def basis(self, p):
        return 0.0, p.el


LINEAR_TERMS: dict[str, type[LinearTerm]] = {
    cls.__name__: cls for cls in (IA, IE, CA, NPAE, AN, AW, TF, TX, ACEC, ACES, ECEC, ECES, PAA1, PEE1)
}
"""TPOINT name -> linear-form term class."""

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
PAA1     -A_T (radians, below)      0                      P12 = -PAA1 (+ a zero point)
PEE1     0                          +E (radians)           P9 = -PEE1 (unitless)
=======  =========================  =====================  ==========================

TPOINT's internal azimuth is ``A_T = 180 deg - A`` (South = 0, East = 90 deg for a file
that counts azimuth North through East), reduced to (-180, +180] deg; TPOINT's azimuth
corrections are changes of ``A_T``, so ``dA = -dA_T``. Wallace's term code
(``tptPterms``/``tptPtermg``/``tptPtpre``, P. T. Wallace's TPOINT routines, public C
source under his copyright) states every term in ``A_T``; the table above and
:mod:`pointax.terms.tpoint_special` are those statements translated.

katpoint's relations are derived from its formulas (``katpoint.PointingModel``, whose
offsets are raw minus observed on North-through-East azimuth), not from its docstrings,
which disagree among themselves.

What is verified: IA, IE, CA, NPAE, AN, AW, TF and TX reproduce a real TPOINT fit of
the MMT run to 0.003" (``tests/test_conformance.py``). The centring terms follow from
TPOINT's identities ACEC = HACA1, ACES = HASA1, ECEC = HECE1, ECES = HESE1 and the
harmonic-term conventions checked against a published TPOINT fit (the azimuth inside
them is 180 deg - A, the sign is -coef for A and +coef for E terms), which give the
signs above; Wallace's term code states the same four. PAA1 and PEE1 are TPOINT's
generic polynomial terms ``P{R}{C}{n}`` (:mod:`pointax.terms.polynomial`): in Wallace's
code the variable ``A`` of a polynomial is ``A_T`` (above), so ``dA = -PAA1 * A_T``
(an earlier pointax used ``-PAA1 * A``, the opposite slope). Neither they nor
the centring terms have yet been checked against TPOINT output.

More of TPOINT's named alt-az terms (NRX, NRY, CRX, CRY, FLOP, TFP and the approximate
ANL, AWL, CAL, NPAEL, TXL) are in :mod:`pointax.terms.tpoint_special`.

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

from . import _TPOINT_ALTAZ_NAMES
from .linear import LinearTerm, NotYetInPointax, tpoint_azimuth
from .tpoint_special import SPECIAL_ALTAZ_TERMS

__all__ = ["NotYetInPointax", "tpoint_azimuth", "LinearTerm", *_TPOINT_ALTAZ_NAMES, "LINEAR_TERMS"]


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
    """Azimuth encoder scale error: TPOINT's first-order polynomial in azimuth,
    ``dA_T = +PAA1 * A_T`` (Wallace's ``tptPtermg``, format ``PRCI``), i.e.
    ``dA = -PAA1 * A_T`` with ``A_T = 180 deg - A`` reduced to (-180, 180] deg, radians
    (:func:`tpoint_azimuth`). On one branch ``A_T = pi - A``: ``dA = PAA1 * A - pi PAA1``,
    so katpoint's P12 = -PAA1 together with an azimuth zero point. Not checked against
    TPOINT output."""

    def basis(self, p):
        return -tpoint_azimuth(p.sin_az, p.cos_az), 0.0


class PEE1(LinearTerm):
    """Elevation encoder scale error: TPOINT's first-order polynomial in elevation
    (Wallace's ``tptPtermg``): ``dE = +PEE1 * E`` with E in radians. katpoint: P9 = -PEE1
    (dimensionless there). Not checked against TPOINT output."""

    def basis(self, p):
        return 0.0, p.el


LINEAR_TERMS: dict[str, type[LinearTerm]] = {name: globals()[name] for name in _TPOINT_ALTAZ_NAMES}
"""TPOINT name -> linear-form term class (with :mod:`pointax.terms.tpoint_special`'s)."""

LINEAR_TERMS.update(SPECIAL_ALTAZ_TERMS)

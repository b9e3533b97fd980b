"""More of TPOINT's named alt-az terms: Nasmyth and coude displacements, FLOP, TFP and
the approximate ("L") variants of the geometric terms, in TPOINT's linear form.

**Source.** P. T. Wallace's TPOINT term routines: ``tptPterms`` (the standard terms,
"last revision 14 November 2006"), ``tptPtappl`` (how each kind of adjustment is
applied) and ``tptPtpre`` (the coordinates the terms see): public C source under
Wallace's copyright, found in a public code index. Each standard term there is one or two
adjustments ``coef * f`` of a kind:

======  ================================================  =================================
kind    what TPOINT changes (positive ...)                here (observed - raw)
======  ================================================  =================================
``A``   mount azimuth ``A_T`` (to the left: towards E)    ``dA = -coef f``
``S``   left-right on the sky, ``dA_T cos E``             ``dA = -coef f / cos E``
``E``   mount elevation (up)                              ``dE = +coef f``
``Z``   zenith distance on the sky (down)                 ``dE = -coef f``
======  ================================================  =================================

with ``A_T = 180 deg - A`` (:func:`pointax.terms.tpoint_terms.tpoint_azimuth`) inside ``f``.
The same translation gives the checked IA, IE, CA, NPAE, AN, AW, TF, TX and the centring
terms of :mod:`pointax.terms.tpoint_terms` (a test checks all of them against it), so it is
the one used here. **None of the terms of this module has been checked against TPOINT
output**: no public run with a published TPOINT fit holds them. Each is checked against
Wallace's statement of it (``tests/test_tpoint_repertoire.py``), and NRX, NRY, CRX, CRY
against the geometry they describe (a fixed offset in a focal plane that turns with
the elevation, or with azimuth plus elevation: the on-sky offset keeps its length).

The rigorous form (``form="rigorous"``) of these terms is their linear form, as for TF
and TX. ANL, AWL, CAL, NPAEL and TXL are TPOINT's approximate forms of AN, AW, CA,
NPAE and TX: TPOINT applies them as plain azimuth and elevation changes rather than
rotations; in the linear form they are the same functions as AN, AW, CA, NPAE and TX.

The MAGIC telescope's TPOINT-style model (MARS ``MPointing``) also has NRX, NRY, CRX and
CRY; its signs are not self-consistent (its NRY elevation part has the sign of its TF,
which turns a fixed focal-plane offset into one whose length varies), so it was not used.
"""

from __future__ import annotations

import jax.numpy as jnp

from .linear import LinearTerm

__all__ = ["NRX", "NRY", "CRX", "CRY", "FLOP", "TFP", "ANL", "AWL", "CAL", "NPAEL", "TXL", "SPECIAL_ALTAZ_TERMS"]


def _a_t_plus_e(p):
    """sin and cos of ``A_T + E`` from the point's sines and cosines (``A_T = pi - A``)."""
    sin_at, cos_at = p.sin_az, -p.cos_az
    return sin_at * p.cos_el + cos_at * p.sin_el, cos_at * p.cos_el - sin_at * p.sin_el


class NRX(LinearTerm):
    """Nasmyth rotator displacement, first component: the rotator axis displaced in the
    Nasmyth focal plane, so that the pointing offset turns with the elevation. TPOINT
    (``tptPterms``): left-right on the sky ``+NRX cos E``, elevation ``-NRX sin E``;
    here ``dA = -NRX``, ``dE = -NRX sin E`` (a pure cross-elevation offset at the
    horizon, a pure elevation offset at the zenith). Not checked against TPOINT output."""

    def basis(self, p):
        return -jnp.ones_like(p.sin_el), -p.sin_el


class NRY(LinearTerm):
    """Nasmyth rotator displacement, second component (perpendicular to NRX's). TPOINT:
    left-right ``+NRY sin E``, elevation ``+NRY cos E``; here ``dA = -NRY tan E``,
    ``dE = +NRY cos E``. With NRX the on-sky offset is ``(dA cos E, dE) =
    (-NRX cos E - NRY sin E, -NRX sin E + NRY cos E)``: a fixed vector turned by E, of
    length ``sqrt(NRX^2 + NRY^2)`` at every elevation. Not checked against TPOINT
    output."""

    def basis(self, p):
        return -p.tan_el, p.cos_el


class CRX(LinearTerm):
    """Alt-az coude displacement, first (north-south) component: an offset in a coude
    focal plane that turns with azimuth plus elevation. TPOINT: left-right
    ``+CRX cos(A_T + E)``, elevation ``-CRX sin(A_T + E)``, ``A_T = 180 deg - A``.
    Not checked against TPOINT output."""

    def basis(self, p):
        s, c = _a_t_plus_e(p)
        return -c / p.cos_el, -s


class CRY(LinearTerm):
    """Alt-az coude displacement, second (east-west) component. TPOINT: left-right
    ``+CRY sin(A_T + E)``, elevation ``+CRY cos(A_T + E)``. Not checked against TPOINT
    output."""

    def basis(self, p):
        s, c = _a_t_plus_e(p)
        return -s / p.cos_el, c


class FLOP(LinearTerm):
    """Constant error in zenith distance (a vertical sag that does not depend on
    elevation). TPOINT: zenith distance ``+FLOP``, so ``dE = -FLOP``: the same function
    as IE with the opposite sign (never fit both). Not checked against TPOINT output."""

    def basis(self, p):
        return 0.0, -jnp.ones_like(p.sin_el)


class TFP(LinearTerm):
    """Tube flexure, non-Hooke's-law part (the AAT's canonical polynomial): zenith
    distance ``+TFP z^4`` with ``z = 90 deg - E`` in radians, so ``dE = -TFP z^4``
    (positive TFP: the tube droops). Not checked against TPOINT output."""

    def basis(self, p):
        z = jnp.pi / 2 - p.el
        return 0.0, -(z**4)


class ANL(LinearTerm):
    """AN applied as azimuth and elevation changes (TPOINT's "approximate" AN):
    ``dA = -ANL sin A tan E``, ``dE = -ANL cos A``, AN's linear form. Not checked
    against TPOINT output."""

    def basis(self, p):
        return -p.sin_az * p.tan_el, -p.cos_az


class AWL(LinearTerm):
    """AW applied as azimuth and elevation changes (approximate AW): ``dA = -AWL cos A
    tan E``, ``dE = +AWL sin A``, AW's linear form. Not checked against TPOINT output."""

    def basis(self, p):
        return -p.cos_az * p.tan_el, p.sin_az


class CAL(LinearTerm):
    """CA applied as an azimuth change (approximate CA): ``dA = -CAL sec E``, CA's
    linear form. Not checked against TPOINT output."""

    def basis(self, p):
        return -1.0 / p.cos_el, 0.0


class NPAEL(LinearTerm):
    """NPAE applied as an azimuth change (approximate NPAE): ``dA = -NPAEL tan E``,
    NPAE's linear form. Not checked against TPOINT output."""

    def basis(self, p):
        return -p.tan_el, 0.0


class TXL(LinearTerm):
    """Tube flexure, cot E law, applied as an elevation change (approximate TX):
    ``dE = -TXL cot E``, TX's linear form. Not checked against TPOINT output."""

    def basis(self, p):
        return 0.0, -p.cos_el / p.sin_el


SPECIAL_ALTAZ_TERMS: dict[str, type[LinearTerm]] = {
    cls.__name__: cls for cls in (NRX, NRY, CRX, CRY, FLOP, TFP, ANL, AWL, CAL, NPAEL, TXL)
}
"""TPOINT name -> class, for the terms of this module (linear form, used in both forms)."""

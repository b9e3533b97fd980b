"""More of TPOINT's named equatorial terms, in TPOINT's linear form: tube flexure by
the tan Z law (TX), TFP, FLOP, declination-axis flexure (DAB), dynamic
non-perpendicularity (DNP), the AAT's special terms (HF, HFX, HFD, X2HC, HGES, HGEC,
DGES, DGEC, CD4A, CD4B, CD5A, CD5B) and the approximate forms CHL, MAL, MEL, NPL.

**Source.** P. T. Wallace's TPOINT routine ``tptPterms`` (standard terms, revision of
14 November 2006) with ``tptPtappl`` (how each kind of adjustment is applied): public C
source under Wallace's copyright, found in a public code index. Each term is one or two
adjustments ``coef * f`` of a kind:

======  =============================================  ======================================
kind    what TPOINT changes (positive ...)             here (observed - raw, angles of the
                                                       mount: h positive West)
======  =============================================  ======================================
``H``   hour angle (West)                              ``dh = +coef f``
``X``   east-west on the sky, ``dh cos dec`` (West)    ``dh = +coef f / cos dec``
``P``   east-west ``coef f sin dec``                   ``dh = +coef f tan dec``
``D``   declination (North)                            ``ddec = +coef f``
``Z``   zenith distance (down)                         ``(dh, ddec) = coef f u(h, dec)``
======  =============================================  ======================================

where ``u`` is the change of (h, dec) per radian of zenith distance: the equatorial TF's
basis divided by ``sin z`` (TF is ``Z`` with ``f = sin z``). The same translation gives
IH, ID, CH, NP, MA, ME, TF, FO and the centring terms of
:mod:`pointax.terms.equatorial` exactly, checked against P. T. Wallace's own fit of his
SPK run for seven of them, so it is the one used here. It also gives DAF, which
Wallace's routine states as ``dh = -DAF (cos phi cos h + sin phi tan dec)`` (an
east-west shift ``-DAF cos z``): :class:`pointax.terms.equatorial.DAF` has that sign.

**None of the terms of this module has been checked against TPOINT output** (no public
run with a published TPOINT fit holds them); each is checked against Wallace's
statement of it, the ``Z`` kind also against a finite zenith-distance change
(``tests/test_tpoint_repertoire.py``).

The AAT terms are that telescope's: HF, HFX, HFD model its horseshoe flexure (HFX, HFD
with Wallace's fixed canonical expressions), HGES/HGEC/DGES/DGEC its 36-minute
hour-angle and 9-degree declination gear errors (40 cycles a turn), CD4A...CD5B its
coude collimation. The approximate forms are applied by TPOINT as plain hour-angle and
declination changes; in the linear form they are CH, MA, ME and NP. The rigorous form of
every term here is its linear form. Like the other equatorial terms, the functions are
of the mechanical angles the mount hands to terms, so on a German mount's flipped side
they change sign on the sky as TPOINT's do (``X``, ``P`` and ``D`` kinds flip,
``H`` and ``Z`` do not).
"""

from __future__ import annotations

import jax.numpy as jnp

from .linear import LatitudeTerm as _LatitudeTerm
from .linear import LinearTerm

__all__ = [
    "TX",
    "TFP",
    "FLOP",
    "DAB",
    "DNP",
    "HF",
    "HFX",
    "HFD",
    "X2HC",
    "HGES",
    "HGEC",
    "DGES",
    "DGEC",
    "CD4A",
    "CD4B",
    "CD5A",
    "CD5B",
    "CHL",
    "MAL",
    "MEL",
    "NPL",
    "SPECIAL_EQUATORIAL_TERMS",
    "SPECIAL_NEEDS_LATITUDE",
]


class _ZenithTerm(_LatitudeTerm):
    """A change of zenith distance ``coef * g(z)`` (TPOINT's ``Z`` kind), in h and dec."""

    def zenith_function(self, sin_z, cos_z):
        raise NotImplementedError

    def basis(self, p):
        s, c = self._trig_lat
        east_west = c * p.sin_az  # dh cos dec per unit sin z of TF
        north = c * p.cos_az * p.sin_el - s * p.cos_el
        sin_z = jnp.sqrt(east_west**2 + north**2)
        cos_z = s * p.sin_el + c * p.cos_el * p.cos_az
        g = self.zenith_function(sin_z, cos_z) / sin_z
        return g * east_west / p.cos_el, g * north


class TX(_ZenithTerm):
    """Tube flexure, tan Z law: zenith distance ``+TX tan z``. ``dh = +TX cos phi sin h
    / (cos z cos dec)``, ``ddec = +TX (cos phi cos h sin dec - sin phi cos dec) / cos z``
    (Wallace's statement), ``cos z = sin phi sin dec + cos phi cos dec cos h``. Needs
    ``latitude``. Not checked against TPOINT output."""

    def zenith_function(self, sin_z, cos_z):
        return sin_z / cos_z


class TFP(_ZenithTerm):
    """Tube flexure, non-Hooke's-law part (the AAT's): zenith distance ``+TFP z^4``,
    z in radians. Needs ``latitude``. Not checked against TPOINT output."""

    def zenith_function(self, sin_z, cos_z):
        return jnp.arctan2(sin_z, cos_z) ** 4


class FLOP(_ZenithTerm):
    """Constant error in zenith distance: ``+FLOP``. Needs ``latitude``. Not checked
    against TPOINT output."""

    def zenith_function(self, sin_z, cos_z):
        return jnp.ones_like(sin_z)


class DAB(_LatitudeTerm):
    """Declination-axis flexure (bending proportional to the sine of the declination
    axis's zenith distance; cf. DAF, a fixed flop): east-west
    ``-DAB sqrt(sin^2 h sin^2 phi + cos^2 h) cos z``, so ``dh = -DAB sqrt(sin^2 h
    sin^2 phi + cos^2 h) (sin phi tan dec + cos phi cos h)`` (Wallace's code; the comment
    beside it omits the square root). Needs ``latitude``. Not checked against TPOINT
    output."""

    def basis(self, p):
        s, c = self._trig_lat
        bend = jnp.sqrt((p.sin_az * s) ** 2 + p.cos_az**2)
        return -bend * (s * p.tan_el + c * p.cos_az), 0.0


class DNP(LinearTerm):
    """Dynamic non-perpendicularity: east-west ``+DNP sin h sin dec``,
    ``dh = +DNP sin h tan dec``. Not checked against TPOINT output."""

    def basis(self, p):
        return p.sin_az * p.tan_el, 0.0


class HF(LinearTerm):
    """Horseshoe flexure (the AAT's): east-west ``+HF sin h``, ``dh = +HF sin h / cos
    dec``. Not checked against TPOINT output."""

    def basis(self, p):
        return p.sin_az / p.cos_el, 0.0


class X2HC(LinearTerm):
    """East-west ``+X2HC cos 2h``: ``dh = +X2HC cos(2h) / cos dec``. Not checked against
    TPOINT output."""

    def basis(self, p):
        return jnp.cos(2 * p.az) / p.cos_el, 0.0


class HGES(LinearTerm):
    """36-minute hour-angle gear error, sine: ``dh = +HGES sin(40 h)``. Not checked
    against TPOINT output."""

    def basis(self, p):
        return jnp.sin(40 * p.az), 0.0


class HGEC(LinearTerm):
    """36-minute hour-angle gear error, cosine: ``dh = +HGEC cos(40 h)``. Not checked
    against TPOINT output."""

    def basis(self, p):
        return jnp.cos(40 * p.az), 0.0


class DGES(LinearTerm):
    """9-degree declination gear error, sine: ``ddec = +DGES sin(40 dec)``. Not checked
    against TPOINT output."""

    def basis(self, p):
        return 0.0, jnp.sin(40 * p.el)


class DGEC(LinearTerm):
    """9-degree declination gear error, cosine: ``ddec = +DGEC cos(40 dec)``. Not
    checked against TPOINT output."""

    def basis(self, p):
        return 0.0, jnp.cos(40 * p.el)


class CD4A(LinearTerm):
    """AAT coude-4 collimation, A component: ``dh = +CD4A``, ``ddec = +CD4A sin dec``.
    Not checked against TPOINT output."""

    def basis(self, p):
        return jnp.ones_like(p.sin_el), p.sin_el


class CD4B(LinearTerm):
    """AAT coude-4 collimation, B component: east-west ``-CD4B sin dec``, declination
    ``+CD4B cos dec``: ``dh = -CD4B tan dec``, ``ddec = +CD4B cos dec``. Not checked
    against TPOINT output."""

    def basis(self, p):
        return -p.tan_el, p.cos_el


class CD5A(LinearTerm):
    """AAT coude-5 collimation, A component: east-west ``-CD5A sin(h + dec)``,
    declination ``+CD5A cos(h + dec)``. Not checked against TPOINT output."""

    def basis(self, p):
        w = p.az + p.el
        return -jnp.sin(w) / p.cos_el, jnp.cos(w)


class CD5B(LinearTerm):
    """AAT coude-5 collimation, B component: east-west ``+CD5B cos(h + dec)``,
    declination ``+CD5B sin(h + dec)`` (Wallace's code; the comment beside it gives the
    hour-angle part a minus sign, which the code does not have). Not checked against
    TPOINT output."""

    def basis(self, p):
        w = p.az + p.el
        return jnp.cos(w) / p.cos_el, jnp.sin(w)


class HFX(LinearTerm):
    """AAT horseshoe flexure, east-west: ``+HFX`` times Wallace's canonical expression
    in h and dec (``tptPterms``, term 53). Not checked against TPOINT output."""

    def basis(self, p):
        h, d, sd = p.az, p.el, p.sin_el
        f = (
            0.219 * jnp.sin(5 * h)
            + 0.368 * jnp.cos(6 * h)
            + 0.195 * jnp.sin(15 * h)
            + (1.279 * jnp.sin(2 * h) - 1.718 * jnp.sin(4 * h) + 1.202 * jnp.cos(5 * h)) * sd
            - 1.928 * jnp.sin(3 * h) * p.cos_el
            + (3.662 * p.sin_az + 0.381 * jnp.cos(3 * h)) * jnp.sin(2 * d)
            - 1.156 * jnp.sin(3 * h) * jnp.cos(2 * d)
            + (-0.633 * jnp.sin(2 * h) + 0.723 * p.sin_az) * jnp.sin(5 * d)
        )
        return f / p.cos_el, 0.0


class HFD(LinearTerm):
    """AAT horseshoe flexure, north-south: ``ddec = +HFD`` times Wallace's canonical
    expression in h and dec (``tptPterms``, term 54). Not checked against TPOINT output."""

    def basis(self, p):
        h, d = p.az, p.el
        f = (
            -2.529 * jnp.sin(2 * h)
            + 3.964 * jnp.sin(3 * h)
            + 3.008 * jnp.cos(3 * h)
            - 2.428 * jnp.sin(4 * h)
            - 0.921 * jnp.cos(5 * h)
            - 0.233 * jnp.cos(12 * h)
            + 0.163 * jnp.sin(6 * d)
            - 0.147 * jnp.cos(11 * d)
            - 0.244 * jnp.cos(15 * h) * p.sin_el
            + (-4.330 * p.cos_az - 2.958 * jnp.cos(2 * h) - 1.805 * p.sin_az) * p.cos_el
            + 1.666 * p.cos_az * jnp.cos(2 * d)
        )
        return 0.0, f


class CHL(LinearTerm):
    """CH applied as an hour-angle change (TPOINT's approximate CH): ``dh = +CHL sec
    dec``, CH's linear form. Not checked against TPOINT output."""

    def basis(self, p):
        return 1.0 / p.cos_el, 0.0


class MAL(LinearTerm):
    """MA applied as hour-angle and declination changes (approximate MA):
    ``dh = -MAL cos h tan dec``, ``ddec = +MAL sin h``. Not checked against TPOINT
    output."""

    def basis(self, p):
        return -p.cos_az * p.tan_el, p.sin_az


class MEL(LinearTerm):
    """ME applied as hour-angle and declination changes (approximate ME):
    ``dh = +MEL sin h tan dec``, ``ddec = +MEL cos h``. Not checked against TPOINT
    output."""

    def basis(self, p):
        return p.sin_az * p.tan_el, p.cos_az


class NPL(LinearTerm):
    """NP applied as an hour-angle change (approximate NP): ``dh = +NPL tan dec``. Not
    checked against TPOINT output."""

    def basis(self, p):
        return p.tan_el, 0.0


SPECIAL_EQUATORIAL_TERMS: dict[str, type[LinearTerm]] = {
    cls.__name__: cls
    for cls in (
        TX, TFP, FLOP, DAB, DNP, HF, HFX, HFD, X2HC, HGES, HGEC, DGES, DGEC, CD4A, CD4B, CD5A, CD5B, CHL, MAL, MEL, NPL
    )
}  # fmt: skip
"""TPOINT equatorial name -> class, for the terms of this module (both forms)."""

SPECIAL_NEEDS_LATITUDE = frozenset({"TX", "TFP", "FLOP", "DAB"})
"""The terms of this module built with ``latitude=``."""

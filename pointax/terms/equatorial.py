"""TPOINT's equatorial terms, in TPOINT's linear form and (where one exists) as exact
rotations.

Each linear term is ``coefficient x basis function`` added to the hour angle ``h`` and
declination ``dec`` at the corrected (sky) position, as TPOINT defines it. ``dh`` and
``ddec`` are *observed minus raw encoder* (TPOINT's corrections: positive when the
corrected position is West, resp. North, of the raw one), ``h`` positive West,
``phi`` the site's latitude. The functions are evaluated at the angles an
:class:`pointax.EquatorialMount` hands to terms (``SkyPoint.az`` = ``h``,
``SkyPoint.el`` = ``dec``).

======  ==========================================  =====================================
TPOINT  dh (observed - raw)                         ddec (observed - raw)
======  ==========================================  =====================================
IH      +1                                          0
ID      0                                           +1
CH      +sec dec                                    0
NP      +tan dec                                    0
MA      -cos h tan dec                              +sin h
ME      +sin h tan dec                              +cos h
TF      +cos phi sin h sec dec                      +(cos phi cos h sin dec - sin phi cos dec)
FO      0                                           +cos h
DAF     -(cos phi cos h + sin phi tan dec)          0
HCES    +sin h                                      0
HCEC    +cos h                                      0
DCES    0                                           +sin dec
DCEC    0                                           +cos dec
======  ==========================================  =====================================

**Meaning.** IH, ID: hour-angle and declination encoder zero points. CH: east-west
collimation (the optical axis not perpendicular to the declination axis). NP:
non-perpendicularity of the polar and declination axes. MA, ME: the polar axis
misaligned in azimuth (left-right of the pole) and in elevation. TF: tube flexure,
Hooke's law: the alt-az TF's droop ``dE = -TF cos E`` written in h and dec (a test
checks this). FO: fork flexure. DAF: declination-axis flexure. HCES, HCEC,
DCES, DCEC: centring (eccentricity) errors of the hour-angle and declination encoders.

**How the signs were fixed** (``tests/test_equatorial_terms.py``):

* IH, ID, CH, MA, ME, TF: an ordinary least-squares fit of these bases (at the star's
  position, residuals ``(dh cos dec, ddec)``) to P. T. Wallace's SPK sample run
  (``shared/data/tpoint/equatorial/spk_5m_horseshoe.dat``) reproduces Wallace's own
  Pmfit values (IH -92.2155, ID -126.7376, CH +44.1696, ME +64.8473, MA -2.9882,
  TF +10.9935) to 0.07", TPOINT's sigmas to 0.001" and the Sky RMS 5.3170"; with any
  of these signs reversed that value would come out reversed.
* NP: the six-term fit IH ID CH NP MA ME of the TheSkyX German-mount run
  (``cgx-l-data.dat``, 70 of 148 rows across the pier, refraction applied to the star)
  reproduces ``REFERENCE.txt`` there: NP = -599.2", the other five values, Sky RMS
  235.0".
* Agreement with published descriptions: ``dh = -MA cos h tan dec, ddec = +MA sin h``
  and ``ddec = +ID`` as TPOINT users quote the manual (HATS pointing model wiki,
  github.com/guigue/CRAAM-Instruments/wiki/HATS-Pointing-Model), with corrections
  "positive when the corrected telescope position is west (north) of the uncorrected
  one" (Software Bisque, TheSkyX help, "Appendix L: The Pointing Terms"). Wallace's
  SPK kernel (indilib/indi ``libs/alignment/spk/equat.c``) maps its generic terms as
  ``pia = -IH, pib = +ID, pca = -CH, pnp = -NP, paw = -MA, pan = +ME`` with roll angle
  ``-h``, against ``+IA, +IE, +CA, +NPAE, +AW, +AN`` for alt-az: IH, CH, NP carry the
  sign opposite to IA, CA, NPAE because h and azimuth turn opposite ways about their
  axes' upward ends, as in the two tables.
* FO and DAF (**not verified against TPOINT output**: no reference fit holds them,
  and the cgx run's nine-term Sky RMS 182.0" with TF FO DAF does not depend on their
  signs): P. T. Wallace's TPOINT term routine ``tptPterms`` (public C source, revision
  of 14 November 2006, which states IH ID CH NP MA ME TF as in the table) gives
  ``ddec = +FO cos h`` and, for DAF, an east-west shift ``-DAF cos z``, i.e.
  ``dh = -DAF (cos phi cos h + sin phi tan dec)``. RTS2's TPOINT-model code
  (``src/teld/model/modelterm.cpp``, whose TF, HCES ... have TPOINT's signs) subtracts
  the same DAF function. (Until this was found pointax followed RTS2 gpoint's GEM model
  and gaker/celestial, which give DAF the opposite sign: their DAF is minus TPOINT's.)
  gpoint (``python/rts2/gpoint.py``, ``model_ha`` and ``model_dec``, observed minus
  raw) writes every one of IH ID CH NP MA ME TF with the opposite sign to the table (its
  ``ih .. tf`` are minus TPOINT's, checked through the data above), ``-fo cos h`` and
  ``-daf (sin phi tan dec + cos phi cos h)``: so gpoint's ``fo = -FO`` but its
  ``daf = +DAF``.
* HCES, HCEC, DCES, DCEC (**not verified**): TPOINT's identities HCES = HHSH1,
  HCEC = HHCH1, DCES = HDSD1, DCEC = HDCD1 with the equatorial harmonic sign rule of
  :mod:`pointax.terms.harmonic` (H and D terms follow IH and ID, ``+coef f``), which
  is itself by analogy with the alt-az rule checked on real TPOINT output.
  celestial-pointing gives them the opposite sign (``+sin h`` in its opposite-sign
  design matrix), but its harmonic terms disagree with TPOINT's checked alt-az ones
  as well, so it is no evidence here.

**Pier side.** Every basis is written in the *mechanical* angles, which is what the
mount hands to terms: on a German mount's flipped side the reading is ``h' = h + 180
deg``, ``dec' = 180 deg - dec`` (``|dec'| > 90 deg``). The sign changes that TPOINT,
gpoint and celestial-pointing apply on flipped rows then fall out with no pier flag:
mapped back to the sky (``dh = dh'``, ``ddec = -ddec'``), ID (constant in dec'), CH
(``sec dec' = -sec dec``), NP (``tan dec' = -tan dec``), DAF, HCES, HCEC and DCES
change sign on the sky, while IH, MA, ME, TF, FO and DCEC do not (a test checks each
against this closed form). Whether a real flipped mount shows the flexure and
centring terms with those signs is a physical question these bases answer in the
simplest way (an encoder eccentricity follows the encoder reading; a flexure follows
the mechanical angles); fit separate terms per side where the data say otherwise.

**Latitude.** TF and DAF need the site's latitude ``phi``. It is a *static* field
``latitude`` (radians) of those two terms, set when the term is built
(``pointax.terms.tpoint("TF", mount="equatorial", latitude=...)``): it is
configuration, not a parameter (every non-static field of a term is fitted), and
a term cannot see its mount. A model at another latitude therefore compiles anew;
give it the same value as ``pointax.Equatorial(..., latitude=...)``. Building TF or
DAF without it raises ``ValueError``.

**Other tools.** gpoint (RTS2 ``python/rts2/gpoint.py``) has a GEM model with the same
functions: ``ih = -IH``, ``id = -ID``, ``ch = -CH``, ``np = -NP``, ``ma = -MA``,
``me = -ME``, ``tf = -TF`` (these seven follow from the data above), ``fo = -FO`` and
``daf = +DAF`` (from Wallace's statement of FO and DAF, not checked against data); gpoint flips the star's place onto
the mechanical branch as pointax does. It has no centring terms. katpoint (MeerKAT)
is alt-az only: it has no equatorial terms.

Rigorous forms (``form="rigorous"``, :data:`EQUATORIAL_RIGOROUS_TERMS`): IH and ID are
encoder zero points, CH a turn of the boresight, NP a tilt of the declination axis, MA
and ME tilts of the polar axis (the rotations of :mod:`pointax.terms.rigorous` in the
equatorial mount's frame: +x West, +y the equator on the meridian, +z the pole);
HCES, HCEC, DCES, DCEC are encoder corrections at the raw reading. TF, FO and DAF have
no rigorous form here: their linear form is used in both.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..core.rotations import rot_x, rot_y, rot_z
from ..core.term import Term, angle_pair, param
from . import _TPOINT_EQUATORIAL_NAMES
from .equatorial_special import SPECIAL_EQUATORIAL_TERMS, SPECIAL_NEEDS_LATITUDE
from .linear import LatitudeTerm as _LatitudeTerm
from .linear import LinearTerm

__all__ = [
    *_TPOINT_EQUATORIAL_NAMES,
    "TF",
    "EQUATORIAL_LINEAR_TERMS",
    "EQUATORIAL_RIGOROUS_TERMS",
    "EQUATORIAL_FORMS",
    "BASIC_EQUATORIAL",
    "NEEDS_LATITUDE",
    "rigorous",
]


class IH(LinearTerm):
    """Hour-angle index error (the hour-angle encoder zero point). ``dh = +IH``.
    The same on both pier sides. gpoint: ``ih`` (opposite sign convention)."""

    def basis(self, p):
        return 1.0, 0.0


class ID(LinearTerm):
    """Declination index error (the declination encoder zero point). ``ddec = +ID``
    in the mechanical declination, so ``-ID`` on the sky across the pier."""

    def basis(self, p):
        return 0.0, 1.0


class CH(LinearTerm):
    """East-west collimation error: the optical axis not perpendicular to the
    declination axis. ``dh = +CH sec dec`` (changes sign across the pier)."""

    def basis(self, p):
        return 1.0 / p.cos_el, 0.0


class NP(LinearTerm):
    """Non-perpendicularity of the polar and declination axes. ``dh = +NP tan dec``
    (changes sign across the pier)."""

    def basis(self, p):
        return p.tan_el, 0.0


class MA(LinearTerm):
    """Polar axis misaligned in azimuth (left-right of the pole).
    ``dh = -MA cos h tan dec``, ``ddec = +MA sin h``."""

    def basis(self, p):
        return -p.cos_az * p.tan_el, p.sin_az


class ME(LinearTerm):
    """Polar axis misaligned in elevation. ``dh = +ME sin h tan dec``,
    ``ddec = +ME cos h``."""

    def basis(self, p):
        return p.sin_az * p.tan_el, p.cos_az


class TF(_LatitudeTerm):
    """Tube flexure, Hooke's law (the tube droops by ``TF sin z``).
    ``dh = +TF cos phi sin h sec dec``, ``ddec = +TF (cos phi cos h sin dec - sin phi
    cos dec)``. Needs ``latitude`` (static, radians)."""

    def basis(self, p):
        s, c = self._trig_lat
        return c * p.sin_az / p.cos_el, c * p.cos_az * p.sin_el - s * p.cos_el


class FO(LinearTerm):
    """Fork flexure. ``ddec = +FO cos h``. Sign from gpoint's form, not verified
    against TPOINT output."""

    def basis(self, p):
        return 0.0, p.cos_az


class DAF(_LatitudeTerm):
    """Declination-axis flop (a fixed downward flop of a cantilevered declination axis,
    English cross-axis and German mounts): an east-west shift ``-DAF cos z``,
    ``dh = -DAF (cos phi cos h + sin phi tan dec)`` (Wallace's ``tptPterms``). Needs
    ``latitude``. Not verified against TPOINT output."""

    def basis(self, p):
        s, c = self._trig_lat
        return -(c * p.cos_az + s * p.tan_el), 0.0


class HCES(LinearTerm):
    """Hour-angle encoder centring error, sine component. ``dh = +HCES sin h``
    (TPOINT's HHSH1). Sign not verified against TPOINT output."""

    def basis(self, p):
        return p.sin_az, 0.0


class HCEC(LinearTerm):
    """Hour-angle encoder centring error, cosine component. ``dh = +HCEC cos h``
    (HHCH1). Sign not verified against TPOINT output."""

    def basis(self, p):
        return p.cos_az, 0.0


class DCES(LinearTerm):
    """Declination encoder centring error, sine component. ``ddec = +DCES sin dec``
    (HDSD1). Sign not verified against TPOINT output."""

    def basis(self, p):
        return 0.0, p.sin_el


class DCEC(LinearTerm):
    """Declination encoder centring error, cosine component. ``ddec = +DCEC cos dec``
    (HDCD1). Sign not verified against TPOINT output."""

    def basis(self, p):
        return 0.0, p.cos_el


EQUATORIAL_LINEAR_TERMS: dict[str, type[LinearTerm]] = {
    name: globals()[name] for name in (*_TPOINT_EQUATORIAL_NAMES[:6], "TF", *_TPOINT_EQUATORIAL_NAMES[6:])
}
"""TPOINT equatorial name -> linear-form term class."""

BASIC_EQUATORIAL = ("IH", "ID", "CH", "NP", "MA", "ME")
"""TPOINT's six basic geometric equatorial terms."""

NEEDS_LATITUDE = frozenset({"TF", "DAF"})
"""Equatorial terms built with ``latitude=``."""


class _Rigorous:
    """Namespace of the rigorous equatorial terms (``equatorial.rigorous.IH``, ...)."""


class _EncoderTerm(Term):
    """``coef * (f_h, f_dec)(raw encoder)`` added to the encoder angles."""

    coef: float = param(0.0)
    neutral_at_zero = True  # 0 adds exactly nothing: carried switched off, never probed

    def encoder_basis(self, h, dec) -> tuple:
        raise NotImplementedError

    def encoder_offset(self, encoder):
        return self.coef * angle_pair(*self.encoder_basis(encoder[0], encoder[1]))


def _named(cls, name):
    cls.__name__ = cls.__qualname__ = name
    return cls


class _RigorousIH(_EncoderTerm):
    """Hour-angle encoder zero point: true hour angle = encoder + IH."""

    def encoder_basis(self, h, dec):
        return 1.0, 0.0


class _RigorousID(_EncoderTerm):
    """Declination encoder zero point: true declination = encoder + ID."""

    def encoder_basis(self, h, dec):
        return 0.0, 1.0


class _RigorousHCES(_EncoderTerm):
    """Hour-angle encoder eccentricity, sine: hour angle + HCES sin(h_encoder)."""

    def encoder_basis(self, h, dec):
        return jnp.sin(h), 0.0


class _RigorousHCEC(_EncoderTerm):
    """Hour-angle encoder eccentricity, cosine: hour angle + HCEC cos(h_encoder)."""

    def encoder_basis(self, h, dec):
        return jnp.cos(h), 0.0


class _RigorousDCES(_EncoderTerm):
    """Declination encoder eccentricity, sine: declination + DCES sin(dec_encoder)."""

    def encoder_basis(self, h, dec):
        return 0.0, jnp.sin(dec)


class _RigorousDCEC(_EncoderTerm):
    """Declination encoder eccentricity, cosine: declination + DCEC cos(dec_encoder)."""

    def encoder_basis(self, h, dec):
        return 0.0, jnp.cos(dec)


class _RigorousCH(Term):
    """East-west collimation: the boresight turned by ``CH`` towards the West about the
    tube's axis perpendicular to the declination axis, an exact east-west offset of
    ``CH`` (linear form ``dh = +CH sec dec``)."""

    coef: float = param(0.0)
    neutral_at_zero = True  # the identity rotation at 0

    def boresight_rotation(self, angles):
        return rot_z(-self.coef)


class _RigorousNP(Term):
    """Declination axis tilted by ``NP`` from perpendicular to the polar axis (linear
    form ``dh = +NP tan dec``)."""

    coef: float = param(0.0)
    neutral_at_zero = True  # the identity rotation at 0

    def axes_rotation(self, angles):
        return rot_y(self.coef)


class _RigorousMA(Term):
    """Polar axis turned by ``MA`` in azimuth, a rotation by ``-MA`` about the mount
    frame's y axis (linear form ``dh = -MA cos h tan dec``, ``ddec = +MA sin h``)."""

    coef: float = param(0.0)
    neutral_at_zero = True  # the identity rotation at 0

    def base_rotation(self, angles):
        return rot_y(-self.coef)


class _RigorousME(Term):
    """Polar axis tilted by ``ME`` in elevation, a rotation by ``+ME`` about the mount
    frame's x axis (West) (linear form ``dh = +ME sin h tan dec``, ``ddec = +ME cos h``)."""

    coef: float = param(0.0)
    neutral_at_zero = True  # the identity rotation at 0

    def base_rotation(self, angles):
        return rot_x(self.coef)


# The rigorous classes are named as TPOINT names them (reports show the term's class
# name); they live in the ``rigorous`` namespace so as not to shadow the linear ones.
_named(_RigorousIH, "IH")
_named(_RigorousID, "ID")
_named(_RigorousCH, "CH")
_named(_RigorousNP, "NP")
_named(_RigorousMA, "MA")
_named(_RigorousME, "ME")
_named(_RigorousHCES, "HCES")
_named(_RigorousHCEC, "HCEC")
_named(_RigorousDCES, "DCES")
_named(_RigorousDCEC, "DCEC")

rigorous = _Rigorous()
for _cls in (
    _RigorousIH, _RigorousID, _RigorousCH, _RigorousNP, _RigorousMA, _RigorousME,
    _RigorousHCES, _RigorousHCEC, _RigorousDCES, _RigorousDCEC,
):  # fmt: skip
    setattr(rigorous, _cls.__name__, _cls)
del _cls

EQUATORIAL_RIGOROUS_TERMS: dict[str, type[Term]] = {
    "IH": _RigorousIH,
    "ID": _RigorousID,
    "CH": _RigorousCH,
    "NP": _RigorousNP,
    "MA": _RigorousMA,
    "ME": _RigorousME,
    "TF": TF,
    "FO": FO,
    "DAF": DAF,
    "HCES": _RigorousHCES,
    "HCEC": _RigorousHCEC,
    "DCES": _RigorousDCES,
    "DCEC": _RigorousDCEC,
}
"""TPOINT equatorial name -> rigorous-form term class (TF, FO, DAF and the terms of
:mod:`pointax.terms.equatorial_special`: the linear form)."""


EQUATORIAL_LINEAR_TERMS.update(SPECIAL_EQUATORIAL_TERMS)
EQUATORIAL_RIGOROUS_TERMS.update(SPECIAL_EQUATORIAL_TERMS)
NEEDS_LATITUDE = NEEDS_LATITUDE | SPECIAL_NEEDS_LATITUDE

EQUATORIAL_FORMS = {"linear": EQUATORIAL_LINEAR_TERMS, "rigorous": EQUATORIAL_RIGOROUS_TERMS}
"""Term form name -> {TPOINT equatorial name: term class}."""

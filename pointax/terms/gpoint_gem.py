"""RTS2 gpoint's German-equatorial (GEM) terms (``ih id ch np ma me tf fo daf``), exactly
as gpoint defines them: :class:`GpointGemTerm` and its nine subclasses,
:data:`GPOINT_GEM_TERM_CLASSES` (name -> class) and :func:`gem_horizontal` (gpoint's
``equ_to_hrz`` of a GEM reading). Transcribed from gpoint's ``GPoint.model_ha``,
``GPoint.model_dec`` and ``GPoint.equ_to_hrz`` (:data:`pointax.terms.gpoint.GPOINT_SOURCE`);
build them by name with :func:`pointax.terms.gpoint.gpoint_term` (``mount="gem"``).

**gpoint's German-equatorial (GEM) model.** With ``H, d`` the mount's (raw) hour angle
(``LST - RA``, positive West) and declination *as the axes read them* (on the flipped
pier side the declination axis reads past the pole, ``|d| > 90 deg``, and ``H`` is
180 deg from the sky's hour angle: :mod:`pointax.io.gpoint`), and ``phi`` the site's
latitude, gpoint fits ``true = raw + model(raw)`` (``fit_model_gem``: the angular
separation of ``(H + model_ha, d + model_dec)`` from the real position), each term an
offset added to the encoder angles at the *raw* position (``model_ha``, ``model_dec``)::

    model_ha  = - ih - ch / cos d - np tan d - (me sin H - ma cos H) tan d
                - tf cos(phi) sin H / cos d - daf (sin(phi) tan d + cos(phi) cos H) + extras(ha)
    model_dec = - id - me cos H - ma sin H - tf (cos(phi) sin d cos H - sin(phi) cos d)
                - fo cos H + extras(dec)

Use them in ``pointax.Equatorial(terms, latitude=phi)``; ``tf`` and ``daf`` hold the
latitude themselves (``pointax.terms.gpoint.gpoint_term("tf", mount="gem",
latitude=phi)``), as gpoint's formulas do. The order of gpoint's ``RTS2_GEM`` model line
is :data:`pointax.terms.gpoint.GPOINT_GEM_TERMS` (``id me ma tf ih ch np daf fo``).

**TPOINT equivalents** of the GEM terms, by formula. TPOINT's equatorial terms in the
sense observed minus raw, ``h`` positive West, as :mod:`pointax.terms.equatorial`
defines them (its docstring records how their signs were fixed: IH ID CH NP MA ME TF
against P. T. Wallace's own fit of his SPK sample and a TheSkyX German-mount run; FO,
DAF not checked against TPOINT output)::

    IH: dH = +IH              ID: dd = +ID              CH: dH = +CH sec d
    NP: dH = +NP tan d        MA: dH = -MA cos H tan d,  dd = +MA sin H
    ME: dH = +ME sin H tan d,  dd = +ME cos H
    TF: dH = +TF cos(phi) sin H sec d,  dd = +TF (cos(phi) cos H sin d - sin(phi) cos d)
    FO: dd = +FO cos H        DAF: dH = -DAF (cos(phi) cos H + sin(phi) tan d)

Eight of gpoint's nine are the same function with the opposite sign, so TPOINT's
coefficient is minus gpoint's (identical for ih/id, equal to first order for the rest:
gpoint evaluates at the raw position, TPOINT at the sky one); DAF has gpoint's sign
(P. T. Wallace's TPOINT routine ``tptPterms`` states ``dH = -DAF (...)``)::

    IH = -ih   ID = -id   CH = -ch   NP = -np   MA = -ma   ME = -me
    TF = -tf   FO = -fo   DAF = +daf

``test_gem_terms_match_tpoint_equatorial_terms`` in ``tests/test_gpoint.py`` checks each
relation against :mod:`pointax.terms.equatorial`. gpoint's ``tf`` is ``+tf cos E`` in
elevation projected onto the axes, as its alt-az ``tf`` is, hence TF = -tf on both
mounts. (gpoint's print-out calls ``np`` the "angle between optical and telescope tube
axes" and ``ma`` the "mechanical orthogonality of RA and DEC axes", but the formulas are
what counts: ``np`` is TPOINT's NP, ``tan d``, and ``ch`` its CH, ``sec d``.)
"""

from __future__ import annotations

import math
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from ..core.term import Term, angle_pair, param

__all__ = [
    "GpointGemTerm",
    "GpointIH",
    "GpointID",
    "GpointCH",
    "GpointNP",
    "GpointMA",
    "GpointME",
    "GpointGemTF",
    "GpointFO",
    "GpointDAF",
    "GPOINT_GEM_TERM_CLASSES",
    "gem_horizontal",
]


class GpointGemTerm(Term):
    """One of gpoint's German-equatorial terms: ``coef * offset(H, d)`` added to the
    encoder angles (hour angle positive West, declination as the axis reads it, past
    +-90 deg on the flipped pier side), evaluated at the raw encoder reading
    (gpoint's ``model_ha`` / ``model_dec``). Use it in :func:`pointax.Equatorial`.

    Attributes:
        coef: the coefficient, radians (reported in arcseconds).
        latitude: the site's latitude, radians (static; required by ``tf`` and ``daf``,
            whose formulas contain it, as gpoint's do).
    """

    coef: float = param(0.0)
    latitude: float | None = eqx.field(static=True, default=None)
    gpoint_name: ClassVar[str] = ""
    gpoint_mount: ClassVar[str] = "gem"
    uses_latitude: ClassVar[bool] = False

    def __check_init__(self):
        if self.uses_latitude and self.latitude is None:
            raise ValueError(
                f"gpoint's GEM term {self.gpoint_name} needs the site's latitude (radians): "
                f"gpoint_term({self.gpoint_name!r}, mount='gem', latitude=...)"
            )

    @property
    def name(self) -> str:
        return self.gpoint_name

    def offset(self, ha, dec) -> tuple:
        """(dH, dd) added per radian of coefficient: gpoint's formula."""
        raise NotImplementedError

    def encoder_offset(self, encoder):
        return self.coef * angle_pair(*self.offset(encoder[0], encoder[1]))


class GpointIH(GpointGemTerm):
    """gpoint ``ih``, zero point in hour angle: ``dH = -ih``. TPOINT: IH = -ih."""

    gpoint_name: ClassVar[str] = "ih"

    def offset(self, ha, dec):
        return -1.0, 0.0


class GpointID(GpointGemTerm):
    """gpoint ``id``, zero point in declination: ``dd = -id``. TPOINT: ID = -id."""

    gpoint_name: ClassVar[str] = "id"

    def offset(self, ha, dec):
        return 0.0, -1.0


class GpointCH(GpointGemTerm):
    """gpoint ``ch``, collimation: ``dH = -ch / cos d``. TPOINT: CH = -ch."""

    gpoint_name: ClassVar[str] = "ch"

    def offset(self, ha, dec):
        return -1.0 / jnp.cos(dec), 0.0


class GpointNP(GpointGemTerm):
    """gpoint ``np``, non-perpendicularity of the polar and declination axes:
    ``dH = -np tan d``. TPOINT: NP = -np."""

    gpoint_name: ClassVar[str] = "np"

    def offset(self, ha, dec):
        return -jnp.tan(dec), 0.0


class GpointMA(GpointGemTerm):
    """gpoint ``ma``, polar axis misaligned left-right: ``dH = +ma cos H tan d``,
    ``dd = -ma sin H``. TPOINT: MA = -ma."""

    gpoint_name: ClassVar[str] = "ma"

    def offset(self, ha, dec):
        return jnp.cos(ha) * jnp.tan(dec), -jnp.sin(ha)


class GpointME(GpointGemTerm):
    """gpoint ``me``, polar axis misaligned in elevation: ``dH = -me sin H tan d``,
    ``dd = -me cos H``. TPOINT: ME = -me."""

    gpoint_name: ClassVar[str] = "me"

    def offset(self, ha, dec):
        return -jnp.sin(ha) * jnp.tan(dec), -jnp.cos(ha)


class GpointGemTF(GpointGemTerm):
    """gpoint's GEM ``tf``, tube flexure: ``dH = -tf cos(phi) sin H / cos d``,
    ``dd = -tf (cos(phi) sin d cos H - sin(phi) cos d)``, ``phi`` the latitude.
    TPOINT: TF = -tf."""

    gpoint_name: ClassVar[str] = "tf"
    uses_latitude: ClassVar[bool] = True

    def offset(self, ha, dec):
        s, c = math.sin(self.latitude), math.cos(self.latitude)
        return (-c * jnp.sin(ha) / jnp.cos(dec),
                -(c * jnp.sin(dec) * jnp.cos(ha) - s * jnp.cos(dec)))


class GpointFO(GpointGemTerm):
    """gpoint ``fo``, fork flexure: ``dd = -fo cos H``. TPOINT: FO = -fo."""

    gpoint_name: ClassVar[str] = "fo"

    def offset(self, ha, dec):
        return 0.0, -jnp.cos(ha)


class GpointDAF(GpointGemTerm):
    """gpoint ``daf``, declination axis flexure: ``dH = -daf (sin(phi) tan d + cos(phi)
    cos H)``, ``phi`` the latitude. TPOINT: DAF = +daf."""

    gpoint_name: ClassVar[str] = "daf"
    uses_latitude: ClassVar[bool] = True

    def offset(self, ha, dec):
        s, c = math.sin(self.latitude), math.cos(self.latitude)
        return -(s * jnp.tan(dec) + c * jnp.cos(ha)), 0.0


GPOINT_GEM_TERM_CLASSES: dict[str, type[GpointGemTerm]] = {
    cls.gpoint_name: cls
    for cls in (GpointID, GpointME, GpointMA, GpointGemTF, GpointIH, GpointCH, GpointNP, GpointDAF, GpointFO)
}
"""gpoint GEM name -> term class, in the order of :data:`pointax.terms.gpoint.GPOINT_GEM_TERMS`."""


def gem_horizontal(ha, dec, latitude: float):
    """gpoint's ``equ_to_hrz`` of a GEM reading: ``(az, el)`` radians, azimuth from South
    through West in ``[0, 2 pi)``, of hour angle ``ha`` and declination ``dec`` (radians)
    at ``latitude`` (radians). gpoint divides both arguments of its ``arctan2`` by the
    zenith distance's sine, which changes nothing but the zenith (where gpoint gives NaN)."""
    s, c = math.sin(latitude), math.cos(latitude)
    el = jnp.arcsin(s * jnp.sin(dec) + c * jnp.cos(dec) * jnp.cos(ha))
    az = jnp.arctan2(jnp.cos(dec) * jnp.sin(ha), s * jnp.cos(dec) * jnp.cos(ha) - c * jnp.sin(dec))
    return jnp.mod(az, 2 * jnp.pi), el

"""RTS2 gpoint's pointing terms (alt-az and German equatorial) and its "extra" terms,
exactly as gpoint defines them.

Source, taken as the definition: RTS2's ``python/rts2/gpoint.py`` (repository
``RTS2/rts2``, commit ``6480a7eb549d3158ee178ce557fab6d75de8eba9``), functions
``GPoint.model_az_hadec``, ``GPoint.model_el_hadec``, ``GPoint.model_ha``,
``GPoint.model_dec``, ``GPoint.cal_extra``, ``GPoint.get_extra_val``,
``GPoint.equ_to_hrz`` and ``GPoint.add_extra_multi``; the ``--extra`` option of
``scripts/gpoint`` (same repository) splits an extra on ``:`` into four fields.

**gpoint's model.** With ``A, E`` the mount's (raw) azimuth and elevation, gpoint fits
``true = raw + model(raw)`` (``fit_model_az`` returns ``a_az - r_az + model_az(a_az,
a_el)``, ``a`` the mount position and ``r`` the real one, and minimises the angular
separation of ``raw + model`` from ``true``). So each term is an offset in radians
added to the encoder angle and evaluated at the *raw* encoder position: in pointax an
:meth:`~pointax.Term.encoder_offset`, which reproduces gpoint's prediction exactly::

    model_az = - ia + tn sin A tan E - te cos A tan E - npae tan E + npoa / cos E + extras(az)
    model_el = - ie + tn cos A + te sin A + tf cos E + extras(el)

**Azimuth.** gpoint counts azimuth as RTS2 and libnova do, from South through West
(its ``hrz_to_equ`` takes ``ha = atan2(sin A, ...)`` with ``A = 0`` South, and its sky
plot puts ``A = 0`` at S and ``A = 90`` at W). gpoint terms therefore see the azimuth
in the ``"S-W"`` convention: build the model with ``pointax.AltAz(terms,
azimuth="S-W")`` (``run.azimuth`` of :func:`pointax.io.read_gpoint`).

**TPOINT equivalents** (same azimuth numbers; exact for the constants, to first order
for the rest, since gpoint evaluates at the raw position and TPOINT at the sky one):

=======  ===========================================  ==============================
gpoint   offset added (radians)                       TPOINT
=======  ===========================================  ==============================
ia       dA = -ia                                     IA = +ia (identical)
ie       dE = -ie                                     IE = -ie (identical)
tn       dA = +tn sin A tan E,  dE = +tn cos A        AN = -tn (tilt towards North)
te       dA = -te cos A tan E,  dE = +te sin A        AW = +te (tilt towards East)
npae     dA = -npae tan E                             NPAE = +npae
npoa     dA = +npoa / cos E                           CA = -npoa
tf       dE = +tf cos E                               TF = -tf (= ECEC)
=======  ===========================================  ==============================

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
latitude themselves (``gpoint_term("tf", mount="gem", latitude=phi)``), as gpoint's
formulas do. The order of gpoint's ``RTS2_GEM`` model line is :data:`GPOINT_GEM_TERMS`
(``id me ma tf ih ch np daf fo``).

**TPOINT equivalents** of the GEM terms, by formula. TPOINT's equatorial terms in the
sense observed minus raw, ``h`` positive West, as :mod:`pointax.terms.equatorial`
defines them (its docstring records how their signs were fixed: IH ID CH NP MA ME TF
against P. T. Wallace's own fit of his SPK sample and a TheSkyX German-mount run; FO,
DAF not checked against TPOINT output)::

    IH: dH = +IH              ID: dd = +ID              CH: dH = +CH sec d
    NP: dH = +NP tan d        MA: dH = -MA cos H tan d,  dd = +MA sin H
    ME: dH = +ME sin H tan d,  dd = +ME cos H
    TF: dH = +TF cos(phi) sin H sec d,  dd = +TF (cos(phi) cos H sin d - sin(phi) cos d)
    FO: dd = +FO cos H        DAF: dH = +DAF (cos(phi) cos H + sin(phi) tan d)

Every one of gpoint's nine is the same function with the opposite sign, so TPOINT's
coefficient is minus gpoint's (identical for ih/id, equal to first order for the rest:
gpoint evaluates at the raw position, TPOINT at the sky one)::

    IH = -ih   ID = -id   CH = -ch   NP = -np   MA = -ma   ME = -me
    TF = -tf   FO = -fo   DAF = -daf

``test_gem_terms_match_tpoint_equatorial_terms`` in ``tests/test_gpoint.py`` checks each
relation against :mod:`pointax.terms.equatorial`. gpoint's ``tf`` is ``+tf cos E`` in
elevation projected onto the axes, as its alt-az ``tf`` is, hence TF = -tf on both
mounts. (gpoint's print-out calls ``np`` the "angle between optical and telescope tube
axes" and ``ma`` the "mechanical orthogonality of RA and DEC axes", but the formulas are
what counts: ``np`` is TPOINT's NP, ``tan d``, and ``ch`` its CH, ``sec d``.)

**Extra terms** are written ``axis:function:variables:multipliers`` (gpoint's
``--extra``): ``axis`` is ``az`` or ``el`` (``alt`` is taken as ``el``) for an alt-az
model, ``ha`` or ``dec`` for a GEM one (gpoint applies only the extras of its model's
axes and ignores the others), ``function`` one of gpoint's functions below,
``variables`` and ``multipliers`` ``;``-separated, one per argument.
``az:sincos:az;el:2;2`` adds ``coef sin(2 A) cos(2 E)`` to the azimuth. Variables:
``az`` (A), ``el`` (E), ``zd`` (pi/2 - E), and for GEM extras ``ha`` (H) and ``dec``
(d) too, all at the raw position; a GEM extra's ``az``, ``el``, ``zd`` are gpoint's
``equ_to_hrz`` of the raw ``(H, d)`` at the latitude (azimuth from South through West,
in [0, 360) deg), so such an extra needs ``latitude``. In alt-az extras gpoint's ``ha``
and ``dec`` variables need an alt-az to equatorial conversion (gpoint's own
``hrz_to_equ`` differs from the standard formula) and are refused. gpoint's ``offset``
function is 1 only for ``az:offset:az`` and ``el:offset:el`` and 0 otherwise, so on a
GEM axis it has no effect and is refused. Functions, with ``x = m1 v1``, ``y = m2 v2``:

    offset: 1 (only on its own axis: az:offset:az:1, el:offset:el:1)
    sin, cos, tan: sin x, cos x, tan x     abssin, abscos: |sin x|, |cos x|
    csc, sec, cot: 1/sin x, 1/cos x, 1/tan x
    sincos, sinsin, coscos: sin x cos y, sin x sin y, cos x cos y

gpoint names the parameter ``axis_function_variables_multipliers`` with dots turned
to underscores (``az_sincos_az_el_2_0_2_0``, :attr:`GpointExtra.gpoint_parname`);
pointax reports it by its canonical spec (``az:sincos:az;el:2;2``,
:attr:`GpointExtra.name`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from .base import Term, angle_pair, param

__all__ = [
    "GPOINT_SOURCE",
    "GPOINT_ALTAZ_TERMS",
    "GPOINT_GEM_TERMS",
    "GPOINT_MOUNTS",
    "GPOINT_FUNCTIONS",
    "GpointTerm",
    "GpointIA",
    "GpointIE",
    "GpointTN",
    "GpointTE",
    "GpointNPAE",
    "GpointNPOA",
    "GpointTF",
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
    "GpointExtra",
    "GPOINT_TERMS",
    "GPOINT_GEM_TERM_CLASSES",
    "gpoint_extra",
    "gpoint_term",
    "gpoint_model_terms",
    "gem_horizontal",
    "check_gpoint_mount",
    "split_tokens",
    "classify",
    "split_names",
]

GPOINT_SOURCE = ("RTS2/rts2", "python/rts2/gpoint.py", "6480a7eb549d3158ee178ce557fab6d75de8eba9")
"""(repository, path, commit) of the gpoint source these definitions follow."""

GPOINT_ALTAZ_TERMS = ("ia", "tn", "te", "npae", "npoa", "ie", "tf")
"""gpoint's alt-az terms, in the order of its ``RTS2_ALTAZ`` model line (``_altaz_params``)."""

GPOINT_GEM_TERMS = ("id", "me", "ma", "tf", "ih", "ch", "np", "daf", "fo")
"""gpoint's German-equatorial terms, in the order of its ``RTS2_GEM`` model line
(``_gem_params``)."""

GPOINT_MOUNTS = ("altaz", "gem")
"""gpoint's two models: ``"altaz"`` (terms on azimuth, elevation) and ``"gem"`` (German
equatorial: terms on hour angle, declination)."""

GPOINT_FUNCTIONS = {
    "offset": 1,
    "sin": 1,
    "cos": 1,
    "abssin": 1,
    "abscos": 1,
    "tan": 1,
    "csc": 1,
    "sec": 1,
    "cot": 1,
    "sincos": 2,
    "sinsin": 2,
    "coscos": 2,
}
"""gpoint's extra-term functions -> number of arguments."""

_ALTAZ_VARIABLES = ("az", "el", "zd")
_GEM_VARIABLES = ("ha", "dec", "az", "el", "zd")
_AXES = {"az": "az", "el": "el", "alt": "el", "ha": "ha", "dec": "dec"}
_MOUNT_OF_AXIS = {"az": "altaz", "el": "altaz", "ha": "gem", "dec": "gem"}


def check_gpoint_mount(mount: str) -> str:
    """``"altaz"`` or ``"gem"``, checked; ``"equatorial"`` (pointax's name for the mount) is
    taken as ``"gem"``.

    Raises:
        ValueError: for another name.
    """
    if mount == "equatorial":
        return "gem"
    if mount not in GPOINT_MOUNTS:
        raise ValueError(f"unknown gpoint model {mount!r}; expected 'altaz' or 'gem' (German equatorial)")
    return mount


def _check_latitude(latitude, what: str) -> float:
    """The latitude as a Python float (radians), refused when it cannot be one."""
    try:
        value = float(latitude)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: latitude must be one number in radians, got {latitude!r}") from None
    if not (math.isfinite(value) and abs(value) <= math.pi / 2 + 1e-12):
        raise ValueError(
            f"{what}: latitude {value!r} rad is not within [-pi/2, pi/2] (give it in radians: pointax.deg(latitude_deg))"
        )
    return value


class GpointTerm(Term):
    """One of gpoint's alt-az terms: ``coef * offset(A, E)`` added to the encoder angles,
    evaluated at the raw encoder reading (azimuth from South through West).

    Attributes:
        coef: the coefficient, radians (reported in arcseconds).
    """

    coef: float = param(0.0)
    gpoint_name: ClassVar[str] = ""
    gpoint_mount: ClassVar[str] = "altaz"

    @property
    def name(self) -> str:
        return self.gpoint_name

    def offset(self, az, el) -> tuple:
        """(dA, dE) added per radian of coefficient: gpoint's formula."""
        raise NotImplementedError

    def encoder_offset(self, encoder):
        return self.coef * angle_pair(*self.offset(encoder[0], encoder[1]))


class GpointIA(GpointTerm):
    """gpoint ``ia``, zero point in azimuth: ``dA = -ia``. TPOINT: IA = +ia."""

    gpoint_name: ClassVar[str] = "ia"

    def offset(self, az, el):
        return -1.0, 0.0


class GpointIE(GpointTerm):
    """gpoint ``ie``, zero point in elevation: ``dE = -ie``. TPOINT: IE = -ie (the
    opposite sign)."""

    gpoint_name: ClassVar[str] = "ie"

    def offset(self, az, el):
        return 0.0, -1.0


class GpointTN(GpointTerm):
    """gpoint ``tn``, tilt of the azimuth axis towards North: ``dA = +tn sin A tan E``,
    ``dE = +tn cos A`` (A from South through West). TPOINT on the same azimuth: AN = -tn."""

    gpoint_name: ClassVar[str] = "tn"

    def offset(self, az, el):
        return jnp.sin(az) * jnp.tan(el), jnp.cos(az)


class GpointTE(GpointTerm):
    """gpoint ``te``, tilt of the azimuth axis towards East: ``dA = -te cos A tan E``,
    ``dE = +te sin A`` (A from South through West). TPOINT on the same azimuth: AW = +te."""

    gpoint_name: ClassVar[str] = "te"

    def offset(self, az, el):
        return -jnp.cos(az) * jnp.tan(el), jnp.sin(az)


class GpointNPAE(GpointTerm):
    """gpoint ``npae``, non-perpendicularity of the elevation and azimuth axes:
    ``dA = -npae tan E``. TPOINT: NPAE = +npae."""

    gpoint_name: ClassVar[str] = "npae"

    def offset(self, az, el):
        return -jnp.tan(el), 0.0


class GpointNPOA(GpointTerm):
    """gpoint ``npoa``, non-perpendicularity of the optical and elevation axes
    (collimation): ``dA = +npoa / cos E``. TPOINT: CA = -npoa."""

    gpoint_name: ClassVar[str] = "npoa"

    def offset(self, az, el):
        return 1.0 / jnp.cos(el), 0.0


class GpointTF(GpointTerm):
    """gpoint ``tf``, tube flexure: ``dE = +tf cos E``. TPOINT: TF = -tf (ECEC = +tf)."""

    gpoint_name: ClassVar[str] = "tf"

    def offset(self, az, el):
        return 0.0, jnp.cos(el)


GPOINT_TERMS: dict[str, type[GpointTerm]] = {
    cls.gpoint_name: cls for cls in (GpointIA, GpointTN, GpointTE, GpointNPAE, GpointNPOA, GpointIE, GpointTF)
}
"""gpoint alt-az name -> term class."""


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
    cos H)``, ``phi`` the latitude. TPOINT: DAF = -daf."""

    gpoint_name: ClassVar[str] = "daf"
    uses_latitude: ClassVar[bool] = True

    def offset(self, ha, dec):
        s, c = math.sin(self.latitude), math.cos(self.latitude)
        return -(s * jnp.tan(dec) + c * jnp.cos(ha)), 0.0


GPOINT_GEM_TERM_CLASSES: dict[str, type[GpointGemTerm]] = {
    cls.gpoint_name: cls
    for cls in (GpointID, GpointME, GpointMA, GpointGemTF, GpointIH, GpointCH, GpointNP, GpointDAF, GpointFO)
}
"""gpoint GEM name -> term class, in the order of :data:`GPOINT_GEM_TERMS`."""


def _number_text(x: float) -> str:
    """Shortest text of a multiplier: 2.0 -> '2', 0.5 -> '0.5'."""
    text = repr(float(x))
    return text[:-2] if text.endswith(".0") else text


def gem_horizontal(ha, dec, latitude: float):
    """gpoint's ``equ_to_hrz`` of a GEM reading: ``(az, el)`` radians, azimuth from South
    through West in ``[0, 2 pi)``, of hour angle ``ha`` and declination ``dec`` (radians)
    at ``latitude`` (radians). gpoint divides both arguments of its ``arctan2`` by the
    zenith distance's sine, which changes nothing but the zenith (where gpoint gives NaN)."""
    s, c = math.sin(latitude), math.cos(latitude)
    el = jnp.arcsin(s * jnp.sin(dec) + c * jnp.cos(dec) * jnp.cos(ha))
    az = jnp.arctan2(jnp.cos(dec) * jnp.sin(ha), s * jnp.cos(dec) * jnp.cos(ha) - c * jnp.sin(dec))
    return jnp.mod(az, 2 * jnp.pi), el


class GpointExtra(Term):
    """A gpoint extra term: ``coef * function(m1 v1[, m2 v2])`` added to one encoder
    angle, evaluated at the raw encoder reading (see :mod:`pointax.terms.gpoint`).

    Build one with :func:`gpoint_extra`. On an ``az`` or ``el`` axis it belongs to an
    alt-az model (encoder = azimuth from South through West, elevation); on ``ha`` or
    ``dec`` to a GEM model (encoder = hour angle, declination).

    Attributes:
        coef: the coefficient, radians (reported in arcseconds).
        axis: ``"az"``, ``"el"``, ``"ha"`` or ``"dec"``, the angle corrected (static).
        function: one of :data:`GPOINT_FUNCTIONS` (static).
        variables: the arguments, each ``"az"``, ``"el"``, ``"zd"`` (or, on a GEM axis,
            ``"ha"``, ``"dec"``) (static).
        multipliers: one number per argument (static).
        latitude: radians (static); needed by a GEM extra whose variables include
            ``az``, ``el`` or ``zd`` (gpoint's ``equ_to_hrz`` of the raw reading).
    """

    coef: float = param(0.0)
    axis: str = eqx.field(static=True, default="az")
    function: str = eqx.field(static=True, default="offset")
    variables: tuple[str, ...] = eqx.field(static=True, default=("az",))
    multipliers: tuple[float, ...] = eqx.field(static=True, default=(1.0,))
    latitude: float | None = eqx.field(static=True, default=None)

    @property
    def name(self) -> str:
        """Canonical spec, e.g. ``az:sincos:az;el:2;2``."""
        return ":".join(
            [self.axis, self.function, ";".join(self.variables), ";".join(_number_text(m) for m in self.multipliers)]
        )

    @property
    def gpoint_mount(self) -> str:
        """``"altaz"`` for an az/el extra, ``"gem"`` for a ha/dec one."""
        return _MOUNT_OF_AXIS[self.axis]

    @property
    def uses_latitude(self) -> bool:
        return self.gpoint_mount == "gem" and any(v in ("az", "el", "zd") for v in self.variables)

    @property
    def gpoint_parname(self) -> str:
        """gpoint's own parameter name, e.g. ``az_sincos_az_el_2_0_2_0``."""
        consts = "_".join(str(float(m)) for m in self.multipliers).replace(".", "_")
        return "_".join([self.axis, self.function, "_".join(self.variables), consts])

    def _variable(self, name: str, a1, a2):
        if self.gpoint_mount == "altaz":
            az, el = a1, a2
        else:
            if name == "ha":
                return a1
            if name == "dec":
                return a2
            az, el = gem_horizontal(a1, a2, self.latitude)
        if name == "az":
            return az
        if name == "el":
            return el
        return jnp.pi / 2 - el  # "zd"

    def value(self, a1, a2):
        """The function at the raw reading ``(a1, a2)`` radians: azimuth (South through
        West) and elevation for an alt-az extra, hour angle and declination for a GEM
        one; per radian of coefficient."""
        fn, m = self.function, self.multipliers
        if fn == "offset":
            return jnp.ones_like(jnp.asarray(a1, float))
        x = m[0] * self._variable(self.variables[0], a1, a2)
        one = {
            "sin": jnp.sin,
            "cos": jnp.cos,
            "abssin": lambda t: jnp.abs(jnp.sin(t)),
            "abscos": lambda t: jnp.abs(jnp.cos(t)),
            "tan": jnp.tan,
            "csc": lambda t: 1.0 / jnp.sin(t),
            "sec": lambda t: 1.0 / jnp.cos(t),
            "cot": lambda t: 1.0 / jnp.tan(t),
        }
        if fn in one:
            return one[fn](x)
        y = m[1] * self._variable(self.variables[1], a1, a2)
        first = jnp.cos(x) if fn == "coscos" else jnp.sin(x)
        second = jnp.sin(y) if fn == "sinsin" else jnp.cos(y)
        return first * second

    def encoder_offset(self, encoder):
        f = self.coef * self.value(encoder[0], encoder[1])
        return angle_pair(f, 0.0) if self.axis in ("az", "ha") else angle_pair(0.0, f)


def _parse_extra(spec: str, mount: str | None = None) -> tuple[str, str, tuple[str, ...], tuple[float, ...]]:
    """``(axis, function, variables, multipliers)`` of an extra spec, checked (not for
    the latitude); ``mount`` ``"altaz"`` or ``"gem"`` restricts the axis, None takes
    the model the axis belongs to."""
    where = f"gpoint extra term {spec!r}"
    fields = spec.strip().split(":")
    if len(fields) != 4:
        raise ValueError(
            f"{where}: has {len(fields)} ':'-separated fields; expected 4, axis:function:variables:multipliers "
            "(e.g. az:sincos:az;el:2;2)"
        )
    axis, function, variables, consts = (f.strip().lower() for f in fields)
    if axis not in _AXES:
        raise ValueError(f"{where}: field 1 (axis) is {axis!r}; expected az or el (alt) for an alt-az model, ha or dec for a GEM one")
    axis = _AXES[axis]
    axis_mount = _MOUNT_OF_AXIS[axis]
    if mount == "altaz" and axis_mount == "gem":
        raise ValueError(
            f"{where}: field 1 (axis) {axis!r} is an equatorial axis; an alt-az model's extras correct az or el "
            "(gpoint ignores ha/dec extras in an alt-az fit)"
        )
    if mount == "gem" and axis_mount == "altaz":
        raise ValueError(
            f"{where}: field 1 (axis) {axis!r} is an alt-az axis; a GEM model's extras correct ha or dec "
            "(gpoint ignores az/el extras in a GEM fit)"
        )
    if function not in GPOINT_FUNCTIONS:
        raise ValueError(f"{where}: field 2 (function) is {function!r}; expected one of {' '.join(GPOINT_FUNCTIONS)}")
    arity = GPOINT_FUNCTIONS[function]
    names = tuple(v.strip() for v in variables.split(";"))
    allowed = _ALTAZ_VARIABLES if axis_mount == "altaz" else _GEM_VARIABLES
    for v in names:
        if axis_mount == "altaz" and v in ("ha", "dec"):
            raise ValueError(
                f"{where}: field 3 (variables): {v!r} needs gpoint's alt-az to equatorial conversion, "
                "which pointax does not reproduce; use az, el or zd"
            )
        if v not in allowed:
            raise ValueError(f"{where}: field 3 (variables): {v!r} is not one of {', '.join(allowed)}")
    if len(names) != arity:
        raise ValueError(f"{where}: field 3 (variables): {function} takes {arity} variable(s), got {len(names)}")
    texts = [c.strip() for c in consts.split(";")]
    numbers = []
    for c in texts:
        try:
            value = float(c)
        except ValueError:
            raise ValueError(f"{where}: field 4 (multipliers): {c!r} is not a number") from None
        if not math.isfinite(value):
            raise ValueError(f"{where}: field 4 (multipliers): {c!r} is not finite")
        numbers.append(value)
    if len(numbers) != arity:
        raise ValueError(f"{where}: field 4 (multipliers): {function} takes {arity} multiplier(s), got {len(numbers)}")
    if function == "offset":
        if axis_mount == "gem":
            raise ValueError(
                f"{where}: gpoint's offset is 1 only for az:offset:az and el:offset:el (cal_extra) and 0 on ha and "
                "dec, so this one would have no effect; use ih or id"
            )
        if names[0] != axis:
            raise ValueError(
                f"{where}: gpoint's offset is 1 only on its own axis ({axis}:offset:{axis}:1) and 0 otherwise; "
                f"this one would have no effect"
            )
    return axis, function, names, tuple(numbers)


def gpoint_extra(spec: str, coef: float = 0.0, latitude: float | None = None, mount: str | None = None) -> GpointExtra:
    """A gpoint extra term from its spec ``axis:function:variables:multipliers``, e.g.
    ``gpoint_extra("az:sincos:az;el:2;2")`` or ``gpoint_extra("ha:sin:dec:2")``; ``coef``
    in radians.

    Args:
        spec: the spec (gpoint's ``--extra``).
        coef: starting value, radians.
        latitude: radians; required by a GEM (ha/dec) extra with ``az``, ``el`` or ``zd``
            among its variables.
        mount: ``"altaz"`` or ``"gem"`` to require the model's axes; None: the axis says.

    Raises:
        ValueError: naming the field that is wrong.
    """
    if mount is not None:
        mount = check_gpoint_mount(mount)
    axis, function, names, numbers = _parse_extra(spec, mount)
    term = GpointExtra(coef=coef, axis=axis, function=function, variables=names, multipliers=numbers)
    if latitude is not None:
        term = GpointExtra(coef=coef, axis=axis, function=function, variables=names, multipliers=numbers,
                           latitude=_check_latitude(latitude, f"gpoint extra term {spec!r}"))
    elif term.uses_latitude:
        raise ValueError(
            f"gpoint extra term {spec!r}: its variables {';'.join(names)} are gpoint's equ_to_hrz of the GEM reading, "
            "which needs the site's latitude: pass latitude= (radians)"
        )
    return term


def split_tokens(spec: str | Iterable[str]) -> list[str]:
    """Split a term list given as ``"ia,ie,az:sin:az:2"`` (commas or spaces) or a
    sequence of names, keeping each name's case."""
    if isinstance(spec, str):
        spec = spec.replace(",", " ").split()
    return [s.strip() for s in spec if s.strip()]


def classify(token: str, mount: str = "altaz") -> tuple[str, str]:
    """``(kind, name)`` of one term name in a ``mount`` model (``"altaz"`` or ``"gem"``):
    kind ``"gpoint"`` for gpoint's lower-case names of that model, ``"extra"`` for
    ``axis:function:...`` specs (name = canonical spec), ``"tpoint"`` otherwise (name
    upper-case).

    Raises:
        ValueError: for gpoint's lower-case name of the other model (``ma`` in an alt-az
            model, ``ia`` in a GEM one) or an extra on the other model's axes.
    """
    mount = check_gpoint_mount(mount)
    own = GPOINT_TERMS if mount == "altaz" else GPOINT_GEM_TERM_CLASSES
    other = GPOINT_GEM_TERM_CLASSES if mount == "altaz" else GPOINT_TERMS
    if token in own:
        return "gpoint", token
    if token in other:
        kind, others = ("GEM", "gem") if mount == "altaz" else ("alt-az", "altaz")
        names = GPOINT_ALTAZ_TERMS if mount == "altaz" else GPOINT_GEM_TERMS
        raise ValueError(
            f"{token!r} is gpoint's {kind} term, not a term of a gpoint {mount} model (whose terms are "
            f"{' '.join(names)}); it belongs in {'a GEM' if kind == 'GEM' else 'an alt-az'} model (mount={others!r})"
        )
    if ":" in token:
        axis, function, names, numbers = _parse_extra(token, mount)
        return "extra", GpointExtra(axis=axis, function=function, variables=names, multipliers=numbers).name
    return "tpoint", token.upper()


def split_names(spec: str | Iterable[str], mount: str = "altaz") -> list[str]:
    """Parameter names of the terms in ``spec`` (see :func:`classify`)."""
    mount = check_gpoint_mount(mount)
    return [classify(token, mount)[1] for token in split_tokens(spec)]


def gpoint_term(token: str, coef: float = 0.0, mount: str = "altaz", latitude: float | None = None) -> Term:
    """gpoint's term called ``token`` in a ``mount`` model, ``coef`` in radians.

    Args:
        token: ``ia ie tn te npae npoa tf`` (alt-az), ``ih id ch np ma me tf fo daf``
            (GEM), or an extra spec ``axis:function:variables:multipliers``.
        coef: starting value, radians.
        mount: ``"altaz"`` (default) or ``"gem"``; ``tf`` differs between them.
        latitude: radians; required by GEM ``tf`` and ``daf`` and by GEM extras of
            ``az``, ``el`` or ``zd``; checked for range.

    Raises:
        ValueError: for a name that is none of these.
    """
    mount = check_gpoint_mount(mount)
    lat = None if latitude is None else _check_latitude(latitude, f"gpoint term {token!r}")
    if mount == "altaz" and token in GPOINT_TERMS:
        return GPOINT_TERMS[token](coef=coef)
    if mount == "gem" and token in GPOINT_GEM_TERM_CLASSES:
        return GPOINT_GEM_TERM_CLASSES[token](coef=coef, latitude=lat)
    if ":" in token:
        return gpoint_extra(token, coef, latitude=lat, mount=mount)
    kind = classify(token, mount)[0]  # raises for the other model's names
    names = GPOINT_ALTAZ_TERMS if mount == "altaz" else GPOINT_GEM_TERMS
    raise ValueError(
        f"unknown gpoint term {token!r} ({kind} name); gpoint's {mount} terms are {' '.join(names)} (lower-case), "
        "extras are axis:function:variables:multipliers"
    )


def gpoint_model_terms(
    spec: str | Iterable[str], mount: str = "altaz", latitude: float | None = None, values: dict | None = None
) -> tuple[Term, ...]:
    """gpoint's own terms only (no TPOINT names), as a gpoint model file holds them: e.g.
    ``gpoint_model_terms("ih id ch np ma me tf fo daf ha:sin:dec:2", "gem", latitude=lat)``.

    ``values`` by parameter name (radians). For mixing TPOINT's names in, see
    :func:`pointax.terms.gpoint_terms`.

    Raises:
        ValueError: for a name that is not gpoint's, a repeated name, or values of terms
            not in the list.
    """
    mount = check_gpoint_mount(mount)
    values = dict(values or {})
    out, seen = [], set()
    for token in split_tokens(spec):
        kind, name = classify(token, mount)
        if kind == "tpoint":
            names = GPOINT_ALTAZ_TERMS if mount == "altaz" else GPOINT_GEM_TERMS
            raise ValueError(f"{token!r} is not a gpoint {mount} term ({' '.join(names)} or an extra)")
        if name in seen:
            raise ValueError(f"gpoint term {name!r} is given twice")
        seen.add(name)
        out.append(gpoint_term(token, coef=values.pop(name, 0.0), mount=mount, latitude=latitude))
    if values:
        raise ValueError(f"values given for terms not in the list: {sorted(values)}")
    return tuple(out)

"""RTS2 gpoint's alt-az pointing terms and its "extra" terms, exactly as gpoint defines them.

Source, taken as the definition: RTS2's ``python/rts2/gpoint.py`` (repository
``RTS2/rts2``, commit ``6480a7eb549d3158ee178ce557fab6d75de8eba9``), functions
``GPoint.model_az_hadec``, ``GPoint.model_el_hadec``, ``GPoint.cal_extra``,
``GPoint.get_extra_val`` and ``GPoint.add_extra_multi``; the ``--extra`` option of
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

**Extra terms** are written ``axis:function:variables:multipliers`` (gpoint's
``--extra``): ``axis`` is ``az`` or ``el`` (``alt`` is taken as ``el``), ``function``
one of gpoint's functions below, ``variables`` and ``multipliers`` ``;``-separated,
one per argument. ``az:sincos:az;el:2;2`` adds ``coef sin(2 A) cos(2 E)`` to the
azimuth. Variables: ``az`` (A), ``el`` (E), ``zd`` (pi/2 - E). gpoint's ``ha`` and
``dec`` variables need an alt-az to equatorial conversion (gpoint's own
``hrz_to_equ`` differs from the standard formula) and are refused. Functions, with
``x = m1 v1``, ``y = m2 v2``:

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
    "GPOINT_FUNCTIONS",
    "GpointTerm",
    "GpointIA",
    "GpointIE",
    "GpointTN",
    "GpointTE",
    "GpointNPAE",
    "GpointNPOA",
    "GpointTF",
    "GpointExtra",
    "GPOINT_TERMS",
    "gpoint_extra",
    "gpoint_term",
    "split_tokens",
    "classify",
    "split_names",
]

GPOINT_SOURCE = ("RTS2/rts2", "python/rts2/gpoint.py", "6480a7eb549d3158ee178ce557fab6d75de8eba9")
"""(repository, path, commit) of the gpoint source these definitions follow."""

GPOINT_ALTAZ_TERMS = ("ia", "tn", "te", "npae", "npoa", "ie", "tf")
"""gpoint's alt-az terms, in the order of its ``RTS2_ALTAZ`` model line."""

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

_VARIABLES = ("az", "el", "zd")
_AXES = {"az": "az", "el": "el", "alt": "el"}


class GpointTerm(Term):
    """One of gpoint's alt-az terms: ``coef * offset(A, E)`` added to the encoder angles,
    evaluated at the raw encoder reading (azimuth from South through West).

    Attributes:
        coef: the coefficient, radians (reported in arcseconds).
    """

    coef: float = param(0.0)
    gpoint_name: ClassVar[str] = ""

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
"""gpoint name -> term class."""


def _number_text(x: float) -> str:
    """Shortest text of a multiplier: 2.0 -> '2', 0.5 -> '0.5'."""
    text = repr(float(x))
    return text[:-2] if text.endswith(".0") else text


def _variable(name: str, az, el):
    if name == "az":
        return az
    if name == "el":
        return el
    return jnp.pi / 2 - el  # "zd"


class GpointExtra(Term):
    """A gpoint extra term: ``coef * function(m1 v1[, m2 v2])`` added to one encoder
    angle, evaluated at the raw encoder reading (see :mod:`pointax.terms.gpoint`).

    Build one with :func:`gpoint_extra`.

    Attributes:
        coef: the coefficient, radians (reported in arcseconds).
        axis: ``"az"`` or ``"el"``, the angle corrected (static).
        function: one of :data:`GPOINT_FUNCTIONS` (static).
        variables: the arguments, each ``"az"``, ``"el"`` or ``"zd"`` (static).
        multipliers: one number per argument (static).
    """

    coef: float = param(0.0)
    axis: str = eqx.field(static=True, default="az")
    function: str = eqx.field(static=True, default="offset")
    variables: tuple[str, ...] = eqx.field(static=True, default=("az",))
    multipliers: tuple[float, ...] = eqx.field(static=True, default=(1.0,))

    @property
    def name(self) -> str:
        """Canonical spec, e.g. ``az:sincos:az;el:2;2``."""
        return ":".join(
            [self.axis, self.function, ";".join(self.variables), ";".join(_number_text(m) for m in self.multipliers)]
        )

    @property
    def gpoint_parname(self) -> str:
        """gpoint's own parameter name, e.g. ``az_sincos_az_el_2_0_2_0``."""
        consts = "_".join(str(float(m)) for m in self.multipliers).replace(".", "_")
        return "_".join([self.axis, self.function, "_".join(self.variables), consts])

    def value(self, az, el):
        """The function at raw azimuth ``az`` (South through West) and elevation ``el``,
        radians, per radian of coefficient."""
        fn, m = self.function, self.multipliers
        if fn == "offset":
            return jnp.ones_like(jnp.asarray(az, float))
        x = m[0] * _variable(self.variables[0], az, el)
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
        y = m[1] * _variable(self.variables[1], az, el)
        first = jnp.cos(x) if fn == "coscos" else jnp.sin(x)
        second = jnp.sin(y) if fn == "sinsin" else jnp.cos(y)
        return first * second

    def encoder_offset(self, encoder):
        f = self.coef * self.value(encoder[0], encoder[1])
        return angle_pair(f, 0.0) if self.axis == "az" else angle_pair(0.0, f)


def gpoint_extra(spec: str, coef: float = 0.0) -> GpointExtra:
    """A gpoint extra term from its spec ``axis:function:variables:multipliers``, e.g.
    ``gpoint_extra("az:sincos:az;el:2;2")``; ``coef`` in radians.

    Raises:
        ValueError: naming the field that is wrong.
    """
    where = f"gpoint extra term {spec!r}"
    fields = spec.strip().split(":")
    if len(fields) != 4:
        raise ValueError(
            f"{where}: has {len(fields)} ':'-separated fields; expected 4, axis:function:variables:multipliers "
            "(e.g. az:sincos:az;el:2;2)"
        )
    axis, function, variables, consts = (f.strip().lower() for f in fields)
    if axis in ("ha", "dec"):
        raise ValueError(f"{where}: field 1 (axis) {axis!r} is an equatorial axis; pointax reads gpoint's alt-az runs (axis az or el)")
    if axis not in _AXES:
        raise ValueError(f"{where}: field 1 (axis) is {axis!r}; expected az or el (alt)")
    if function not in GPOINT_FUNCTIONS:
        raise ValueError(f"{where}: field 2 (function) is {function!r}; expected one of {' '.join(GPOINT_FUNCTIONS)}")
    arity = GPOINT_FUNCTIONS[function]
    names = tuple(v.strip() for v in variables.split(";"))
    for v in names:
        if v in ("ha", "dec"):
            raise ValueError(
                f"{where}: field 3 (variables): {v!r} needs gpoint's alt-az to equatorial conversion, "
                "which pointax does not reproduce; use az, el or zd"
            )
        if v not in _VARIABLES:
            raise ValueError(f"{where}: field 3 (variables): {v!r} is not one of az, el, zd")
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
    axis = _AXES[axis]
    if function == "offset" and names[0] != axis:
        raise ValueError(
            f"{where}: gpoint's offset is 1 only on its own axis ({axis}:offset:{axis}:1) and 0 otherwise; "
            f"this one would have no effect"
        )
    return GpointExtra(coef=coef, axis=axis, function=function, variables=names, multipliers=tuple(numbers))


def split_tokens(spec: str | Iterable[str]) -> list[str]:
    """Split a term list given as ``"ia,ie,az:sin:az:2"`` (commas or spaces) or a
    sequence of names, keeping each name's case."""
    if isinstance(spec, str):
        spec = spec.replace(",", " ").split()
    return [s.strip() for s in spec if s.strip()]


def classify(token: str) -> tuple[str, str]:
    """``(kind, name)`` of one term name: kind ``"gpoint"`` for gpoint's lower-case
    names, ``"extra"`` for ``axis:function:...`` specs (name = canonical spec),
    ``"tpoint"`` otherwise (name upper-case)."""
    if token in GPOINT_TERMS:
        return "gpoint", token
    if ":" in token:
        return "extra", gpoint_extra(token).name
    return "tpoint", token.upper()


def split_names(spec: str | Iterable[str]) -> list[str]:
    """Parameter names of the terms in ``spec`` (see :func:`classify`)."""
    return [classify(token)[1] for token in split_tokens(spec)]


def gpoint_term(token: str, coef: float = 0.0) -> Term:
    """gpoint's term called ``token`` (``ia`` ... ``tf``, or an extra spec), ``coef`` in radians.

    Raises:
        ValueError: for a name that is neither.
    """
    if token in GPOINT_TERMS:
        return GPOINT_TERMS[token](coef=coef)
    if ":" in token:
        return gpoint_extra(token, coef)
    raise ValueError(
        f"unknown gpoint term {token!r}; gpoint's alt-az terms are {' '.join(GPOINT_ALTAZ_TERMS)} (lower-case), "
        "extras are axis:function:variables:multipliers"
    )

"""RTS2 gpoint's user-defined "extra" terms (``az:sincos:az;el:2;2``): the term class
:class:`GpointExtra`, the spec parser :func:`parse_extra` and the function table
:data:`GPOINT_FUNCTIONS`. Transcribed from gpoint's ``GPoint.cal_extra``,
``GPoint.get_extra_val`` and ``GPoint.add_extra_multi`` and the ``--extra`` option of its
``scripts/gpoint`` (:data:`pointax.terms.gpoint.GPOINT_SOURCE`); build one with
:func:`pointax.terms.gpoint.gpoint_extra`.

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

import equinox as eqx
import jax.numpy as jnp

from ..core.term import Term, angle_pair, param
from .gpoint_gem import gem_horizontal

__all__ = ["GPOINT_FUNCTIONS", "GpointExtra", "parse_extra"]

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


def _number_text(x: float) -> str:
    """Shortest text of a multiplier: 2.0 -> '2', 0.5 -> '0.5'."""
    text = repr(float(x))
    return text[:-2] if text.endswith(".0") else text



class GpointExtra(Term):
    """A gpoint extra term: ``coef * function(m1 v1[, m2 v2])`` added to one encoder
    angle, evaluated at the raw encoder reading (see :mod:`pointax.terms.gpoint_extras`).

    Build one with :func:`pointax.terms.gpoint.gpoint_extra`. On an ``az`` or ``el`` axis it belongs to an
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



def parse_extra(spec: str, mount: str | None = None) -> tuple[str, str, tuple[str, ...], tuple[float, ...]]:
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


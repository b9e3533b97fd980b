"""A pointing model: a mount plus its error terms, with named, fixable parameters."""

from __future__ import annotations

import dataclasses
import math
import os
import sys
from collections.abc import Iterable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from .compiled import compile_by_structure
from .precision import float64
from .mounts import Mount, SphericalMount
from .readings import bind_readings, readings_needed
from .term import Term, check_linear_claim, param_fields, param_unit
from .units import TURN, UNITS, check_angle_radians, check_pointing_term, is_quantity, value_in_unit

__all__ = ["Model", "ParameterInfo", "RESIDUAL_FORMS"]

RESIDUAL_FORMS = ("sky", "tpoint")
"""What a fit minimises (:attr:`Model.residual_form`)."""


_INTERNAL_DIRS = tuple(
    os.path.dirname(os.path.abspath(m.__file__)) + os.sep for m in (sys.modules[__name__.split(".")[0]], eqx, jax)
)
"""Frames in these packages are not the user's: equinox wraps a Module's methods (and jax
its Partial), so a fixed ``stacklevel`` would point a warning into equinox."""


def _user_stacklevel(base: int = 3) -> int:
    """The ``stacklevel`` for a check called by a method (``base`` the one that names the
    method's direct caller) that makes the warning name the first frame outside
    pointax, equinox and jax: the user's line. The caller's if every frame is internal."""
    frame, extra = sys._getframe(2), 0  # 0: this function, 1: the method, 2: its caller
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(_INTERNAL_DIRS):
        frame, extra = frame.f_back, extra + 1
    return base if frame is None else base + extra


def _in_unit(value, p: "ParameterInfo", unit):
    """``value`` (internal units) of parameter ``p`` in ``unit``: a unit name of
    :data:`pointax.core.units.UNITS` gives a float, an astropy unit a Quantity."""
    if isinstance(unit, str):
        if unit not in UNITS:
            raise ValueError(f"unknown unit {unit!r}; expected one of {sorted(UNITS)}")
        if (unit == "1") != (p.unit == "1"):
            raise ValueError(f"parameter {p.name} is in {p.unit}; it cannot be given in {unit}")
        return float(value) / UNITS[unit]
    u = sys.modules.get("astropy.units")  # an astropy unit was given: its package is loaded
    if u is None or not isinstance(unit, u.UnitBase):
        raise ValueError(f"unit must be one of {sorted(UNITS)} or an astropy unit, got {unit!r}")

    internal = u.dimensionless_unscaled if p.unit == "1" else u.rad
    try:
        return (float(value) * internal).to(unit)
    except u.UnitConversionError:
        raise ValueError(f"parameter {p.name} is in {p.unit}; it cannot be given in {unit}") from None


@dataclasses.dataclass(frozen=True)
class ParameterInfo:
    """Where one scalar parameter lives: its name, term index, field name and unit, and
    what its declaration says of its values (:func:`pointax.terms.param`): the range
    ``expected`` of a sound fit and the ``period`` of an angle whose multiples give the
    same model (None when not declared)."""

    name: str
    term: int
    field: str
    unit: str
    expected: tuple[float, float] | None = None
    period: float | None = None


class Model(eqx.Module):
    """A mount and a tuple of error terms.

    The model is a pytree whose leaves are the term parameters (radians unless a term
    declares another unit). ``fixed`` names parameters that :func:`pointax.fit` keeps
    at their current values.

    Args:
        mount: the mount kinematics, e.g. :class:`pointax.AltAzMount`.
        terms: error terms (:mod:`pointax.terms`), applied as described in
            :mod:`pointax.core.term`.
        fixed: names of parameters held fixed in fits.
        sky_iterations: fixed-point iterations that place sky offsets at the corrected
            position (each contracts the error by a factor of about the largest
            offset derivative, ~1e-4 for real models: 3 is ample).
        residual_form: what a fit minimises; the model itself (:meth:`direction`,
            :func:`pointax.command`) is the same either way.

            * ``"sky"`` (default): the tangent-plane offset of the observed direction
              from where the model points, sky offsets evaluated at the sky position
              the model reaches (a fixed point). Exact, with no pole.
            * ``"tpoint"``: TPOINT's own residuals, ``(dA cos E, dE)`` with ``d`` the
              observed angles minus the chain's angles and minus the sky offsets, these
              evaluated *at the observed position* (DESIGN.md: this is the
              least-squares problem TPOINT solves). Linear in the coefficients of
              TPOINT's linear-form terms, so a fit of them is one linear solve; the
              fitted values differ from ``"sky"``'s at second order (4e-9 rad =
              0.0009" on the MMT run, ``tests/test_residual_form.py``; 1e-8 rad with
              offsets of 100",
              ``benchmarks/batch_fit.py``).
              Needs a mount with spherical angles (alt-az, X-Y, equatorial).
    """

    mount: Mount
    terms: tuple[Term, ...]
    fixed: frozenset[str] = eqx.field(static=True, default=frozenset())
    sky_iterations: int = eqx.field(static=True, default=3)
    residual_form: str = eqx.field(static=True, default="sky")

    def __init__(
        self,
        mount: Mount,
        terms: Iterable[Term] = (),
        fixed: Iterable[str] = (),
        sky_iterations: int = 3,
        residual_form: str = "sky",
    ):
        self.mount = mount
        self.terms = tuple(terms)
        self.fixed = frozenset(fixed)
        self.sky_iterations = int(sky_iterations)
        self.residual_form = residual_form
        if residual_form not in RESIDUAL_FORMS:
            raise ValueError(f"residual_form must be one of {RESIDUAL_FORMS}, got {residual_form!r}")
        if residual_form == "tpoint" and not isinstance(mount, SphericalMount):
            raise ValueError(
                f"residual_form='tpoint' needs a mount with spherical angles (alt-az, X-Y, "
                f"equatorial); {type(mount).__name__} has none: use residual_form='sky'"
            )
        for t in self.terms:
            if not isinstance(t, Term):
                hint = " (build terms with pointax.terms.tpoint(...))" if isinstance(t, str) else ""
                raise TypeError(f"{t!r} is not a pointax.Term{hint}")
            check_linear_claim(t)
        names = [t.name for t in self.terms]
        duplicated = sorted({n for n in names if names.count(n) > 1})
        if duplicated:
            raise ValueError(f"terms appear more than once: {', '.join(duplicated)}")
        unknown = sorted(self.fixed - set(self.parameter_names))
        if unknown:
            raise ValueError(
                f"cannot fix unknown parameters {unknown}; the model has {self.parameter_names}"
            )

    # ----------------------------------------------------------------- parameters

    @property
    def parameters(self) -> tuple[ParameterInfo, ...]:
        """Every scalar parameter, in term order then field order."""
        out = []
        for i, term in enumerate(self.terms):
            fields = param_fields(term)
            for f in fields:
                name = term.name if len(fields) == 1 else f"{term.name}.{f.name}"
                out.append(ParameterInfo(name, i, f.name, param_unit(f), f.metadata.get("expected"), f.metadata.get("period")))
        return tuple(out)

    @property
    def parameter_names(self) -> list[str]:
        """Names of every parameter, fixed or free."""
        return [p.name for p in self.parameters]

    @property
    def free_parameters(self) -> tuple[ParameterInfo, ...]:
        """The parameters a fit adjusts."""
        return tuple(p for p in self.parameters if p.name not in self.fixed)

    def _select(self, which: str) -> tuple[ParameterInfo, ...]:
        if which == "all":
            return self.parameters
        if which == "free":
            return self.free_parameters
        raise ValueError(f"which must be 'all' or 'free', got {which!r}")

    def replace_parameters(self, params: Sequence[ParameterInfo], values: Sequence) -> "Model":
        """A copy with the parameters ``params`` (from :attr:`parameters`) set to
        ``values``, one value (a scalar, or an array of any batch shape) each, in
        internal units. Pure: usable inside ``jit`` and ``vmap``."""
        if not params:
            return self
        return eqx.tree_at(
            lambda m: [getattr(m.terms[p.term], p.field) for p in params],
            self,
            list(values),
            is_leaf=lambda x: x is None,
        )

    @float64
    def values(self, which: str = "all") -> Float[Array, " n"]:
        """Parameter values (internal units) as one vector; ``which`` is 'all' or 'free'.

        float64 whether or not JAX's x64 mode is on (outside it, JAX would make the
        vector float32 and ``with_values(values())`` would truncate the model)."""
        params = self._select(which)
        if not params:
            return jnp.zeros((0,))
        return jnp.stack([jnp.asarray(getattr(self.terms[p.term], p.field), float) for p in params])

    @float64
    def with_values(self, values: Float[ArrayLike, " n"], which: str = "all") -> "Model":
        """A copy with parameter values replaced from a vector (see :meth:`values`);
        float64 values stay float64 whether or not JAX's x64 mode is on."""
        params = self._select(which)
        values = jnp.asarray(values)
        if values.shape != (len(params),):
            raise ValueError(f"expected {len(params)} values, got shape {values.shape}")
        return self.replace_parameters(params, [values[k] for k in range(len(params))])

    def get(self, name: str, unit=None):
        """Value of the parameter called ``name``: in internal units (radians for
        angles) by default; in ``unit`` when given, a unit name ('arcsec', 'deg',
        'mrad', 'rad') for a float or an astropy unit for a Quantity."""
        for p in self.parameters:
            if p.name == name:
                value = getattr(self.terms[p.term], p.field)
                return value if unit is None else _in_unit(value, p, unit)
        raise KeyError(f"no parameter {name!r}; the model has {self.parameter_names}")

    def set(self, **values) -> "Model":
        """A copy with the named parameters set, e.g. ``model.set(IA=px.arcsec(10))``
        or, with astropy, ``model.set(IA=10 * u.arcsec)`` (a Quantity is converted to
        internal units; a bare number is taken as internal units, radians for angles).

        Use ``model.set(**{"Wobble.amp": x})`` for dotted names.
        """
        info = {p.name: p for p in self.parameters}
        for name in values:
            if name not in info:
                raise KeyError(f"no parameter {name!r}; the model has {self.parameter_names}")
        converted = [
            value_in_unit(v, "1" if info[n].unit == "1" else "rad", f"parameter {n}") if is_quantity(v) else v
            for n, v in values.items()
        ]
        level = _user_stacklevel()  # a warning names the user's line, not equinox's method wrapper
        for (n, v), given in zip(values.items(), converted):
            if info[n].unit != "1" and not is_quantity(v):  # a bare number: radians assumed, so checked
                if info[n].unit == "arcsec":  # a pointing term's coefficient: refused beyond a turn
                    check_pointing_term(given, n, stacklevel=level)
                elif info[n].period is not None:  # an angle modulo a turn (alpha0): refused beyond one
                    check_angle_radians(given, n, stacklevel=level)
                else:  # another angle: named beyond a turn
                    check_angle_radians(given, n, limit=math.inf, warn_above=TURN, stacklevel=level)
        return self.replace_parameters([info[n] for n in values], converted)

    def restructured(self, terms: Iterable[Term] | None = None, fixed: Iterable[str] | None = None) -> "Model":
        """A copy with other ``terms`` and/or ``fixed`` names, everything else kept."""
        terms = self.terms if terms is None else terms
        fixed = self.fixed if fixed is None else fixed
        return Model(self.mount, terms, fixed, self.sky_iterations, self.residual_form)

    def with_residual_form(self, residual_form: str) -> "Model":
        """A copy whose fits minimise ``residual_form`` residuals ('sky' or 'tpoint')."""
        return Model(self.mount, self.terms, self.fixed, self.sky_iterations, residual_form)

    def fix(self, *names: str) -> "Model":
        """A copy with ``names`` held fixed in fits."""
        return self.restructured(fixed=self.fixed | set(names))

    def free(self, *names: str) -> "Model":
        """A copy with ``names`` fitted again (all parameters if no name is given)."""
        return self.restructured(fixed=frozenset() if not names else self.fixed - set(names))

    def with_terms(self, *terms: Term) -> "Model":
        """A copy with ``terms`` appended."""
        return self.restructured(terms=self.terms + tuple(terms))

    def without_terms(self, *names: str) -> "Model":
        """A copy without the terms called ``names``."""
        keep = tuple(t for t in self.terms if t.name not in names)
        kept = {p.name for p in self.parameters if self.terms[p.term].name not in names}
        return self.restructured(terms=keep, fixed=self.fixed & kept)

    # ----------------------------------------------------------------- readings

    @property
    def readings(self) -> tuple[str, ...]:
        """Sorted names of the auxiliary readings the model's terms read
        (:attr:`pointax.Term.readings`); ``()`` for a model that reads none."""
        return readings_needed(self.terms)

    def at_readings(self, readings) -> "Model":
        """A copy whose terms that read auxiliary readings see ``readings`` (a mapping
        name -> value: scalars for one observation); terms that read none are the
        same objects. ``readings`` must hold every name of :attr:`readings` (KeyError
        naming the term and the reading otherwise); others are ignored. The model
        itself when it reads none. Pure: the values are traced data (a change of them
        never recompiles)."""
        if not self.readings:
            return self
        terms = tuple(bind_readings(t, readings) if t.readings else t for t in self.terms)
        copy = object.__new__(type(self))
        copy.__dict__.update(self.__dict__)
        object.__setattr__(copy, "terms", terms)
        return copy

    def _bound(self, readings) -> "Model":
        return self if readings is None else self.at_readings(readings)

    # ----------------------------------------------------------------- evaluation

    def _apply(self, hook: str, angles: Array, v: Array) -> Array:
        """``v`` turned by the product of the terms' rotations at one place in the
        chain (in term order), as matrix-vector products."""
        for term in reversed(self.terms):
            r = getattr(term, hook)(angles)
            if r is not None:
                v = r @ v
        return v

    @float64
    def corrected_encoder(self, encoder: Float[Array, "2"]) -> Float[Array, "2"]:
        """Axis angles after the terms' encoder corrections (one observation's raw
        reading; see :meth:`pointax.Mount.axis_angles`)."""
        nominal = self.mount.axis_angles(encoder)
        angles = nominal
        for term in self.terms:
            offset = term.encoder_offset(nominal)
            if offset is not None:
                angles = angles + offset
        return angles

    @float64
    def sky_offset(self, angles: Float[Array, "2"]) -> Float[Array, "2"] | None:
        """The sum of the terms' sky offsets at ``angles`` (one observation; None when no
        term has one)."""
        total = None
        for term in self.terms:
            offset = term.sky_offset(angles)
            if offset is not None:
                total = offset if total is None else total + offset
        return total

    @float64
    def sky_position(self, chain_angles: Float[Array, "*batch 2"]) -> Float[Array, "*batch 2"]:
        """Solve ``sky = chain_angles + sum(term.sky_offset(sky))`` by fixed-point
        iteration (``sky_iterations`` of them). A loop, not unrolled: unrolled, the
        iterations of a many-term model multiply its compilation time. Called outside a
        trace, it is compiled once per model structure (:mod:`pointax.core.compiled`):
        op by op, a loop is compiled again at every call."""
        return _sky_fixed_point(self, jnp.asarray(chain_angles))

    @float64
    def chain_direction(self, encoder: Float[Array, "2"]) -> tuple[Float[Array, "3"], Float[Array, "2"]]:
        """Where the chain of rotations points, before any sky offset: ``(direction in
        the mount frame, corrected axis angles)`` for one observation's raw reading."""
        angles = self.corrected_encoder(jnp.asarray(encoder))
        mount = self.mount
        # Rotate the boresight vector from the right: matrix-vector products only.
        d = self._apply("boresight_rotation", angles, mount.boresight)
        d = mount.axis2(angles[1]) @ d
        d = self._apply("axes_rotation", angles, d)
        d = mount.axis1(angles[0]) @ d
        d = self._apply("base_rotation", angles, d)
        return d, angles

    @float64
    def mount_direction(self, encoder: Float[Array, "2"], readings=None) -> Float[Array, "3"]:
        """Pointing direction in the *mount* frame for one observation's raw encoder
        angles (radians) and, for a model that reads them, its auxiliary ``readings``
        (a mapping name -> scalar; :meth:`at_readings`). Use :meth:`direction` for
        East-North-Up."""
        if readings is not None:
            return self.at_readings(readings).mount_direction(encoder)
        d, angles = self.chain_direction(encoder)
        if self.sky_offset(angles) is None:
            return d
        chain_angles = self.mount.angles_of(d, near=angles)
        return self.mount.direction(self.sky_position(chain_angles))

    @float64
    def sky_angles(self, encoder: Float[Array, "2"], readings=None) -> Float[Array, "2"]:
        """Where the mount points, as angles in the mount's convention (one observation;
        ``readings`` as in :meth:`mount_direction`)."""
        encoder = jnp.asarray(encoder)
        return self.mount.angles_of(self.mount_direction(encoder, readings), near=self.mount.axis_angles(encoder))

    @float64
    def direction(self, encoder: Float[Array, "2"], readings=None) -> Float[Array, "3"]:
        """Pointing direction (ENU unit vector) for one observation's raw encoder angles
        (``readings`` as in :meth:`mount_direction`)."""
        return self.mount.frame @ self.mount_direction(encoder, readings)

    @float64
    def __call__(self, encoder: Float[ArrayLike, "*batch 2"], readings=None) -> Float[Array, "*batch 3"]:
        """Pointing directions (ENU) for raw encoder angles of any batch shape (radians,
        or an astropy Quantity, converted). ``readings``: for a model that reads
        auxiliary readings (:attr:`readings`), a mapping name -> value per observation,
        arrays of the batch shape ``(*batch,)`` (or scalars, the same for all). Called
        outside a trace, compiled once per model structure and batch size
        (:mod:`pointax.core.compiled`)."""
        if is_quantity(encoder):
            encoder = value_in_unit(encoder, "rad", "encoder")
        encoder = jnp.asarray(encoder, float)
        flat = encoder.reshape(-1, 2)
        per = None
        if readings is not None and self.readings:
            batch = encoder.shape[:-1]
            per = {k: jnp.broadcast_to(jnp.asarray(v, float), batch).reshape(-1) for k, v in readings.items() if k in self.readings}
        return _directions(self, flat, per).reshape(encoder.shape[:-1] + (3,))

    def describe(self) -> str:
        """One line naming the mount and terms."""
        names = " ".join(t.name for t in self.terms) or "(no terms)"
        return f"{type(self.mount).__name__}({getattr(self.mount, 'convention', '') or ''}): {names}"


@compile_by_structure
def _directions(model: Model, encoder: Float[Array, "n 2"], readings: dict | None) -> Float[Array, "n 3"]:
    """:meth:`Model.__call__` of ``(n, 2)`` encoder angles (``readings``: name -> ``(n,)``)."""
    if readings is None:
        return jax.vmap(model.direction)(encoder)
    return jax.vmap(lambda e, r: model.at_readings(r).direction(e))(encoder, readings)


@compile_by_structure
def _sky_fixed_point(model: Model, chain_angles: Float[Array, "*batch 2"]) -> Float[Array, "*batch 2"]:
    """:meth:`Model.sky_position`."""
    offset = model.sky_offset
    for _ in range(chain_angles.ndim - 1):
        offset = jax.vmap(offset)
    return jax.lax.fori_loop(0, model.sky_iterations, lambda _, sky: chain_angles + offset(sky), chain_angles)

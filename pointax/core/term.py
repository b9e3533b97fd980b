"""The error-term interface.

A term is a small :class:`equinox.Module`. Its non-static fields are its parameters
(scalars, radians unless declared otherwise with :func:`param`); its static fields are
configuration. A term changes the mount's pointing by overriding one or more of the
hooks below; each hook sees one observation at a time (scalars), the model ``vmap``-s
it over observations, and JAX differentiates it: no derivative is ever written by hand.

The pointing of a two-axis mount is computed as (see :mod:`pointax.core.mounts`)::

    nominal = mount.axis_angles(reading)                               # 0. raw reading -> angles
    angles = nominal + sum(term.encoder_offset(nominal))              # 1. encoder corrections
    d = R_base . R1(angles[0]) . R_axes . R2(angles[1]) . R_bore . b0  # 2. rotations in the chain
    sky angles s solve  s = angles_of(d) + sum(term.sky_offset(s))  # 3. pointing offsets

where ``R_base`` is the product of every term's :meth:`Term.base_rotation`, and so on.
All angles are in the mount's own angle convention (for an alt-az mount: the encoder's
azimuth and elevation, radians). For mounts whose encoders read angles the nominal
angles are the raw readings; a heliostat's actuator increments become joint angles
first.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

__all__ = ["Term", "SkyPoint", "param", "param_fields", "param_unit", "angle_pair", "check_linear_claim"]


class SkyPoint(NamedTuple):
    """A position in the mount's angle coordinates with the sines and cosines of its
    angles, as :meth:`Term.sky_offset_at` takes it (scalars, or arrays of one shape).

    Batched fits compute these once per observation; a term that reads them instead of
    calling ``jnp.sin`` itself costs those fits no trigonometric function at all.
    """

    az: Array
    el: Array
    sin_az: Array
    cos_az: Array
    sin_el: Array
    cos_el: Array

    @classmethod
    def at(cls, angles: Float[Array, "2"]) -> "SkyPoint":
        """The point at ``angles = (axis-1, axis-2)`` radians."""
        az, el = angles[0], angles[1]
        return cls(az, el, jnp.sin(az), jnp.cos(az), jnp.sin(el), jnp.cos(el))

    @property
    def tan_el(self) -> Array:
        return self.sin_el / self.cos_el


def angle_pair(axis1, axis2) -> Float[Array, "2"]:
    """Stack two per-axis values (scalars or arrays, Python numbers allowed) into ``(2,)``."""
    return jnp.stack(jnp.broadcast_arrays(jnp.asarray(axis1, float), jnp.asarray(axis2, float)))


def param(
    default: float = 0.0,
    *,
    unit: str = "arcsec",
    expected: tuple[float, float] | None = None,
    period: float | None = None,
    **kwargs,
) -> Any:
    """Declare a term parameter with a default value (in radians) and a display unit.

    ``unit`` is how reports and model files show the value: ``"arcsec"`` (default),
    ``"deg"``, ``"rad"`` or ``"1"`` (dimensionless). The stored value is always the
    internal one: radians for angles, the plain number for ``"1"``.

    ``expected``, ``(low, high)`` in internal units, is where the parameter lies in a
    sound fit (a small mechanical error, say): a fitted value outside it is flagged,
    as the sign of an equivalent solution in another branch (a turntable whose encoder
    zeros came out 180 deg off) or of a bad start. ``period``: values that differ by a
    multiple of it give the same model (an encoder zero); fits bring such a value into
    ``[0, period)``.
    """
    metadata = {"unit": unit}
    if expected is not None:
        low, high = (float(x) for x in expected)
        if not low < high:
            raise ValueError(f"expected range must be (low, high) with low < high, got {expected}")
        metadata["expected"] = (low, high)
    if period is not None:
        if not float(period) > 0:
            raise ValueError(f"period must be positive, got {period}")
        metadata["period"] = float(period)
    return eqx.field(default=default, metadata=metadata, **kwargs)


def param_fields(term: "Term") -> list[dataclasses.Field]:
    """The parameter fields of ``term`` (every non-static dataclass field but the bound
    readings, :meth:`Term.reading`), in order."""
    return [
        f for f in dataclasses.fields(term) if not f.metadata.get("static", False) and not f.metadata.get("readings")
    ]


def param_unit(field: dataclasses.Field) -> str:
    """Display unit of a parameter field ('arcsec' unless declared with :func:`param`)."""
    return field.metadata.get("unit", "arcsec")


class Term(eqx.Module):
    """Base class of every pointing error term.

    Override any of the hooks; each returns ``None`` (no effect) by default. Hooks get
    one observation's angles, ``angles = (axis-1 angle, axis-2 angle)`` in radians, in
    the mount's convention (alt-az: azimuth and elevation as the encoders count them).

    The parameter name shown in reports is :attr:`name` for a one-parameter term and
    ``name.field`` otherwise.

    A term whose :meth:`sky_offset` is linear in its parameters (``coef x f(angles)``,
    as every TPOINT linear-form term) may say so with ``linear_sky_offset = True``:
    where the offset is evaluated at data-only angles (fits with
    ``residual_form="tpoint"``), batched fits then compute ``f`` once per observation
    instead of at every step. A model refuses a term whose claim does not hold
    (:func:`check_linear_claim`), so leave it False unless it holds exactly.

    A term that depends on auxiliary readings (temperature, time, ...;
    :data:`pointax.core.readings.READINGS`) names them in :attr:`readings` and calls
    :meth:`reading` inside its hooks::

        class TubeFlexure(px.Term):
            readings: ClassVar[tuple[str, ...]] = ("temperature",)
            TF: float = px.terms.param(0.0)
            TF_T: float = px.terms.param(0.0)  # radians per deg C

            def sky_offset(self, angles):
                tf = self.TF + self.TF_T * self.reading("temperature")
                return jnp.stack([0.0 * tf, -tf * jnp.cos(angles[1])])

    A term that wraps another with coefficients that vary with a reading:
    :func:`pointax.terms.thermal`, :func:`pointax.terms.in_time`.
    """

    linear_sky_offset: ClassVar[bool] = False

    readings: ClassVar[tuple[str, ...]] = ()
    """Names of the auxiliary readings the term's hooks read (:meth:`reading`)."""

    _bound_readings: dict | None = eqx.field(default=None, kw_only=True, metadata={"readings": True})
    """The current observation's readings, bound by the model
    (:meth:`pointax.Model.at_readings`) before the hooks run; not a parameter."""

    neutral_at_zero: ClassVar[bool | None] = None
    """True when the term with every parameter 0 leaves the pointing unchanged by
    construction (TPOINT's linear terms: a coefficient times a basis function), so that
    a fit may carry it, switched off, for a model that lacks it
    (:mod:`pointax.fitting.structure`); None: that is checked numerically when needed."""

    linear_by_construction: ClassVar[bool] = False
    """True when :meth:`sky_offset_at` is a coefficient times a function of the position
    alone, so that :func:`check_linear_claim` has nothing to check (the library's
    classes that say so are checked once by the test suite instead)."""

    @property
    def name(self) -> str:
        """Short name of the term (TPOINT's name for the library's TPOINT terms)."""
        return type(self).__name__

    def reading(self, name: str) -> Float[Array, ""]:
        """The current observation's value of the auxiliary reading ``name`` (one of
        :attr:`readings`; a scalar, traced in fits), in its own unit
        (:data:`pointax.core.readings.READINGS`)."""
        if name not in self.readings:
            raise ValueError(
                f"term {self.name} reads {name!r} but does not declare it: add it to the class's "
                f"readings (readings: ClassVar[tuple[str, ...]] = ({name!r},))"
            )
        if self._bound_readings is None:
            raise ValueError(
                f"term {self.name} reads {name!r}, but no readings were given: evaluate it through its model "
                f"with readings (model(encoder, readings={{{name!r}: ...}}), or Observations(..., readings=...) in fits)"
            )
        return jnp.asarray(self._bound_readings[name], float)

    def encoder_offset(self, encoder: Float[Array, "2"]) -> Float[Array, "2"] | None:
        """Correction (radians) added to the nominal axis angles; sees the uncorrected
        angles (the raw encoder angles for angle-encoder mounts)."""
        return None

    def base_rotation(self, angles: Float[Array, "2"]) -> Float[Array, "3 3"] | None:
        """Rotation between the local frame and axis 1 (e.g. a tilted azimuth axis)."""
        return None

    def axes_rotation(self, angles: Float[Array, "2"]) -> Float[Array, "3 3"] | None:
        """Rotation between axis 1 and axis 2 (e.g. axis non-perpendicularity)."""
        return None

    def boresight_rotation(self, angles: Float[Array, "2"]) -> Float[Array, "3 3"] | None:
        """Rotation between axis 2 and the boresight (e.g. collimation)."""
        return None

    def sky_offset(self, angles: Float[Array, "2"]) -> Float[Array, "2"] | None:
        """Pointing offset (radians) in the mount's angle coordinates, added to the
        pointing and evaluated *at the corrected (sky) position*: the TPOINT linear
        form (flexure, harmonic terms, every TPOINT term in its linear form)."""
        return None

    def sky_offset_at(self, point: SkyPoint) -> Float[Array, "2"] | None:
        """:meth:`sky_offset` at a :class:`SkyPoint` whose sines and cosines are already
        known (batched fits compute them once per observation). Override it, and
        define :meth:`sky_offset` through it, to use them; by default it calls
        :meth:`sky_offset` on the point's angles."""
        return self.sky_offset(jnp.stack([point.az, point.el]))


_PROBE_POINTS = np.array([[0.3, 0.4], [2.1, 1.1], [-1.7, 0.2], [4.0, -0.6], [1.0, 1.5]])
_CLAIMS: dict = {}


def check_linear_claim(term: Term) -> None:
    """Raise ValueError, naming the term, when ``term`` says ``linear_sky_offset`` but
    its sky offset is not linear in its parameters (batched fits would be silently
    wrong). Checked numerically at a few sky points, once per term class and
    configuration: the offset must vanish with the parameters, double with them, and be
    the sum of each parameter's own contribution, to 1e-9 of its size."""
    if not term.linear_sky_offset or term.linear_by_construction:
        return
    key = (type(term), jax.tree.structure(term))
    if key not in _CLAIMS:
        _CLAIMS[key] = _linearity_error(term)
    if _CLAIMS[key]:
        raise ValueError(f"term {term.name} declares linear_sky_offset = True, but {_CLAIMS[key]}; set it False")


def _linearity_error(term: Term) -> str:
    fields = [f.name for f in param_fields(term)]
    if not fields:
        return ""
    theta = np.array([0.7e-4, -1.3e-4, 2.2e-4, -0.4e-4, 1.7e-4, 0.9e-4] * (1 + len(fields) // 6))[: len(fields)]

    def offsets(values, point):
        t = eqx.tree_at(lambda t: [getattr(t, f) for f in fields], term, list(values))
        return t.sky_offset_at(SkyPoint.at(point))

    def probe(points):
        cases = [theta, 2 * theta, 0 * theta] + [np.eye(len(fields))[k] * 1e-4 for k in range(len(fields))]
        return [jax.vmap(lambda p, v=jnp.asarray(v): offsets(v, p))(points) for v in cases]

    # Compiled and called on NumPy data: concrete values even while a fit is traced.
    with jax.enable_x64(True):
        try:
            got = jax.jit(probe).lower(_PROBE_POINTS).compile()(_PROBE_POINTS)
        except Exception:  # no sky offset to check, or not evaluable here: nothing to refuse
            return ""
    if any(g is None for g in got):
        return ""
    at, doubled, zero, *units = (np.asarray(g, np.float64) for g in got)
    size = max(float(np.max(np.abs(at))), 1e-300)
    summed = sum(u * (v / 1e-4) for u, v in zip(units, theta))
    for what, error in (
        ("it is not zero when its parameters are", zero),
        ("it does not double when its parameters do", doubled - 2 * at),
        ("it is not the sum of each parameter's own offset", at - summed),
    ):
        if np.max(np.abs(error)) > 1e-9 * size:
            return what
    return ""

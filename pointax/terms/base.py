"""The error-term interface.

A term is a small :class:`equinox.Module`. Its non-static fields are its parameters
(scalars, radians unless declared otherwise with :func:`param`); its static fields are
configuration. A term changes the mount's pointing by overriding one or more of the
hooks below; each hook sees one observation at a time (scalars), the model ``vmap``-s
it over observations, and JAX differentiates it: no derivative is ever written by hand.

The pointing of a two-axis mount is computed as (see :mod:`pointax.mounts`)::

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
import jax.numpy as jnp
from jaxtyping import Array, Float

__all__ = ["Term", "SkyPoint", "param", "param_fields", "param_unit", "angle_pair"]


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


def param(default: float = 0.0, *, unit: str = "arcsec", **kwargs) -> Any:
    """Declare a term parameter with a default value (in radians) and a display unit.

    ``unit`` is how reports and model files show the value: ``"arcsec"`` (default),
    ``"deg"``, ``"rad"`` or ``"1"`` (dimensionless). The stored value is always the
    internal one: radians for angles, the plain number for ``"1"``.
    """
    return eqx.field(default=default, metadata={"unit": unit}, **kwargs)


def param_fields(term: "Term") -> list[dataclasses.Field]:
    """The parameter fields of ``term`` (every non-static dataclass field), in order."""
    return [f for f in dataclasses.fields(term) if not f.metadata.get("static", False)]


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
    instead of at every step. A wrong claim gives wrong fits, so leave it False unless
    it holds exactly.
    """

    linear_sky_offset: ClassVar[bool] = False

    @property
    def name(self) -> str:
        """Short name of the term (TPOINT's name for the library's TPOINT terms)."""
        return type(self).__name__

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

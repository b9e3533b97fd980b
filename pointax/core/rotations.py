"""Rotation matrices, azimuth/elevation <-> unit vectors, tangent-plane offsets.

Conventions (used everywhere in pointax):

* Angles are radians.
* Directions are unit 3-vectors in a local East-North-Up (ENU) frame: x East, y North,
  z Up.
* Azimuth is measured from North through East (astropy's AltAz convention), so
  ``azel_to_enu(az, el) = (sin az cos el, cos az cos el, sin el)``.
* ``rot_x``, ``rot_y``, ``rot_z`` and ``rot_axis`` are right-handed (counter-clockwise
  seen from the tip of the axis) *active* rotations: ``rot_z(t) @ v`` turns ``v`` by
  ``t`` about +z.

Every function but :func:`azel_to_enu_numpy` (its float64 NumPy twin for file readers
and the astropy edge) is pure ``jax.numpy``: it works under ``jit``, ``vmap`` and ``grad``,
broadcasts over leading batch dimensions where stated, and has finite gradients at the
zenith and at the poles of the azimuth for valid inputs (the singular ``atan2`` and
``hypot`` are guarded with the "double where" idiom).
"""

from __future__ import annotations

from collections.abc import Callable

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

__all__ = [
    "rot_x",
    "rot_y",
    "rot_z",
    "rot_axis",
    "small_tilt",
    "azel_to_enu",
    "azel_to_enu_numpy",
    "hadec_to_enu_numpy",
    "enu_to_azel",
    "azel_trig",
    "tangent_basis",
    "tangent_offset",
    "offset_angle",
    "offset_direction",
    "angle_between",
    "wrap_pi",
]

_TINY = 1e-300


def _rot(angle: ArrayLike, i: int, j: int) -> Float[Array, "*batch 3 3"]:
    """Rotation by ``angle`` in the (i, j) plane, turning axis i towards axis j."""
    angle = jnp.asarray(angle)
    c, s = jnp.cos(angle), jnp.sin(angle)
    zero, one = jnp.zeros_like(c), jnp.ones_like(c)
    rows = [[one, zero, zero], [zero, one, zero], [zero, zero, one]]
    rows[i][i], rows[j][j] = c, c
    rows[j][i], rows[i][j] = s, -s
    return jnp.stack([jnp.stack(r, axis=-1) for r in rows], axis=-2)


def rot_x(angle: ArrayLike) -> Float[Array, "*batch 3 3"]:
    """Right-handed rotation about +x (East) by ``angle`` radians: turns +y towards +z."""
    return _rot(angle, 1, 2)


def rot_y(angle: ArrayLike) -> Float[Array, "*batch 3 3"]:
    """Right-handed rotation about +y (North) by ``angle`` radians: turns +z towards +x."""
    return _rot(angle, 2, 0)


def rot_z(angle: ArrayLike) -> Float[Array, "*batch 3 3"]:
    """Right-handed rotation about +z (Up) by ``angle`` radians: turns +x towards +y."""
    return _rot(angle, 0, 1)


def rot_axis(axis: Float[ArrayLike, "*batch 3"], angle: ArrayLike) -> Float[Array, "*batch 3 3"]:
    """Right-handed rotation by ``angle`` radians about an arbitrary ``axis`` (Rodrigues).

    ``axis`` need not be normalised; it must not be the zero vector.
    """
    axis = jnp.asarray(axis)
    k = axis / jnp.linalg.norm(axis, axis=-1, keepdims=True)
    angle = jnp.asarray(angle)[..., None, None]
    kx, ky, kz = k[..., 0], k[..., 1], k[..., 2]
    zero = jnp.zeros_like(kx)
    cross = jnp.stack(
        [
            jnp.stack([zero, -kz, ky], axis=-1),
            jnp.stack([kz, zero, -kx], axis=-1),
            jnp.stack([-ky, kx, zero], axis=-1),
        ],
        axis=-2,
    )
    eye = jnp.eye(3, dtype=cross.dtype)
    return eye + jnp.sin(angle) * cross + (1.0 - jnp.cos(angle)) * (cross @ cross)


def small_tilt(about_x: ArrayLike, about_y: ArrayLike) -> Float[Array, "*batch 3 3"]:
    """Tilt ``rot_x(about_x) @ rot_y(about_y)``: the usual way to tilt a vertical axis.

    A positive ``about_x`` tips +z towards -y; a positive ``about_y`` tips +z towards +x.
    """
    return rot_x(about_x) @ rot_y(about_y)


def azel_to_enu(az: ArrayLike, el: ArrayLike) -> Float[Array, "*batch 3"]:
    """Unit vector in ENU for azimuth ``az`` (from North through East) and elevation ``el``."""
    az, el = jnp.asarray(az), jnp.asarray(el)
    cos_el = jnp.cos(el)
    return jnp.stack([jnp.sin(az) * cos_el, jnp.cos(az) * cos_el, jnp.sin(el)], axis=-1)


def azel_to_enu_numpy(az, el) -> np.ndarray:
    """:func:`azel_to_enu` in NumPy float64, for code outside JAX (readers, astropy)."""
    az, el = np.asarray(az, np.float64), np.asarray(el, np.float64)
    cos_el = np.cos(el)
    return np.stack([np.sin(az) * cos_el, np.cos(az) * cos_el, np.sin(el)], axis=-1)


def hadec_to_enu_numpy(ha, dec, latitude: float) -> np.ndarray:
    """East-North-Up unit vectors of hour angle ``ha`` (positive West) and declination
    ``dec`` at ``latitude`` (radians; :class:`pointax.EquatorialMount`'s formulas), NumPy
    float64, for the readers of equatorial runs."""
    ha, dec = np.asarray(ha, np.float64), np.asarray(dec, np.float64)
    s, c = np.sin(latitude), np.cos(latitude)
    return np.stack(
        [
            -np.cos(dec) * np.sin(ha),
            c * np.sin(dec) - s * np.cos(dec) * np.cos(ha),
            s * np.sin(dec) + c * np.cos(dec) * np.cos(ha),
        ],
        axis=-1,
    )


def _safe_hypot(x: Array, y: Array) -> Array:
    """hypot with a finite gradient at (0, 0) (there it is taken as zero)."""
    r2 = x * x + y * y
    ok = r2 > _TINY
    return jnp.where(ok, jnp.sqrt(jnp.where(ok, r2, 1.0)), 0.0)


def _safe_atan2(y: Array, x: Array, atan2=jnp.arctan2) -> Array:
    """atan2 that returns 0 with a zero gradient at (0, 0) instead of NaN."""
    ok = (x * x + y * y) > _TINY
    return jnp.where(ok, atan2(jnp.where(ok, y, 0.0), jnp.where(ok, x, 1.0)), 0.0)


def enu_to_azel(
    v: Float[ArrayLike, "*batch 3"], atan2: Callable[[Array, Array], Array] = jnp.arctan2
) -> tuple[Float[Array, "*batch"], Float[Array, "*batch"]]:
    """Azimuth (from North through East, in (-pi, pi]) and elevation of a direction.

    ``v`` need not be normalised (its norm must lie between about 1e-150 and 1e150).
    At the zenith and nadir the azimuth is taken as 0 and its gradient as zero.
    ``atan2``: the arctangent to use; :func:`pointax.core.trig.atan2` (a vectorised
    polynomial) for many observations at once, computed once (a batched fit's site data).
    """
    v = jnp.asarray(v)
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    horizontal = _safe_hypot(x, y)
    return _safe_atan2(x, y, atan2), atan2(z, horizontal)


def azel_trig(v: Float[ArrayLike, "*batch 3"]) -> tuple[Float[Array, "*batch"], ...]:
    """``(cos az, sin az, cos el, sin el)`` of directions ``v`` as :func:`enu_to_azel`
    defines their angles (azimuth 0 at the zenith and nadir), from the components with
    no trigonometric function: ``cos el = hypot(x, y) / |v|``, ``sin az = x / hypot(x,
    y)``, ... (batched fits take these for every observation)."""
    v = jnp.asarray(v)
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    h2 = x * x + y * y
    ok = h2 > _TINY
    h = jnp.sqrt(jnp.where(ok, h2, 1.0))
    r = jnp.sqrt(h2 + z * z)
    return jnp.where(ok, y / h, 1.0), jnp.where(ok, x / h, 0.0), jnp.where(ok, h, 0.0) / r, z / r


def tangent_basis(ref: Float[ArrayLike, "*batch 3"]) -> tuple[Float[Array, "*batch 3"], Float[Array, "*batch 3"]]:
    """Unit vectors along increasing azimuth and increasing elevation at ``ref``.

    ``ref`` is a unit vector. At the zenith (where azimuth is undefined) the basis of
    azimuth 0 is used: increasing azimuth points East (+x), increasing elevation
    points South (-y).
    """
    az, el = enu_to_azel(ref)
    e_az = jnp.stack([jnp.cos(az), -jnp.sin(az), jnp.zeros_like(az)], axis=-1)
    e_el = jnp.stack(
        [-jnp.sin(el) * jnp.sin(az), -jnp.sin(el) * jnp.cos(az), jnp.cos(el)], axis=-1
    )
    return e_az, e_el


def tangent_offset(
    v: Float[ArrayLike, "*batch 3"], ref: Float[ArrayLike, "*batch 3"]
) -> Float[Array, "*batch 2"]:
    """Gnomonic offset of direction ``v`` from ``ref`` in ``ref``'s tangent plane.

    Returns ``(cross-elevation, elevation)`` in radians: the first component is along
    increasing azimuth (for small offsets ``d_az * cos(el)``), the second along
    increasing elevation. Exact inverse of :func:`offset_direction`.
    """
    v, ref = jnp.asarray(v), jnp.asarray(ref)
    e_az, e_el = tangent_basis(ref)
    depth = jnp.sum(v * ref, axis=-1)
    return jnp.stack([jnp.sum(v * e_az, axis=-1), jnp.sum(v * e_el, axis=-1)], axis=-1) / depth[..., None]


def offset_angle(offset: Float[ArrayLike, "*batch 2"]) -> Float[Array, "*batch"]:
    """Angle (radians) between ``ref`` and the direction at gnomonic ``offset`` from it:
    ``arctan(|offset|)``; the tangent-plane offset's norm is the tangent of the angle."""
    offset = jnp.asarray(offset)
    return jnp.arctan(jnp.sqrt(jnp.sum(offset**2, axis=-1)))


def offset_direction(
    ref: Float[ArrayLike, "*batch 3"], offset: Float[ArrayLike, "*batch 2"]
) -> Float[Array, "*batch 3"]:
    """Direction at gnomonic ``offset`` = (cross-elevation, elevation) radians from ``ref``."""
    ref, offset = jnp.asarray(ref), jnp.asarray(offset)
    e_az, e_el = tangent_basis(ref)
    v = ref + offset[..., 0:1] * e_az + offset[..., 1:2] * e_el
    return v / jnp.linalg.norm(v, axis=-1, keepdims=True)


def angle_between(a: Float[ArrayLike, "*batch 3"], b: Float[ArrayLike, "*batch 3"]) -> Float[Array, "*batch"]:
    """Great-circle angle between two unit vectors (radians), accurate at small angles.

    Its gradient is undefined (NaN) where ``a == b``, the tip of the cone |angle|."""
    a, b = jnp.asarray(a), jnp.asarray(b)
    sin_part = jnp.linalg.norm(jnp.cross(a, b), axis=-1)
    return jnp.arctan2(sin_part, jnp.sum(a * b, axis=-1))


def wrap_pi(angle: ArrayLike) -> Array:
    """Wrap an angle to [-pi, pi).

    By ``floor`` rather than ``%``: XLA on the CPU computes a floating-point remainder
    several times slower than this (which costs about a copy), and batched fits wrap
    every observation's angles."""
    angle = jnp.asarray(angle)
    turns = jnp.floor((angle + jnp.pi) * (0.5 / jnp.pi))
    return angle - (2 * jnp.pi) * turns

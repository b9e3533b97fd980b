"""A camera fixed to the mount: its mounting rotation as a term, and its observations.

The sun-vector turntable (Acta Optica Sinica 39(11) 1128001) carries a sun-sensor camera
fixed "parallel" to the mirror normal. What the camera measures is the sun's position
in its image: after the intrinsics (:mod:`pointax.sunsensor.camera`), the sun's
direction ``s`` in the camera frame (x right in the image, y down, z along the optical
axis). At raw reading ``e``::

    S_enu = F . R_chain(e) . R_mount . M . s                                    (1)

``R_chain(e)`` is the mount's chain with every error term (the attitude that carries
the mirror normal ``b0`` to its direction in the sky), ``R_mount`` the camera's small
mounting rotation relative to the mirror, and ``M`` the fixed matrix that lays the
camera frame on the mount frame at zero angles: the optical axis along the boresight
``b0``, the image's x axis horizontal, pointing right when one looks along ``b0``
(East for the turntable, whose normal faces North at zero), y down (:func:`camera_axes`).

**The choice.** A pointax fit compares a model's direction for each raw reading with
an observed target direction. The camera's optical axis is the natural boresight: the
model for it is the mount model plus :class:`CameraMounting` (``R_mount`` as a
``boresight_rotation``), and the observation is "the camera axis pointed at ``T`` at
reading ``e``", where ``T`` is where the axis must point for the sun to appear at the
measured ray ``s``: from (1), with ``A = F R_chain R_mount M`` the camera's attitude,
``T = A z`` and ``S = A s``. :func:`camera_axis_target` computes ``T`` from ``S`` and
``s`` in closed form for the nominal attitude (image x along increasing azimuth, y down
the elevation: the turntable's and an alt-az mount's camera when level and unrolled),
or, given an attitude estimate ``A_hat`` (:func:`camera_frame` of a fitted model), as
``T = C . A_hat z`` with ``C`` the smallest rotation taking ``A_hat s`` to ``S``: exact
when ``A_hat = A``, and wrong only by the attitude's roll error about the line of sight
times the sun's offset from the axis (a second-order error: 0.1 deg of roll at a
1 deg offset moves ``T`` by 6"; refit once with the fitted model's attitude to remove it).
The alternative (moving the *mirror normal's* target) needs the same attitude and the
unknown mounting rotation, so it is no simpler. A servo that keeps the sun near the
image centre makes the offsets, hence the second-order error, small.

**What can be fitted.** :class:`CameraMounting` has two parameters, the tilts of the
camera axis from the mirror normal towards the image's x axis (``cross``) and up
(``up``). With the sun as the only reference they are partly degenerate with the
turntable's own terms:

* ``up`` turns the axis about the pitch axis, exactly as the pitch zero ``beta0`` does:
  ``Rx(beta - beta0) Rx(up) = Rx(beta - beta0 + up)``. Only their sum is observable:
  fix one (``fixed=["camera.up"]``); the fit then gives the camera axis's pitch zero.
* ``cross`` is a collimation error: its effect in azimuth grows as ``sec(el)``, the
  non-perpendicularity ``omega0``'s as ``tan(el)``, the zero ``alpha0``'s is constant.
  Over a day of sun elevations the three separate, but strongly correlated (the fit
  reports the correlations; examples/sun_sensor_calibration.py shows a case).

The mirror normal is the camera-axis model without :class:`CameraMounting`; its
``up`` offset stays unknown (absorbed in ``beta0``) unless measured independently, which
is the "sun sensor mounting" line of the paper's error budget.

``roll`` (the camera's rotation about its own axis) is configuration, not a parameter:
it does not move the axis, only the image's orientation, so only :func:`camera_frame`
uses it.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from ..core.precision import float64
from ..core.rotations import azel_to_enu, enu_to_azel, rot_x, rot_y, rot_z
from ..core.term import Term, param

__all__ = ["CameraMounting", "camera_axes", "camera_frame", "camera_axis_target", "rotation_between"]


class CameraMounting(Term):
    """The camera's mounting rotation relative to the mirror normal (boresight):
    ``R_mount = Rz(-cross) . Rx(up) . Ry(roll)`` in the mount frame at zero angles
    (boresight +y, image x along +x, image up along +z).

    Attributes:
        cross: tilt of the camera axis towards the image's x axis (right; East at the
            turntable's zero), radians, reported in degrees.
        up: tilt of the camera axis towards the image's up (-y), radians, reported in
            degrees. Degenerate with a pitch zero (``beta0``, TPOINT's IE): fix one.
        roll: right-handed rotation of the camera about its axis, radians (static:
            it does not move the axis).
    """

    cross: float = param(0.0, unit="deg")
    up: float = param(0.0, unit="deg")
    roll: float = eqx.field(static=True, default=0.0, converter=float)

    @property
    def name(self) -> str:
        return "camera"

    def boresight_rotation(self, angles):
        return rot_z(-self.cross) @ rot_x(self.up) @ rot_y(self.roll)


def camera_axes(boresight: Float[ArrayLike, "3"]) -> Float[Array, "3 3"]:
    """``M``: columns are the camera's x (right), y (down) and z (optical axis) in the
    mount frame at zero angles, for a horizontal ``boresight``: ``z = boresight``,
    ``x = boresight x up`` (right when looking along the boresight), ``y = z x x``."""
    b = jnp.asarray(boresight, float)
    b = b / jnp.linalg.norm(b)
    right = jnp.cross(b, jnp.array([0.0, 0.0, 1.0]))
    right = right / jnp.linalg.norm(right)
    down = jnp.cross(b, right)
    return jnp.stack([right, down, b], axis=-1)


def _apply(terms, hook: str, angles, v):
    """``v`` turned by the terms' rotations at one place of the chain (term order)."""
    for term in reversed(terms):
        r = getattr(term, hook)(angles)
        if r is not None:
            v = r @ v
    return v


def camera_frame(model, reading: Float[ArrayLike, "2"]) -> Float[Array, "3 3"]:
    """The camera's attitude for one raw reading: the matrix whose columns are the
    camera's x (right), y (down) and z (axis) in East-North-Up, ``F R_chain R_mount M``.

    ``model`` is a :class:`pointax.Model` whose mount has a horizontal boresight at zero
    angles, typically with a :class:`CameraMounting` term (without one the camera axis is
    the boresight). Terms with sky offsets (TPOINT's linear form) have no attitude and
    are refused. Pure JAX: ``vmap`` it over readings.
    """
    zero = jnp.zeros(2)
    if any(t.sky_offset(zero) is not None for t in model.terms):
        raise ValueError("camera_frame: terms with sky offsets (TPOINT linear form) have no attitude; use rotation terms")
    mount = model.mount
    angles = model.corrected_encoder(jnp.asarray(reading, float))
    axes = camera_axes(mount.boresight)

    def chain(v):
        v = _apply(model.terms, "boresight_rotation", angles, v)
        v = mount.axis2(angles[1]) @ v
        v = _apply(model.terms, "axes_rotation", angles, v)
        v = mount.axis1(angles[0]) @ v
        v = _apply(model.terms, "base_rotation", angles, v)
        return mount.frame @ v

    return jnp.stack([chain(axes[:, k]) for k in range(3)], axis=-1)


def rotation_between(a: Float[ArrayLike, "*batch 3"], b: Float[ArrayLike, "*batch 3"]) -> Float[Array, "*batch 3 3"]:
    """The smallest rotation taking unit vector ``a`` to unit vector ``b`` (Rodrigues
    about ``a x b``); the identity where they coincide. ``a`` and ``-b`` must differ."""
    a, b = jnp.asarray(a), jnp.asarray(b)
    k = jnp.cross(a, b)
    c = jnp.sum(a * b, axis=-1)[..., None, None]
    kx, ky, kz = k[..., 0], k[..., 1], k[..., 2]
    zero = jnp.zeros_like(kx)
    cross = jnp.stack(
        [jnp.stack([zero, -kz, ky], -1), jnp.stack([kz, zero, -kx], -1), jnp.stack([-ky, kx, zero], -1)], -2
    )
    eye = jnp.eye(3, dtype=cross.dtype)
    return eye + cross + (cross @ cross) / (1.0 + c)


def _nominal_target(sun, ray):
    """Closed form for one observation: the axis direction ``T`` with ``S = R(T) M s``,
    ``R(T) = Rz(-az) Rx(el)`` the nominal attitude of a level, unrolled camera at
    azimuth ``az`` and elevation ``el`` of ``T``."""
    v = camera_axes(jnp.array([0.0, 1.0, 0.0])) @ ray
    rho = jnp.hypot(v[1], v[2])
    phi = jnp.arctan2(v[2], v[1])
    el = jnp.arcsin(jnp.clip(sun[2] / rho, -1.0, 1.0)) - phi
    w = rot_x(el) @ v
    az_sun, _ = enu_to_azel(sun)
    az_w = jnp.arctan2(w[0], w[1])
    return azel_to_enu(az_sun - az_w, el)


def _target_from_frame(sun, ray, frame):
    seen = frame @ ray
    return rotation_between(seen, sun) @ frame[:, 2]


@float64
def camera_axis_target(
    sun: Float[ArrayLike, "n 3"],
    ray: Float[ArrayLike, "n 3"],
    frame: Float[ArrayLike, "n 3 3"] | None = None,
) -> Float[Array, "n 3"]:
    """Where the camera axis pointed, for each observation: the direction ``T`` such
    that the sun ``S`` lies along the measured ray ``s`` of a camera whose axis points
    at ``T`` (see the module docstring).

    Args:
        sun: ``(n, 3)`` sun directions, East-North-Up unit vectors.
        ray: ``(n, 3)`` the sun's measured directions in the camera frame (x right, y
            down, z along the axis), unit vectors.
        frame: optional ``(n, 3, 3)`` camera attitudes (:func:`camera_frame` of a model
            at each reading). Without it the nominal attitude is used: image x along
            increasing azimuth, image y down the elevation (a level, unrolled camera).

    Returns:
        ``(n, 3)`` unit vectors in East-North-Up: the observation targets of a model whose
        boresight is the camera axis (the mount model plus :class:`CameraMounting`).
    """
    sun = jnp.asarray(sun, float)
    ray = jnp.asarray(ray, float)
    if frame is None:
        return jax.vmap(_nominal_target)(sun, ray)
    return jax.vmap(_target_from_frame)(sun, ray, jnp.asarray(frame, float))

"""Two-axis mount kinematics as chains of rotations.

A mount turns two axis angles into a boresight direction::

    d = F . R1(a1) . R2(a2) . b0

``R1`` turns about the fixed (first) axis, ``R2`` about the moving (second) axis,
``b0`` is the boresight at zero angles and ``F`` is a fixed frame change from the
mount's own frame to East-North-Up. Error terms (:mod:`pointax.terms`) slot extra
rotations in between (``R_base`` before ``R1``, ``R_axes`` between the axes,
``R_bore`` before ``b0``) and add encoder and sky offsets; the mount itself knows
nothing of them. A new mount (X-Y, equatorial, a mirror turntable) is a new subclass
of :class:`Mount`; the model and the fitting code do not change.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .rotations import azel_to_enu, enu_to_azel, rot_x, rot_z, wrap_pi

__all__ = ["Mount", "AltAzMount", "TurntableMount", "HeliostatMount", "AZIMUTH_CONVENTIONS", "nearest_solution"]


# Frame changes F from the alt-az mount frame (where azimuth runs from +y through +x)
# to ENU, for each way of counting azimuth. "N-E" is astropy's and TPOINT's standard.
AZIMUTH_CONVENTIONS: dict[str, tuple[tuple[float, ...], ...]] = {
    # from North through East: the mount frame is ENU.
    "N-E": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    # from South through East (A = 180 deg - A_NE), as in the MMT TPOINT files: a
    # mirror image, the mount frame's +y is South.
    "S-E": ((1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),
    # from South through West (A = A_NE - 180 deg), the old astronomical convention.
    "S-W": ((-1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),
}


class Mount(eqx.Module):
    """A two-axis mount: axis rotations, boresight, and the frame change to ENU.

    Subclasses implement :meth:`axis1`, :meth:`axis2`, :meth:`angles_of` and set
    :attr:`boresight`, :attr:`frame` and :attr:`axis_names`.
    """

    axis_names: ClassVar[tuple[str, str]] = ("axis1", "axis2")

    @property
    def boresight(self) -> Float[Array, "3"]:
        """Boresight direction at zero axis angles, in the mount frame."""
        raise NotImplementedError

    @property
    def frame(self) -> Float[Array, "3 3"]:
        """Matrix taking mount-frame vectors to East-North-Up."""
        return jnp.eye(3)

    @property
    def convention(self) -> str | None:
        """Name of the angle convention that encoder readings must follow, if any."""
        return None

    def axis_angles(self, reading: Float[Array, "2"]) -> Float[Array, "2"]:
        """Nominal axis angles (radians) for one raw reading of the two axes.

        The identity for mounts whose encoders read angles; a mount driven by linear
        actuators (:class:`pointax.HeliostatMount`) turns actuator increments into joint
        angles here. Terms' ``encoder_offset`` corrections are added to these angles.
        """
        return reading

    def readings_of(self, angles: Float[Array, "2"]) -> Float[Array, "2"]:
        """Inverse of :meth:`axis_angles`: the raw reading that gives ``angles``."""
        return angles

    def axis1(self, angle: Float[Array, ""]) -> Float[Array, "3 3"]:
        """Rotation of the first (fixed) axis by its angle."""
        raise NotImplementedError

    def axis2(self, angle: Float[Array, ""]) -> Float[Array, "3 3"]:
        """Rotation of the second (moving) axis by its angle."""
        raise NotImplementedError

    def direction(self, angles: Float[Array, "2"]) -> Float[Array, "3"]:
        """Nominal (error-free) boresight direction in the mount frame."""
        return self.axis1(angles[0]) @ self.axis2(angles[1]) @ self.boresight

    def angles_of(self, direction: Float[Array, "3"], near: Float[Array, "2"]) -> Float[Array, "2"]:
        """Nominal inverse: the axis angles that point at ``direction`` (mount frame),
        choosing among equivalent solutions the one closest to ``near``."""
        raise NotImplementedError


class AltAzMount(Mount):
    """Alt-azimuth mount: azimuth about the vertical, then elevation about the
    horizontal axis; at zero angles the boresight points at azimuth 0 on the horizon.

    ``azimuth`` names how the encoders count azimuth: ``"N-E"`` from North through East
    (default; astropy and TPOINT's standard), ``"S-E"`` from South through East (the
    MMT TPOINT files), ``"S-W"`` from South through West. Angles handed to terms are in
    this convention, so TPOINT-form terms mean what TPOINT means on such a file.
    """

    azimuth: str = eqx.field(static=True, default="N-E")
    axis_names: ClassVar[tuple[str, str]] = ("az", "el")

    def __check_init__(self):
        if self.azimuth not in AZIMUTH_CONVENTIONS:
            raise ValueError(
                f"unknown azimuth convention {self.azimuth!r}; expected one of {sorted(AZIMUTH_CONVENTIONS)}"
            )

    @property
    def boresight(self) -> Float[Array, "3"]:
        return jnp.array([0.0, 1.0, 0.0])

    @property
    def frame(self) -> Float[Array, "3 3"]:
        return jnp.array(AZIMUTH_CONVENTIONS[self.azimuth])

    @property
    def convention(self) -> str:
        return self.azimuth

    def axis1(self, angle):
        # Azimuth turns from +y through +x: clockwise seen from above.
        return rot_z(-angle)

    def axis2(self, angle):
        # Elevation lifts the boresight from +y towards +z.
        return rot_x(angle)

    def direction(self, angles):
        # In the mount frame azimuth runs from +y through +x, exactly as N-E does in ENU.
        return azel_to_enu(angles[0], angles[1])

    def angles_of(self, direction, near):
        az, el = enu_to_azel(direction)  # the mount frame is ENU-like; safe at the zenith
        return nearest_solution(az, el, near, _on_axis(direction, 2))


def _on_axis(direction, axis: int):
    """Whether ``direction`` lies exactly along coordinate axis ``axis`` (0, 1 or 2)."""
    others = [k for k in range(3) if k != axis]
    return direction[others[0]] ** 2 + direction[others[1]] ** 2 <= 1e-300


def nearest_solution(a1, a2, near, at_pole=False):
    """Of the two mechanical solutions ``(a1, a2)`` and ``(a1 + pi, pi - a2)`` ("over
    the top") of a two-axis mount, the one nearer ``near``, with axis 1 on the branch
    of ``near`` (within pi of it). At the pole (``at_pole``: the direction lies along
    the first axis) every axis-1 angle points the same way: ``near``'s is kept."""
    a1 = jnp.where(at_pole, near[0], a1)
    a1_a = near[0] + wrap_pi(a1 - near[0])
    a1_b = near[0] + wrap_pi(a1 + jnp.pi - near[0])
    a2_b = jnp.pi - a2
    dist_a = jnp.abs(a1_a - near[0]) + jnp.abs(a2 - near[1])
    dist_b = jnp.abs(a1_b - near[0]) + jnp.abs(a2_b - near[1])
    use_a = dist_a <= dist_b
    return jnp.stack([jnp.where(use_a, a1_a, a1_b), jnp.where(use_a, a2, a2_b)])


class TurntableMount(Mount):
    """Sun-tracking mirror turntable: an azimuth turntable carrying a pitch fork, the
    mirror normal as the boresight (the sun-vector calibration paper, Acta Optica
    Sinica 39(11) 1128001)::

        S = Rz'(alpha0 - alpha) . Rx(beta - beta0) . (0, 1, 0)      in East-North-Up

    with ``Rz'(t) = [[cos t, sin t, 0], [-sin t, cos t, 0], [0, 0, 1]]`` (= ``rot_z(-t)``).
    The raw readings are the encoder angles ``(alpha, beta)`` in radians: the pitch
    ``beta - beta0`` is the elevation of the normal, and the azimuth encoder turns
    *against* the azimuth (North through East): ``alpha - alpha0 = 360 deg - azimuth``,
    as in the paper's Table 1. The zeros ``alpha0, beta0``, the level tilts and the
    axis non-perpendicularity are terms (:func:`pointax.terms.turntable`).
    """

    axis_names: ClassVar[tuple[str, str]] = ("alpha", "beta")

    @property
    def boresight(self) -> Float[Array, "3"]:
        return jnp.array([0.0, 1.0, 0.0])

    @property
    def convention(self) -> str:
        return "turntable"

    def axis1(self, angle):
        # Rz'(-angle): the azimuth encoder counts against North-through-East azimuth.
        return rot_z(angle)

    def axis2(self, angle):
        return rot_x(angle)

    def direction(self, angles):
        return azel_to_enu(-angles[0], angles[1])

    def angles_of(self, direction, near):
        az, el = enu_to_azel(direction)
        return nearest_solution(-az, el, near, _on_axis(direction, 2))


class HeliostatMount(Mount):
    """A tilt-tilt heliostat driven by two linear actuators (the PAINT / DLR Juelich
    heliostats). The raw readings are actuator increments (motor steps); the mirror
    normal is the boresight::

        n = Re(theta1 - pi/2) . Ru(theta2) . (0, -1, 0)       (= Re(theta1) Rn(theta2) (0, 0, 1))

    in East-North-Up, with right-handed rotations Re, Rn, Ru about East, North, Up:
    ``theta1`` is the mirror's zenith angle. Axis tilts (``t1n, t1u, t2e, t2n``) and
    joint-angle zeros are terms (:mod:`pointax.terms.heliostat`).

    Each axis's actuator turns increments into a joint angle by the law of cosines::

        s = increments / increment + initial_stroke            stroke, m
        phi(s) = arccos((offset^2 + pivot_radius^2 - s^2) / (2 offset pivot_radius))
        theta = initial_angle + sign (phi(s0) - phi(s))        s0 = initial_stroke

    with ``sign = +1`` for clockwise axis movement, ``-1`` otherwise.

    Fields are ``(2,)`` arrays, one value per axis (SI units, radians). They are the
    nominal geometry, not fitted parameters; build the mount from a PAINT heliostat
    file with :meth:`from_paint`.
    """

    increment: Float[Array, "2"]
    initial_stroke: Float[Array, "2"]
    offset: Float[Array, "2"]
    pivot_radius: Float[Array, "2"]
    initial_angle: Float[Array, "2"]
    sign: Float[Array, "2"]
    axis_names: ClassVar[tuple[str, str]] = ("axis1", "axis2")

    def __init__(self, increment, initial_stroke, offset, pivot_radius, initial_angle, clockwise):
        def pair(x, name):
            x = jnp.asarray(x, float)
            if x.shape != (2,):
                raise ValueError(f"HeliostatMount: {name} needs one value per axis, got shape {x.shape}")
            return x

        self.increment = pair(increment, "increment")
        self.initial_stroke = pair(initial_stroke, "initial_stroke")
        self.offset = pair(offset, "offset")
        self.pivot_radius = pair(pivot_radius, "pivot_radius")
        self.initial_angle = pair(initial_angle, "initial_angle")
        self.sign = jnp.where(pair(clockwise, "clockwise") != 0, 1.0, -1.0)

    @classmethod
    def from_paint(cls, heliostat) -> "HeliostatMount":
        """The nominal mount of a PAINT heliostat (:func:`pointax.io.read_heliostat`)."""
        orientation = np.asarray(heliostat.initial_orientation, float)
        if not np.allclose(orientation, [0.0, -1.0, 0.0], atol=1e-12):
            raise ValueError(
                f"{getattr(heliostat, 'path', 'heliostat')}: initial_orientation {orientation.tolist()} is not supported; "
                "HeliostatMount models mirrors facing South at zero angles, (0, -1, 0)"
            )
        acts = heliostat.actuators

        def field(name):
            return [getattr(a, name) for a in acts]

        return cls(
            increment=field("increment"),
            initial_stroke=field("initial_stroke_length"),
            offset=[a.offset + a.offset_shift for a in acts],
            pivot_radius=[a.pivot_radius + a.radius_shift for a in acts],
            initial_angle=field("initial_angle"),
            clockwise=[float(a.clockwise) for a in acts],
        )

    @property
    def boresight(self) -> Float[Array, "3"]:
        return jnp.array([0.0, -1.0, 0.0])

    @property
    def convention(self) -> str:
        return "heliostat"

    def _phi(self, stroke):
        a, r = self.offset, self.pivot_radius
        return jnp.arccos(jnp.clip((a**2 + r**2 - stroke**2) / (2 * a * r), -1.0, 1.0))

    def axis_angles(self, reading):
        stroke = reading / self.increment + self.initial_stroke
        return self.initial_angle + self.sign * (self._phi(self.initial_stroke) - self._phi(stroke))

    def readings_of(self, angles):
        a, r = self.offset, self.pivot_radius
        phi = self._phi(self.initial_stroke) - self.sign * (angles - self.initial_angle)
        stroke = jnp.sqrt(a**2 + r**2 - 2 * a * r * jnp.cos(phi))
        return (stroke - self.initial_stroke) * self.increment

    def axis1(self, angle):
        return rot_x(angle - jnp.pi / 2)

    def axis2(self, angle):
        return rot_z(angle)

    def direction(self, angles):
        t1, t2 = angles[0], angles[1]
        return jnp.stack([jnp.sin(t2), -jnp.cos(t2) * jnp.sin(t1), jnp.cos(t2) * jnp.cos(t1)])

    def angles_of(self, direction, near):
        e, n, u = direction[0], direction[1], direction[2]
        theta1 = jnp.arctan2(-n, jnp.where(_on_axis(direction, 0), 1.0, u))
        theta2 = jnp.arctan2(e, jnp.hypot(n, u))
        return nearest_solution(theta1, theta2, near, _on_axis(direction, 0))

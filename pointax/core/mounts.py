"""Two-axis mount kinematics as chains of rotations.

A mount turns two axis angles into a boresight direction::

    d = F . R1(a1) . R2(a2) . b0

``R1`` turns about the fixed (first) axis, ``R2`` about the moving (second) axis,
``b0`` is the boresight at zero angles and ``F`` is a fixed frame change from the
mount's own frame to East-North-Up. Error terms (:mod:`pointax.terms`) slot extra
rotations in between (``R_base`` before ``R1``, ``R_axes`` between the axes,
``R_bore`` before ``b0``) and add encoder and sky offsets; the mount itself knows
nothing of them. A new mount is a new subclass of :class:`Mount`; the model and the
fitting code do not change.

Mounts whose two axes are perpendicular (alt-az, X-Y, equatorial) share one chain,
:class:`SphericalMount`: in the mount's own frame the boresight points at
``(sin a1 cos a2, cos a1 cos a2, sin a2)``, axis 1 about the frame's +z and axis 2
lifting the boresight towards +z. They differ only in ``F``, which puts the frame's
+z pole on the first axis: the zenith (alt-az), the north horizon (X-Y) or the
celestial pole (equatorial). Fit residuals, taken in the tangent plane of that frame,
are then ``(d a1 cos a2, d a2)``: per-axis offsets with the pole where no one
observes (:meth:`Mount.axis_residuals`).
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from . import trig
from .precision import float64
from .rotations import (
    azel_to_enu,
    azel_trig,
    enu_to_azel,
    rot_x,
    rot_z,
    tangent_offset,
    wrap_pi,
)
from .term import SkyPoint

__all__ = [
    "Mount",
    "SphericalMount",
    "AltAzMount",
    "XYMount",
    "EquatorialMount",
    "TurntableMount",
    "HeliostatMount",
    "AZIMUTH_CONVENTIONS",
    "XY_FRAME",
    "nearest_solution",
]


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
    def boresight(self) -> Float[ArrayLike, "3"]:
        """Boresight direction at zero axis angles, in the mount frame (a NumPy array
        when it is a constant, as :attr:`frame`)."""
        raise NotImplementedError

    @property
    def frame(self) -> Float[ArrayLike, "3 3"]:
        """Matrix taking mount-frame vectors to East-North-Up (a NumPy array when it is a
        constant: fits then skip its zeros while tracing, and no small program is
        compiled to make it)."""
        return np.eye(3)

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

    def sky_point_of(self, direction: Float[Array, "*batch 3"], near: Float[Array, "*batch 2"]) -> SkyPoint:
        """:meth:`angles_of` for a batch of directions, as a
        :class:`pointax.terms.SkyPoint` of ``(*batch)`` arrays: the angles with their
        sines and cosines (what TPOINT-form terms read)."""
        angles = jnp.vectorize(self.angles_of, signature="(3),(2)->(2)")(direction, near)
        return SkyPoint.at(jnp.moveaxis(angles, -1, 0))

    def axis_residuals(
        self, predicted: Float[ArrayLike, "*batch 3"], target: Float[ArrayLike, "*batch 3"]
    ) -> Float[Array, "*batch 2"]:
        """Observed minus model on the sky, per axis, radians: exactly the residuals of
        :func:`pointax.fit` (:func:`pointax.residuals`).

        Args:
            predicted: ``(..., 3)`` where the model points (East-North-Up unit vectors,
                e.g. ``model(encoder)``).
            target: ``(..., 3)`` where the star was (observed, catalogue), ENU.

        Returns:
            ``(..., 2)``: the gnomonic offset of ``target`` from ``predicted`` in the
            tangent plane at ``target``, in the mount frame. For a
            :class:`SphericalMount` that is ``(d a1 cos a2, d a2)`` with ``d = observed -
            model``, to first order: ``(dA cos E, dE)`` for an alt-az mount, ``(dL cos B,
            dB)`` for an X-Y mount (the level-mount paper's eqs 21-23 use the angle
            residual dL itself, see :func:`pointax.compare`), ``(dH cos dec, d dec)`` for an equatorial mount. Pure JAX;
            float64 only where JAX's x64 mode is on.
        """
        frame = self.frame
        return -tangent_offset(jnp.asarray(predicted) @ frame, jnp.asarray(target) @ frame)


class SphericalMount(Mount):
    """A mount with perpendicular axes whose own frame puts axis 1 on +z: at axis
    angles ``(a1, a2)`` the boresight points at ``(sin a1 cos a2, cos a1 cos a2,
    sin a2)`` in the mount frame, i.e. ``Rz(-a1) . Rx(a2) . (0, 1, 0)``: axis 1 turns
    the boresight from +y through +x, axis 2 lifts it towards +z. Subclasses choose the
    frame change ``F`` (:attr:`frame`) to East-North-Up.

    The two mechanical solutions are ``(a1, a2)`` and ``(a1 + pi, pi - a2)``
    (:func:`nearest_solution`); at the frame's +z pole axis 1 is undetermined.
    """

    @property
    def boresight(self) -> Float[ArrayLike, "3"]:
        return np.array([0.0, 1.0, 0.0])

    def axis1(self, angle):
        # Axis 1 turns from +y through +x: clockwise seen from the +z pole.
        return rot_z(-angle)

    def axis2(self, angle):
        # Axis 2 lifts the boresight from +y towards +z.
        return rot_x(angle)

    def direction(self, angles):
        return azel_to_enu(angles[0], angles[1])

    def angles_of(self, direction, near):
        a1, a2 = enu_to_azel(direction)  # safe at the +z pole
        return nearest_solution(a1, a2, near, _on_axis(direction, 2))

    def sky_point_of(self, direction, near):
        """:meth:`Mount.sky_point_of` with the sines and cosines from the direction's
        components, no trigonometric function: the direction is ``r (sin a1 cos a2, cos
        a1 cos a2, sin a2)``, so ``cos a2 = +-hypot(x, y) / r`` (the sign: which of the
        two solutions :func:`nearest_solution` took), ``sin a1 = x / (r cos a2)``, ...
        (a batched TPOINT-form fit spent a fifth of its time on these sines and cosines).

        At the pole (the direction along axis 1) :meth:`angles_of` keeps ``near``'s
        axis-1 angle, whose sine and cosine are then computed in a ``jax.lax.cond`` that
        runs only when some direction of the batch is there: call this on the whole batch
        (under ``jax.vmap`` the condition becomes a select that always computes them).
        """
        if type(self).angles_of is not SphericalMount.angles_of:  # a subclass's own angles
            return super().sky_point_of(direction, near)
        direction, near = jnp.asarray(direction), jnp.asarray(near)
        at_pole = _on_axis(direction, 2)
        # One compiled call computes this for every observation: the polynomial arctangent.
        a1, a2, first = _nearest(*enu_to_azel(direction, trig.atan2), near[..., 0], near[..., 1], at_pole)
        sign = jnp.where(first, 1.0, -1.0)  # the other solution: a1 + pi, pi - a2
        cos1, sin1, cos2, sin2 = azel_trig(direction)

        def near_trig(sin1, cos1):
            return jnp.where(at_pole, jnp.sin(near[..., 0]), sin1), jnp.where(at_pole, jnp.cos(near[..., 0]), cos1)

        sin1, cos1 = jax.lax.cond(jnp.any(at_pole), near_trig, lambda s, c: (s, c), sin1, cos1)
        return SkyPoint(a1, a2, sign * sin1, sign * cos1, sin2, sign * cos2)


class AltAzMount(SphericalMount):
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

    # The chain is SphericalMount's: in the mount frame azimuth runs from +y through +x,
    # exactly as N-E does in ENU, and the +z pole is the zenith.

    @property
    def frame(self) -> Float[ArrayLike, "3 3"]:
        return np.array(AZIMUTH_CONVENTIONS[self.azimuth])

    @property
    def convention(self) -> str:
        return self.azimuth


def _on_axis(direction, axis: int):
    """Whether ``direction`` (``(..., 3)``) lies exactly along coordinate axis ``axis``
    (0, 1 or 2)."""
    others = [k for k in range(3) if k != axis]
    return direction[..., others[0]] ** 2 + direction[..., others[1]] ** 2 <= 1e-300


def nearest_solution(a1, a2, near, at_pole=False):
    """Of the two mechanical solutions ``(a1, a2)`` and ``(a1 + pi, pi - a2)`` ("over
    the top") of a two-axis mount, the one nearer ``near``, with axis 1 on the branch
    of ``near`` (within pi of it). Axis 2 of the over-the-top solution is compared
    with ``near`` modulo a turn (``-180 deg - a2`` is ``180 deg - a2``). At the pole (``at_pole``: the direction lies along
    the first axis) every axis-1 angle points the same way: ``near``'s is kept."""
    a1, a2, _ = _nearest(a1, a2, near[0], near[1], at_pole)
    return jnp.stack([a1, a2])


def _nearest(a1, a2, near1, near2, at_pole):
    """:func:`nearest_solution` elementwise: ``(a1, a2, first)``, ``first`` where the
    solution taken is ``(a1, a2)`` itself (up to turns of axis 1)."""
    a1 = jnp.where(at_pole, near1, a1)
    a1_a = near1 + wrap_pi(a1 - near1)
    a1_b = near1 + wrap_pi(a1 + jnp.pi - near1)
    a2_b = jnp.pi - a2
    dist_a = jnp.abs(a1_a - near1) + jnp.abs(a2 - near2)
    # Axis 2 of the over-the-top solution compared modulo a turn: an equatorial mount
    # past the south pole reads -180 deg - dec (TheSkyX writes -179.85), the same
    # reading as 180 deg - dec.
    dist_b = jnp.abs(a1_b - near1) + jnp.abs(wrap_pi(a2_b - near2))
    first = dist_a <= dist_b
    return jnp.where(first, a1_a, a1_b), jnp.where(first, a2, a2_b), first


# The X-Y mount's frame: mount (x, y, z) = (East, Up, North). A mirror image (det -1),
# like the "S-E" azimuth convention: the mount frame's +z pole is the north horizon.
XY_FRAME: tuple[tuple[float, ...], ...] = ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, 1.0, 0.0))
"""Matrix taking X-Y mount-frame vectors (East, Up, North) to East-North-Up."""


class XYMount(SphericalMount):
    """X-Y mount (the level-mount telescope paper, Laser & Infrared 47(5) 2017): the
    primary axis lies horizontal along North-South, the secondary axis rides on it::

        d = (sin L cos B, sin B, cos L cos B)            in East-North-Up

    ``L`` (axis 1, radians) turns the secondary axis about the primary (North) axis,
    the boresight from the zenith towards East for ``L > 0``; ``B`` (axis 2, radians)
    tilts the boresight towards North for ``B > 0``. At zero angles the boresight is
    at the zenith. In ENU, ``d = Ry(L) . Rx(-B) . (0, 0, 1)`` (the paper's ``ML MB``,
    eqs 11 and 13).

    The mount frame is ``(East, Up, North)`` (:data:`XY_FRAME`, a mirror image of ENU),
    where ``(L, B)`` are the azimuth and elevation of a :class:`SphericalMount`: its
    pole, where ``L`` is undetermined, is the North or South point of the horizon, and
    fit residuals are ``(dL cos B, dB)`` (observed minus model), the paper's per-axis
    residuals. Error terms: :mod:`pointax.terms.xy` (the paper's model families).

    The other mechanical solution, ``(L + pi, pi - B)``, points the same way: the
    normal one has ``|B| <= 90 deg`` and ``|L| < 90 deg`` above the horizon.
    """

    axis_names: ClassVar[tuple[str, str]] = ("L", "B")

    @property
    def frame(self) -> Float[ArrayLike, "3 3"]:
        return np.array(XY_FRAME)

    @property
    def convention(self) -> str:
        return "xy"


class EquatorialMount(SphericalMount):
    """Equatorial mount at a given ``latitude`` (radians, North positive): axis 1 (hour
    angle ``H``) turns about the polar axis, axis 2 (declination ``dec``) about the
    declination axis. With the nominal readings ``(H, dec)`` (radians; ``H`` positive
    West of the meridian, as the sky turns), the boresight is::

        E = -cos dec sin H
        N =  cos lat sin dec - sin lat cos dec cos H
        U =  sin lat sin dec + cos lat cos dec cos H

    (the standard hour-angle / declination to horizon rotation). The mount frame is
    right-handed with +x West, +y the celestial equator on the meridian, +z the north
    celestial pole: ``(H, dec)`` are the azimuth and elevation of a
    :class:`SphericalMount` there, so fit residuals are ``(dH cos dec, d dec)``
    (observed minus model) and the pole of the residual basis is the celestial pole
    (axis 1 undetermined there).

    **Pier sides.** Every direction has two readings: the *normal* one ``(H, dec)``
    with ``|dec| <= 90 deg`` and the *flipped* one ``(H + 180 deg, 180 deg - dec)``,
    the German equatorial mount's other side of the pier (meridian flip): the
    declination axis reads past the pole. :func:`pointax.command` gives either
    (``solution="normal"`` or ``"flipped"``) and error terms see the readings as they
    are, so pier-side-dependent terms can tell the sides apart by ``cos(axis 2) < 0``.
    Which physical side (East or West of the pier) the tube is on for the normal
    reading depends on the end of the declination axis that carries it.

    ``latitude`` is a pytree leaf (not fitted): models of mounts at different latitudes
    share one compilation.
    """

    latitude: Float[Array, ""]
    axis_names: ClassVar[tuple[str, str]] = ("ha", "dec")

    def __init__(self, latitude: Float[ArrayLike, ""]):
        if isinstance(latitude, jax.core.Tracer):
            self.latitude = latitude
            return
        lat = np.asarray(latitude, np.float64)
        if lat.shape != ():
            raise ValueError(f"EquatorialMount: latitude must be one number (radians), got shape {lat.shape}")
        if not (np.isfinite(lat) and abs(float(lat)) <= np.pi / 2 + 1e-12):
            raise ValueError(
                f"EquatorialMount: latitude {float(lat)!r} rad is not within [-pi/2, pi/2] "
                "(give it in radians: pointax.deg(latitude_deg))"
            )
        self.latitude = lat

    @property
    def frame(self) -> Float[Array, "3 3"]:
        s, c = jnp.sin(self.latitude), jnp.cos(self.latitude)
        zero, one = jnp.zeros_like(s), jnp.ones_like(s)
        # Columns: West, the equator on the meridian, the north celestial pole.
        return jnp.stack(
            [
                jnp.stack([-one, zero, zero]),
                jnp.stack([zero, -s, c]),
                jnp.stack([zero, c, s]),
            ]
        )

    @property
    def convention(self) -> str:
        return "ha-dec"



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
    def boresight(self) -> Float[ArrayLike, "3"]:
        return np.array([0.0, 1.0, 0.0])

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
    """A tilt-tilt heliostat driven by two actuators, linear or ideal (the PAINT / DLR Juelich
    heliostats). The raw readings are actuator increments (motor steps; on an ideal
    axis, the joint angle in radians); the mirror normal is the boresight::

        n = Re(theta1 - pi/2) . Ru(theta2) . (0, -1, 0)       (= Re(theta1) Rn(theta2) (0, 0, 1))

    in East-North-Up, with right-handed rotations Re, Rn, Ru about East, North, Up:
    ``theta1`` is the mirror's zenith angle. Axis tilts (``t1n, t1u, t2e, t2n``) and
    joint-angle zeros are terms (:mod:`pointax.terms.heliostat_terms`).

    Each axis's actuator turns increments into a joint angle by the law of cosines::

        s = increments / increment + initial_stroke            stroke, m
        phi(s) = arccos((offset^2 + pivot_radius^2 - s^2) / (2 offset pivot_radius))
        theta = initial_angle + sign (phi(s0) - phi(s))        s0 = initial_stroke

    with ``sign = +1`` for clockwise axis movement, ``-1`` otherwise. An axis marked
    ``ideal`` (PAINT's ``"ideal"`` actuator, DLR ARTIST's ``IdealActuators``) has no
    actuator geometry: its reading *is* the joint angle, ``theta = reading`` (radians),
    and its linear parameters (NaN allowed) are not used.

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
    ideal: Float[Array, "2"]
    axis_names: ClassVar[tuple[str, str]] = ("axis1", "axis2")

    @float64  # the geometry as float64 arrays whether or not JAX's x64 mode is on
    def __init__(self, increment, initial_stroke, offset, pivot_radius, initial_angle, clockwise, ideal=(0.0, 0.0)):
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
        self.ideal = jnp.where(pair(ideal, "ideal") != 0, 1.0, 0.0)

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
            ideal=[float(getattr(a, "law", "linear") == "ideal") for a in acts],
        )

    @property
    def boresight(self) -> Float[ArrayLike, "3"]:
        return np.array([0.0, -1.0, 0.0])

    @property
    def convention(self) -> str:
        return "heliostat"

    def _linear(self):
        """``(increment, initial_stroke, offset, pivot_radius, initial_angle)`` with
        harmless stand-ins on ideal axes (their values may be NaN), so that the
        linear law, evaluated on every axis and then discarded on ideal ones, stays
        finite (and so do its derivatives)."""
        ideal = self.ideal != 0
        return tuple(
            jnp.where(ideal, safe, x)
            for x, safe in (
                (self.increment, 1.0),
                (self.initial_stroke, 0.5),
                (self.offset, 1.0),
                (self.pivot_radius, 1.0),
                (self.initial_angle, 0.0),
            )
        )

    @staticmethod
    def _phi(stroke, a, r):
        return jnp.arccos(jnp.clip((a**2 + r**2 - stroke**2) / (2 * a * r), -1.0, 1.0))

    def axis_angles(self, reading):
        ideal = self.ideal != 0
        increment, s0, a, r, angle0 = self._linear()
        stroke = jnp.where(ideal, s0, reading / increment + s0)
        linear = angle0 + self.sign * (self._phi(s0, a, r) - self._phi(stroke, a, r))
        return jnp.where(ideal, reading, linear)

    def readings_of(self, angles):
        ideal = self.ideal != 0
        increment, s0, a, r, angle0 = self._linear()
        phi = self._phi(s0, a, r) - self.sign * (jnp.where(ideal, angle0, angles) - angle0)
        stroke = jnp.sqrt(a**2 + r**2 - 2 * a * r * jnp.cos(phi))
        return jnp.where(ideal, angles, (stroke - s0) * increment)

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

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
from jaxtyping import Array, Float

from .rotations import azel_to_enu, enu_to_azel, rot_x, rot_z, wrap_pi

__all__ = ["Mount", "AltAzMount", "AZIMUTH_CONVENTIONS"]


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
        # At the exact zenith every azimuth points the same way: keep the encoder's.
        at_pole = direction[0] ** 2 + direction[1] ** 2 <= 1e-300
        az = jnp.where(at_pole, near[0], az)
        # Two mechanical solutions point the same way: (az, el) and (az + pi, pi - el)
        # ("over the top"). Take the one nearer the encoders, on the encoder's branch.
        az_a = near[0] + wrap_pi(az - near[0])
        az_b = near[0] + wrap_pi(az + jnp.pi - near[0])
        el_b = jnp.pi - el
        dist_a = jnp.abs(wrap_pi(az - near[0])) + jnp.abs(el - near[1])
        dist_b = jnp.abs(wrap_pi(az + jnp.pi - near[0])) + jnp.abs(el_b - near[1])
        use_a = dist_a <= dist_b
        return jnp.stack([jnp.where(use_a, az_a, az_b), jnp.where(use_a, el, el_b)])

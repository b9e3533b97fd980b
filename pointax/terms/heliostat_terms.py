"""Error terms of a tilt-tilt heliostat (:class:`pointax.HeliostatMount`).

With every term the mirror normal is (DESIGN.md, checked on the PAINT samples)::

    n = Rn(t1n) Ru(t1u) . Re(theta1 + d1 - pi/2) . Re(t2e) Rn(t2n) . Ru(theta2 + d2) . (0, -1, 0)

=========  ===============================================  ======================
parameter  meaning                                          place in the chain
=========  ===============================================  ======================
t1n        tilt of axis 1 about North                       ``Rn(t1n)``, base
t1u        turn of axis 1 about Up (heading of the mount)   ``Ru(t1u)``, base
t2e        tilt of axis 2 about East                        ``Re(t2e)``, between axes
t2n        tilt of axis 2 about North                       ``Rn(t2n)``, between axes
d1, d2     joint-angle zeros (actuator initial angles)      added to theta1, theta2
=========  ===============================================  ======================

``t2e`` and ``d1`` turn about the same axis one after the other and enter only as their
sum: a fit of both is rank-deficient and :func:`pointax.fit` names them.
Parameters are shown in mrad, the unit heliostat engineers use.
"""

from __future__ import annotations

import equinox as eqx

from ..core.rotations import rot_x, rot_y, rot_z
from ..core.term import Term, angle_pair, param

__all__ = ["AxisTilt", "JointZero", "HELIOSTAT_TERMS", "HELIOSTAT_DEFAULT", "heliostat"]


class AxisTilt(Term):
    """Tilt of one heliostat axis: ``t1n``, ``t1u`` (base) or ``t2e``, ``t2n`` (between axes)."""

    coef: float = param(0.0, unit="mrad")
    which: str = eqx.field(static=True, default="t1n")

    def __check_init__(self):
        if self.which not in ("t1n", "t1u", "t2e", "t2n"):
            raise ValueError(f"unknown heliostat axis tilt {self.which!r}; expected t1n, t1u, t2e or t2n")

    @property
    def name(self) -> str:
        return self.which

    def _rotation(self):
        return {"n": rot_y, "u": rot_z, "e": rot_x}[self.which[2]](self.coef)

    def base_rotation(self, angles):
        return self._rotation() if self.which[1] == "1" else None

    def axes_rotation(self, angles):
        return self._rotation() if self.which[1] == "2" else None


class JointZero(Term):
    """Zero offset ``d1`` or ``d2`` added to a joint angle (an actuator's initial angle)."""

    coef: float = param(0.0, unit="mrad")
    axis: int = eqx.field(static=True, default=1)

    @property
    def name(self) -> str:
        return f"d{self.axis}"

    def encoder_offset(self, encoder):
        return angle_pair(self.coef, 0.0) if self.axis == 1 else angle_pair(0.0, self.coef)


HELIOSTAT_TERMS = ("t1n", "t1u", "t2e", "t2n", "d1", "d2")
"""Every heliostat parameter, in chain order."""

HELIOSTAT_DEFAULT = ("t1n", "t1u", "t2e", "t2n")
"""The four axis tilts: what a PAINT calibration fits by default."""


def heliostat(spec=HELIOSTAT_DEFAULT, values: dict | None = None) -> tuple[Term, ...]:
    """Heliostat terms by name, e.g. ``heliostat("t1n t1u t2e t2n")``.

    Args:
        spec: names from :data:`HELIOSTAT_TERMS`, space or comma separated, or a sequence.
        values: optional starting values in radians, by name.
    """
    chosen = spec.replace(",", " ").split() if isinstance(spec, str) else list(spec)
    values = dict(values or {})
    out = []
    for name in chosen:
        if name not in HELIOSTAT_TERMS:
            raise ValueError(f"unknown heliostat parameter {name!r}; expected names from {' '.join(HELIOSTAT_TERMS)}")
        v = values.pop(name, 0.0)
        out.append(JointZero(v, axis=int(name[1])) if name[0] == "d" else AxisTilt(v, which=name))
    if values:
        raise ValueError(f"values given for parameters not in the list: {sorted(values)}")
    return tuple(sorted(out, key=lambda t: HELIOSTAT_TERMS.index(t.name)))

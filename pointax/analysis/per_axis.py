"""What a model comparison measures along each axis: the first axis's angle (the
level-mount paper's ``DL``) or the cross-axis offset on the sky (TPOINT's
``dA cos E``), and the cosines that turn one into the other.

The figures themselves (per-axis RMS, AIC and BIC, significance) are in
:mod:`pointax.fitting.statistics` with TPOINT's.
"""

from __future__ import annotations

import numpy as np

from ..core.mounts import Mount, SphericalMount, XYMount
from ..core.observations import Observations

__all__ = ["PER_AXIS", "resolve_per_axis", "second_axis_cosines"]

PER_AXIS = ("angle", "sky")
"""What the per-axis RMS measures on the first axis: its angle (the paper's ``DL``) or
the cross-axis offset on the sky (TPOINT's ``dA cos E``)."""


def resolve_per_axis(mount: Mount, per_axis: str | None) -> str:
    """``per_axis``, or its default for ``mount`` when None: the paper's axis angles on
    an X-Y mount, TPOINT's sky offsets elsewhere (where the first-axis angle residual
    grows as ``sec E`` towards the zenith)."""
    if per_axis is None:
        return "angle" if isinstance(mount, XYMount) else "sky"
    return per_axis


def second_axis_cosines(mount: Mount, obs: Observations, per_axis: str) -> np.ndarray | None:
    """cos of each target's second-axis angle in the mount frame (None for 'sky'): the
    ``cos_axis2`` of :func:`pointax.fitting.statistics.axis_rms`.

    Raises:
        ValueError: an unknown ``per_axis``, or 'angle' on a mount without spherical
            axis angles.
    """
    if per_axis not in PER_AXIS:
        raise ValueError(f"per_axis must be one of {PER_AXIS}, got {per_axis!r}")
    if per_axis == "sky":
        return None
    if not isinstance(mount, SphericalMount):
        raise ValueError(
            f"per_axis='angle' needs a mount with perpendicular axes (alt-az, X-Y, equatorial); "
            f"a {type(mount).__name__} has no first-axis angle residual: use per_axis='sky'"
        )
    t = np.asarray(obs.target) @ np.asarray(mount.frame)
    return np.hypot(t[:, 0], t[:, 1])

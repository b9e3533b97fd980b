"""Where a model must be read to point at a direction, and how its pointing moves with
its parameters there: the two ingredients of predicted accuracy and of planning.

:func:`readings_for` is a fast approximate inverse of a model (a fixed-point iteration
on the mount's nominal inverse, no Newton solve): ample for evaluating a Jacobian, and
it compiles in a fraction of :func:`pointax.command`'s time. :func:`pointing_jacobian`
is ``d offset / d parameters`` by forward-mode autodiff (``jax.jacfwd``), the offset
being the gnomonic offset of where the model points, in the tangent plane of the
mount's frame at that direction: the axes of the fit residuals
(:func:`pointax.residuals`), i.e. (cross-elevation, elevation) for an alt-az mount,
``(dL cos B, dB)`` for an X-Y mount.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ..core.compiled import compile_by_structure
from ..core.precision import float64
from ..core.model import Model
from ..core.observations import COUNTED_READINGS
from ..core.padding import pad_rows, power_of_two
from ..core.rotations import angle_between, tangent_offset, wrap_pi
from ..core.units import directions_enu

__all__ = [
    "readings_for",
    "pointing_jacobian",
    "reading_limits_ok",
    "padded_size",
    "pad_rows",
    "INVERSE_ITERATIONS",
    "INVERSE_TOL",
]

INVERSE_ITERATIONS = 6
"""Fixed-point iterations of :func:`readings_for` (each reduces the error by a factor of
about the largest derivative of the model's offsets, ~1e-3 for real models)."""

INVERSE_TOL = 1e-8
"""A reading from :func:`readings_for` counts as found when the model points within
this (radians, 2 mas) of the wanted direction."""

_TWO_PI = 2.0 * np.pi
_MIN_BATCH = 64


def padded_size(n: int) -> int:
    """The batch size ``n`` is padded to (a power of two, at least 64): one compilation
    serves many sizes (as :func:`pointax.command` does)."""
    return power_of_two(n, _MIN_BATCH)


@compile_by_structure
def _readings(model: Model, directions, flipped):
    mount = model.mount
    frame = jnp.asarray(mount.frame)

    def one(d):
        dm = frame.T @ d
        a = mount.angles_of(dm, jnp.zeros(2, d.dtype))
        turn = jnp.cos(a[1]) < 0
        normal = jnp.where(turn, jnp.stack([a[0] - jnp.pi, jnp.pi - a[1]]), a)
        want = jnp.where(flipped, jnp.stack([normal[0] + jnp.pi, jnp.pi - normal[1]]), normal)
        # Undo the encoder corrections (exact at once for constant zeros, however
        # large), then the rest of the chain, by fixed-point steps in axis-angle space.
        angles = want
        for _ in range(3):
            angles = angles + (want - model.corrected_encoder(mount.readings_of(angles)))
        for _ in range(INVERSE_ITERATIONS):
            reading = mount.readings_of(angles)
            got = mount.angles_of(model.mount_direction(reading), want)
            diff = jnp.stack([wrap_pi(want[0] - got[0]), want[1] - got[1]])
            angles = angles + diff
        reading = mount.readings_of(angles)
        miss = angle_between(model.direction(reading), d)
        return reading, miss

    return jax.vmap(one)(directions)


@float64
def readings_for(
    model: Model,
    directions: Float[ArrayLike, "n 3"],
    *,
    solution: str = "normal",
) -> tuple[Float[np.ndarray, "n 2"], np.ndarray]:
    """Raw readings that point ``model`` at ``directions`` (approximately: see the
    module), and which were found.

    Args:
        model: the pointing model.
        directions: ``(n, 3)`` East-North-Up unit vectors (or an astropy ``SkyCoord`` in
            ``AltAz``, or an ``(n, 2)`` Quantity of azimuth and elevation).
        solution: ``'normal'`` (axis-2 angle within 90 deg of its zero: elevation for an
            alt-az mount) or ``'flipped'`` (over the top; the other pier side of an
            equatorial mount).

    Returns:
        ``(readings (n, 2), ok (n,))``: NumPy arrays; ``ok`` where the model points within
        :data:`INVERSE_TOL` of the direction (else the reading is not to be used).
        Axis 1 is in ``(-pi, pi]`` from the nominal inverse; :func:`reading_limits_ok`
        moves it by whole turns into a mount's limits.
    """
    if solution not in ("normal", "flipped"):
        raise ValueError(f"solution must be 'normal' or 'flipped', got {solution!r}")
    d = np.asarray(directions_enu(directions, "directions"), np.float64).reshape(-1, 3)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    n = d.shape[0]
    if n == 0:
        return np.zeros((0, 2)), np.zeros(0, bool)
    reading, miss = _readings(model, jnp.asarray(pad_rows(d, padded_size(n))), jnp.asarray(solution == "flipped"))
    reading, miss = np.asarray(reading)[:n], np.asarray(miss)[:n]
    return reading, np.isfinite(miss) & (miss <= INVERSE_TOL) & np.all(np.isfinite(reading), axis=-1)


def reading_limits_ok(model: Model, readings: np.ndarray, limits) -> tuple[np.ndarray, np.ndarray]:
    """Readings moved into ``limits`` where they can be, and which lie inside them.

    ``limits`` as for :func:`pointax.command`: ``((axis1_min, axis1_max), (axis2_min,
    axis2_max))`` in reading units, None for no limit. Axis 1 of an angle-reading mount
    is moved by whole turns to the branch inside its limits nearest their middle (an
    alt-az cable wrap of +-270 deg puts azimuth 300 deg at -60 deg); axis 2 is only
    checked. Returns ``(readings, inside)``.
    """
    from ..core.inverse import limits_array

    lim = np.asarray(limits_array(limits))
    r = np.array(readings, np.float64, copy=True)
    lo, hi = lim[:, 0], lim[:, 1]
    if model.mount.convention not in COUNTED_READINGS and (np.isfinite(lo[0]) or np.isfinite(hi[0])):
        if np.isfinite(lo[0]) and np.isfinite(hi[0]):
            mid = 0.5 * (lo[0] + hi[0])
        elif np.isfinite(lo[0]):
            mid = lo[0] + np.pi
        else:
            mid = hi[0] - np.pi
        base = r[:, 0] + _TWO_PI * np.round((mid - r[:, 0]) / _TWO_PI)
        cands = base[:, None] + _TWO_PI * np.arange(-2, 3)[None, :]
        inside = (cands >= lo[0]) & (cands <= hi[0])
        dist = np.where(inside, np.abs(cands - mid), np.inf)
        pick = np.argmin(dist, axis=1)
        r[:, 0] = np.where(inside.any(axis=1), cands[np.arange(len(r)), pick], r[:, 0])
    ok = np.all((r >= lo) & (r <= hi), axis=1)
    return r, ok


@compile_by_structure
def _jacobian(model: Model, readings):
    free = model.free_parameters
    y0 = model.values("free")
    frame = jnp.asarray(model.mount.frame)

    def one(reading):
        d0 = model.mount_direction(reading)

        def offset(y):
            moved = model.replace_parameters(free, [y[k] for k in range(len(free))])
            return tangent_offset(moved.mount_direction(reading), d0)

        return jax.jacfwd(offset)(y0), frame @ d0

    return jax.vmap(one)(readings)


@float64
def pointing_jacobian(
    model: Model, readings: Float[ArrayLike, "n 2"]
) -> tuple[Float[Array, "n 2 p"], Float[Array, "n 3"]]:
    """``(n, 2, p)`` derivatives of where ``model`` points at raw ``readings`` with
    respect to its ``p`` free parameters (radians of tangent-plane offset per internal
    unit, in the mount frame's tangent plane: the fit residuals' axes), by
    ``jax.jacfwd``; and ``(n, 3)`` the directions (ENU) it points at. Compiled once per
    model structure and number of readings."""
    readings = np.asarray(readings, np.float64).reshape(-1, 2)
    if not model.free_parameters:
        raise ValueError("the model has no free parameters: nothing to predict or plan")
    n = readings.shape[0]
    jac, d = _jacobian(model, jnp.asarray(pad_rows(readings, padded_size(n))))
    return jac[:n], d[:n]

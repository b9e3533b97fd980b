"""A model's pointing evaluated over all of one site's observations at once, arranged
for speed: the evaluation under :mod:`pointax.fitting.problem`'s residuals.

:meth:`pointax.Model.mount_direction` evaluates one observation at a time, which is
the clearest way to write a model and what ``jax.vmap`` turns into array code. Batched
fits of thousands of sites evaluate the same model millions of times, and there the
arrangement matters more than the arithmetic (``benchmarks/batch_fit_notes.md``):

* **What the data fix is computed once** (:func:`pointax.fitting.problem.site_data`):
  the nominal axis angles, their sines and cosines, the targets in the mount frame.
  An axis rotation by ``nominal + offset`` is evaluated by angle addition,
  ``sin(n + o) = sin n cos o + cos n sin o``, so a fit never takes the sine of an
  observation: only of the (per-site) offsets.
* **Structure of arrays**: vectors are three ``(n,)`` arrays, not ``(n, 3)``; rotations
  that do not depend on the observation (tilts, zero points, collimation, ...) are
  multiplied together once per site and applied as one matrix.

Nothing here knows any particular term: the terms' hooks are called exactly as
:meth:`pointax.Model.mount_direction` calls them (through ``jax.vmap`` over the
observations; a hook whose result does not depend on the observation is evaluated
once), and :func:`site_pointing` equals ``jax.vmap(model.mount_direction)`` (checked in
``tests/test_site.py``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..core.model import Model
from ..core.mounts import SphericalMount
from ..core.term import SkyPoint
from ..core.trig import sincos
from .matrix_entries import (
    axis_form,
    constant_entries,
    dot,
    entries,
    matmul,
    nominal_entries,
    turn,
    value,
)

if TYPE_CHECKING:
    from .problem import SiteData

__all__ = [
    "chain_pointing",
    "site_pointing",
    "chain_angles",
    "has_sky_offsets",
    "sky_offsets_at",
    "direction_at",
    "tangent_offsets",
    "per_observation",
    "corrected_angles",
    "rotated",
    "sine_function",
    "in_mount_frame",
]

_HOOKS = ("boresight_rotation", "axes_rotation", "base_rotation")


def per_observation(fn, angles):
    """``(jax.vmap(fn)(angles), True)``, or ``(fn's result, False)`` evaluated once when it
    does not depend on the observation."""
    try:
        return jax.vmap(fn, out_axes=None)(angles), False
    except ValueError:
        return jax.vmap(fn)(angles), True


def _hook_matrices(model: Model, hook: str, angles) -> list:
    """The terms' rotations at one place in the chain, in term order: ``(entries, per_observation)``."""
    out = []
    for term in model.terms:
        r, batched = per_observation(getattr(term, hook), angles)
        if r is not None:
            out.append((entries(r), batched))
    return out


def _encoder_offset(model: Model, nominal):
    """Total encoder offset per axis, ``[(offset or None, per_observation), ...]``."""
    total = [None, None]
    batched = [False, False]
    for term in model.terms:
        off, b = per_observation(term.encoder_offset, nominal)
        if off is None:
            continue
        for k in range(2):
            total[k] = off[..., k] if total[k] is None else total[k] + off[..., k]
            batched[k] = batched[k] or b
    return list(zip(total, batched))


def _axis_matrices(mount, axis: str, cos_n, sin_n, nominal, offset) -> list:
    """``axis(nominal + offset)`` in chain order. For a fixed-axis rotation
    ``axis(n + o) = axis(n) . axis(0)^T . axis(o)``: the first factor comes from the
    data's cos and sin, the second is per site unless the offset varies by observation."""
    axis_fn = getattr(mount, axis)
    form = axis_form(mount, axis)
    value, batched = offset
    if form is None:  # not a fixed-axis rotation: the whole matrix per observation
        angle = nominal if value is None else nominal + value
        return [(entries(jax.vmap(axis_fn)(angle)), True)]
    out = [(nominal_entries(form, cos_n, sin_n), True)]
    if value is not None:
        zero_t = (form[0] + form[2]).T  # axis(0)^T
        turn = jax.vmap(axis_fn)(value) if batched else axis_fn(value)
        out.append((entries(jnp.asarray(zero_t) @ turn if not np.allclose(zero_t, np.eye(3)) else turn), batched))
    return out


def _apply_chain(matrices, v):
    """Apply ``M_1 . M_2 ... M_k`` to ``v``: neighbouring per-site matrices are multiplied
    together once per site, so each observation sees one matrix per run of them."""
    pending = None
    for matrix, batched in reversed(matrices):
        if not batched:
            pending = matrix if pending is None else matmul(matrix, pending)
            continue
        if pending is not None:
            v, pending = turn(pending, v), None
        v = turn(matrix, v)
    return v if pending is None else turn(pending, v)


def corrected_angles(model: Model, nominal):
    """``(angles, offset)``: the axis angles after the terms' encoder corrections, ``(n,
    2)``, and the per-axis offsets of :func:`_encoder_offset`."""
    offset = _encoder_offset(model, nominal)
    angles = nominal
    for k in range(2):
        if offset[k][0] is not None:
            angles = angles.at[:, k].add(offset[k][0])
    return angles, offset


def rotated(model: Model, angles) -> bool:
    """Whether any term turns the chain (a rotation hook that is not None)."""
    return any(getattr(t, h)(angles[0]) is not None for t in model.terms for h in _HOOKS)


def chain_pointing(model: Model, data: SiteData) -> tuple[list, Array]:
    """Where the chain of rotations points before any sky offset: ``(v, angles)`` with
    ``v`` three ``(n,)`` arrays in the mount frame and ``angles`` the corrected axis
    angles ``(n, 2)``."""
    mount = model.mount
    nominal = data.nominal
    angles, offset = corrected_angles(model, nominal)
    cos1, sin1, cos2, sin2 = data.trig
    hooks = {h: _hook_matrices(model, h, angles) for h in _HOOKS}
    chain = (
        hooks["base_rotation"]
        + _axis_matrices(mount, "axis1", cos1, sin1, nominal[:, 0], offset[0])
        + hooks["axes_rotation"]
        + _axis_matrices(mount, "axis2", cos2, sin2, nominal[:, 1], offset[1])
        + hooks["boresight_rotation"]
    )
    v = _boresight(mount)
    v = _apply_chain(chain, v)
    n = nominal.shape[0]
    v = [jnp.broadcast_to(jnp.asarray(value(x), nominal.dtype), (n,)) for x in v]
    return v, angles


def site_pointing(model: Model, data: SiteData) -> list[Float[Array, " n"]]:
    """Pointing directions in the mount frame, as three ``(n,)`` arrays (x, y, z);
    the same as ``jax.vmap(model.mount_direction)`` over the site's readings."""
    v, angles = chain_pointing(model, data)
    if not has_sky_offsets(model, angles):
        return v
    sky = _sky_position(model, chain_angles(model, v, angles), data)
    return direction_at(model, sky[:, 0], sky[:, 1], data)


def has_sky_offsets(model: Model, angles) -> bool:
    """Whether any term adds a pointing offset at the sky position (decided while tracing)."""
    return any(per_observation(t.sky_offset, angles)[0] is not None for t in model.terms)


def chain_angles(model: Model, v, angles):
    """The axis angles ``(n, 2)`` where the chain points (``v``, three ``(n,)`` arrays),
    near the corrected ``angles``."""
    if rotated(model, angles):
        return jax.vmap(model.mount.angles_of)(jnp.stack(v, axis=-1), angles)
    return angles  # no rotation term in the chain: its direction's angles are these


def direction_at(model: Model, a1, a2, data: SiteData) -> list[Float[Array, " n"]]:
    """The mount's direction at the axis angles ``a1, a2`` (``(n,)`` each) as three ``(n,)``
    arrays."""
    if type(model.mount).direction is SphericalMount.direction:
        # (sin a1 cos a2, cos a1 cos a2, sin a2) from the sines and cosines at hand.
        p = _sky_point(a1, a2, data)
        return [p.sin_az * p.cos_el, p.cos_az * p.cos_el, p.sin_el]
    d = jax.vmap(model.mount.direction)(jnp.stack([a1, a2], axis=-1))
    return [d[:, 0], d[:, 1], d[:, 2]]


def _sky_point(a1, a2, data: SiteData) -> SkyPoint:
    """The :class:`SkyPoint` at the axis angles ``a1, a2`` (``(n,)`` each), its sines and
    cosines by angle addition from those of the site's nominal angles (``data.trig``)
    and the sine and cosine of the small differences: vectorised
    (:func:`pointax.core.trig.sincos`: XLA on the CPU calls the C library once per element
    for ``jnp.sin``) unless ``data.library_trig``."""
    cos1, sin1, cos2, sin2 = data.trig
    nominal = data.nominal
    sines = sine_function(data.library_trig)
    (s1, c1), (s2, c2) = sines(a1 - nominal[:, 0]), sines(a2 - nominal[:, 1])
    return SkyPoint(
        a1, a2, sin1 * c1 + cos1 * s1, cos1 * c1 - sin1 * s1, sin2 * c2 + cos2 * s2, cos2 * c2 - sin2 * s2
    )


def _sky_offsets(model: Model, point: SkyPoint):
    """The sum of the terms' sky offsets at ``point`` (arrays ``(n,)``), ``(n, 2)``."""
    total = None
    for term in model.terms:
        off, batched = per_observation(term.sky_offset_at, point)
        if off is not None:
            off = off if batched else jnp.broadcast_to(off, (point.az.shape[0], 2))
            total = off if total is None else total + off
    return total


def sine_function(library_trig: bool):
    """``x -> (sin x, cos x)``: XLA's library functions when ``library_trig``
    (:attr:`pointax.fitting.problem.SiteData.library_trig`), else :func:`pointax.core.trig.sincos`."""
    return (lambda x: (jnp.sin(x), jnp.cos(x))) if library_trig else sincos


def _sky_position(model: Model, start, data: SiteData):
    """:meth:`pointax.Model.sky_position` over a site, from the chain's angles ``start``
    ``(n, 2)``: the same fixed-point iterations (a loop, as there: unrolled, they compile
    much longer), with :func:`_sky_point`'s sines and cosines, on the two angles as
    separate ``(n,)`` arrays (one carried ``(n, 2)`` array runs slower)."""
    c1, c2 = start[:, 0], start[:, 1]

    def step(_, sky):
        g1, g2 = sky_offsets_at(model, *sky, data)
        return c1 + g1, c2 + g2

    return jnp.stack(jax.lax.fori_loop(0, model.sky_iterations, step, (c1, c2)), axis=-1)


def sky_offsets_at(model: Model, a1, a2, data: SiteData):
    """The terms' total sky offset at the axis angles ``a1, a2`` as two ``(n,)`` arrays:
    the map of :func:`site_pointing`'s fixed point (``sky = chain + offsets at sky``)."""
    g = _sky_offsets(model, _sky_point(a1, a2, data))
    return g[:, 0], g[:, 1]


def _boresight(mount) -> list:
    """The mount's boresight as three entries (:func:`constant_entries`)."""
    return constant_entries(lambda: mount.boresight)


def in_mount_frame(mount, v: Float[Array, "n 3"]) -> Float[Array, "n 3"]:
    """``v @ mount.frame`` entry by entry: the frame is usually a constant signed
    permutation, and XLA on the CPU runs even a product with the identity as a library
    call."""
    frame = constant_entries(lambda: mount.frame)
    components = [v[:, i] for i in range(3)]
    return jnp.stack([value(dot([frame[i][j] for i in range(3)], components)) for j in range(3)], axis=-1)


def tangent_offsets(pointing, target_trig) -> tuple[Array, Array]:
    """The sky form's residuals, observed minus model in the tangent plane of the target:
    ``pointing`` three ``(n,)`` arrays (mount frame), ``target_trig`` as in :class:`pointax.fitting.problem.SiteData`."""
    x, y, z = pointing
    ca, sa, ce, se = target_trig
    # target (ce sa, ce ca, se); e_az (ca, -sa, 0); e_el (-se sa, -se ca, ce)
    horizontal = x * sa + y * ca
    inv_depth = 1.0 / (ce * horizontal + se * z)
    return (y * sa - x * ca) * inv_depth, (se * horizontal - ce * z) * inv_depth


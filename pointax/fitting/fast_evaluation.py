"""A model evaluated over all of one site's observations at once, arranged for speed.

:meth:`pointax.Model.mount_direction` evaluates one observation at a time, which is
the clearest way to write a model and what ``jax.vmap`` turns into array code. Batched
fits of thousands of sites evaluate the same model millions of times, and there the
arrangement matters more than the arithmetic (measured in ``benchmarks/batch_fit_notes.md``):

* **What the data fix is computed once** (:func:`site_data`): the nominal axis angles,
  their sines and cosines, the targets in the mount frame and their tangent-plane
  basis. An axis rotation by ``nominal + offset`` is evaluated by angle addition,
  ``sin(n + o) = sin n cos o + cos n sin o``, so a fit never takes the sine of an
  observation: only of the (per-site) offsets.
* **Structure of arrays**: vectors are three ``(n,)`` arrays, not ``(n, 3)``; rotations
  that do not depend on the observation (tilts, zero points, collimation, ...) are
  multiplied together once per site and applied as one matrix.

Nothing here knows any particular term: the terms' hooks are called exactly as
:meth:`pointax.Model.mount_direction` calls them (through ``jax.vmap`` over the
observations; a hook whose result does not depend on the observation is evaluated
once), and :func:`site_residuals` equals :func:`pointax.residuals` times the square
root of the normalised weights (checked to 1e-15 rad in ``tests/test_site.py``).
The derivatives of these residuals, for the fits, are :mod:`pointax.fitting.fast_jacobian`'s.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from ..core.model import Model
from ..core.mounts import SphericalMount
from ..core.observations import Observations
from ..core.rotations import azel_trig, wrap_pi
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
from ..core.term import SkyPoint
from ..core.trig import sincos

__all__ = [
    "SiteData",
    "site_data",
    "site_geometry",
    "observed_point",
    "with_sky_basis",
    "without_pinned_singularities",
    "site_residuals",
    "site_pointing",
    "is_affine",
    "chain_pointing",
    "chain_angles",
    "has_sky_offsets",
    "sky_offsets_at",
    "direction_at",
    "tangent_offsets",
]

_HOOKS = ("boresight_rotation", "axes_rotation", "base_rotation")


class SiteData(eqx.Module):
    """What one site's observations fix, computed once per fit (a pytree; batch it).

    Attributes:
        nominal: ``(n, 2)`` nominal axis angles (:meth:`pointax.Mount.axis_angles`).
        trig: four ``(n,)`` arrays: cos and sin of the nominal axis-1 angle, cos and sin
            of axis 2 (None for ``residual_form="tpoint"`` when no term turns the chain).
        target_trig: for ``residual_form="sky"`` (else None): four ``(n,)`` arrays: cos
            and sin of the observed directions' azimuth, cos and sin of their elevation,
            in the mount frame (the direction and its tangent-plane basis,
            :func:`pointax.core.rotations.tangent_basis`, follow).
        sqrt_weight: ``(n,)`` square roots of the weights normalised to mean 1 over the
            used observations (0 for unused ones).
        used: ``(n,)`` observations with positive weight.
        observed: for ``residual_form="tpoint"`` (else None): the observed directions'
            angles in the mount's convention, as two ``(n,)`` arrays, and the cosine of
            the second.
        sky_basis: for ``residual_form="tpoint"`` (else None): per parameter of the
            terms with ``linear_sky_offset``, in model order, its sky offset per unit
            at the observed angles as two ``(n,)`` arrays.
        library_trig: sines and cosines (of the nominal angles, and of the sky form's
            fixed point inside every evaluation) from XLA's per-element library calls
            instead of :func:`pointax.core.trig.sincos`'s vectorised polynomials. The
            polynomials are several times faster over thousands of sites, but XLA copies
            them into every consumer: the solo fit of the MMT run's 8 terms compiled to a
            2.6 MB executable with them against 1.6 MB without (loaded from disk by every
            warm ``pointax fit``: 0.25 against 0.11-0.15 s). Values agree to rounding.
    """

    nominal: Float[Array, "n 2"]
    trig: tuple[Float[Array, " n"], ...] | None
    target_trig: tuple[Float[Array, " n"], ...] | None
    sqrt_weight: Float[Array, " n"]
    used: Bool[Array, " n"]
    observed: tuple[Float[Array, " n"], ...] | None = None
    sky_basis: tuple[tuple[Float[Array, " n"], Float[Array, " n"]], ...] | None = None
    library_trig: bool = eqx.field(static=True, default=False)


def site_data(
    model: Model, obs: Observations, used: Bool[Array, " n"] | None = None, library_trig: bool = False
) -> SiteData:
    """Precompute one site's :class:`SiteData` (pure JAX; ``vmap`` over sites).

    Args:
        model: the model (its mount; for ``residual_form="tpoint"`` its linear sky terms).
        obs: the site's observations, ``(n, ...)``. Rows with weight 0 may hold NaN.
        used: which observations to fit (default: weight > 0); the weights are
            normalised to mean 1 over these.
        library_trig: see :attr:`SiteData.library_trig` (one site's fit: True).
    """
    data, target = site_geometry(model, obs, used, library_trig)
    return with_sky_basis(model, data, None if target is None else observed_point(model, data, target))


def observed_point(model: Model, data: SiteData, target: Float[Array, "*sites n 3"]) -> SkyPoint:
    """The observed directions' angles in the mount's convention with their sines and
    cosines (:meth:`pointax.Mount.sky_point_of`, near the nominal angles), ``(*sites,
    n)`` arrays: for one site or, in a batched fit, a whole chunk at once (where the
    mount's treatment of its pole runs only when some observation is there)."""
    return model.mount.sky_point_of(target, data.nominal)


def with_sky_basis(model: Model, data: SiteData, point: SkyPoint | None) -> SiteData:
    """``data`` with the observed angles and the unit offsets of the model's linear sky
    terms at the observed ``point`` (:func:`observed_point`; nothing to add when it is
    None).

    The sines and cosines come from the directions' components, not from the angles
    (:meth:`pointax.SphericalMount.sky_point_of`), and TPOINT's terms read them from the
    point: within one computation XLA on the CPU recomputes an ``atan2``, sine or cosine
    in every output that uses it (15 transcendental functions per observation for
    TPOINT's eight basic terms once measured; now two ``atan2`` and four square roots)."""
    if point is None:
        return data
    observed = (point.az, point.el, point.cos_el)
    return dataclasses.replace(data, observed=observed, sky_basis=tuple(_unit_offsets(model, point)))


def site_geometry(
    model: Model, obs: Observations, used: Bool[Array, " n"] | None = None, library_trig: bool = False
) -> tuple[SiteData, Float[Array, "n 3"] | None]:
    """The first part of :func:`site_data`: everything but what
    :func:`with_sky_basis` adds, and the observed directions in the mount frame (for
    :func:`observed_point`; None unless ``residual_form="tpoint"``)."""
    mount = model.mount
    used = obs.weight > 0 if used is None else used & (obs.weight > 0)
    reading, target = obs.filled(used)  # unused rows: the first used row's
    nominal = jax.vmap(mount.axis_angles)(reading)
    target = _in_mount_frame(mount, target)
    weight = jnp.where(used, obs.weight, 0.0)
    weight = weight * jnp.sum(used) / jnp.sum(weight)
    # Only what the residual form needs (transcendentals dominate this call's cost).
    # Separate arrays, not one (4, n) array: slices of a stacked array cost copies.
    trig = target_trig = None
    tpoint = model.residual_form == "tpoint"
    if not tpoint or _rotated(model, nominal):
        sines = _sincos(library_trig)
        (sin1, cos1), (sin2, cos2) = sines(nominal[:, 0]), sines(nominal[:, 1])
        trig = (cos1, sin1, cos2, sin2)
    if not tpoint:
        target_trig = azel_trig(target)
    data = SiteData(nominal, trig, target_trig, jnp.sqrt(weight), used, None, None, library_trig)
    return data, target if tpoint else None


def is_affine(model: Model) -> bool:
    """Whether the model's fit residuals are affine in its free parameters: TPOINT's
    residual form with every free parameter in a term whose ``linear_sky_offset``
    holds (the chain and the other terms are then fixed). Decided from the structure,
    while tracing."""
    return model.residual_form == "tpoint" and all(
        model.terms[p.term].linear_sky_offset for p in model.free_parameters
    )


def without_pinned_singularities(model: Model, data: SiteData, free: Bool[Array, " m"]) -> SiteData:
    """``data`` with the unit offsets of the parameters that stay at 0 in a fit (not
    ``free`` and 0 in ``model``) set to 0 where they are not finite: such a parameter adds
    nothing, but ``0 * inf`` would make the observation's residual NaN. TPOINT's terms are
    singular somewhere (NPAE, AN, AW: ``tan E`` at the zenith, where the observed point of
    a star exactly there has ``cos E = 0``), and a fit carries at 0 the terms its model
    lacks (:mod:`pointax.fitting.structure`). Done once per fit, so the residuals cost
    nothing more. ``free``: ``(M,)`` over ``model.parameters``."""
    if data.sky_basis is None:
        return data
    values = model.values("all")
    position = {(p.term, p.field): k for k, p in enumerate(model.parameters)}
    basis = []
    for key, (u1, u2) in zip(_linear_sky_parameters(model), data.sky_basis):
        k = position[key]
        pinned = ~free[k] & (values[k] == 0)
        basis.append(tuple(jnp.where(pinned & ~jnp.isfinite(u), 0.0, u) for u in (u1, u2)))
    return dataclasses.replace(data, sky_basis=tuple(basis))


def _linear_sky_parameters(model: Model) -> list[tuple[int, str]]:
    """``(term index, field)`` of every parameter of the terms with ``linear_sky_offset``."""
    return [(p.term, p.field) for p in model.parameters if model.terms[p.term].linear_sky_offset]


def _unit_offsets(model: Model, point: SkyPoint):
    """Per parameter of :func:`_linear_sky_parameters`: its term's sky offset per unit
    of it at the observations' ``point`` (:meth:`pointax.Term.sky_offset_at`), ``(d axis
    1, d axis 2)``."""
    for index, field in _linear_sky_parameters(model):
        term = model.terms[index]
        value = jnp.asarray(getattr(term, field), float)

        def offset(x, p, field=field, term=term):
            out = eqx.tree_at(lambda t: getattr(t, field), term, x).sky_offset_at(p)
            if out is None:
                raise TypeError(f"{term.name} says linear_sky_offset but has no sky_offset")
            return out

        unit = jax.vmap(lambda p: jax.jvp(lambda x: offset(x, p), (value,), (jnp.ones_like(value),))[1])(point)
        yield unit[:, 0], unit[:, 1]


def _per_observation(fn, angles):
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
        r, batched = _per_observation(getattr(term, hook), angles)
        if r is not None:
            out.append((entries(r), batched))
    return out


def _encoder_offset(model: Model, nominal):
    """Total encoder offset per axis, ``[(offset or None, per_observation), ...]``."""
    total = [None, None]
    batched = [False, False]
    for term in model.terms:
        off, b = _per_observation(term.encoder_offset, nominal)
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


def _corrected(model: Model, nominal):
    """``(angles, offset)``: the axis angles after the terms' encoder corrections, ``(n,
    2)``, and the per-axis offsets of :func:`_encoder_offset`."""
    offset = _encoder_offset(model, nominal)
    angles = nominal
    for k in range(2):
        if offset[k][0] is not None:
            angles = angles.at[:, k].add(offset[k][0])
    return angles, offset


def _rotated(model: Model, angles) -> bool:
    """Whether any term turns the chain (a rotation hook that is not None)."""
    return any(getattr(t, h)(angles[0]) is not None for t in model.terms for h in _HOOKS)


def chain_pointing(model: Model, data: SiteData) -> tuple[list, Array]:
    """Where the chain of rotations points before any sky offset: ``(v, angles)`` with
    ``v`` three ``(n,)`` arrays in the mount frame and ``angles`` the corrected axis
    angles ``(n, 2)``."""
    mount = model.mount
    nominal = data.nominal
    angles, offset = _corrected(model, nominal)
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
    return any(_per_observation(t.sky_offset, angles)[0] is not None for t in model.terms)


def chain_angles(model: Model, v, angles):
    """The axis angles ``(n, 2)`` where the chain points (``v``, three ``(n,)`` arrays),
    near the corrected ``angles``."""
    if _rotated(model, angles):
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
    (:func:`pointax.core.trig.sincos`; XLA on the CPU calls the C library once per element
    for ``jnp.sin``, and the sky form's batched fit ran 70 times slower than the TPOINT
    form's with them) unless ``data.library_trig``."""
    cos1, sin1, cos2, sin2 = data.trig
    nominal = data.nominal
    sines = _sincos(data.library_trig)
    (s1, c1), (s2, c2) = sines(a1 - nominal[:, 0]), sines(a2 - nominal[:, 1])
    return SkyPoint(
        a1, a2, sin1 * c1 + cos1 * s1, cos1 * c1 - sin1 * s1, sin2 * c2 + cos2 * s2, cos2 * c2 - sin2 * s2
    )


def _sky_offsets(model: Model, point: SkyPoint):
    """The sum of the terms' sky offsets at ``point`` (arrays ``(n,)``), ``(n, 2)``."""
    total = None
    for term in model.terms:
        off, batched = _per_observation(term.sky_offset_at, point)
        if off is not None:
            off = off if batched else jnp.broadcast_to(off, (point.az.shape[0], 2))
            total = off if total is None else total + off
    return total


def _sincos(library_trig: bool):
    """``x -> (sin x, cos x)``: XLA's library functions when ``library_trig``
    (:attr:`SiteData.library_trig`), else :func:`pointax.core.trig.sincos`."""
    return (lambda x: (jnp.sin(x), jnp.cos(x))) if library_trig else sincos


def _sky_position(model: Model, start, data: SiteData):
    """:meth:`pointax.Model.sky_position` over a site, from the chain's angles ``start``
    ``(n, 2)``: the same fixed-point iterations (a loop, as there: unrolled, they tripled
    the compilation), with :func:`_sky_point`'s sines and cosines, on the two angles as
    separate ``(n,)`` arrays (carried as one ``(n, 2)`` array, the loop ran at half the
    speed)."""
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


def _tpoint_site_residuals(model: Model, data: SiteData) -> tuple[Array, Array]:
    """TPOINT's residuals ``(dA cos E, dE)`` unweighted (see :func:`pointax.residuals`):
    the linear sky terms from their precomputed unit offsets, the others evaluated at
    the observed angles."""
    if data.observed is None:
        raise ValueError("this SiteData was built for residual_form='sky': rebuild it with the model")
    angles, _ = _corrected(model, data.nominal)
    if _rotated(model, angles):
        v, angles = chain_pointing(model, data)
        chain = jax.vmap(model.mount.angles_of)(jnp.stack(v, axis=-1), angles)
    else:
        chain = angles  # no rotation term in the chain: the angles are where it points
    a1, a2, cos2 = data.observed
    d1, d2 = a1 - chain[:, 0], a2 - chain[:, 1]
    linear = _linear_sky_parameters(model)
    if data.sky_basis is None:
        raise ValueError("this SiteData has no unit offsets: complete it with with_sky_basis (or use site_data)")
    if len(linear) != len(data.sky_basis):
        raise ValueError("this SiteData was built for another model: rebuild it with the model")
    for (index, field), (u1, u2) in zip(linear, data.sky_basis):
        c = getattr(model.terms[index], field)
        d1, d2 = d1 - c * u1, d2 - c * u2
    observed = None
    for term in model.terms:
        if term.linear_sky_offset:
            continue
        if observed is None:
            observed = jnp.stack([a1, a2], axis=-1)
        off, _ = _per_observation(term.sky_offset, observed)
        if off is not None:
            d1, d2 = d1 - off[..., 0], d2 - off[..., 1]
    return wrap_pi(d1) * cos2, wrap_pi(d2)  # both wrapped, as pointax.residuals (an over-the-pole axis 2)


def _boresight(mount) -> list:
    """The mount's boresight as three entries (:func:`constant_entries`)."""
    return constant_entries(lambda: mount.boresight)


def _in_mount_frame(mount, v: Float[Array, "n 3"]) -> Float[Array, "n 3"]:
    """``v @ mount.frame`` entry by entry: the frame is usually a constant signed
    permutation, and XLA on the CPU runs even a product with the identity as a library
    call."""
    frame = constant_entries(lambda: mount.frame)
    components = [v[:, i] for i in range(3)]
    return jnp.stack([value(dot([frame[i][j] for i in range(3)], components)) for j in range(3)], axis=-1)


def site_residuals(model: Model, data: SiteData, weighted: bool = True) -> tuple[Array, Array]:
    """Observed minus model in the tangent plane, ``(cross-elevation, elevation)`` as two
    ``(n,)`` arrays (radians), times the square roots of the normalised weights unless
    ``weighted=False``; 0 for unused observations. The model's ``residual_form`` picks
    which residuals (see :func:`pointax.residuals`).

    A nested ``jax.jit``: a fit evaluates this function and a forward derivative of it
    per parameter, at every step; through the jit it is traced from Python once per
    model structure and data shape, and JAX differentiates the traced program (tracing
    it ~14 times cost most of a batched fit's 2 s of tracing)."""
    return _site_residuals_jit(model, data, weighted)


def _site_residuals(model: Model, data: SiteData, weighted: bool) -> tuple[Array, Array]:
    if model.residual_form == "tpoint":
        rx, ry = _tpoint_site_residuals(model, data)
    else:
        rx, ry = tangent_offsets(site_pointing(model, data), data.target_trig)
    scale = data.sqrt_weight if weighted else 1.0
    return jnp.where(data.used, rx * scale, 0.0), jnp.where(data.used, ry * scale, 0.0)


def tangent_offsets(pointing, target_trig) -> tuple[Array, Array]:
    """The sky form's residuals, observed minus model in the tangent plane of the target:
    ``pointing`` three ``(n,)`` arrays (mount frame), ``target_trig`` as in :class:`SiteData`."""
    x, y, z = pointing
    ca, sa, ce, se = target_trig
    # target (ce sa, ce ca, se); e_az (ca, -sa, 0); e_el (-se sa, -se ca, ce)
    horizontal = x * sa + y * ca
    inv_depth = 1.0 / (ce * horizontal + se * z)
    return (y * sa - x * ca) * inv_depth, (se * horizontal - ce * z) * inv_depth


_site_residuals_jit = jax.jit(_site_residuals, static_argnums=2)

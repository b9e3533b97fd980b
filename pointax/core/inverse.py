"""Encoder commands for wanted directions: the inverse of a pointing model.

:func:`command` finds, for each wanted direction ``d`` (East-North-Up unit vector), the
raw reading ``r`` of the two axes with ``model.direction(r) = d``. It solves the two
equations ``tangent_offset(model.direction(r), d) = 0`` (the tangent-plane offset, in
radians, of where the model points from where it should) with optimistix's Newton
root finder, Jacobian by JAX, batched with ``vmap`` over directions under one
``jit``. Sky offsets (TPOINT's linear form) and large encoder zeros are handled alike:

1. The nominal inverse ``mount.angles_of(F^T d)`` gives the error-free axis angles of
   both mechanical solutions, *normal* ``(a1, a2)`` with ``cos a2 >= 0`` and
   *flipped* ("over the top") ``(a1 + pi, pi - a2)``.
2. The terms' encoder corrections are undone by a fixed-point iteration (exact for
   constant zeros such as IA, IE, alpha0, beta0, however large) and the mount turns
   angles into raw readings (:meth:`pointax.Mount.readings_of`).
3. Each axis is put on the branch (``2 pi k`` shifts) that lies inside ``limits``;
   where several do, the one nearest ``near`` if given, else the one nearest the
   middle of the limits (without limits: axis 1 nearest 0, axis 2 unshifted).
4. Newton from there; the branch rule is applied once more to the converged reading
   (a shift by whole turns is kept only if the model still points at ``d`` there,
   so models that are not periodic in the readings stay on the Newton branch).
5. ``solution`` picks between the two mechanical solutions.

Nothing raises for a bad direction: each gets ``ok`` and a reason
(:meth:`Command.reasons`), and the other directions are unaffected.

Gradients: the reading is differentiable with respect to the model's parameters and
the direction (implicit differentiation through ``optx.root_find``); ``residual`` is a
diagnostic and carries no gradient.
"""

from __future__ import annotations

import functools
import itertools
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx
from jaxtyping import Array, ArrayLike, Bool, Float, Int

from . import xla_options
from .padding import power_of_two
from .precision import float64
from .model import Model
from .rotations import angle_between, tangent_offset
from .units import angles_in_radians, check_unit_vectors, directions_enu, is_quantity

__all__ = ["LIMIT_TURNS", "OPPOSITE_TOL", "SOLUTIONS", "ZENITH_TOL", "Command", "command", "command_reflector", "limits_array", "reflect_normal"]

SOLUTIONS = ("nearest", "normal", "flipped")
"""Values of ``command(..., solution=...)``."""

OPPOSITE_TOL = 1e-9
""":func:`reflect_normal` gives NaN where ``|sun + target|`` (about the angle by which
the two miss being exactly opposite, radians) is at most this."""

# Per-direction status codes (Command.status). Codes below 8 exclude each other; the
# two limit bits may be set together.
_OK = 0
_NON_FINITE = 1
_NOT_CONVERGED = 2
_OPPOSITE = 3
_NO_FLIP = 4
_AXIS1_OUT = 8  # bit
_AXIS2_OUT = 16  # bit

ZENITH_TOL = 1e-3
"""Without ``near``, :func:`command` returns the flipped solution in place of a failed
normal one only where the flipped reading's axis-2 angle is within this (as cos of
the angle, about 0.06 deg) of the pole of axis 1, where the two are the same pointing."""

_TWO_PI = 2.0 * np.pi
# A safe direction solved in place of a non-finite one (its result is discarded).
_SAFE = np.array([0.0, np.sqrt(0.5), np.sqrt(0.5)])
# Branch shifts (whole turns of axis 1, axis 2) tried for the Newton start and for
# the converged reading.
_START_SHIFTS = np.array(list(itertools.product(range(-2, 3), range(-1, 2))), float)
_FINAL_SHIFTS = np.array(list(itertools.product(range(-1, 2), range(-1, 2))), float)
# Smallest padded batch (see command): every batch up to 64 directions runs one program
# (a compilation takes seconds; 64 directions solve as fast as 8).
_MIN_BATCH = 64
# Fixed-point iterations undoing encoder corrections for the Newton start.
_ENCODER_ITERATIONS = 3


class Command(eqx.Module):
    """Encoder commands from :func:`command` (a pytree; batch shape ``...`` is that of
    the directions).

    Attributes:
        reading: ``(..., 2)`` raw readings of the two axes (the mount's reading units,
            radians for angle encoders). Filled even where ``ok`` is False (the best
            attempt, e.g. where an out-of-limits solution would be); NaN for a
            non-finite direction.
        ok: ``(...,)`` whether the reading points at the direction (within
            ``10 * tol``) and lies inside the limits.
        residual: ``(...,)`` angle (radians) between ``model.direction(reading)`` and
            the wanted direction.
        iterations: ``(...,)`` Newton steps taken.
        solution: ``(...,)`` 0 for the normal mechanical solution, 1 for the flipped
            one ("over the top": axis 1 + pi, pi - axis 2).
        status: ``(...,)`` integer reason code; see :meth:`reasons` for words.
        limits: ``(2, 2)`` the limits used (``-inf``/``inf`` where none).
        axis_names: the mount's names for its axes.
    """

    reading: Float[Array, "*batch 2"]
    ok: Bool[Array, "*batch"]
    residual: Float[Array, "*batch"]
    iterations: Int[Array, "*batch"]
    solution: Int[Array, "*batch"]
    status: Int[Array, "*batch"]
    limits: Float[Array, "2 2"]
    axis_names: tuple[str, str] = eqx.field(static=True, default=("axis1", "axis2"))

    @property
    def shape(self) -> tuple[int, ...]:
        """Batch shape (that of the directions without their last axis)."""
        return tuple(self.ok.shape)

    def reasons(self) -> list[str]:
        """Why each direction is not ``ok``, in words ('' where it is), flattened in
        row-major (C) order: ``"non-finite direction"``, ``"sun and target are
        opposite: mirror normal undefined"``, ``"did not converge"``, ``"no flipped
        solution..."`` (a mount that cannot go over the top, such as a heliostat's
        linear actuators) or ``"out of limits: axis 2 (el) reading 1.7 rad outside
        [0, 1.5708]"``."""
        status = np.asarray(self.status).reshape(-1)
        reading = np.asarray(self.reading).reshape(-1, 2)
        residual = np.asarray(self.residual).reshape(-1)
        limits = np.asarray(self.limits)
        out = []
        for s, r, res in zip(status, reading, residual):
            s = int(s)
            if s == _OK:
                out.append("")
            elif s == _NON_FINITE:
                out.append("non-finite direction")
            elif s == _OPPOSITE:
                out.append("sun and target are opposite: mirror normal undefined")
            elif s == _NOT_CONVERGED:
                out.append(f"did not converge (residual {res:.3g} rad)")
            elif s == _NO_FLIP:
                out.append("no flipped solution: it gives the same reading as the normal one")
            else:
                parts = []
                for axis, bit in ((0, _AXIS1_OUT), (1, _AXIS2_OUT)):
                    if s & bit:
                        lo, hi = limits[axis]
                        parts.append(
                            f"axis {axis + 1} ({self.axis_names[axis]}) reading {r[axis]:.6g} rad "
                            f"outside [{lo:.6g}, {hi:.6g}]"
                        )
                out.append("out of limits: " + "; ".join(parts))
        return out


# ---------------------------------------------------------------------- helpers


def _offset(reading, args):
    """The equations solved: where the model points, offset from the wanted direction."""
    model, target = args
    return tangent_offset(model.direction(reading), target)


def _readings_for(model: Model, angles: Array) -> Array:
    """Raw reading whose corrected axis angles (after the terms' encoder corrections)
    are ``angles``: a fixed-point iteration, exact at once for constant offsets."""
    mount = model.mount
    nominal = angles
    for _ in range(_ENCODER_ITERATIONS):
        nominal = nominal + (angles - model.corrected_encoder(mount.readings_of(nominal)))
    return mount.readings_of(nominal)


def _centre(limits, near, has_near, base):
    """Reading around which branch candidates are generated, per axis."""
    lo, hi = limits[:, 0], limits[:, 1]
    flo, fhi = jnp.isfinite(lo), jnp.isfinite(hi)
    free = jnp.where(has_near, near, base.at[0].set(0.0))
    mid = jnp.where(flo & fhi, 0.5 * (jnp.where(flo, lo, 0.0) + jnp.where(fhi, hi, 0.0)), free)
    mid = jnp.where(flo & ~fhi, jnp.where(flo, lo, 0.0) + np.pi, mid)
    return jnp.where(~flo & fhi, jnp.where(fhi, hi, 0.0) - np.pi, mid)


def _pick(cands, limits, near, has_near, pref):
    """Index of the candidate reading (rows of ``cands``) chosen by the branch rule:
    inside the limits, then nearest ``near`` if given, else nearest the middle of the
    limits (an axis limited at one end: half a turn inside that end) or, on an axis
    without limits, nearest ``pref``. With none inside, the least out of limits."""
    lo, hi = limits[:, 0], limits[:, 1]
    valid = jnp.all((cands >= lo) & (cands <= hi), axis=-1)
    # Without ``near``: nearest the middle of the limits (axis 1 of a cable wrap
    # -270..270 deg commands azimuth 90 deg to 90, not -270), else nearest ``pref``.
    target = jnp.where(has_near, near, _centre(limits, near, False, pref))
    score = jnp.sum(jnp.abs(cands - target), axis=-1)
    violation = jnp.sum(jnp.maximum(lo - cands, 0.0) + jnp.maximum(cands - hi, 0.0), axis=-1)
    best = jnp.argmin(jnp.where(valid, score, jnp.inf))
    least_bad = jnp.argmin(violation)
    return jnp.where(jnp.any(valid), best, least_bad)


def _starts(model: Model, d, near, has_near, limits):
    """Newton starts ``(2, 2)`` (normal, flipped) and the base readings used as the
    branch preference where there are no limits and no ``near``."""
    mount = model.mount
    a = mount.angles_of(mount.frame.T @ d, jnp.zeros(2, d.dtype))
    # Normalise to the normal solution: cos(axis 2) >= 0.
    flip = jnp.cos(a[1]) < 0
    normal = jnp.where(flip, jnp.stack([a[0] - np.pi, np.pi - a[1]]), a)
    flipped = jnp.stack([normal[0] + np.pi, np.pi - normal[1]])
    starts, prefs = [], []
    for c in (normal, flipped):
        base = _readings_for(model, c)
        k0 = jnp.round((_centre(limits, near, has_near, base) - base) / _TWO_PI)
        cands = jax.vmap(lambda k, c=c: _readings_for(model, c + _TWO_PI * k))(k0 + _START_SHIFTS)
        pref = base.at[0].set(0.0)
        starts.append(cands[_pick(cands, limits, near, has_near, pref)])
        prefs.append(pref)
    return jnp.stack(starts), jnp.stack(prefs)


def _newton(model: Model, start, target, tol: float, max_steps: int):
    solver = optx.Newton(rtol=tol, atol=tol, linear_solver=lx.AutoLinearSolver(well_posed=False))
    sol = optx.root_find(_offset, solver, start, (model, target), max_steps=max_steps, throw=False)
    return sol.value, sol.stats["num_steps"]


def _settle(model: Model, reading, target, near, has_near, limits, pref, tol: float):
    """Apply the branch rule to a converged reading; status bits and residual."""
    # Whole turns back towards the preferred branch first: near the pole of axis 1 (the
    # zenith of an alt-az mount) Newton may wander many turns along axis 1.
    turns = jnp.round((_centre(limits, near, has_near, pref) - reading) / _TWO_PI)
    turns = jnp.where(jnp.isfinite(turns), turns, 0.0)
    cands = reading + _TWO_PI * (turns + _FINAL_SHIFTS)
    shifted = cands[_pick(cands, limits, near, has_near, pref)]
    sg = jax.lax.stop_gradient
    res = angle_between(model.direction(sg(reading)), sg(target))
    res_shifted = angle_between(model.direction(sg(shifted)), sg(target))
    use = res_shifted <= 10.0 * tol
    reading = jnp.where(use, shifted, reading)
    res = jnp.where(use, res_shifted, res)
    converged = jnp.all(jnp.isfinite(reading)) & (res <= 10.0 * tol)
    lo, hi = limits[:, 0], limits[:, 1]
    out = (reading < lo) | (reading > hi)
    status = jnp.where(
        converged,
        jnp.where(out[0], _AXIS1_OUT, 0) + jnp.where(out[1], _AXIS2_OUT, 0),
        _NOT_CONVERGED,
    )
    return reading, res, status


@functools.cache
def _command_program():
    """:func:`_command_flat` compiled with the quicker compiler options
    (:mod:`pointax.core.xla_options`: about half the compile time, the same speed):
    ``program(arrays, structure, tol, max_steps)``, the arguments split by
    ``eqx.partition(..., eqx.is_array)`` (the readings as ``(name, values)`` pairs: a
    static part must be hashable)."""

    def run(arrays, structure, tol, max_steps):
        model, d, near, has_near, limits, solution, values = eqx.combine(arrays, structure)
        return _command_flat(model, d, near, has_near, limits, tol, max_steps, solution, dict(values))

    return xla_options.jit(run, static_argnums=(1, 2, 3))


def _command_flat(model: Model, d, near, has_near, limits, tol: float, max_steps: int, solution: Array, values=None):
    """The solve for ``(n, 3)`` directions; see :func:`command` (compiled by
    :func:`_command_program`). ``near`` is ``(n, 2)`` and used only where the scalar
    ``has_near`` is True, ``solution`` is the index into :data:`SOLUTIONS`: both are
    traced, so they do not cause recompiling.
    ``values``: the auxiliary readings the model reads, name -> ``(n,)`` (``{}`` for
    a model that reads none); each direction is solved with the model bound to its own
    (:meth:`pointax.Model.at_readings`)."""
    values = {} if values is None else values
    at = model.at_readings
    n = d.shape[0]
    finite = jnp.all(jnp.isfinite(d), axis=-1)
    norm = jnp.linalg.norm(jnp.where(finite[:, None], d, 0.0), axis=-1)
    good = finite & (norm > 0)
    safe_norm = jnp.where(good, norm, 1.0)[:, None]
    target = jnp.where(good[:, None], d / safe_norm, jnp.asarray(_SAFE, d.dtype))

    starts, prefs = jax.vmap(lambda t, m, v: _starts(at(v), t, m, has_near, limits))(target, near, values)
    # One batched Newton solve over both mechanical solutions of every direction.
    targets2 = jnp.repeat(target, 2, axis=0)
    near2 = jnp.repeat(near, 2, axis=0)
    values2 = {k: jnp.repeat(v, 2, axis=0) for k, v in values.items()}
    readings, steps = jax.vmap(lambda s, t, v: _newton(at(v), s, t, tol, max_steps))(
        starts.reshape(2 * n, 2), targets2, values2
    )
    readings, residuals, status = jax.vmap(lambda r, t, m, p, v: _settle(at(v), r, t, m, has_near, limits, p, tol))(
        readings, targets2, near2, prefs.reshape(2 * n, 2), values2
    )
    readings = readings.reshape(n, 2, 2)
    residuals = residuals.reshape(n, 2)
    status = status.reshape(n, 2)
    # A mount that cannot go over the top (linear actuators, whose reading of an angle
    # does not tell it from its mirror image) solves "flipped" back to the normal
    # reading: there is no distinct second solution.
    same = jnp.all(jnp.abs(readings[:, 1] - readings[:, 0]) <= 1e-6 * (1.0 + jnp.abs(readings[:, 0])), axis=-1)
    status = status.at[:, 1].set(jnp.where(same & (status[:, 1] != _NOT_CONVERGED), _NO_FLIP, status[:, 1]))
    steps = steps.reshape(n, 2)
    ok2 = status == _OK

    # solution: 0 "nearest", 1 "normal", 2 "flipped" (a traced code: no recompiling).
    dist = jnp.sum(jnp.abs(readings - near[:, None, :]), axis=-1)
    prefer = jnp.where(has_near & (dist[:, 1] < dist[:, 0]), 1, 0)
    other = 1 - prefer
    ok_prefer = jnp.take_along_axis(ok2, prefer[:, None], axis=1)[:, 0]
    ok_other = jnp.take_along_axis(ok2, other[:, None], axis=1)[:, 0]
    # Without ``near`` the normal solution is returned where it exists, ok or not (with
    # its reason): the flipped one takes its place only where the normal one is out of
    # the limits given, where the model cannot be evaluated at it (NaN: a term's pole,
    # such as TX's cot E at E = 0 exactly), or where the flipped reading is the normal
    # one in all but name (within ZENITH_TOL of the pole of axis 1, at the zenith,
    # where the normal Newton solve meets a singular Jacobian). A normal solve that
    # merely did not converge (near the horizon of a model with a cot E term) is
    # reported as such, never replaced by the flipped one.
    flipped_angles = jax.vmap(lambda r, v: at(v).corrected_encoder(r))(
        jnp.where(jnp.isfinite(readings[:, 1]), readings[:, 1], 0.0), values
    )
    at_pole = jnp.cos(flipped_angles[:, 1]) >= -ZENITH_TOL
    normal_status = status[:, 0]
    out_of_limits = (normal_status & (_AXIS1_OUT | _AXIS2_OUT)) != 0
    unevaluable = ~jnp.all(jnp.isfinite(readings[:, 0]), axis=-1) | ~jnp.isfinite(residuals[:, 0])
    fallback = has_near | ((prefer == 0) & (at_pole | out_of_limits | unevaluable))
    nearest = jnp.where(fallback & ~ok_prefer & ok_other, other, prefer)
    pick = jnp.where(solution == 0, nearest, solution - 1)

    def take(x):
        idx = pick.reshape((n, 1) + (1,) * (x.ndim - 2))
        return jnp.take_along_axis(x, idx, axis=1)[:, 0]

    reading = jnp.where(good[:, None], take(readings), jnp.nan)
    residual = jnp.where(good, take(residuals), jnp.nan)
    status = jnp.where(good, take(status), _NON_FINITE)
    iterations = jnp.where(good, take(steps), 0)
    return reading, status == _OK, residual, iterations, pick, status


LIMIT_TURNS = 2.0
"""Limits beyond this many turns (4 pi rad) in magnitude are refused: they are degrees
given where radians are expected."""


def _limit_value(x, axis: int, end: str) -> float:
    """One end of an axis limit in radians (a Quantity converted, a bare number as it is)."""
    name = f"limits: axis {axis + 1} {end}"
    value = angles_in_radians(x, name)
    if value.shape != ():
        raise ValueError(f"{name} must be one number, got shape {value.shape}")
    value = float(value)
    if math.isnan(value):
        raise ValueError(f"{name} is NaN (use None for no limit)")
    if math.isfinite(value) and abs(value) > LIMIT_TURNS * _TWO_PI:
        raise ValueError(
            f"{name} is {value:g} rad, beyond {LIMIT_TURNS:g} turns: it looks like degrees; limits are in "
            "reading units (radians for angle encoders): use px.deg(x) or an astropy Quantity"
        )
    return value


def limits_array(limits) -> Array:
    """``((lo1, hi1), (lo2, hi2))`` with None for "no limit" -> ``(2, 2)`` float64.

    Raises:
        ValueError: for a bad shape, NaN, an inverted axis (min above max) or a limit
            beyond :data:`LIMIT_TURNS` turns (degrees given for radians)."""
    if limits is None:
        limits = (None, None)
    if is_quantity(limits):
        limits = angles_in_radians(limits, "limits").tolist()
    if len(limits) != 2:
        raise ValueError(f"limits: expected ((axis1_min, axis1_max), (axis2_min, axis2_max)), got {limits!r}")
    rows = []
    for k, axis in enumerate(limits):
        if axis is None:
            axis = (None, None)
        if len(axis) != 2:
            raise ValueError(f"limits: axis {k + 1}: each axis limit must be (min, max) or None, got {axis!r}")
        lo = -np.inf if axis[0] is None else _limit_value(axis[0], k, "min")
        hi = np.inf if axis[1] is None else _limit_value(axis[1], k, "max")
        if lo > hi:
            raise ValueError(f"limits: axis {k + 1} is inverted: min {lo:g} rad is above max {hi:g} rad")
        rows.append(jnp.stack([jnp.asarray(lo, float), jnp.asarray(hi, float)]))
    return jnp.stack(rows)


def _command_readings(model: Model, readings, batch: tuple[int, ...], xp=jnp) -> dict:
    """The readings ``model`` reads, each ``(prod(batch),)`` float64 (``{}`` for a model
    that reads none), as ``xp`` arrays (NumPy or jax.numpy); ValueError naming the
    missing ones or a wrong shape."""
    if not model.readings:
        return {}
    readings = {} if readings is None else readings
    missing = [n for n in model.readings if n not in readings]
    if missing:
        raise ValueError(
            f"the model reads {', '.join(map(repr, missing))}: give their values at the time of the command "
            f"with readings={{...}} (given: {sorted(readings) or 'none'})"
        )
    out = {}
    for name in model.readings:
        value = xp.asarray(readings[name], float)
        try:
            value = xp.broadcast_to(value, batch)
        except ValueError:
            raise ValueError(
                f"reading {name!r} has shape {value.shape}; expected a scalar or the directions' batch shape {batch}"
            ) from None
        out[name] = value.reshape(-1)
    return out


# ---------------------------------------------------------------------- public API


@float64
def command(
    model: Model,
    direction: Float[ArrayLike, "*batch 3"],
    *,
    solution: str = "nearest",
    near: Float[ArrayLike, "*batch 2"] | None = None,
    limits=None,
    tol: float = 1e-12,
    max_steps: int = 50,
    readings=None,
) -> Command:
    """Raw encoder readings that point ``model`` at ``direction`` (the model's inverse).

    Args:
        model: the pointing model (:class:`pointax.Model`).
        direction: ``(..., 3)`` wanted directions, East-North-Up (normalised here; a
            non-finite or zero vector gives ``ok=False``, "non-finite direction"); or
            an astropy ``SkyCoord`` in ``AltAz``, or a ``(..., 2)`` Quantity of azimuth
            (North through East) and elevation.
        solution: ``"normal"`` (the mount's axis-2 angle, after encoder corrections,
            within 90 deg of its zero: for an alt-az mount elevation in [-90, 90] deg),
            ``"flipped"`` (over the top: axis 1 + 180 deg, axis 2 = 180 deg -
            elevation) or ``"nearest"`` (of those that are ``ok``, the one nearer
            ``near``; where neither is ok, that one is returned with its reason).
            Without ``near``, ``"nearest"`` is ``"normal"``: the normal solution is
            returned even where it is not ok (near the horizon of a model with a
            cot E term, for instance), never the flipped one in its place.
        near: ``(2,)`` or ``(..., 2)`` current readings (reading units): the branch of
            each axis (whole-turn shifts) and, for ``"nearest"``, the mechanical
            solution nearest them are chosen. Distances are summed over the two axes.
        limits: ``((axis1_min, axis1_max), (axis2_min, axis2_max))`` in reading units
            (radians for angle encoders), None for an axis (or the whole) without
            limits; e.g. ``((0, 2 pi), None)`` for a turntable's azimuth encoder or
            ``((-1.5 pi, 1.5 pi), (0, pi / 2))`` for a telescope's cable wrap. Each
            axis is put on the branch (shifts by 2 pi) inside its limits: of several,
            the one nearest ``near``, else the one nearest the middle of the limits
            (a cable wrap of -270..270 deg commands azimuth 90 deg to about 90, not
            -270). A direction that cannot be
            reached inside them gets ``ok=False`` and an "out of limits" reason.
            Whole-turn candidates are searched within about +-2.5 turns of the middle
            of the limits. Astropy Quantities are converted; an inverted axis (min
            above max) or a limit beyond two turns (degrees given as radians) raises
            ``ValueError``.
        tol: Newton tolerance (radians) on the tangent-plane offset and the step; a
            result counts as converged when its residual is at most ``10 * tol``.
            Directions the model cannot reach at all (e.g. within ``|CA|`` of the
            zenith of an alt-az mount with collimation error) report "did not
            converge".
        max_steps: most Newton steps.
        readings: for a model that reads auxiliary readings (:attr:`pointax.Model.readings`):
            their values at the time of the command, a mapping name -> a scalar or an
            array of the batch shape ``direction.shape[:-1]`` (each direction solved
            with its own). Others are ignored; a missing one raises ``ValueError``.

    Returns:
        A :class:`Command` with batch shape ``direction.shape[:-1]``.

    Raises:
        ValueError: for an unknown ``solution``, badly shaped ``direction``, ``near``
            or ``limits``, inverted limits or limits that look like degrees.
    """
    if solution not in SOLUTIONS:
        raise ValueError(f"unknown solution {solution!r}; expected one of {SOLUTIONS}")
    if not is_quantity(direction) and not isinstance(direction, jax.core.Tracer):
        # az/el in degrees where unit vectors belong is named (non-unit vectors are normalised)
        check_unit_vectors(direction, "direction", warn=True, tolerance=1.0)
    # Called outside a trace, the padding and slicing around the compiled solve run in
    # NumPy: JAX would compile each of those small operations again for every new batch
    # size. Inside a caller's jit, vmap or grad the solve is part of the caller's trace.
    traced = any(isinstance(x, jax.core.Tracer) for x in jax.tree.leaves((direction, near, model, readings)))
    xp = jnp if traced else np
    direction = xp.asarray(directions_enu(direction, "direction"), float)
    if direction.ndim < 1 or direction.shape[-1] != 3:
        raise ValueError(f"direction must have shape (..., 3), got {direction.shape}")
    batch = direction.shape[:-1]
    flat = direction.reshape(-1, 3)
    n = flat.shape[0]
    if near is None:
        near_flat = xp.zeros((n, 2))
    else:
        near = xp.asarray(angles_in_radians(near, "near") if is_quantity(near) else near, float)
        if near.shape[-1:] != (2,):
            raise ValueError(f"near must have shape (2,) or (..., 2), got {near.shape}")
        near_flat = xp.broadcast_to(near, batch + (2,)).reshape(-1, 2)
    lim = limits_array(limits)
    values = _command_readings(model, readings, batch, xp)
    # Parameters as arrays, so that jit traces them instead of baking Python floats in
    # (one compilation for every set of values).
    model = model.with_values(model.values())
    # Pad the batch to a power of two: one compilation serves many batch sizes.
    size = power_of_two(n, _MIN_BATCH)
    pad = size - n
    flat = xp.concatenate([flat, xp.broadcast_to(xp.asarray(_SAFE), (pad, 3))])
    near_flat = xp.concatenate([near_flat, xp.zeros((pad, 2))])
    values = {k: xp.concatenate([v, xp.broadcast_to(v[:1], (pad,))]) for k, v in values.items()}
    has_near, choice = xp.asarray(near is not None), xp.asarray(SOLUTIONS.index(solution))
    if traced:
        outputs = _command_flat(model, flat, near_flat, has_near, lim, float(tol), int(max_steps), choice, values)
        shaped = [x[:n].reshape(batch + x.shape[1:]) for x in outputs]
    else:
        arrays, structure = eqx.partition(
            (model, flat, near_flat, has_near, lim, choice, tuple(values.items())), eqx.is_array
        )
        outputs = jax.device_get(_command_program()(arrays, structure, float(tol), int(max_steps)))
        shaped = [jax.device_put(x[:n].reshape(batch + x.shape[1:])) for x in outputs]  # (no compiling)
    reading, ok, residual, iterations, pick, status = shaped
    return Command(
        reading=reading,
        ok=ok,
        residual=residual,
        iterations=iterations,
        solution=pick,
        status=status,
        limits=lim,
        axis_names=tuple(model.mount.axis_names),
    )


def _unit(v: Array) -> Array:
    return v / jnp.linalg.norm(v, axis=-1, keepdims=True)


def _opposite(sun: Array, target: Array) -> tuple[Array, Array]:
    """Bisector sum and the mask of (finite) exactly-opposite pairs."""
    s, t = _unit(sun), _unit(target)
    b = s + t
    nb = jnp.linalg.norm(b, axis=-1)
    opposite = jnp.all(jnp.isfinite(b), axis=-1) & (nb <= OPPOSITE_TOL)
    return b / nb[..., None], opposite


@float64
def reflect_normal(sun: Float[ArrayLike, "*batch 3"], target: Float[ArrayLike, "*batch 3"]) -> Float[Array, "*batch 3"]:
    """Mirror normal that reflects light from the ``sun`` direction towards ``target``.

    ``n = (s + t) / |s + t|`` with ``s``, ``t`` the normalised directions (ENU, from
    the mirror towards the sun and towards the target; shapes broadcast). Reflecting
    the sun about it, ``2 (n.s) n - s``, gives ``t``.

    Where sun and target are opposite (``|s + t| <= OPPOSITE_TOL``: the light would
    have to come back through the mirror, and the bisector is undefined) the normal is
    NaN, per direction, not an exception; :func:`command_reflector` reports those as
    "sun and target are opposite".
    """
    sun = jnp.asarray(sun, float)
    target = jnp.asarray(target, float)
    n, opposite = _opposite(sun, target)
    return jnp.where(opposite[..., None], jnp.nan, n)


@float64
def command_reflector(
    model: Model,
    sun: Float[ArrayLike, "*batch 3"],
    target: Float[ArrayLike, "*batch 3"],
    **kwargs,
) -> Command:
    """Commands that turn a mirror (``model``'s boresight is its normal, e.g.
    :func:`pointax.Turntable`) to throw sunlight from ``sun`` onto ``target``:
    ``command(model, reflect_normal(sun, target), **kwargs)``.

    Pairs where sun and target are opposite get ``ok=False`` with the reason "sun and
    target are opposite: mirror normal undefined"; the others are unaffected.
    """
    sun = jnp.asarray(directions_enu(sun, "sun"), float)
    target = jnp.asarray(directions_enu(target, "target"), float)
    sun, target = jnp.broadcast_arrays(sun, target)
    n, opposite = _opposite(sun, target)
    n = jnp.where(opposite[..., None], jnp.nan, n)
    result = command(model, n, **kwargs)
    status = jnp.where(opposite, _OPPOSITE, result.status)
    return eqx.tree_at(lambda c: c.status, result, status)

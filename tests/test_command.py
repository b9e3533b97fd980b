"""Tests for pointax.command: the inverse of a pointing model."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pointax as px
from pointax.core.errors import InputWarning
from pointax.core.inverse import Command, command, command_reflector, reflect_normal
from pointax.core.rotations import angle_between, azel_to_enu

DEG = np.pi / 180
ARCSEC = DEG / 3600
N = 200
ROUND_TRIP_TOL = 1e-9  # rad


def _directions(seed: int, n: int, el_min: float, el_max: float) -> np.ndarray:
    rng = np.random.default_rng(seed)
    az = rng.uniform(0.0, 2 * np.pi, n)
    # Uniform on the sphere between the two elevations.
    el = np.arcsin(rng.uniform(np.sin(el_min * DEG), np.sin(el_max * DEG), n))
    return np.array(azel_to_enu(az, el))


@eqx.filter_jit
def _forward(model, reading):
    return jax.vmap(model.direction)(reading)


def _error(model, reading, direction) -> np.ndarray:
    return np.asarray(angle_between(_forward(model, reading), direction))


def _turntable(values) -> px.Model:
    return px.Turntable("full").with_values(jnp.asarray(values, float))


def _altaz(form: str, values) -> px.Model:
    model = px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX", form=form))
    return model.with_values(jnp.asarray(values, float))


small = st.floats(-0.1, 0.1)  # degrees
zero = st.floats(-360.0, 360.0)  # degrees
tpoint_coef = st.floats(-300.0, 300.0)  # arcsec


# ------------------------------------------------------------------ round trips


@settings(max_examples=6, deadline=None)
@given(tilts=st.tuples(small, small, small), zeros=st.tuples(zero, zero), seed=st.integers(0, 2**31))
def test_round_trip_turntable(tilts, zeros, seed):
    model = _turntable(np.radians([*tilts, *zeros]))
    # The turntable's pitch reaches below the horizon too.
    d = _directions(seed, N, -60.0, 85.0)
    c = command(model, d)
    assert bool(jnp.all(c.ok)), set(c.reasons())
    assert np.max(_error(model, c.reading, d)) < ROUND_TRIP_TOL
    assert np.max(np.asarray(c.residual)) < ROUND_TRIP_TOL
    assert np.all(np.asarray(c.solution) == 0)


@pytest.mark.parametrize("form", ["rigorous", "linear"])
@settings(max_examples=5, deadline=None)
@given(coefs=st.tuples(*[tpoint_coef] * 8), seed=st.integers(0, 2**31))
def test_round_trip_altaz(form, coefs, seed):
    model = _altaz(form, np.asarray(coefs) * ARCSEC)
    # The linear form has poles at the horizon (TX) and the zenith (CA, NPAE, AN, AW).
    d = _directions(seed, N, 5.0, 85.0)
    c = command(model, d)
    assert bool(jnp.all(c.ok)), set(c.reasons())
    err = _error(model, c.reading, d)
    assert np.max(err) < ROUND_TRIP_TOL
    assert np.max(np.asarray(c.iterations)) <= 10


def test_perfect_mount_is_nominal_inverse():
    model = _altaz("rigorous", np.zeros(8))
    az = np.radians([10.0, 100.0, 200.0, 350.0])
    el = np.radians([5.0, 30.0, 60.0, 89.0])
    c = command(model, azel_to_enu(az, el))
    np.testing.assert_allclose(c.reading[:, 0] % (2 * np.pi), az, atol=1e-12)
    np.testing.assert_allclose(c.reading[:, 1], el, atol=1e-12)


def test_zenith_of_a_perfect_mount():
    # Every azimuth points at the zenith: the Jacobian is singular there.
    model = _altaz("rigorous", np.zeros(8))
    c = command(model, np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]))
    assert bool(jnp.all(c.ok))
    np.testing.assert_allclose(c.reading[0, 1], np.pi / 2, atol=1e-12)
    assert np.max(np.asarray(c.residual)) < 1e-12


# ------------------------------------------------------------------ azimuth wrap


def test_turntable_azimuth_wrap_inside_limits():
    # alpha0 = 0: readings of directions near azimuth 0 lie near 0 and 2 pi.
    model = _turntable(np.radians([0.1, -0.08, 0.1, 0.0, 3.0]))
    az = np.concatenate([np.geomspace(1e-9, 0.05, 100), -np.geomspace(1e-9, 0.05, 99), [0.0]])
    el = np.linspace(0.0, 1.2, az.size)
    d = np.asarray(azel_to_enu(az, el))
    c = command(model, d, limits=((0.0, 2 * np.pi), None))
    assert bool(jnp.all(c.ok)), set(c.reasons())
    r = np.asarray(c.reading)
    assert np.all((r[:, 0] >= 0.0) & (r[:, 0] <= 2 * np.pi))
    assert np.max(_error(model, r, d)) < ROUND_TRIP_TOL
    # Both ends of the range are used.
    assert np.any(r[:, 0] < 0.1) and np.any(r[:, 0] > 2 * np.pi - 0.1)
    # Same directions, other window: the same physical settings, other branch.
    c2 = command(model, d, limits=((-np.pi, np.pi), None))
    assert bool(jnp.all(c2.ok))
    r2 = np.asarray(c2.reading)
    assert np.all(np.abs(r2[:, 0]) <= np.pi)
    np.testing.assert_allclose(np.cos(r2[:, 0]), np.cos(r[:, 0]), atol=1e-12)


def test_cable_wrap_branch_nearest_near():
    model = _altaz("rigorous", np.array([20, -30, 10, 15, 5, -8, 12, 3]) * ARCSEC)
    limits = ((-1.5 * np.pi, 1.5 * np.pi), (0.0, np.pi / 2))
    az = np.radians([100.0, 100.0, 100.0, 250.0, -100.0])
    d = np.asarray(azel_to_enu(az, np.full(az.shape, np.radians(45.0))))
    near = np.radians([[-200.0, 45.0], [50.0, 45.0], [260.0, 10.0], [-100.0, 45.0], [250.0, 45.0]])
    c = command(model, d, near=near, limits=limits)
    assert bool(jnp.all(c.ok)), c.reasons()
    expected = np.radians([-260.0, 100.0, 100.0, -110.0, 260.0])
    np.testing.assert_allclose(np.asarray(c.reading[:, 0]), expected, atol=0.01)
    assert np.max(_error(model, c.reading, d)) < ROUND_TRIP_TOL
    # Without near: the branch nearest the middle of the limits (issue 30).
    c = command(model, d, limits=limits)
    np.testing.assert_allclose(np.asarray(c.reading[:, 0]), np.radians([100.0, 100, 100, -110, -100]), atol=0.01)
    # One near for every direction broadcasts.
    c = command(model, d, near=np.radians([200.0, 45.0]), limits=limits)
    np.testing.assert_allclose(np.asarray(c.reading[:, 0]), np.radians([100.0, 100, 100, 250, 260]), atol=0.01)


def test_no_window_reaches():
    model = _altaz("rigorous", np.zeros(8))
    d = np.asarray(azel_to_enu(np.radians([10.0, 200.0]), np.radians([30.0, 30.0])))
    c = command(model, d, limits=((0.0, np.pi), None), solution="normal")
    assert np.asarray(c.ok).tolist() == [True, False]
    reason = c.reasons()[1]
    assert reason.startswith("out of limits: axis 1 (az)"), reason


# ------------------------------------------------------------------ mechanical solutions


def test_two_mechanical_solutions():
    model = _altaz("rigorous", np.array([30, -20, 40, -25, 15, 10, 20, 5]) * ARCSEC)
    d = _directions(1, N, 5.0, 85.0)
    normal = command(model, d, solution="normal")
    flipped = command(model, d, solution="flipped")
    for c, which in ((normal, 0), (flipped, 1)):
        assert bool(jnp.all(c.ok)), set(c.reasons())
        assert np.all(np.asarray(c.solution) == which)
        assert np.max(_error(model, c.reading, d)) < ROUND_TRIP_TOL
    assert np.all(np.asarray(normal.reading[:, 1]) < np.pi / 2)
    assert np.all(np.asarray(flipped.reading[:, 1]) > np.pi / 2)
    # Over the top: azimuth half a turn away, elevation mirrored (to the model's errors).
    np.testing.assert_allclose(
        np.cos(flipped.reading[:, 0] - normal.reading[:, 0]), -1.0, atol=1e-5
    )
    np.testing.assert_allclose(flipped.reading[:, 1], np.pi - normal.reading[:, 1], atol=0.01)

    # Elevation limited to 0..90 deg: only the normal solution is reachable.
    horizon_to_zenith = ((None, None), (0.0, np.pi / 2))
    c = command(model, d, limits=horizon_to_zenith)
    assert bool(jnp.all(c.ok)) and np.all(np.asarray(c.solution) == 0)
    # even when the encoders are near the flipped one.
    c = command(model, d, limits=horizon_to_zenith, near=flipped.reading)
    assert bool(jnp.all(c.ok)) and np.all(np.asarray(c.solution) == 0)
    c = command(model, d, limits=horizon_to_zenith, solution="flipped")
    assert not bool(jnp.any(c.ok))
    assert all(r.startswith("out of limits: axis 2 (el)") for r in c.reasons())

    # Flip-capable range: "nearest" follows near, default is normal.
    over_the_top = ((None, None), (0.0, np.pi))
    c = command(model, d, limits=over_the_top, near=flipped.reading)
    assert bool(jnp.all(c.ok)) and np.all(np.asarray(c.solution) == 1)
    c = command(model, d, limits=over_the_top)
    assert np.all(np.asarray(c.solution) == 0)
    # Only the upper half of the elevation range: "nearest" falls back to flipped.
    c = command(model, d, limits=((None, None), (np.pi / 2, np.pi)))
    assert bool(jnp.all(c.ok)) and np.all(np.asarray(c.solution) == 1)


# ------------------------------------------------------------------ reflector


def test_reflector_perfect_turntable():
    model = _turntable(np.radians([0.0, 0.0, 0.0, 123.0, -7.0]))
    sun = _directions(2, N, 1.0, 89.0)
    target = _directions(3, N, -10.0, 30.0)
    c = command_reflector(model, sun, target)
    assert bool(jnp.all(c.ok)), set(c.reasons())
    n = np.asarray(_forward(model, c.reading))
    reflected = 2 * np.sum(n * sun, axis=-1, keepdims=True) * n - sun
    assert np.max(np.abs(reflected - target)) < 1e-12
    np.testing.assert_allclose(np.asarray(reflect_normal(sun, target)), n, atol=1e-12)


def test_reflector_opposite_sun_and_target():
    model = _turntable(np.radians([0.05, 0.02, -0.03, 10.0, 5.0]))
    sun = _directions(4, 4, 10.0, 80.0)
    target = _directions(5, 4, 0.0, 20.0)
    target[1] = -sun[1]
    normal = np.asarray(reflect_normal(sun, target))
    assert np.all(np.isnan(normal[1])) and np.all(np.isfinite(normal[[0, 2, 3]]))
    c = command_reflector(model, sun, target)
    assert np.asarray(c.ok).tolist() == [True, False, True, True]
    assert c.reasons()[1] == "sun and target are opposite: mirror normal undefined"
    # Broadcasting: one sun, several targets.
    c = command_reflector(model, sun[0], target)
    assert c.shape == (4,)


# ------------------------------------------------------------------ shapes, bad input


def test_batch_shapes_and_non_finite():
    model = _turntable(np.radians([0.05, -0.02, 0.03, 40.0, 2.0]))
    d = _directions(6, 4, 0.0, 80.0)
    one = command(model, d[0])
    assert isinstance(one, Command)
    assert one.reading.shape == (2,) and one.ok.shape == () and one.shape == ()
    assert bool(one.ok) and one.reasons() == [""]
    flat = command(model, d)
    grid = command(model, d.reshape(2, 2, 3))
    assert grid.reading.shape == (2, 2, 2) and grid.ok.shape == (2, 2)
    assert grid.residual.shape == grid.iterations.shape == grid.solution.shape == (2, 2)
    np.testing.assert_allclose(grid.reading.reshape(4, 2), flat.reading, atol=1e-13)
    np.testing.assert_allclose(one.reading, flat.reading[0], atol=1e-13)
    # Non-finite and zero directions are flagged; the others are unaffected.
    bad = d.copy()
    bad[1] = [np.nan, 0.0, 1.0]
    bad[2] = 0.0
    c = command(model, bad)
    assert np.asarray(c.ok).tolist() == [True, False, False, True]
    assert c.reasons() == ["", "non-finite direction", "non-finite direction", ""]
    assert np.all(np.isnan(np.asarray(c.reading[1:3])))
    np.testing.assert_allclose(np.asarray(c.reading)[[0, 3]], np.asarray(flat.reading)[[0, 3]], atol=1e-13)
    # Unnormalised directions are normalised, with a warning.
    with pytest.warns(InputWarning, match="4 of 4 vectors are not unit vectors"):
        c = command(model, 3.0 * d)
    np.testing.assert_allclose(c.reading, flat.reading, atol=1e-12)


def test_one_program_for_every_batch_up_to_64_with_the_quicker_options(monkeypatch):
    """The solve is compiled with the quicker XLA options (pointax.core.xla_options: half
    the compile time, the same speed; benchmarks/interactive_notes.md), and batches of 1
    to 64 directions run that one program (padded: nothing compiles again)."""
    from compile_counter import COUNTER

    from pointax.core import inverse, xla_options

    built = []
    real = xla_options.jit
    monkeypatch.setattr(xla_options, "jit", lambda fn, fast=True, **kw: built.append(fast) or real(fn, fast, **kw))
    inverse._command_program.cache_clear()
    try:
        model = _turntable(np.radians([0.05, -0.02, 0.03, 40.0, 2.0]))
        d = _directions(9, 64, 10.0, 80.0)
        first = command(model, d[:1])
        with COUNTER as compiled:
            batches = [command(model, d[:n]) for n in (2, 17, 64)]
        assert built == [True] and compiled.count == 0, (built, compiled.count)
        np.testing.assert_allclose(np.asarray(batches[-1].reading)[:1], np.asarray(first.reading), atol=1e-13)
    finally:
        inverse._command_program.cache_clear()


def test_bad_arguments():
    model = _turntable(np.zeros(5))
    with pytest.raises(ValueError, match="solution"):
        command(model, [0.0, 1.0, 0.0], solution="upside-down")
    with pytest.raises(ValueError, match="shape"):
        command(model, [0.0, 1.0])
    with pytest.raises(ValueError, match="limits"):
        command(model, [0.0, 1.0, 0.0], limits=(0.0, 1.0, 2.0))


# ------------------------------------------------------------------ differentiability


def test_gradient_through_the_inverse():
    d = _directions(7, 5, 0.0, 80.0)
    weights = jnp.arange(1.0, 11.0).reshape(5, 2)
    values = jnp.radians(jnp.array([0.05, -0.08, 0.1, 30.0, 4.0]))

    def loss(v):
        return jnp.sum(command(_turntable(v), d).reading * weights)

    grad = np.asarray(jax.grad(loss)(values))
    assert np.all(np.isfinite(grad))
    eps = 1e-6
    for i in range(values.size):
        fd = (loss(values.at[i].add(eps)) - loss(values.at[i].add(-eps))) / (2 * eps)
        np.testing.assert_allclose(grad[i], fd, rtol=1e-6, atol=1e-6)
    # The encoder zeros shift the readings one for one.
    np.testing.assert_allclose(grad[3:], [float(weights[:, 0].sum()), float(weights[:, 1].sum())], rtol=1e-10)


def test_float64_without_global_x64():
    code = textwrap.dedent(
        """
        import jax, jax.numpy as jnp, numpy as np
        import pointax as px
        from pointax.core.inverse import command
        assert not jax.config.jax_enable_x64
        model = px.AltAz(px.terms.tpoint("IA CA", form="rigorous"))
        c = command(model, [0.3, 0.4, np.sqrt(0.75)])
        assert c.reading.dtype == jnp.float64, c.reading.dtype
        assert bool(c.ok) and float(c.residual) < 1e-14, (c.reasons(), c.residual)
        assert not jax.config.jax_enable_x64
        print("ok")
        """
    )
    proc = subprocess.run([sys.executable, "-c", code], check=False, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().endswith("ok")

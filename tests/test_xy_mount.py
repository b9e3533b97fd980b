"""The X-Y mount (level-mount paper): pointing, inverse, residuals, commands.

References: the paper's pointing formula (sin L cos B, sin B, cos L cos B) in ENU (eq 5)
and its NumPy inverse written out here; central finite differences of L and B for the
meaning of the fit residuals; the forward model for the inverse (command).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import pointax as px
from pointax.terms.model_factories import XY, xy_family
from pointax.core.mounts import XYMount
from pointax.terms import xy

ARCSEC = np.pi / 648000


def xy_direction(L, B):
    """Eq 5 of the paper: the pointing of an X-Y mount in (East, North, Up)."""
    L, B = np.asarray(L, float), np.asarray(B, float)
    return np.stack([np.sin(L) * np.cos(B), np.sin(B), np.cos(L) * np.cos(B)], axis=-1)


def xy_angles(d):
    """NumPy inverse of eq 5 (the normal solution, |B| <= 90 deg)."""
    d = np.asarray(d, float)
    return np.stack([np.arctan2(d[..., 0], d[..., 2]), np.arcsin(np.clip(d[..., 1], -1, 1))], axis=-1)


def sky_readings(n, min_elevation_deg=10.0, seed=0):
    """Readings (L, B) of directions spread over the sky above ``min_elevation_deg``."""
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(8 * n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v = v[v[:, 2] > np.sin(np.radians(min_elevation_deg))][:n]
    return xy_angles(v)


def paper_example_model():
    """The issue's simulated X-Y mount: rotation model (v = 100" at Lv = -60 deg, phi
    30", C 60", zero points -10" and -130", eccentricities 60" and 50") plus two terms
    outside the basic family (24" tan L / cos B in dL, 14" sin L / cos B in dB)."""
    values = xy.rotation_values(
        v=100 * ARCSEC,
        Lv=np.radians(-60),
        phi=30 * ARCSEC,
        C=60 * ARCSEC,
        L_zero=-10 * ARCSEC,
        B_zero=-130 * ARCSEC,
        L_ecc=60 * ARCSEC,
        L_ecc_phase=np.radians(20),
        B_ecc=50 * ARCSEC,
        B_ecc_phase=np.radians(-70),
    )
    extra = (xy.Linearised("dL_tanL_secB", 24 * ARCSEC), xy.Linearised("dB_sinL_secB", 14 * ARCSEC))
    return XY(xy_family("rotation", values) + extra)


def test_nominal_pointing_is_eq_5_on_both_mechanical_solutions():
    rng = np.random.default_rng(1)
    L = rng.uniform(-np.pi, np.pi, 50)
    B = rng.uniform(-np.pi / 2, np.pi / 2, 50)
    enc = np.stack([L, B], -1)
    model = XY()
    np.testing.assert_allclose(np.asarray(model(enc)), xy_direction(L, B), atol=1e-15)
    # Over the top: (L + pi, pi - B) points the same way.
    flipped = np.stack([L + np.pi, np.pi - B], -1)
    np.testing.assert_allclose(np.asarray(model(flipped)), xy_direction(L, B), atol=1e-15)
    # Zero readings point at the zenith; L > 0 tips towards East, B > 0 towards North.
    np.testing.assert_allclose(np.asarray(model(np.zeros(2))), [0, 0, 1], atol=1e-16)
    assert float(model(np.array([0.1, 0.0]))[0]) > 0
    assert float(model(np.array([0.0, 0.1]))[1]) > 0
    assert XYMount.axis_names == ("L", "B") and XYMount().convention == "xy"


def test_nominal_inverse_picks_the_solution_nearest_the_current_reading():
    mount = XYMount()
    enc = sky_readings(40, min_elevation_deg=1.0)
    frame = np.asarray(mount.frame)
    for L, B in enc:
        d_mount = jnp.asarray(frame.T @ xy_direction(L, B))
        normal = np.asarray(mount.angles_of(d_mount, jnp.array([L + 0.01, B - 0.01])))
        np.testing.assert_allclose(normal, [L, B], atol=1e-12)
        flipped = np.asarray(mount.angles_of(d_mount, jnp.array([L + np.pi, np.pi - B])))
        np.testing.assert_allclose(flipped, [L + np.pi, np.pi - B], atol=1e-12)
    # The zenith is no pole: L and B are both defined there.
    np.testing.assert_allclose(np.asarray(mount.angles_of(jnp.array([0.0, 1.0, 0.0]), jnp.zeros(2))), [0, 0], atol=0)


@pytest.mark.parametrize("L, B", [(0.0, 0.0), (1e-9, -2e-9), (0.4, 0.3), (-1.0, 0.6), (0.3, -1.2)])
def test_fit_residuals_are_dL_cosB_and_dB(L, B):
    """The residual of a fit (observed minus model) is (dL cos B, dB): the paper's
    per-axis residuals, regular at the zenith (L = B = 0)."""
    dL, dB = 3e-6, -2e-6
    model = XY()
    obs = px.Observations(np.array([[L, B]]), xy_direction(L + dL, B + dB)[None], convention="xy")
    r = np.asarray(px.residuals(model, obs))[0]
    # First order: (dL cos B, dB), up to O(d^2) ~ 1e-11.
    np.testing.assert_allclose(r, [dL * np.cos(B), dB], atol=2e-11)
    # Central finite differences of eq 5: the residual's basis is (dd/dL / cos B, dd/dB).
    h = 1e-6
    e_L = (xy_direction(L + h, B) - xy_direction(L - h, B)) / (2 * h) / np.cos(B)
    e_B = (xy_direction(L, B + h) - xy_direction(L, B - h)) / (2 * h)
    offset = xy_direction(L + dL, B + dB) - xy_direction(L, B)
    np.testing.assert_allclose(r, [offset @ e_L, offset @ e_B], atol=2e-11)
    # axis_residuals gives the same numbers from two directions.
    ar = np.asarray(model.mount.axis_residuals(model(np.array([L, B])), xy_direction(L + dL, B + dB)))
    np.testing.assert_allclose(ar, r, atol=1e-18)


def test_axis_residuals_batch_equal_fit_residuals_for_a_model_with_errors():
    model = paper_example_model()
    enc = sky_readings(30, seed=4)
    target = xy_direction(*(enc + np.random.default_rng(5).normal(0, 5 * ARCSEC, enc.shape)).T)
    obs = px.Observations(enc, target, convention="xy")
    r = np.asarray(jax.jit(px.residuals)(model, obs))
    ar = np.asarray(jax.jit(lambda m: m.mount.axis_residuals(jax.vmap(m.direction)(jnp.asarray(enc)), target))(model))
    np.testing.assert_allclose(ar, r, atol=1e-18)
    # Alt-az mounts: the same definition gives (dA cos E, dE).
    altaz = px.AltAzMount()
    A, E, dA, dE = 1.0, 0.5, 2e-6, 1e-6
    azel = px.rotations.azel_to_enu_numpy
    np.testing.assert_allclose(
        np.asarray(altaz.axis_residuals(azel(A, E), azel(A + dA, E + dE))), [dA * np.cos(E), dE], atol=1e-11
    )


def test_command_inverts_the_model_on_both_solutions():
    # The rotation family (rigorous rotations and encoder terms) at the paper's sizes.
    model = XY(xy_family("rotation", xy.rotation_values(
        v=100 * ARCSEC, Lv=np.radians(-60), phi=30 * ARCSEC, C=60 * ARCSEC, L_zero=-10 * ARCSEC,
        B_zero=-130 * ARCSEC, L_ecc=60 * ARCSEC, L_ecc_phase=0.3, B_ecc=50 * ARCSEC, B_ecc_phase=-1.2,
    )))  # fmt: skip
    model = model.with_values(model.values())  # arrays, not Python floats: one compilation
    enc = sky_readings(40, min_elevation_deg=5.0, seed=2)
    wanted = np.concatenate([xy_direction(*enc.T), [[0.0, 0.0, 1.0]]])
    for solution in ("normal", "flipped"):
        cmd = px.command(model, wanted, solution=solution)
        assert bool(np.all(np.asarray(cmd.ok))), cmd.reasons()
        np.testing.assert_allclose(np.asarray(model(cmd.reading)), wanted, atol=1e-12)
        b = np.asarray(cmd.reading)[:, 1]
        assert np.all(np.cos(b) > 0) if solution == "normal" else np.all(np.cos(b) < 0)
    # Error-free mount (the same model at zero: no recompiling): the normal reading is
    # eq 5's inverse, the flipped one (L + pi, pi - B).
    perfect = model.with_values(jnp.zeros(len(model.parameter_names)))
    nominal = px.command(perfect, wanted, solution="normal")
    np.testing.assert_allclose(np.asarray(nominal.reading), xy_angles(wanted), atol=1e-12)
    flip = px.command(perfect, wanted, solution="flipped", limits=((0, 2 * np.pi), None))
    expected = xy_angles(wanted) + [np.pi, 0]
    expected[:, 1] = np.pi - expected[:, 1]
    np.testing.assert_allclose(np.asarray(flip.reading), expected, atol=1e-12)
    assert nominal.axis_names == ("L", "B")


def test_jit_vmap_grad_through_an_xy_model():
    model = paper_example_model()
    enc = jnp.asarray(sky_readings(5, seed=3))
    np.testing.assert_allclose(
        np.asarray(jax.jit(jax.vmap(model.direction))(enc)), np.asarray(model(enc)), atol=1e-16
    )
    y0 = model.values()

    @jax.jit
    def north(y):
        return jnp.sum(jax.vmap(model.with_values(y).direction)(enc)[:, 1])

    grad = np.asarray(jax.grad(north)(y0))
    h = 1e-7
    for i in range(y0.size):
        fd = (north(y0.at[i].add(h)) - north(y0.at[i].add(-h))) / (2 * h)
        np.testing.assert_allclose(grad[i], float(fd), rtol=1e-6, atol=1e-9)


def test_convention_is_checked():
    obs = px.Observations(np.zeros((3, 2)), np.tile([0.0, 0.0, 1.0], (3, 1)), convention="N-E")
    with pytest.raises(ValueError, match="'N-E' convention but the model's mount expects 'xy'"):
        px.fit(XY("basic"), obs)

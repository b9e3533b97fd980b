"""Heliostat kinematics, terms and calibration (HeliostatMount, terms.heliostat,
calibrate_heliostat, ``pointax fit --format paint``).

Independent references written here in numpy/scipy, never pointax itself:

* DESIGN.md's actuator law (stroke, law of cosines, clockwise sign) with AA39's actuator
  constants typed in from ``heliostat-properties.json``;
* the full rotation chain ``n = Rn(t1n) Ru(t1u) Re(theta1 + d1 - pi/2) Re(t2e) Rn(t2n)
  Ru(theta2 + d2) (0, -1, 0)`` with right-handed Re, Rn, Ru written out;
* central finite differences for the Jacobian;
* scipy.optimize.least_squares (LM) on the numpy model for the final stage of the
  AA39 calibration.
"""

from __future__ import annotations

import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.optimize
from numpy_rotations import Rx as Re
from numpy_rotations import Ry as Rn
from numpy_rotations import Rz as Ru

import pointax as px
from pointax.cli import main

MRAD = 1e-3

# AA39's actuators, copied from ../shared/data/paint/AA39/heliostat-properties.json
# (kinematics_properties.actuators[0], [1]).
AA39 = {
    "increment": (154166.6667, 154166.6667),
    "initial_stroke": (0.077412795, 0.077522286),
    "offset": (0.335308, 0.340771),
    "pivot_radius": (0.338095, 0.3191),
    "initial_angle": (0.039009536, 0.943922248),
    "clockwise": (0, 1),
}
MOTOR_LIMITS = ((0.0, 68745.0), (0.0, 75308.0))
ANGLE_LIMITS = ((0.015123278, 1.570796327), (-0.95993, 0.925674074))
ALL_TERMS = "t1n t1u t2e t2n d1 d2"


# --------------------------------------------------------------------------- numpy reference


def np_axis_angles(motor):
    """DESIGN's actuator law, one column per axis: motor increments -> joint angles."""
    motor = np.asarray(motor, float)
    out = np.empty_like(motor)
    for k in range(2):
        a, r = AA39["offset"][k], AA39["pivot_radius"][k]
        s0 = AA39["initial_stroke"][k]
        s = motor[..., k] / AA39["increment"][k] + s0

        def phi(stroke, a=a, r=r):
            return np.arccos((a**2 + r**2 - stroke**2) / (2 * a * r))

        sign = 1.0 if AA39["clockwise"][k] == 1 else -1.0
        out[..., k] = AA39["initial_angle"][k] + sign * (phi(s0) - phi(s))
    return out


def np_normal(theta, p=None):
    """Mirror normal (ENU) for joint angles ``theta`` and parameters ``p`` (dict, rad)."""
    p = {k: 0.0 for k in ALL_TERMS.split()} | dict(p or {})
    t1, t2 = theta
    chain = (
        Rn(p["t1n"])
        @ Ru(p["t1u"])
        @ Re(t1 + p["d1"] - math.pi / 2)
        @ Re(p["t2e"])
        @ Rn(p["t2n"])
        @ Ru(t2 + p["d2"])
    )
    return chain @ np.array([0.0, -1.0, 0.0])


def np_tangent_offset(v, ref):
    """Gnomonic (cross-elevation, elevation) offset of ``v`` in ``ref``'s tangent plane."""
    x, y, z = ref
    az, el = math.atan2(x, y), math.atan2(z, math.hypot(x, y))
    e_az = np.array([math.cos(az), -math.sin(az), 0.0])
    e_el = np.array([-math.sin(el) * math.sin(az), -math.sin(el) * math.cos(az), math.cos(el)])
    return np.array([v @ e_az, v @ e_el]) / (v @ ref)


def np_angle(a, b):
    """Great-circle angle between unit vectors."""
    return math.atan2(np.linalg.norm(np.cross(a, b)), float(a @ b))


def aa39_mount():
    return px.HeliostatMount(
        increment=AA39["increment"],
        initial_stroke=AA39["initial_stroke"],
        offset=AA39["offset"],
        pivot_radius=AA39["pivot_radius"],
        initial_angle=AA39["initial_angle"],
        clockwise=AA39["clockwise"],
    )


def random_motor(rng, n):
    lo = np.array([m[0] for m in MOTOR_LIMITS])
    hi = np.array([m[1] for m in MOTOR_LIMITS])
    return lo + rng.uniform(size=(n, 2)) * (hi - lo)


PARAMS = {"t1n": 3.1e-3, "t1u": -2.4e-3, "t2e": 1.7e-3, "t2n": -4.2e-3, "d1": 2.2e-3, "d2": -1.3e-3}


# --------------------------------------------------------------------------- 1. actuators


def test_axis_angles_follow_the_actuator_law_and_invert():
    mount = aa39_mount()
    rng = np.random.default_rng(11)
    motor = np.vstack([random_motor(rng, 200), [[0.0, 0.0]], [[MOTOR_LIMITS[0][1], MOTOR_LIMITS[1][1]]]])
    got = np.asarray(jax.vmap(mount.axis_angles)(jnp.asarray(motor)))
    want = np_axis_angles(motor)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    # At motor 0 the joint sits at its initial angle.
    np.testing.assert_allclose(got[-2], AA39["initial_angle"], atol=1e-15)
    # The counts inside the limits stay (about) within the angle limits: the law and the
    # file's limits belong together (a sign error would throw axis 1 far outside).
    for k in range(2):
        assert ANGLE_LIMITS[k][0] - 0.05 <= want[:, k].min() and want[:, k].max() <= ANGLE_LIMITS[k][1] + 0.05
    back = np.asarray(jax.vmap(mount.readings_of)(jnp.asarray(got)))
    np.testing.assert_allclose(back, motor, rtol=0, atol=1e-6)


# --------------------------------------------------------------------------- 2. chain


@pytest.fixture(scope="module")
def full_model():
    values = dict(PARAMS)
    return px.Model(aa39_mount(), px.terms.heliostat(ALL_TERMS, values=values))


def test_full_chain_matches_numpy_product(full_model):
    rng = np.random.default_rng(5)
    motor = random_motor(rng, 50)
    got = np.asarray(full_model(motor))
    theta = np_axis_angles(motor)
    want = np.array([np_normal(t, PARAMS) for t in theta])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-13)
    # Model.direction (one reading) agrees with the batched call.
    np.testing.assert_allclose(np.asarray(full_model.direction(jnp.asarray(motor[0]))), want[0], atol=1e-13)
    # Every term matters: dropping any one changes the normal by about its size.
    for name, value in PARAMS.items():
        other = np.array([np_normal(t, {k: v for k, v in PARAMS.items() if k != name}) for t in theta])
        assert np.max(np.linalg.norm(other - got, axis=-1)) > 0.3 * abs(value)


def test_nominal_chain_is_tilt_tilt():
    mount = aa39_mount()
    model = px.Model(mount)
    rng = np.random.default_rng(6)
    motor = random_motor(rng, 40)
    theta = np_axis_angles(motor)
    want = np.array([Re(t1) @ Rn(t2) @ np.array([0.0, 0.0, 1.0]) for t1, t2 in theta])
    np.testing.assert_allclose(np.asarray(model(motor)), want, atol=1e-14)
    np.testing.assert_allclose(np.asarray(jax.vmap(mount.direction)(jnp.asarray(theta))), want, atol=1e-14)
    # theta1 is the mirror's zenith angle when theta2 = 0.
    for t1 in (0.1, 0.7, 1.4):
        n = np.asarray(mount.direction(jnp.array([t1, 0.0])))
        assert math.isclose(math.acos(n[2]), t1, abs_tol=1e-14)


# --------------------------------------------------------------------------- 3. inverse


def test_angles_of_inverts_direction_both_solutions():
    mount = aa39_mount()
    rng = np.random.default_rng(7)
    n_cases = 30
    t1 = rng.uniform(*ANGLE_LIMITS[0], n_cases)
    t2 = rng.uniform(*ANGLE_LIMITS[1], n_cases)
    for a, b in zip(t1, t2):
        d = Re(a) @ Rn(b) @ np.array([0.0, 0.0, 1.0])
        first = np.array([a, b])
        second = np.array([a + math.pi, math.pi - b])  # over the top
        np.testing.assert_allclose(Re(second[0]) @ Rn(second[1]) @ [0, 0, 1], d, atol=1e-14)
        for sol in (first, second, first + [2 * math.pi, 0.0]):
            near = sol + rng.normal(scale=0.05, size=2)
            got = np.asarray(mount.angles_of(jnp.asarray(d), jnp.asarray(near)))
            np.testing.assert_allclose(got, sol, atol=1e-12)
            np.testing.assert_allclose(Re(got[0]) @ Rn(got[1]) @ [0, 0, 1], d, atol=1e-13)


# --------------------------------------------------------------------------- 4. Jacobian


def test_residual_jacobian_matches_finite_differences(full_model):
    rng = np.random.default_rng(8)
    motor = random_motor(rng, 12)
    obs = px.simulate(full_model, motor, noise=1e-3, seed=2)
    start = full_model.with_values(np.zeros(6))
    y0 = jnp.asarray(rng.normal(scale=2e-3, size=6))

    def r(y):
        return px.residuals(start.with_values(y), obs).reshape(-1)

    jac = np.asarray(jax.jacfwd(r)(y0))
    rf = jax.jit(r)
    h = 1e-6
    fd = np.stack(
        [(np.asarray(rf(y0.at[j].add(h))) - np.asarray(rf(y0.at[j].add(-h)))) / (2 * h) for j in range(6)], axis=1
    )
    assert np.max(np.abs(jac)) > 0.1
    np.testing.assert_allclose(jac, fd, rtol=0, atol=1e-8)


# --------------------------------------------------------------------------- 5. AA39


@pytest.fixture(scope="module")
def aa39_dir(shared_data):
    return shared_data / "paint" / "AA39"


@pytest.fixture(scope="module")
def aa39_run(aa39_dir):
    return px.io.read_paint(aa39_dir)


@pytest.fixture(scope="module")
def aa39_cal(aa39_run):
    return px.calibrate_heliostat(aa39_run)


TILTS = ("t1n", "t1u", "t2e", "t2n")


def _scipy_tilts(motor, normals, residual="tangent"):
    """The four tilts by scipy LM on the numpy model; residual 'tangent' (gnomonic
    offsets in the measured normal's tangent plane, as pointax) or 'chord' (3-vector)."""
    theta = np_axis_angles(motor)

    def f(y):
        p = dict(zip(TILTS, y))
        out = []
        for t, m in zip(theta, normals):
            n = np_normal(t, p)
            out.append(np_tangent_offset(n, m) if residual == "tangent" else n - m)
        return np.concatenate(out)

    sol = scipy.optimize.least_squares(f, np.zeros(4), method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    assert sol.success
    return sol.x, f(sol.x).reshape(len(motor), -1)


def test_aa39_mount_from_file(aa39_run):
    mount = px.HeliostatMount.from_paint(aa39_run.heliostat)
    np.testing.assert_array_equal(np.asarray(mount.increment), AA39["increment"])
    np.testing.assert_array_equal(np.asarray(mount.initial_stroke), AA39["initial_stroke"])
    np.testing.assert_array_equal(np.asarray(mount.offset), AA39["offset"])
    np.testing.assert_array_equal(np.asarray(mount.pivot_radius), AA39["pivot_radius"])
    np.testing.assert_array_equal(np.asarray(mount.initial_angle), AA39["initial_angle"])
    np.testing.assert_array_equal(np.asarray(mount.sign), [-1.0, 1.0])


def test_aa39_calibration(aa39_run, aa39_cal):
    cal = aa39_cal
    ids = list(cal.sample_ids)
    assert ids == aa39_run.sample_ids and len(ids) == 18
    assert bool(cal.result.converged)
    assert np.all(cal.loo_converged)
    flagged = {ids[i] for i in np.flatnonzero(cal.outliers)}
    assert {"86520", "multi1"} <= flagged
    assert len(flagged) <= 6

    motor, normals = np.asarray(aa39_run.motor), np.asarray(aa39_run.measured_normal)
    # Before: the nominal kinematics, numpy; the errors are great-circle angles.
    nominal = np.array([np_angle(np_normal(t), m) for t, m in zip(np_axis_angles(motor), normals)])
    np.testing.assert_allclose(cal.before, nominal, rtol=1e-9, atol=0)
    for sid in ("86520", "multi1"):
        assert 65 * MRAD < nominal[ids.index(sid)] < 85 * MRAD
    before_all = math.sqrt(np.mean(nominal**2))
    assert 20 * MRAD < before_all < 40 * MRAD
    assert math.isclose(cal.rms("before", include_outliers=True), before_all, rel_tol=1e-9)

    keep = ~cal.outliers
    loo = cal.rms("loo")
    after = cal.rms("after")
    assert math.isclose(loo, math.sqrt(np.mean(cal.loo[keep] ** 2)), rel_tol=1e-12)
    assert loo <= 2.5 * MRAD
    assert after <= loo
    # An outlier's leave-one-out error is its error after the fit (it was not used).
    np.testing.assert_allclose(cal.loo[~keep], cal.after[~keep], rtol=1e-9)

    # The final stage: plain least squares of the four tilts on the unflagged samples.
    x, res = _scipy_tilts(motor[keep], normals[keep], "tangent")
    got = np.array([cal.result.value(n, "rad") for n in TILTS])
    np.testing.assert_allclose(got / MRAD, x / MRAD, rtol=0, atol=5e-6)  # measured 3e-7 mrad
    np.testing.assert_allclose(cal.result.sky_rms, math.sqrt(np.sum(res**2) / keep.sum()), rtol=1e-9)
    # Errors are angles: arctan of the tangent-plane offset's norm.
    np.testing.assert_allclose(after, math.sqrt(np.mean(np.arctan(np.linalg.norm(res, axis=-1)) ** 2)), rtol=1e-9)
    # After-errors of every sample (outliers too) from the numpy model with scipy's tilts.
    p = dict(zip(TILTS, x))
    after_np = np.array(
        [np.arctan(np.linalg.norm(np_tangent_offset(np_normal(t, p), m))) for t, m in zip(np_axis_angles(motor), normals)]
    )
    np.testing.assert_allclose(cal.after, after_np, rtol=0, atol=1e-9)

    # The chord (3-vector difference, 2 sin(angle/2) long instead of tan(angle)) differs
    # at third order in the few-mrad residuals: its minimiser moves by ~3e-6 mrad.
    x_chord, res_chord = _scipy_tilts(motor[keep], normals[keep], "chord")
    np.testing.assert_allclose(got / MRAD, x_chord / MRAD, rtol=0, atol=1e-3)
    rms_chord = math.sqrt(np.sum(res_chord**2) / keep.sum())
    assert math.isclose(cal.result.sky_rms, rms_chord, rel_tol=0, abs_tol=1e-3 * MRAD)


def test_aa39_t2e_and_d1_are_degenerate(aa39_run, aa39_cal):
    model = px.heliostat_model(aa39_run, "t1n t1u t2e t2n d1")
    r = px.fit(model, aa39_run.observations, loss="cauchy")
    assert bool(r.converged)
    assert r.names == ("t1n", "t1u", "t2e", "t2n", "d1")
    assert [n for n, d in zip(r.names, np.asarray(r.degenerate)) if d] == ["t2e", "d1"]
    assert np.isinf(r.sigma("t2e")) and np.isinf(r.sigma("d1"))
    assert np.all(np.isfinite([r.sigma(n) for n in ("t1n", "t1u", "t2n")]))
    text = " ".join(r.warnings())
    assert "t2e" in text and "d1" in text
    four = aa39_cal.result
    np.testing.assert_array_equal(np.asarray(r.outliers), aa39_cal.outliers)
    assert abs(r.value("t2e") + r.value("d1") - four.value("t2e")) < 1e-6  # mrad
    for n in ("t1n", "t1u", "t2n"):
        assert abs(r.value(n) - four.value(n)) < 1e-6


# --------------------------------------------------------------------------- 6. CLI


def test_cli_paint_json(aa39_dir, aa39_cal, capsys, monkeypatch):
    monkeypatch.setenv("POINTAX_JAX_CACHE", "")
    code = main(["fit", str(aa39_dir), "--format", "paint", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    assert out["n_obs"] == 18
    files = sorted(p.name for p in aa39_dir.iterdir() if p.name.endswith("-calibration-properties.json"))
    assert out["samples"] == [f.removesuffix("-calibration-properties.json") for f in files]
    assert [p["name"] for p in out["params"]] == list(TILTS)
    for p, name in zip(out["params"], TILTS):
        assert set(p) == {"name", "value", "sigma", "unit"} and p["unit"] == "mrad"
        assert math.isclose(p["value"], aa39_cal.result.value(name), rel_tol=0, abs_tol=1e-9)
    errors = out["error_mrad"]
    for k in ("before", "after", "loo"):
        assert len(errors[k]) == 18
        np.testing.assert_allclose(np.array(errors[k]) * MRAD, getattr(aa39_cal, k), rtol=1e-9)
        keep = ~aa39_cal.outliers
        assert math.isclose(errors["rms"][k], math.sqrt(np.mean(np.array(errors[k])[keep] ** 2)), rel_tol=1e-9)
    assert {"86520", "multi1"} <= set(out["outliers"])


def test_cli_paint_bad_directory(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("POINTAX_JAX_CACHE", "")
    missing = tmp_path / "no-such-heliostat"
    code = main(["fit", str(missing), "--format", "paint", "--json"])
    captured = capsys.readouterr()
    assert code == 2
    assert str(missing) in captured.err
    assert captured.out == ""


def test_from_paint_rejects_other_initial_orientations(aa39_run):
    import dataclasses

    other = dataclasses.replace(aa39_run.heliostat, initial_orientation=np.array([0.0, 0.0, 1.0]))
    with pytest.raises(ValueError, match="initial_orientation"):
        px.HeliostatMount.from_paint(other)

"""PAINT heliostats with 'ideal' actuators, and leave-one-out made optional (issue 27).

An ideal actuator, as DLR's ARTIST defines it (``IdealActuators.motor_positions_to_angles``
returns the motor positions unchanged), turns its motor position into the joint angle
by the identity: theta = motor position, radians, with no stroke, lever, zero offset
or turning sign. The heliostat here is PAINT's AA39 with both actuators typed 'ideal'
(tests/data/paint_ideal/PROVENANCE.txt says how it was derived).

Independent references, numpy and scipy only (never pointax): WGS84 to East-North-Up
(the ellipsoid's formulas typed in), PAINT's sun direction, the kinematic chain of
DESIGN.md ``n = Rn(t1n) Ru(t1u) Re(theta1 - pi/2) Re(t2e) Rn(t2n) Ru(theta2) (0, -1, 0)``
with right-handed rotations, and scipy's least squares to find the joint angles at
which a heliostat with known axis tilts points at the bisector of sun and focal spot.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

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
from pointax.io.paint import PaintFormatError, read_heliostat, read_paint

DATA = Path(__file__).parent / "data" / "paint_ideal"
PROPERTIES = DATA / "AA39-ideal" / "heliostat-properties.json"
TOWER = DATA / "tower-measurements.json"
MRAD = 1e-3
TILTS = {"t1n": 2.5e-3, "t1u": -6.0e-3, "t2e": 1.5e-3, "t2n": -3.5e-3}  # rad; t1u like AA39's measured ~6 mrad
TARGET = "multi_focus_tower"
# (PAINT azimuth: South = 0, East positive; elevation), degrees: a spread over a day and a year.
SUNS = [(-60, 15), (-45, 30), (-30, 45), (-10, 55), (0, 60), (15, 50), (35, 38), (55, 22), (70, 12), (-20, 25)]


# --------------------------------------------------------------------------- numpy reference


def wgs84_enu(point, origin):
    """WGS84 ``[lat, lon, h]`` -> ENU metres at ``origin`` (a = 6378137 m, f = 1/298.257223563)."""
    a, f = 6378137.0, 1 / 298.257223563
    e2 = f * (2 - f)

    def ecef(lat, lon, h):
        lat, lon = math.radians(lat), math.radians(lon)
        n = a / math.sqrt(1 - e2 * math.sin(lat) ** 2)
        return np.array(
            [(n + h) * math.cos(lat) * math.cos(lon), (n + h) * math.cos(lat) * math.sin(lon), (n * (1 - e2) + h) * math.sin(lat)]
        )

    lat0, lon0 = math.radians(origin[0]), math.radians(origin[1])
    d = ecef(*point) - ecef(*origin)
    east = np.array([-math.sin(lon0), math.cos(lon0), 0.0])
    north = np.array([-math.sin(lat0) * math.cos(lon0), -math.sin(lat0) * math.sin(lon0), math.cos(lat0)])
    up = np.array([math.cos(lat0) * math.cos(lon0), math.cos(lat0) * math.sin(lon0), math.sin(lat0)])
    return np.array([d @ east, d @ north, d @ up])


def sun_enu(azimuth_deg, elevation_deg):
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    return np.array([math.sin(a) * math.cos(e), -math.cos(a) * math.cos(e), math.sin(e)])


def chain_normal(theta, p=None):
    p = {k: 0.0 for k in TILTS} | dict(p or {})
    t1, t2 = theta
    m = Rn(p["t1n"]) @ Ru(p["t1u"]) @ Re(t1 - math.pi / 2) @ Re(p["t2e"]) @ Rn(p["t2n"]) @ Ru(t2)
    return m @ np.array([0.0, -1.0, 0.0])


def closed_form_normal(t1, t2):
    """The nominal chain multiplied out: theta1 the mirror's zenith angle, theta2 its
    turn towards East."""
    return np.array([math.sin(t2), -math.cos(t2) * math.sin(t1), math.cos(t2) * math.cos(t1)])


def joint_angles_for(normal, p):
    """Joint angles at which the chain with parameters ``p`` gives ``normal``."""
    start = [math.atan2(-normal[1], normal[2]), math.atan2(normal[0], math.hypot(normal[1], normal[2]))]
    sol = scipy.optimize.least_squares(lambda t: chain_normal(t, p) - normal, start, xtol=1e-15, ftol=1e-15, gtol=1e-15)
    assert sol.success and np.linalg.norm(sol.fun) < 1e-13
    return sol.x


def simulate(folder: Path, suns=SUNS, p=TILTS, properties: Path = PROPERTIES) -> tuple[np.ndarray, np.ndarray]:
    """A PAINT folder of samples for a heliostat with tilts ``p``: each sample's focal
    spot at the target's centre, its motor positions the joint angles (ideal
    actuators) that put the normal on the bisector. Returns (motor, normals)."""
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copy(properties, folder / "heliostat-properties.json")
    helio = json.loads(properties.read_text())
    spot = json.loads(TOWER.read_text())[TARGET]["coordinates"]["center"]
    to_spot = wgs84_enu(spot, helio["heliostat_position"])
    to_spot /= np.linalg.norm(to_spot)
    limits = [(a["min_increment"], a["max_increment"]) for a in helio["kinematics_properties"]["actuators"]]
    motors, normals = [], []
    for k, (az, el) in enumerate(suns):
        b = sun_enu(az, el) + to_spot
        normal = b / np.linalg.norm(b)
        theta = joint_angles_for(normal, p)
        assert all(lo <= t <= hi for t, (lo, hi) in zip(theta, limits)), (az, el, theta)
        sample = {
            "motor_position": {"axis_1_motor_position": float(theta[0]), "axis_2_motor_position": float(theta[1])},
            "target_name": TARGET,
            "focal_spot": {"HeliOS": spot, "UTIS": spot},
            "sun_elevation": float(el),
            "sun_azimuth": float(az),
        }
        (folder / f"{1000 + k}-calibration-properties.json").write_text(json.dumps(sample, indent=2))
        motors.append(theta)
        normals.append(normal)
    return np.array(motors), np.array(normals)


def angle(a, b):
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


# --------------------------------------------------------------------------- reading


def test_ideal_actuators_are_read():
    h = read_heliostat(PROPERTIES)
    assert [a.type_axis for a in h.actuators] == ["ideal", "ideal"]
    assert [a.law for a in h.actuators] == ["ideal", "ideal"] and all(a.ideal for a in h.actuators)
    a1, a2 = h.actuators
    assert (a1.min_increment, a1.max_increment) == (0.015123278, 1.570796327)  # radians, typed in from the file
    assert (a2.min_increment, a2.max_increment) == (-0.95993, 0.925674074)
    mount = px.HeliostatMount.from_paint(h)
    np.testing.assert_array_equal(np.asarray(mount.ideal), [1.0, 1.0])


def test_a_linear_heliostat_stays_linear(shared_data):
    h = read_heliostat(shared_data / "paint" / "AA39" / "heliostat-properties.json")
    assert [a.law for a in h.actuators] == ["linear", "linear"]
    np.testing.assert_array_equal(np.asarray(px.HeliostatMount.from_paint(h).ideal), [0.0, 0.0])


def test_schema1_ideal_actuators_keep_the_linear_law(shared_data):
    """Schema-1 files type every actuator 'ideal' yet give motor positions in
    increments (AC43: 26000-69000), which only the linear law turns into the measured
    normals (test_io_paint): read as linear."""
    folder = shared_data / "paint" / "AC43-schema1"
    if not folder.is_dir():
        pytest.skip(f"{folder} not found")
    h = read_heliostat(folder / "heliostat-properties.json")
    assert [a.type_axis for a in h.actuators] == ["ideal", "ideal"]
    assert [a.law for a in h.actuators] == ["linear", "linear"]
    run = read_paint(folder)
    measured = np.asarray(run.measured_normal)
    # Taken as joint angles (ARTIST's ideal law), its motor positions point nowhere near
    # (measured: 651 and 1490 mrad); the linear law is off by the usual 6 and 17 mrad.
    as_angles = np.array([closed_form_normal(*m) for m in np.asarray(run.motor)])
    assert np.all(angle(as_angles, measured) > 0.5)
    before = px.calibrate_heliostat(run, "t1u t2n", loss="linear", loo=False).before
    assert np.all(before < 25e-3)


def test_an_ideal_actuator_needs_only_its_motor_range(tmp_path):
    d = json.loads(PROPERTIES.read_text())
    for a in d["kinematics_properties"]["actuators"]:
        for key in ("increment", "initial_stroke_length", "offset", "pivot_radius", "initial_angle", "offset_shift", "radius_shift"):
            del a[key]
    path = tmp_path / "heliostat-properties.json"
    path.write_text(json.dumps(d, indent=2))
    h = read_heliostat(path)
    assert all(math.isnan(a.increment) and math.isnan(a.initial_angle) for a in h.actuators)
    mount = px.HeliostatMount.from_paint(h)
    motor = jnp.array([0.7, -0.2])
    np.testing.assert_array_equal(np.asarray(mount.axis_angles(motor)), [0.7, -0.2])
    del d["kinematics_properties"]["actuators"][1]["max_increment"]
    path.write_text(json.dumps(d, indent=2))
    with pytest.raises(PaintFormatError, match=r"heliostat-properties\.json.*actuators\[1\]\.max_increment"):
        read_heliostat(path)


def test_bad_ideal_actuators_name_file_and_field(tmp_path):
    d = json.loads(PROPERTIES.read_text())
    d["kinematics_properties"]["actuators"][0]["max_increment"] = 68745  # increments: a linear actuator's range
    path = tmp_path / "heliostat-properties.json"
    path.write_text(json.dumps(d, indent=2))
    with pytest.raises(PaintFormatError, match=r"heliostat-properties\.json.*actuators\[0\]\.max_increment.*no range of joint angles"):
        read_heliostat(path)
    d["kinematics_properties"]["actuators"][0].update(max_increment=1.570796327, type_axis="rotary")
    path.write_text(json.dumps(d, indent=2))
    with pytest.raises(PaintFormatError, match=r"actuators\[0\]\.type_axis.*'rotary'.*'linear' and 'ideal'"):
        read_heliostat(path)


def test_a_motor_position_outside_an_ideal_range_is_refused(tmp_path):
    simulate(tmp_path / "h", suns=SUNS[:3])
    sample = tmp_path / "h" / "1001-calibration-properties.json"
    d = json.loads(sample.read_text())
    d["motor_position"]["axis_2_motor_position"] = 1.2  # beyond max 0.925674074 rad
    sample.write_text(json.dumps(d))
    with pytest.raises(PaintFormatError, match=r"1001-calibration-properties\.json.*axis_2_motor_position.*1\.2 is outside.*rad, an ideal actuator"):
        read_paint(tmp_path / "h", tower=TOWER)


# --------------------------------------------------------------------------- kinematics


def test_ideal_kinematics_reproduce_the_closed_form():
    """theta = motor position exactly (the identity: slope 1, intercept 0, whatever
    the unused linear numbers, initial angle and turning sign say), its inverse, and
    the nominal normal (sin t2, -cos t2 sin t1, cos t2 cos t1)."""
    mount = px.HeliostatMount.from_paint(read_heliostat(PROPERTIES))
    rng = np.random.default_rng(5)
    motor = np.column_stack([rng.uniform(0.015123278, 1.570796327, 50), rng.uniform(-0.95993, 0.925674074, 50)])
    theta = np.asarray(jax.vmap(mount.axis_angles)(jnp.asarray(motor)))
    np.testing.assert_array_equal(theta, motor)
    np.testing.assert_array_equal(np.asarray(jax.vmap(mount.readings_of)(jnp.asarray(motor))), motor)
    model = px.Model(mount, px.terms.heliostat("t1n t1u t2e t2n"))
    got = np.asarray(model(jnp.asarray(motor)))
    want = np.array([closed_form_normal(*m) for m in motor])
    np.testing.assert_allclose(got, want, atol=1e-14)
    np.testing.assert_allclose(want, [chain_normal(m) for m in motor], atol=1e-15)
    # Derivatives of the normal with respect to the motor positions are the closed form's.
    jac = np.asarray(jax.jacfwd(lambda m: model(m[None])[0])(jnp.asarray(motor[0])))
    t1, t2 = motor[0]
    want_jac = np.array(
        [[0.0, math.cos(t2)], [-math.cos(t2) * math.cos(t1), math.sin(t2) * math.sin(t1)], [-math.cos(t2) * math.sin(t1), -math.sin(t2) * math.cos(t1)]]
    )
    np.testing.assert_allclose(jac, want_jac, atol=1e-13)


def test_mixed_axes_keep_each_law():
    """One ideal, one linear axis: the linear one follows the law of cosines (numpy)."""
    lin = read_heliostat(PROPERTIES).actuators[1]
    mount = px.HeliostatMount(
        increment=[math.nan, lin.increment],
        initial_stroke=[math.nan, lin.initial_stroke_length],
        offset=[math.nan, lin.offset],
        pivot_radius=[math.nan, lin.pivot_radius],
        initial_angle=[math.nan, lin.initial_angle],
        clockwise=[0, 1],
        ideal=[1, 0],
    )
    motor = np.array([0.4, 30000.0])
    a, r, s0 = lin.offset, lin.pivot_radius, lin.initial_stroke_length

    def phi(s):
        return math.acos((a * a + r * r - s * s) / (2 * a * r))

    want = [0.4, lin.initial_angle + (phi(s0) - phi(motor[1] / lin.increment + s0))]
    got = np.asarray(mount.axis_angles(jnp.asarray(motor)))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(mount.readings_of(jnp.asarray(got))), motor, rtol=1e-10)
    grad = jax.grad(lambda m: jnp.sum(mount.axis_angles(m)))(jnp.asarray(motor))
    assert np.all(np.isfinite(np.asarray(grad))) and float(grad[0]) == 1.0


# --------------------------------------------------------------------------- calibration


@pytest.mark.slow
def test_simulated_calibration_recovers_known_tilts(tmp_path):
    motor, normals = simulate(tmp_path / "AA39-ideal")
    run = read_paint(tmp_path / "AA39-ideal", tower=TOWER)
    np.testing.assert_array_equal(run.motor, motor)
    assert np.max(angle(np.asarray(run.measured_normal), normals)) < 1e-9  # the reader's normals are numpy's
    cal = px.calibrate_heliostat(run, loss="linear")
    assert bool(cal.result.converged) and cal.loo_ran and np.all(cal.loo_converged)
    for name, value in TILTS.items():
        assert cal.result.value(name) == pytest.approx(value / MRAD, abs=1e-6), name  # mrad
    nominal = np.array([closed_form_normal(*m) for m in motor])
    np.testing.assert_allclose(cal.before, angle(nominal, normals), atol=1e-12)  # what the tilts do: 2.1 mrad RMS
    assert 1e-3 < cal.rms("before") < 5e-3
    assert cal.rms("after") < 1e-9 and cal.rms("loo") < 1e-8


def test_noisy_calibration_and_its_cross_check(tmp_path):
    """0.3 mrad of noise on the motor positions: the tilts come back within a few
    sigma, leave-one-out errs more than the fit, both sub-mrad."""
    motor, _ = simulate(tmp_path / "h")
    rng = np.random.default_rng(3)
    for k, path in enumerate(sorted((tmp_path / "h").glob("*-calibration-properties.json"))):
        d = json.loads(path.read_text())
        for axis in (1, 2):
            d["motor_position"][f"axis_{axis}_motor_position"] += float(rng.normal(0, 0.3e-3))
        path.write_text(json.dumps(d))
    cal = px.calibrate_heliostat(read_paint(tmp_path / "h", tower=TOWER), loss="linear")
    for row in cal.result.table():
        assert abs(row["value"] - TILTS[row["name"]] / MRAD) < 4 * row["sigma"] + 0.05, row
    assert cal.rms("after") < cal.rms("loo") < 1.5e-3


@pytest.mark.slow
def test_leave_one_out_is_optional_and_skipped_when_samples_are_too_few(tmp_path):
    simulate(tmp_path / "three", suns=SUNS[:3])
    run = read_paint(tmp_path / "three", tower=TOWER)
    cal = px.calibrate_heliostat(run, loss="linear")  # 3 samples, 4 tilts: each fold keeps 4 residuals
    assert not cal.loo_ran and np.all(np.isnan(cal.loo)) and math.isnan(cal.rms("loo"))
    assert "leave-one-out skipped: 3 sample(s)" in cal.loo_note and "at least 4 samples" in cal.loo_note
    assert cal.loo_note in cal.warnings() and f"Note: {cal.loo_note}." in cal.report()
    assert cal.to_dict()["loo_skipped"] == cal.loo_note and cal.to_dict()["error_mrad"]["loo"] == [None] * 3
    with pytest.raises(ValueError, match=r"three: 3 sample\(s\).*at least 4 samples"):
        px.calibrate_heliostat(run, loss="linear", loo=True)
    # Two tilts fixed: 2 free parameters, 3 samples suffice.
    cal = px.calibrate_heliostat(run, loss="linear", fixed=("t1n", "t2e"), loo=True)
    assert cal.loo_ran and np.all(np.isfinite(cal.loo))
    off = px.calibrate_heliostat(run, loss="linear", fixed=("t1n", "t2e"), loo=False)
    assert off.loo_note == "leave-one-out not asked for" and np.all(np.isnan(off.loo))
    np.testing.assert_array_equal(off.after, cal.after)


def test_cli_loo_option_and_plot(tmp_path, capsys):
    simulate(tmp_path / "h", suns=SUNS[:3])
    shutil.copy(TOWER, tmp_path / "tower-measurements.json")
    folder = str(tmp_path / "h")
    assert main(["fit", folder, "--loss", "linear", "--json", "--quiet"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["loo_skipped"].startswith("leave-one-out skipped") and out["error_mrad"]["rms"]["loo"] is None
    assert main(["fit", folder, "--loss", "linear", "--loo", "yes"]) == 2
    assert "at least 4 samples" in capsys.readouterr().err
    assert main(["fit", folder, "--loss", "linear", "--loo", "no", "--fix", "t1n,t2e"]) == 0
    assert "leave-one-out not asked for" in capsys.readouterr().out
    pytest.importorskip("matplotlib")
    assert main(["plot", folder, "--loss", "linear", "-o", str(tmp_path / "h.ps")]) == 0
    text = (tmp_path / "h.ps").read_text("latin-1")
    assert "%%Orientation: landscape" in text
    from pointax.plots import heliostat_figure

    cal = px.calibrate_heliostat(read_paint(folder, tower=TOWER), loss="linear")
    fig = heliostat_figure(cal)
    gids = {line.get_gid() for line in fig.axes[0].get_lines()}
    assert "loo-used" not in gids and "before-used" in gids and "no leave-one-out" in fig._suptitle.get_text()


def test_cli_loo_applies_to_paint_only(capsys):
    from conftest import MMT_DAT

    assert main(["fit", str(MMT_DAT), "--loo", "no"]) == 2
    assert "--loo applies to PAINT heliostat runs" in capsys.readouterr().err

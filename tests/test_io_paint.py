"""Tests of pointax.io.paint: PAINT heliostat calibration JSON files.

Independent references: a closed-form WGS84 geodetic -> ECEF -> ENU conversion and a
flat-earth approximation written here (not astropy), hand-worked sun directions, the
nominal actuator kinematics of DESIGN.md (to check the sign of the sun azimuth against
the motor positions), line numbers found by searching the file text.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from pointax.io import paint
from pointax.io.paint import (
    CalibrationSample,
    HeliostatProperties,
    LinearActuator,
    PaintFormatError,
    PaintRun,
    Tower,
    paint_azimuth_to_north_east,
    read_calibration,
    read_heliostat,
    read_paint,
    read_tower,
    sun_enu_from_paint,
    wgs84_to_enu,
)

# --------------------------------------------------------------------------- independent geometry

A_WGS84 = 6378137.0
F_WGS84 = 1.0 / 298.257223563
E2_WGS84 = F_WGS84 * (2.0 - F_WGS84)
JUELICH = (50.913643297719794, 6.3880132701249455, 88.68894196)


def ecef_closed_form(lat_deg, lon_deg, h):
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    n = A_WGS84 / np.sqrt(1.0 - E2_WGS84 * np.sin(lat) ** 2)
    return np.stack(
        [
            (n + h) * np.cos(lat) * np.cos(lon),
            (n + h) * np.cos(lat) * np.sin(lon),
            (n * (1.0 - E2_WGS84) + h) * np.sin(lat),
        ],
        axis=-1,
    )


def enu_closed_form(lat_deg, lon_deg, h, origin):
    lat0, lon0 = np.radians(origin[0]), np.radians(origin[1])
    up = np.array([np.cos(lat0) * np.cos(lon0), np.cos(lat0) * np.sin(lon0), np.sin(lat0)])
    east = np.array([-np.sin(lon0), np.cos(lon0), 0.0])
    north = np.cross(up, east)
    d = ecef_closed_form(lat_deg, lon_deg, h) - ecef_closed_form(*origin)
    return np.stack([d @ east, d @ north, d @ up], axis=-1)


def enu_flat_earth(lat_deg, lon_deg, h, origin):
    """Small offsets: meridian and prime-vertical radii of curvature at the origin."""
    lat0 = math.radians(origin[0])
    w = 1.0 - E2_WGS84 * math.sin(lat0) ** 2
    m = A_WGS84 * (1.0 - E2_WGS84) / w**1.5
    n = A_WGS84 / math.sqrt(w)
    return np.stack(
        [
            np.radians(np.asarray(lon_deg) - origin[1]) * (n + origin[2]) * math.cos(lat0),
            np.radians(np.asarray(lat_deg) - origin[0]) * (m + origin[2]),
            np.asarray(h) - origin[2],
        ],
        axis=-1,
    )


def test_wgs84_to_enu_matches_closed_form_near_and_far():
    rng = np.random.default_rng(1)
    near = (
        JUELICH[0] + rng.uniform(-0.01, 0.01, 50),
        JUELICH[1] + rng.uniform(-0.01, 0.01, 50),
        JUELICH[2] + rng.uniform(-50, 300, 50),
    )
    far = (rng.uniform(-89, 89, 50), rng.uniform(-180, 180, 50), rng.uniform(-100, 9000, 50))
    for origin in (JUELICH, (-33.9, 18.4, 10.0), (0.0, -120.0, 0.0)):
        for pts in (near, far):
            got = wgs84_to_enu(*pts, origin)
            want = enu_closed_form(*pts, origin)
            assert got.shape == (50, 3)
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-6)


def test_wgs84_to_enu_flat_earth_and_shapes():
    rng = np.random.default_rng(2)
    lat = JUELICH[0] + rng.uniform(-5e-4, 5e-4, (4, 5))  # within about 60 m
    lon = JUELICH[1] + rng.uniform(-5e-4, 5e-4, (4, 5))
    h = JUELICH[2] + rng.uniform(0, 60, (4, 5))
    got = wgs84_to_enu(lat, lon, h, JUELICH)
    assert got.shape == (4, 5, 3)
    # curvature drop over 60 m is d^2 / 2R < 0.5 mm
    np.testing.assert_allclose(got, enu_flat_earth(lat, lon, h, JUELICH), rtol=0, atol=2e-3)
    np.testing.assert_allclose(wgs84_to_enu(*JUELICH, JUELICH), np.zeros(3), atol=1e-9)
    assert wgs84_to_enu(JUELICH[0], JUELICH[1], [0.0, 1.0, 2.0], np.array(JUELICH)).shape == (3, 3)
    # one metre up is (0, 0, 1); 1e-5 deg north is about 1.11 m north
    np.testing.assert_allclose(wgs84_to_enu(JUELICH[0], JUELICH[1], JUELICH[2] + 1, JUELICH), [0, 0, 1], atol=1e-9)
    north = wgs84_to_enu(JUELICH[0] + 1e-5, JUELICH[1], JUELICH[2], JUELICH)
    assert abs(north[0]) < 1e-9 and 1.10 < north[1] < 1.12 and abs(north[2]) < 1e-6


# --------------------------------------------------------------------------- sun direction

S45 = math.sqrt(0.5)


@pytest.mark.parametrize(
    "azimuth, elevation, expected",
    [
        (0.0, 0.0, (0, -1, 0)),  # South
        (90.0, 0.0, (1, 0, 0)),  # East
        (-90.0, 0.0, (-1, 0, 0)),  # West
        (180.0, 0.0, (0, 1, 0)),  # North
        (-180.0, 0.0, (0, 1, 0)),
        (45.0, 0.0, (S45, -S45, 0)),  # South-East
        (-45.0, 0.0, (-S45, -S45, 0)),  # South-West
        (45.0, 45.0, (0.5, -0.5, S45)),
        (123.0, 90.0, (0, 0, 1)),  # zenith
    ],
)
def test_sun_enu_from_paint_hand_cases(azimuth, elevation, expected):
    np.testing.assert_allclose(sun_enu_from_paint(azimuth, elevation), expected, atol=1e-15)


def test_sun_enu_matches_pointax_azimuth_convention():
    from pointax.core.rotations import azel_to_enu

    rng = np.random.default_rng(3)
    az, el = rng.uniform(-180, 180, 100), rng.uniform(-10, 90, 100)
    ne = paint_azimuth_to_north_east(az)
    assert np.all((ne >= 0) & (ne < 360))
    np.testing.assert_allclose(paint_azimuth_to_north_east([0, 90, -90, 45]), [180, 90, 270, 135])
    want = np.asarray(azel_to_enu(np.radians(180.0 - az), np.radians(el)))
    got = sun_enu_from_paint(az, el)
    np.testing.assert_allclose(got, want, atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(got, axis=-1), 1.0, atol=1e-15)
    assert sun_enu_from_paint([[10.0, 20.0]], 30.0).shape == (1, 2, 3)


# --------------------------------------------------------------------------- the real data


@pytest.fixture(scope="module")
def aa39(shared_data) -> Path:
    folder = shared_data / "paint" / "AA39"
    if not folder.is_dir():
        pytest.skip(f"{folder} not found")
    return folder


@pytest.fixture(scope="module")
def run(aa39) -> PaintRun:
    return read_paint(aa39)


@pytest.fixture(scope="module")
def run_utis(aa39) -> PaintRun:
    return read_paint(aa39, focal_spot="UTIS")


def test_real_heliostat_properties(aa39):
    h = read_heliostat(aa39 / "heliostat-properties.json")
    assert isinstance(h, HeliostatProperties)
    # values read by hand from the file
    np.testing.assert_array_equal(h.position, [50.913643297719794, 6.3880132701249455, 88.68894196])
    assert (h.lat_deg, h.lon_deg, h.height_m) == tuple(h.position)
    np.testing.assert_array_equal(h.initial_orientation, [0.0, -1.0, 0.0])
    assert h.width == pytest.approx(3.2200000286102295) and h.height == pytest.approx(2.559999942779541)
    assert len(h.actuators) == 2 and all(isinstance(a, LinearActuator) for a in h.actuators)
    a1, a2 = h.actuators
    assert (a1.increment, a1.initial_stroke_length, a1.offset, a1.pivot_radius) == (
        154166.6667,
        0.077412795,
        0.335308,
        0.338095,
    )
    assert (a1.initial_angle, a1.clockwise, a1.min_increment, a1.max_increment) == (0.039009536, False, 0, 68745)
    assert (a1.min_movement_angle, a1.max_movement_angle) == (0.015123278, 1.570796327)
    assert (a2.initial_angle, a2.clockwise, a2.max_increment, a2.min_movement_angle) == (0.943922248, True, 75308, -0.95993)
    assert a1.offset_shift == 0 and a2.radius_shift == 0
    np.testing.assert_array_equal(h.joint_translations, np.zeros((2, 3)))
    np.testing.assert_array_equal(h.concentrator_translation, [0.0, 0.175, 0.0])
    assert h.renovation == "2021-04-15"
    with pytest.raises(ValueError):
        h.position[0] = 0.0  # read-only arrays


def test_real_calibration_sample(aa39):
    s = read_calibration(aa39 / "151375-calibration-properties.json")
    assert isinstance(s, CalibrationSample)
    assert s.sample_id == "151375" and s.target_name == "solar_tower_juelich_lower"
    np.testing.assert_array_equal(s.motor, [30076, 37935])
    assert s.sun_azimuth_deg == 50.34934144284222 and s.sun_elevation_deg == 46.22075476078824
    assert set(s.focal_spot) == {"HeliOS", "UTIS"}
    np.testing.assert_array_equal(s.focal_spot["UTIS"], [50.91339204305797, 6.387831520033172, 122.0087432861328])
    np.testing.assert_allclose(s.sun_enu, sun_enu_from_paint(s.sun_azimuth_deg, s.sun_elevation_deg))


def test_real_tower(shared_data):
    t = read_tower(shared_data / "paint" / "tower-measurements.json")
    assert isinstance(t, Tower)
    assert t.plant_id == "WRI1030197"
    np.testing.assert_array_equal(t.plant_position, [50.913421122592574, 6.387824755874856, 87.0])
    assert set(t) == {"solar_tower_juelich_upper", "solar_tower_juelich_lower", "multi_focus_tower", "receiver"}
    lower = t["solar_tower_juelich_lower"]
    assert lower.type == "planar"
    np.testing.assert_array_equal(lower.center, [50.91339203683997, 6.387824563513243, 122.8815])
    assert set(lower.corners) == {"upper_left", "upper_right", "lower_left", "lower_middle", "lower_right"}
    np.testing.assert_array_equal(lower.normal_vector, [0, 1, 0])
    assert t["receiver"].type == "convex_cylinder" and t["receiver"].extra == {"radius": 4.14, "opening_angle": 60}
    assert dict(t)["multi_focus_tower"] is t.targets["multi_focus_tower"]


def test_real_run_shapes_and_order(run, aa39):
    names = sorted(p.name for p in aa39.glob("*-calibration-properties.json"))
    assert len(run) == 18 and len(names) == 18
    assert run.sample_ids == [n.removesuffix("-calibration-properties.json") for n in names]
    assert run.sample_ids[:2] == ["151375", "158378"] and run.sample_ids[12] == "86520"  # lexicographic
    assert run.motor.shape == (18, 2) and run.sun.shape == (18, 3)
    assert run.focal_spot_enu.shape == (18, 3) and run.measured_normal.shape == (18, 3)
    assert run.focal_spot_method == ("HeliOS",) * 18
    assert Path(run.targets.path).parent == aa39.parent  # found in the parent folder
    for s, m in zip(run.samples, run.motor):
        np.testing.assert_array_equal(m, s.motor)


def test_real_motor_positions_within_limits(run):
    for k, a in enumerate(run.heliostat.actuators):
        assert np.all(run.motor[:, k] >= a.min_increment) and np.all(run.motor[:, k] <= a.max_increment)


def test_real_sun_elevation_and_units(run):
    elevation = np.array([s.sun_elevation_deg for s in run.samples])
    np.testing.assert_allclose(np.degrees(np.arcsin(run.sun[:, 2])), elevation, atol=1e-10)
    azimuth = np.array([s.sun_azimuth_deg for s in run.samples])
    np.testing.assert_allclose(np.degrees(np.arctan2(run.sun[:, 0], -run.sun[:, 1])), azimuth, atol=1e-10)
    for v in (run.sun, run.measured_normal, run.reflected):
        np.testing.assert_allclose(np.linalg.norm(v, axis=-1), 1.0, atol=1e-14)


def test_real_geometry_heliostat_north_of_tower(run):
    """AA39 sits north of the tower (the Juelich field is north of it): the focal spots
    are south of, above, and 45-66 m from the heliostat."""
    f = run.focal_spot_enu
    distance = np.linalg.norm(f, axis=-1)
    assert np.all(f[:, 1] < -25) and np.all(f[:, 1] > -30)  # about 28 m south
    assert np.all((distance > 40) & (distance < 70))
    assert np.all((f[:, 2] > 30) & (f[:, 2] < 55))  # target planes 33-51 m above the heliostat
    # each focal spot lies on its target plane, within its ~8 x 7 m area
    for s, spot in zip(run.samples, f):
        centre = wgs84_to_enu(*run.targets[s.target_name].center, run.heliostat.position)
        off = spot - centre
        assert abs(off[1]) < 0.2 and abs(off[0]) < 4 and abs(off[2]) < 3.5, (s.sample_id, off)


def test_real_measured_normals_plausible(run):
    n, sun, r = run.measured_normal, run.sun, run.reflected
    assert np.all(n[:, 2] > 0.3)  # the mirror faces up-ish
    assert np.all(n[:, 1] < 0)  # ... and south, towards the tower
    np.testing.assert_allclose(r, run.focal_spot_enu / np.linalg.norm(run.focal_spot_enu, axis=-1)[:, None], atol=1e-12)
    # angle of incidence = angle of reflection, both under 60 deg here
    incidence = np.degrees(np.arccos(np.sum(n * sun, axis=-1)))
    np.testing.assert_allclose(incidence, np.degrees(np.arccos(np.sum(n * r, axis=-1))), atol=1e-9)
    assert np.all((incidence > 5) & (incidence < 60))


def test_real_heliOS_vs_utis(run, run_utis):
    cos = np.clip(np.sum(run.measured_normal * run_utis.measured_normal, axis=-1), -1, 1)
    rms_mrad = 1e3 * math.sqrt(np.mean(np.arccos(cos) ** 2))
    assert 0.3 < rms_mrad < 2.0  # DESIGN: about 0.8 mrad RMS (measured 0.77)
    assert run_utis.focal_spot_method == ("UTIS",) * 18
    np.testing.assert_array_equal(run.sun, run_utis.sun)


def _nominal_normal(heliostat, motor):
    """DESIGN.md's nominal kinematics: n = Re(theta1) Rn(theta2) (0, 0, 1)."""
    theta = []
    for k, a in enumerate(heliostat.actuators):

        def phi(s, a=a):
            return np.arccos((a.offset**2 + a.pivot_radius**2 - s**2) / (2 * a.offset * a.pivot_radius))

        s = motor[:, k] / a.increment + a.initial_stroke_length
        d = phi(a.initial_stroke_length) - phi(s)
        theta.append(a.initial_angle + d if a.clockwise else a.initial_angle - d)
    t1, t2 = theta
    # Re(t1) Rn(t2) z = Re(t1) (sin t2, 0, cos t2)
    return np.stack([np.sin(t2), -np.sin(t1) * np.cos(t2), np.cos(t1) * np.cos(t2)], axis=-1)


def test_real_azimuth_sign_agrees_with_the_motors(run):
    """With PAINT azimuth as South = 0, East positive, the nominal kinematics explain the
    measured normals to tens of mrad (DESIGN: 13-42 mrad RMS); with the East-West
    mirror image of the sun they miss by hundreds of mrad."""
    nominal = _nominal_normal(run.heliostat, run.motor)
    err = np.arccos(np.clip(np.sum(nominal * run.measured_normal, axis=-1), -1, 1))
    assert np.median(err) < 0.02 and np.sqrt(np.mean(err**2)) < 0.045
    mirrored_sun = run.sun * np.array([-1.0, 1.0, 1.0])
    to_spot = run.focal_spot_enu / np.linalg.norm(run.focal_spot_enu, axis=-1)[:, None]
    wrong = mirrored_sun + to_spot
    wrong /= np.linalg.norm(wrong, axis=-1)[:, None]
    err_wrong = np.arccos(np.clip(np.sum(nominal * wrong, axis=-1), -1, 1))
    assert np.median(err_wrong) > 0.2


def test_real_mirror_offset(aa39, run):
    off = read_paint(aa39, mirror_offset=True)
    assert off.mirror_offset and not run.mirror_offset
    angle = np.arccos(np.clip(np.sum(off.measured_normal * run.measured_normal, axis=-1), -1, 1))
    assert np.all((angle > 1e-4) & (angle < 1.5e-3))  # 0.3-1.0 mrad on AA39
    # self-consistent: the normal bisects the sun and the ray from centre = p - 0.175 n
    centre = -0.175 * off.measured_normal
    ray = off.focal_spot_enu - centre
    b = off.sun + ray / np.linalg.norm(ray, axis=-1)[:, None]
    np.testing.assert_allclose(off.measured_normal, b / np.linalg.norm(b, axis=-1)[:, None], atol=1e-12)


def test_value_lines_on_real_file(aa39):
    path = aa39 / "heliostat-properties.json"
    lines = path.read_text().splitlines()
    increments = [k + 1 for k, line in enumerate(lines) if line.strip().startswith('"increment"')]
    table = paint._value_lines(path.read_text())
    assert table["kinematics_properties.actuators[1].increment"] == increments[1]
    assert table["kinematics_properties.actuators[0].increment"] == increments[0]
    assert table["heliostat_position"] == 2 and table["heliostat_position[2]"] == 5
    assert table[""] == 1


# --------------------------------------------------------------------------- bad input


# A small PAINT folder written here (values copied from AA39), so that the error
# tests run without the shared data.
HELIOSTAT = {
    "heliostat_position": [50.913643297719794, 6.3880132701249455, 88.68894196],
    "height": 2.559999942779541,
    "width": 3.2200000286102295,
    "initial_orientation": [0.0, -1.0, 0.0],
    "kinematics_properties": {
        "actuators": [
            {
                "type_axis": "linear",
                "min_increment": 0,
                "max_increment": 68745,
                "increment": 154166.6667,
                "offset_shift": 0,
                "initial_stroke_length": 0.077412795,
                "offset": 0.335308,
                "pivot_radius": 0.338095,
                "radius_shift": 0,
                "clockwise_axis_movement": 0,
                "initial_angle": 0.039009536,
                "min_movement_angle": 0.015123278,
                "max_movement_angle": 1.570796327,
                "movement_speed": 0,
            },
            {
                "type_axis": "linear",
                "min_increment": 0,
                "max_increment": 75308,
                "increment": 154166.6667,
                "offset_shift": 0,
                "initial_stroke_length": 0.077522286,
                "offset": 0.340771,
                "pivot_radius": 0.3191,
                "radius_shift": 0,
                "clockwise_axis_movement": 1,
                "initial_angle": 0.943922248,
                "min_movement_angle": -0.95993,
                "max_movement_angle": 0.925674074,
                "movement_speed": 0,
            },
        ],
        **{f"joint_translation_{c}_{j}": 0.0 for j in (1, 2) for c in "enu"},
        "concentrator_translation_e": 0.0,
        "concentrator_translation_n": 0.175,
        "concentrator_translation_u": 0.0,
    },
    "renovation": "2021-04-15",
}
LOWER, MULTI = "solar_tower_juelich_lower", "multi_focus_tower"
SAMPLES = {
    "151375": ((30076, 37935), LOWER, 46.22075476078824, 50.34934144284222,
               (50.91339203324901, 6.387829833293479, 122.04976089554536),
               (50.91339204305797, 6.387831520033172, 122.0087432861328)),
    "205363": ((24810, 54260), MULTI, 57.70566616209893, -2.5585424862802917,
               (50.913395618299305, 6.387574082411708, 138.68539882227918),
               (50.913395620694814, 6.387575101256503, 138.68528747558594)),
    "209075": ((28061, 47874), LOWER, 59.87137244638667, 10.872092580221869,
               (50.91339202845171, 6.387825415672288, 122.84648628718551),
               (50.91339204305797, 6.387826907411465, 122.7989273071289)),
    "field2": ((16963, 72374), MULTI, 27.809486551769538, -85.31171110078206,
               (50.91339645043245, 6.387574299623125, 137.70818056409652),
               (50.91339645480913, 6.387573933261633, 137.70894622802734)),
    "field3": ((25702, 33826), LOWER, 43.81453437734031, 68.52002947921484,
               (50.91339201932565, 6.3878282653934475, 122.50069327110258),
               (50.91339202742253, 6.3878294207790125, 122.50684356689452)),
}  # fmt: skip


def _plane(center, corners):
    return {"type": "planar", "normal_vector": [0, 1, 0], "coordinates": {"center": center, **corners}}


TOWER = {
    "power_plant_properties": {"ID": "WRI1030197", "coordinates": [50.913421122592574, 6.387824755874856, 87.0]},
    LOWER: _plane(
        [50.91339203683997, 6.387824563513243, 122.8815],
        {"upper_left": [50.913391865959426, 6.387886052532387, 126.476]},
    ),
    MULTI: _plane(
        [50.91339645088695, 6.387574436728054, 138.97975],
        {"upper_left": [50.91339628900999, 6.387612983329586, 142.175]},
    ),
}


@pytest.fixture()
def copy(tmp_path) -> Path:
    """A writable PAINT folder of 5 samples, with the tower file in its parent."""
    folder = tmp_path / "AA39"
    folder.mkdir()
    (folder / "heliostat-properties.json").write_text(json.dumps(HELIOSTAT, indent=2))
    for name, (motor, target, el, az, helios, utis) in SAMPLES.items():
        sample = {
            "motor_position": {"axis_1_motor_position": motor[0], "axis_2_motor_position": motor[1]},
            "target_name": target,
            "focal_spot": {"HeliOS": list(helios), "UTIS": list(utis)},
            "sun_elevation": el,
            "sun_azimuth": az,
        }
        (folder / f"{name}-calibration-properties.json").write_text(json.dumps(sample, indent=2))
    (tmp_path / "tower-measurements.json").write_text(json.dumps(TOWER, indent=2))
    return folder


def test_synthetic_folder_matches_real_data(copy, run):
    """The written folder reproduces the real samples it copies."""
    r = read_paint(copy)
    assert r.sample_ids == ["151375", "205363", "209075", "field2", "field3"]
    idx = [run.sample_ids.index(k) for k in r.sample_ids]
    np.testing.assert_array_equal(r.measured_normal, run.measured_normal[idx])
    np.testing.assert_array_equal(r.motor, run.motor[idx])


def edit(path: Path, change) -> str:
    """Apply ``change`` to the parsed JSON, write it back (indent 2), return the text."""
    data = json.loads(path.read_text())
    change(data)
    text = json.dumps(data, indent=2)
    path.write_text(text)
    return text


def line_of(text: str, needle: str) -> int:
    hits = [k + 1 for k, line in enumerate(text.splitlines()) if needle in line]
    assert len(hits) == 1, hits
    return hits[0]


def test_wrong_type_names_file_field_and_line(copy):
    path = copy / "heliostat-properties.json"
    text = edit(path, lambda d: d["kinematics_properties"]["actuators"][1].update(increment="abc"))
    with pytest.raises(PaintFormatError) as info:
        read_paint(copy)
    e = info.value
    assert e.path == str(path) and e.field == "kinematics_properties.actuators[1].increment"
    assert e.line == line_of(text, '"increment": "abc"')
    assert str(e).startswith(f"{path}:{e.line}: field kinematics_properties.actuators[1].increment:")
    assert "'abc'" in str(e) and "number" in str(e)


def test_bool_is_not_a_number(copy):
    path = copy / "151375-calibration-properties.json"
    edit(path, lambda d: d.update(sun_elevation=True))
    with pytest.raises(PaintFormatError, match="sun_elevation.*boolean"):
        read_calibration(path)


def test_missing_field(copy):
    path = copy / "151375-calibration-properties.json"
    edit(path, lambda d: d.pop("sun_elevation"))
    with pytest.raises(PaintFormatError) as info:
        read_paint(copy)
    assert info.value.field == "sun_elevation" and "missing" in str(info.value)
    assert info.value.path == str(path) and info.value.line == 1  # the enclosing object

    hpath = copy / "heliostat-properties.json"
    text = edit(hpath, lambda d: d["kinematics_properties"]["actuators"][0].pop("offset"))
    with pytest.raises(PaintFormatError) as info:
        read_heliostat(hpath)
    assert info.value.field == "kinematics_properties.actuators[0].offset"
    first_actuator_key = next(k + 1 for k, line in enumerate(text.splitlines()) if '"type_axis"' in line)
    assert info.value.line == first_actuator_key - 1  # the actuator's '{'


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
def test_non_finite(copy, bad):
    path = copy / "151375-calibration-properties.json"
    text = edit(path, lambda d: d["focal_spot"]["UTIS"].__setitem__(2, bad))
    with pytest.raises(PaintFormatError) as info:
        read_calibration(path)
    assert info.value.field == "focal_spot.UTIS[2]" and "finite" in str(info.value)
    assert info.value.line == line_of(text, json.dumps(bad))


def test_unknown_or_inconsistent_actuator(copy):
    """'ideal' actuators are read (tests/test_paint_actuators.py), but one whose motor
    range is in increments (AA39's 0..68745) is no ideal actuator, whose motor position
    is the joint angle in radians; other types are refused."""
    path = copy / "heliostat-properties.json"
    edit(path, lambda d: d["kinematics_properties"]["actuators"][0].update(type_axis="ideal"))
    with pytest.raises(PaintFormatError, match=r"actuators\[0\]\.max_increment.*0\.\.68745 is no range of joint angles"):
        read_heliostat(path)
    edit(path, lambda d: d["kinematics_properties"]["actuators"][0].update(type_axis="rotary"))
    with pytest.raises(PaintFormatError, match=r"actuators\[0\]\.type_axis.*'rotary'.*only 'linear' and 'ideal'"):
        read_heliostat(path)


@pytest.mark.parametrize(
    "change, field",
    [
        (lambda k: k["actuators"].pop(), "kinematics_properties.actuators"),
        (lambda k: k["actuators"].append(dict(k["actuators"][0])), "kinematics_properties.actuators"),
        (lambda k: k["actuators"][1].update(pivot_radius=-0.3), "kinematics_properties.actuators[1].pivot_radius"),
        (lambda k: k["actuators"][1].update(increment=0), "kinematics_properties.actuators[1].increment"),
        (lambda k: k["actuators"][1].update(clockwise_axis_movement=2), "kinematics_properties.actuators[1].clockwise_axis_movement"),
        (lambda k: k["actuators"][0].update(max_increment=-1), "kinematics_properties.actuators[0].max_increment"),
        (lambda k: k.update(concentrator_translation_u=None), "kinematics_properties.concentrator_translation_u"),
        (lambda k: k.update(actuators={}), "kinematics_properties.actuators"),
    ],
)
def test_bad_heliostat_fields(copy, change, field):
    path = copy / "heliostat-properties.json"
    edit(path, lambda d: change(d["kinematics_properties"]))
    with pytest.raises(PaintFormatError) as info:
        read_heliostat(path)
    assert info.value.field == field and info.value.line is not None


def test_bad_position(copy):
    path = copy / "heliostat-properties.json"
    edit(path, lambda d: d.update(heliostat_position=[95.0, 6.0, 88.0]))
    with pytest.raises(PaintFormatError, match=r"heliostat_position\[0\].*latitude"):
        read_heliostat(path)
    edit(path, lambda d: d.update(heliostat_position=[50.0, 6.0]))
    with pytest.raises(PaintFormatError, match="heliostat_position.*array of 3"):
        read_heliostat(path)


def test_malformed_json_names_file_and_line(copy):
    path = copy / "151375-calibration-properties.json"
    lines = path.read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if '"target_name"' in line)
    lines[k] = lines[k].rstrip(",")  # drop the comma after target_name's value
    path.write_text("\n".join(lines))
    with pytest.raises(PaintFormatError) as info:
        read_paint(copy)
    e = info.value
    assert e.path == str(path) and e.field is None
    assert e.line == k + 2  # the next line, where ',' was expected
    assert f"{path}:{k + 2}:" in str(e) and "malformed JSON" in str(e)


def test_not_an_object(copy):
    path = copy / "151375-calibration-properties.json"
    path.write_text("[1, 2]")
    with pytest.raises(PaintFormatError, match="JSON object"):
        read_calibration(path)


def test_empty_and_missing_directory(tmp_path):
    with pytest.raises(FileNotFoundError, match="heliostat-properties.json"):
        read_paint(tmp_path)
    with pytest.raises(FileNotFoundError, match="nowhere"):
        read_paint(tmp_path / "nowhere")


def test_missing_heliostat_properties(copy):
    (copy / "heliostat-properties.json").unlink()
    with pytest.raises(FileNotFoundError) as info:
        read_paint(copy)
    assert str(copy / "heliostat-properties.json") in str(info.value)


def test_no_calibration_files(copy):
    for p in copy.glob("*-calibration-properties.json"):
        p.unlink()
    with pytest.raises(PaintFormatError, match="no .*calibration-properties.json"):
        read_paint(copy)


def test_tower_lookup(copy, tmp_path):
    (tmp_path / "tower-measurements.json").rename(tmp_path / "elsewhere.json")
    with pytest.raises(FileNotFoundError, match="tower-measurements.json"):
        read_paint(copy)
    assert len(read_paint(copy, tower=tmp_path / "elsewhere.json")) == 5
    shutil.copy(tmp_path / "elsewhere.json", copy / "tower-measurements.json")
    assert Path(read_paint(copy).targets.path).parent == copy


def test_unknown_target(copy):
    path = copy / "209075-calibration-properties.json"
    text = edit(path, lambda d: d.update(target_name="moon"))
    with pytest.raises(PaintFormatError) as info:
        read_paint(copy)
    assert info.value.field == "target_name" and "'moon'" in str(info.value)
    assert info.value.line == line_of(text, '"moon"')


def test_bad_tower(copy, tmp_path):
    path = tmp_path / "tower-measurements.json"
    edit(path, lambda d: d["multi_focus_tower"]["coordinates"].pop("center"))
    with pytest.raises(PaintFormatError, match=r"multi_focus_tower\.coordinates\.center.*missing"):
        read_tower(path)


def test_focal_spot_fallback(copy):
    helios, utis = read_paint(copy), read_paint(copy, focal_spot="UTIS")
    edit(copy / "205363-calibration-properties.json", lambda d: d["focal_spot"].pop("HeliOS"))
    edit(copy / "field2-calibration-properties.json", lambda d: d["focal_spot"].update(HeliOS=None))
    r = read_paint(copy)
    k1, k2 = r.sample_ids.index("205363"), r.sample_ids.index("field2")
    assert r.focal_spot_method == ("HeliOS", "UTIS", "HeliOS", "UTIS", "HeliOS")
    assert (k1, k2) == (1, 3)
    for k in range(len(r)):
        want = utis if k in (k1, k2) else helios
        np.testing.assert_allclose(r.measured_normal[k], want.measured_normal[k], atol=1e-14)
    # a sample with neither method is an error
    edit(copy / "205363-calibration-properties.json", lambda d: d["focal_spot"].pop("UTIS"))
    with pytest.raises(PaintFormatError, match="focal_spot.*none of the methods"):
        read_paint(copy)


def test_bad_arguments(copy):
    with pytest.raises(ValueError, match="focal_spot"):
        read_paint(copy, focal_spot="heliOS")
    edit(copy / "heliostat-properties.json", lambda d: d["kinematics_properties"].update(concentrator_translation_e=0.1))
    assert read_paint(copy).mirror_offset is False
    # A concentrator translation across the normal is applied through the chain (it was
    # refused before both layouts were read): the centre is R1 R2 Tc.
    off = read_paint(copy, mirror_offset=True)
    np.testing.assert_allclose(off.mirror_centre, paint.mirror_centre(off.heliostat, off.measured_normal), atol=1e-15)


def test_sample_id_from_file_name(copy):
    s = read_calibration(copy / "field3-calibration-properties.json")
    assert s.sample_id == "field3"


# --------------------------------------------------------------------------- both layouts


@pytest.fixture(scope="module")
def ac43(shared_data) -> Path:
    folder = shared_data / "paint" / "AC43-schema1"
    if not folder.is_dir():
        pytest.skip(f"{folder} not found")
    return folder


def test_layout_of_current_files(aa39, run):
    h = read_heliostat(aa39 / "heliostat-properties.json")
    assert h.layout == paint.LAYOUT_CURRENT == "kinematics_properties (current)"
    assert run.layout == h.layout and h.kinematics_key == "kinematics_properties"
    np.testing.assert_array_equal(h.file_orientation, h.initial_orientation)
    assert [a.type_axis for a in h.actuators] == ["linear", "linear"]


def test_schema1_heliostat_properties(ac43):
    """Values read by hand from AC43-schema1/heliostat-properties.json."""
    h = read_heliostat(ac43 / "heliostat-properties.json")
    assert h.layout == paint.LAYOUT_SCHEMA1 == "kinematic_properties (schema 1)"
    assert h.kinematics_key == "kinematic_properties"
    np.testing.assert_array_equal(h.file_orientation, [0, 0, 1])
    np.testing.assert_array_equal(h.initial_orientation, [0, -1, 0])  # Re(pi/2) (0, 0, 1)
    assert [a.type_axis for a in h.actuators] == ["ideal", "ideal"]
    a1, a2 = h.actuators
    assert (a1.increment, a1.initial_stroke_length, a1.initial_angle, a1.clockwise) == (154166.6667, 0.071051608, 0.007796821, False)
    assert (a2.initial_stroke_length, a2.initial_angle, a2.clockwise, a2.max_increment) == (0.076357226, 0.933083607, True, 74920)
    np.testing.assert_array_equal(h.joint_translations, [[0, 0, 0], [0, 0, 0.314999997615814]])
    np.testing.assert_array_equal(h.concentrator_translation, [0, -0.177550002932549, -0.404500007629395])
    assert h.renovation == "2021-03-04"
    from pointax import HeliostatMount

    mount = HeliostatMount.from_paint(h)  # the nominal mount builds
    np.testing.assert_array_equal(np.asarray(mount.sign), [-1.0, 1.0])


def _angles(a, b):
    return np.arccos(np.clip(np.sum(a * b, axis=-1), -1, 1))


def test_schema1_run_reports_layout_and_fits(ac43):
    """AC43 (schema 1) read with the current chain: nominal errors of the size DESIGN
    gives for the current layout's heliostats (13-42 mrad RMS; measured 6.0 and 16.9
    mrad, RMS 12.7), mrad-level after a fit, and hundreds of mrad if (0, 0, 1) were
    taken literally as the current chain's orientation."""
    import pointax as px
    from pointax.analysis.heliostat import _errors

    r = read_paint(ac43)  # the tower file is in the parent folder
    assert r.layout == paint.LAYOUT_SCHEMA1 and len(r) == 2
    assert r.sample_ids == ["62900", "72752"]
    nominal = _nominal_normal(r.heliostat, r.motor)  # DESIGN's Re(theta1) Rn(theta2) (0, 0, 1), numpy
    before = _angles(nominal, r.measured_normal)
    assert np.all((before > 3e-3) & (before < 25e-3))
    assert 10e-3 < math.sqrt(np.mean(before**2)) < 45e-3
    model = px.heliostat_model(r, "t1u t2n")  # 2 samples: 4 residuals, at most 2 parameters
    np.testing.assert_allclose(_errors(model, r.observations), before, rtol=1e-9)
    # Taken literally, (0, 0, 1) in Re(theta1 - pi/2) Ru(theta2) is no mirror normal at all.
    t1 = np.arctan2(-nominal[:, 1], nominal[:, 2])
    literal = np.stack([np.zeros(2), -np.sin(t1 - np.pi / 2), np.cos(t1 - np.pi / 2)], axis=-1)
    assert np.all(_angles(literal, r.measured_normal) > 0.3)
    for mirror_offset in (False, True):
        obs = read_paint(ac43, mirror_offset=mirror_offset).observations
        result = px.fit(model, obs, loss="linear")
        assert bool(result.converged)
        after = _errors(result.model, obs)
        assert np.all(after < 3e-3), after  # measured 1.9, 1.2 mrad (2.5, 1.6 with the offset)
        assert 2 < abs(result.value("t1u")) < 15  # mrad: mostly a turn of axis 1 about Up (measured 6.0)


def test_schema1_mirror_centre(ac43):
    """The translations of schema 1 (joint 2 and concentrator) move the reflection point
    by ~0.2 m and the normals by ~1 mrad; the normals bisect the sun and the ray from
    that point, and the centre follows the chain (hand-worked poses below)."""
    plain = read_paint(ac43)
    off = read_paint(ac43, mirror_offset=True)
    assert off.mirror_offset and np.all(plain.mirror_centre == 0)
    turn = _angles(plain.measured_normal, off.measured_normal)
    assert np.all((turn > 0.5e-3) & (turn < 2e-3))  # measured 0.95, 1.05 mrad
    distance = np.linalg.norm(off.mirror_centre, axis=-1)
    assert np.all((distance > 0.1) & (distance < 0.5))
    np.testing.assert_allclose(off.mirror_centre, paint.mirror_centre(off.heliostat, off.measured_normal), atol=1e-15)
    ray = off.focal_spot_enu - off.mirror_centre
    b = off.sun + ray / np.linalg.norm(ray, axis=-1)[:, None]
    np.testing.assert_allclose(off.measured_normal, b / np.linalg.norm(b, axis=-1)[:, None], atol=1e-12)
    h = off.heliostat
    t2, tc = np.array([0, 0, 0.314999997615814]), np.array([0, -0.177550002932549, -0.404500007629395])
    # mirror vertical, facing South: theta1 = pi/2, theta2 = 0, both rotations the identity
    np.testing.assert_allclose(paint.mirror_centre(h, [0.0, -1.0, 0.0]), t2 + tc, atol=1e-15)
    # mirror facing up: theta1 = 0, Re(-pi/2) (x, y, z) = (x, z, -y)
    s = t2 + tc
    np.testing.assert_allclose(paint.mirror_centre(h, [0.0, 0.0, 1.0]), [s[0], s[2], -s[1]], atol=1e-15)
    # facing East-up: theta1 = 0, theta2 = 45 deg, Ru(45 deg) turns tc first
    c, si = math.cos(math.pi / 4), math.sin(math.pi / 4)
    inner = t2 + np.array([c * tc[0] - si * tc[1], si * tc[0] + c * tc[1], tc[2]])
    np.testing.assert_allclose(paint.mirror_centre(h, [si, 0.0, c]), [inner[0], inner[2], -inner[1]], atol=1e-15)


def _to_schema1(d):
    """The copy's heliostat file in the schema-1 layout (as AC43 writes it)."""
    kin = d.pop("kinematics_properties")
    for a in kin["actuators"]:
        a["type_axis"] = "ideal"
    d["kinematic_properties"] = kin
    d["initial_orientation"] = [0, 0, 1]


def test_schema1_copy_reads_like_the_current_layout(copy):
    current = read_paint(copy)
    edit(copy / "heliostat-properties.json", _to_schema1)
    schema1 = read_paint(copy)
    assert current.layout == paint.LAYOUT_CURRENT and schema1.layout == paint.LAYOUT_SCHEMA1
    np.testing.assert_array_equal(schema1.measured_normal, current.measured_normal)
    np.testing.assert_array_equal(schema1.heliostat.initial_orientation, current.heliostat.initial_orientation)


def test_schema1_errors_name_file_and_field(copy):
    path = copy / "heliostat-properties.json"
    text = edit(path, lambda d: (_to_schema1(d), d["kinematic_properties"]["actuators"][1].update(offset="x")))
    with pytest.raises(PaintFormatError) as info:
        read_paint(copy)
    e = info.value
    assert e.path == str(path) and e.field == "kinematic_properties.actuators[1].offset"
    assert e.line == line_of(text, '"offset": "x"') and "number" in str(e)

    edit(path, lambda d: d["kinematic_properties"]["actuators"][1].update(offset=0.34, type_axis="rotary"))
    with pytest.raises(PaintFormatError, match=r"kinematic_properties\.actuators\[1\]\.type_axis.*'rotary'.*'ideal'"):
        read_heliostat(path)
    edit(path, lambda d: (d["kinematic_properties"]["actuators"][1].update(type_axis="ideal"), d["kinematic_properties"].pop("joint_translation_u_2")))
    with pytest.raises(PaintFormatError) as info:
        read_heliostat(path)
    assert info.value.field == "kinematic_properties.joint_translation_u_2" and "missing" in str(info.value)

    edit(path, lambda d: d["kinematic_properties"].update(joint_translation_u_2=0.3))
    edit(path, lambda d: d.update(kinematics_properties=d["kinematic_properties"]))
    with pytest.raises(PaintFormatError, match="kinematic_properties.*beside kinematics_properties.*not both"):
        read_heliostat(path)
    edit(path, lambda d: (d.pop("kinematics_properties"), d.pop("kinematic_properties")))
    with pytest.raises(PaintFormatError) as info:
        read_heliostat(path)
    assert info.value.field == "kinematics_properties" and info.value.line == 1
    assert "is missing" in str(info.value) and "kinematic_properties" in str(info.value)

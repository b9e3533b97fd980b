"""Issue 30, PAINT's edges: every error raised while a PAINT file or folder is read names
the file (and the field as a JSON path, and its line, where known), whichever module
raises it; a sample whose sun position, focal spot and motor positions contradict each
other is named with both mirror normals.

Real files from ../shared/data/paint are copied into tmp_path and corrupted there.
References: the line of a field is found by searching the written text; the nominal
normal is checked against :class:`pointax.HeliostatMount`'s JAX forward model.
"""

from __future__ import annotations

import json
import re
import shutil
import warnings
from pathlib import Path

import jax
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pointax as px
from pointax.io import InputWarning
from pointax.io.paint import PaintFormatError, read_calibration, read_heliostat, read_paint, read_tower
from pointax.io.paint.run import AIM_SEPARATION_DEG, nominal_normal

SAMPLE = "151375-calibration-properties.json"


@pytest.fixture()
def folder(shared_data, tmp_path) -> Path:
    """A writable copy of the real AA39 folder (18 samples) with the tower file beside it."""
    copy = tmp_path / "AA39"
    shutil.copytree(shared_data / "paint" / "AA39", copy)
    shutil.copy(shared_data / "paint" / "tower-measurements.json", tmp_path)
    return copy


_READERS = {"calibration": read_calibration, "heliostat": read_heliostat, "tower": read_tower}


def _files(folder: Path) -> dict:
    return {
        "calibration": (folder / SAMPLE, read_calibration),
        "heliostat": (folder / "heliostat-properties.json", read_heliostat),
        "tower": (folder.parent / "tower-measurements.json", read_tower),
    }


def _set(data, keys, value):
    for key in keys[:-1]:
        data = data[key]
    if value is _DELETE:
        del data[keys[-1]]
    else:
        data[keys[-1]] = value


_DELETE = object()
_TARGET = "solar_tower_juelich_lower"

# kind, JSON keys, new value (or _DELETE), field named, words of the message
_CORRUPTIONS = [
    ("calibration", ["sun_elevation"], "46.2", "sun_elevation", "the string '46.2'.*expected a number"),
    ("calibration", ["motor_position", "axis_2_motor_position"], _DELETE, "motor_position.axis_2_motor_position", "missing"),
    ("calibration", ["sun_azimuth"], float("nan"), "sun_azimuth", "nan, expected a finite number"),
    ("calibration", ["motor_position", "axis_1_motor_position"], 10**400, "motor_position.axis_1_motor_position",
     "integer of about 401 digits"),
    ("calibration", ["focal_spot", "HeliOS"], [50.9, 6.38], "focal_spot.HeliOS", "array of 2, expected an array of 3"),
    ("heliostat", ["kinematics_properties", "actuators", 1, "pivot_radius"], [0.3],
     "kinematics_properties.actuators[1].pivot_radius", "array of 1, expected a number"),
    ("heliostat", ["width"], _DELETE, "width", "missing"),
    ("heliostat", ["heliostat_position", 2], float("inf"), "heliostat_position[2]", "inf, expected a finite number"),
    ("heliostat", ["kinematics_properties", "joint_translation_e_1"], -(10**330),
     "kinematics_properties.joint_translation_e_1", "beyond a float's range"),
    ("tower", [_TARGET, "normal_vector", 1], float("nan"), f"{_TARGET}.normal_vector[1]", "finite"),
    ("tower", [_TARGET, "coordinates", "center"], _DELETE, f"{_TARGET}.coordinates.center", "missing"),
    ("tower", ["power_plant_properties", "ID"], 30197, "power_plant_properties.ID", "expected a string"),
]  # fmt: skip


@pytest.mark.parametrize("kind, keys, value, field, words", _CORRUPTIONS, ids=lambda x: x if isinstance(x, str) else None)
def test_corrupted_real_file_names_file_field_and_line(folder, kind, keys, value, field, words):
    path, reader = _files(folder)[kind]
    data = json.loads(path.read_text())
    _set(data, keys, value)
    text = json.dumps(data, indent=2)  # NaN and Infinity as Python's json writes them
    path.write_text(text)
    for read, where in ((reader, path), (read_paint, folder)):  # alone and within its folder
        with pytest.raises(PaintFormatError) as info:
            read(where)
        err = info.value
        assert err.path == str(path) and err.field == field, (err.path, err.field)
        assert str(err).startswith(f"{path}:{err.line}: field {field}: "), str(err)
        assert re.search(words, str(err)), str(err)
        if value is not _DELETE:  # the line of the value written
            written = json.dumps(keys[-1]) + ":" if isinstance(keys[-1], str) else json.dumps(value)
            assert text.splitlines()[err.line - 1].strip().startswith(written)


@pytest.mark.parametrize("kind", ["calibration", "heliostat", "tower"])
def test_truncated_real_file_names_file_and_line(folder, kind):
    path, reader = _files(folder)[kind]
    text = path.read_text()
    cut = text[: len(text) * 2 // 3]
    path.write_text(cut)
    with pytest.raises(PaintFormatError) as info:
        reader(path)
    assert str(info.value).startswith(f"{path}:{len(cut.splitlines())}: malformed JSON"), str(info.value)


def test_unreadably_long_integer_names_the_file(folder):
    path = folder / SAMPLE
    path.write_text(path.read_text().replace("30076", "9" * 5000))  # beyond Python's int-to-string limit
    with pytest.raises(PaintFormatError, match=rf"^{re.escape(str(path))}: unreadable JSON"):
        read_calibration(path)


# ---------------------------------------------------------------- the root: errors of any module


def test_unexpected_error_inside_a_reader_names_file_and_field(folder, monkeypatch):
    """An error of a kind no check raises (here planted in the array helper every reader
    calls after reading its numbers) leaves each reader as a PaintFormatError naming
    the file and the field last read, with its line."""
    from pointax.io.paint import files

    def broken(values):
        raise TypeError("planted")

    monkeypatch.setattr(files, "frozen_array", broken)
    path = folder / SAMPLE
    with pytest.raises(PaintFormatError) as info:
        read_calibration(path)
    err = info.value
    assert err.path == str(path) and err.field == "motor_position.axis_2_motor_position"
    assert str(err) == (
        f"{path}:4: field motor_position.axis_2_motor_position: TypeError: planted (while reading this field)"
    )
    assert isinstance(err.__cause__, TypeError)
    for reader, name in ((read_heliostat, "heliostat-properties.json"),):
        with pytest.raises(PaintFormatError, match=rf"^{re.escape(str(folder / name))}:\d+: field .*TypeError: planted"):
            reader(folder / name)


def test_unexpected_error_in_a_folder_names_the_folder(folder, monkeypatch):
    from pointax.io.paint import run

    def broken(*args):
        raise ZeroDivisionError("planted")

    monkeypatch.setattr(run, "wgs84_to_enu", broken)
    with pytest.raises(PaintFormatError, match=rf"^{re.escape(str(folder))}: ZeroDivisionError: planted$"):
        read_paint(folder)


def test_bad_arguments_and_missing_files_pass_as_they_are(folder):
    with pytest.raises(ValueError, match="unknown focal_spot method"):
        read_paint(folder, focal_spot="nosuch")
    with pytest.raises(FileNotFoundError):
        read_calibration(folder / "nosuch-calibration-properties.json")


# ---------------------------------------------------------------- property: random corruption

_KINDS = ["calibration", "heliostat", "tower"]
_VALUES = [None, True, "x", 1e308, 10**400, float("nan"), float("-inf"), [], {}, [1.0, 2.0], [1, 2, 3], {"a": 1}, -1, 0]


def _paths(data, prefix=()):
    yield prefix
    items = data.items() if isinstance(data, dict) else enumerate(data) if isinstance(data, list) else ()
    for key, value in items:
        yield from _paths(value, prefix + (key,))


def _read_checked(reader, path: Path) -> None:
    """Read, or a PaintFormatError whose message starts with the file; nothing else."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        try:
            reader(path)
        except PaintFormatError as err:
            assert str(err).startswith(str(path)), err


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(kind=st.sampled_from(_KINDS), data=st.data())
def test_random_values_give_only_paint_errors(shared_data, tmp_path, kind, data):
    source = {
        "calibration": shared_data / "paint" / "AA39" / SAMPLE,
        "heliostat": shared_data / "paint" / "AA39" / "heliostat-properties.json",
        "tower": shared_data / "paint" / "tower-measurements.json",
    }[kind]
    doc = json.loads(source.read_text())
    keys = data.draw(st.sampled_from(list(_paths(doc))[1:]))
    _set(doc, list(keys), data.draw(st.sampled_from(_VALUES + [_DELETE])))
    path = tmp_path / source.name
    path.write_text(json.dumps(doc, indent=1))
    _read_checked(_READERS[kind], path)


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(kind=st.sampled_from(_KINDS), data=st.data())
def test_random_bytes_give_only_paint_errors(shared_data, tmp_path, kind, data):
    source = {
        "calibration": shared_data / "paint" / "AA39" / SAMPLE,
        "heliostat": shared_data / "paint" / "AC43-schema1" / "heliostat-properties.json",
        "tower": shared_data / "paint" / "tower-measurements.json",
    }[kind]
    raw = source.read_bytes()
    where = data.draw(st.integers(0, len(raw)))
    cut = data.draw(st.integers(0, 4))
    path = tmp_path / source.name
    path.write_bytes(raw[:where] + data.draw(st.binary(min_size=0, max_size=6)) + raw[where + cut :])
    _read_checked(_READERS[kind], path)


# ---------------------------------------------------------------- contradicting samples


def test_nominal_normal_matches_the_heliostat_mount(shared_data):
    """The numpy nominal kinematics of the reader against HeliostatMount's JAX forward
    model, on both layouts and beyond the samples' motor range."""
    for name in ("AA39", "AC43-schema1"):
        heliostat = read_heliostat(shared_data / "paint" / name / "heliostat-properties.json")
        mount = px.HeliostatMount.from_paint(heliostat)
        rng = np.random.default_rng(3)
        lo = [a.min_increment for a in heliostat.actuators]
        hi = [a.max_increment for a in heliostat.actuators]
        motor = rng.uniform(lo, hi, (50, 2))
        expected = np.asarray(jax.vmap(lambda m: mount.direction(mount.axis_angles(m)))(motor))
        np.testing.assert_allclose(nominal_normal(heliostat, motor), expected, atol=1e-12)


def test_real_folders_have_no_contradicting_samples(shared_data):
    for name in ("AA39", "AC43-schema1"):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            read_paint(shared_data / "paint" / name)


def test_sample_with_a_sun_position_of_another_time_is_named(folder):
    """One real sample's sun azimuth moved by 60 deg (a sun position of another time):
    its measured normal lies about 30 deg from where its motors point the mirror. The
    warning names the sample's file and both normals; the others are not named."""
    path = folder / "202558-calibration-properties.json"
    data = json.loads(path.read_text())
    data["sun_azimuth"] -= 60.0
    path.write_text(json.dumps(data, indent=2))
    with pytest.warns(InputWarning) as record:
        run = read_paint(folder)
    (w,) = record
    assert w.filename == __file__  # the user's line
    message = str(w.message)
    assert message.startswith(f"{path}: 1 of 18 samples have their measured mirror normal")
    shown = re.search(
        r"202558-calibration-properties\.json: (\d+\.\d) deg \(measured az (\S+) el (\S+), nominal az (\S+) el (\S+) deg\)",
        message,
    )
    assert shown, message
    k = run.sample_ids.index("202558")
    normal = run.measured_normal[k]
    assert float(shown.group(2)) == pytest.approx(np.degrees(np.arctan2(normal[0], normal[1])) % 360, abs=0.01)
    assert float(shown.group(3)) == pytest.approx(np.degrees(np.arcsin(normal[2])), abs=0.01)
    nominal = nominal_normal(run.heliostat, run.motor[k : k + 1])[0]
    assert float(shown.group(4)) == pytest.approx(np.degrees(np.arctan2(nominal[0], nominal[1])) % 360, abs=0.01)
    assert float(shown.group(1)) > AIM_SEPARATION_DEG
    assert len(run) == 18  # warned of, not dropped


def test_sample_with_a_mistyped_motor_position_is_named(folder):
    path = folder / "field2-calibration-properties.json"
    data = json.loads(path.read_text())
    data["motor_position"]["axis_1_motor_position"] //= 4  # a digit lost
    path.write_text(json.dumps(data, indent=2))
    with pytest.warns(InputWarning, match=r"field2-calibration-properties\.json: 1 of 18 samples .*field2-calibration-"
                      r"properties\.json: \d+\.\d deg \(measured az"):
        read_paint(folder)

"""Property tests (issue 20, item 6), with hypothesis:

* a random corruption of a valid file of every format (TPOINT run and model, gpoint,
  sun, X-Y, PAINT calibration) never gives a traceback of another kind and never a
  silent success: the reader raises its FileFormatError (naming the file) or issues an
  InputWarning;
* a fit to observations simulated without noise from a random model gives back the
  model with residuals of zero;
* the inverse of a random model points where it was asked: forward(inverse(d)) = d.

References: the corruptions are chosen to be invalid by each format's definition (a
field that is not a number, not finite or out of every angle's range; a wrong number
of fields; a record written twice); the fit and the inverse are checked against the
forward model that made the data.
"""

from __future__ import annotations

import json
import math
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pointax as px
from pointax.io import FileFormatError, InputWarning
from pointax.core.rotations import azel_to_enu_numpy

from conftest import MMT_DAT, MMT_MOD, SHARED_DATA

GPOINT = Path(__file__).parent / "data" / "gpoint" / "altaz_manual.txt"
PAINT = SHARED_DATA / "paint" / "AA39"
SUN_TEXT = "# alpha beta sun_az sun_el\n" + "\n".join(
    f"{279.4 - 5 * k:.3f} {216.5 + k:.3f} {141.0 + 6 * k:.3f} {50.5 + 0.8 * k:.3f}" for k in range(12)
)
XY_TEXT = "\n".join(f"{-40 + 7 * k:.2f} {-30 + 5 * k:.2f} {-40 + 7 * k + 0.01:.2f} {-30 + 5 * k + 0.02:.2f}" for k in range(12))

FAST = settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _data_lines(lines: list[str], is_data) -> list[int]:
    return [k for k, line in enumerate(lines) if is_data(line)]


def _tpoint_run_data(line: str) -> bool:
    tokens = line.split()
    return len(tokens) == 4 and not line.startswith("!")


def _tpoint_model_data(line: str) -> bool:
    tokens = line.split()
    return len(tokens) == 3 and tokens[0][0].isalpha() and tokens[0] != "T"


def _gpoint_data(line: str) -> bool:
    return bool(line.strip()) and not line.startswith("#")


def _plain_data(line: str) -> bool:
    return bool(line.strip()) and not line.startswith("#")


FORMATS = {
    # name: (text, which lines are data, reader, corruptions that are invalid there)
    "tpoint": (MMT_DAT.read_text(), _tpoint_run_data, lambda p: px.io.read_tpoint(p, azimuth="S-E"),
               ("garbage", "nonfinite", "huge", "drop", "extra2", "twice")),
    "tpoint-model": (MMT_MOD.read_text(), _tpoint_model_data, px.io.read_model,
                     ("garbage", "nonfinite", "extra2", "twice")),
    "gpoint": (GPOINT.read_text(), _gpoint_data, px.io.read_gpoint,
               ("garbage", "nonfinite", "drop", "extra2", "twice")),
    "sun": (SUN_TEXT, _plain_data, px.io.read_sun_observations,
            ("garbage", "nonfinite", "huge", "drop", "extra2", "twice")),
    "xy": (XY_TEXT, _plain_data, px.io.read_xy_run, ("garbage", "nonfinite", "huge", "drop", "extra2", "twice")),
}


def _corrupt(text: str, is_data, kind: str, line_pick: int, field_pick: int, junk: str, big: float) -> str:
    lines = text.splitlines()
    rows = _data_lines(lines, is_data)
    k = rows[line_pick % len(rows)]
    tokens = lines[k].split()
    # gpoint's first field is the observation id (any text), TPOINT models' the name.
    first = 1 if is_data in (_gpoint_data, _tpoint_model_data) else 0
    j = first + field_pick % (len(tokens) - first)
    if kind == "garbage":
        tokens[j] = "x" + junk
    elif kind == "nonfinite":
        tokens[j] = ("nan", "inf", "-inf", "+nan")[field_pick % 4]
    elif kind == "huge":
        tokens[j] = f"{big:.3f}"
    elif kind == "drop":
        del tokens[j]
    elif kind == "extra2":
        tokens += ["1.0", "2.0"]
    if kind == "twice":
        lines.insert(k + 1, lines[k])
    else:
        lines[k] = " ".join(tokens)
    return "\n".join(lines) + "\n"


@FAST
@given(
    fmt=st.sampled_from(sorted(FORMATS)),
    kind_pick=st.integers(0, 100),
    line_pick=st.integers(0, 10_000),
    field_pick=st.integers(0, 100),
    junk=st.text(alphabet="abcdefghijklmnopqrstuvwxyz_;:%", min_size=0, max_size=6),
    big=st.floats(1000.0, 1e9) | st.floats(-1e9, -1000.0),
)
def test_corrupted_files_are_refused_or_flagged(tmp_path, fmt, kind_pick, line_pick, field_pick, junk, big):
    text, is_data, read, kinds = FORMATS[fmt]
    kind = kinds[kind_pick % len(kinds)]
    path = tmp_path / f"corrupt-{fmt}.txt"
    path.write_text(_corrupt(text, is_data, kind, line_pick, field_pick, junk, big))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            read(path)
        except FileFormatError as err:
            assert str(path) in str(err)
            return
    flagged = [w for w in caught if issubclass(w.category, InputWarning)]
    assert flagged, f"{fmt}: corruption {kind!r} was read without an error or a warning"
    assert str(path) in str(flagged[0].message)


@pytest.mark.skipif(not PAINT.is_dir(), reason=f"{PAINT} not found")
@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    kind=st.sampled_from(["motor-high", "motor-low", "elevation", "drop-key", "truncate", "text-number"]),
    pick=st.integers(0, 1000),
)
def test_corrupted_paint_samples_are_refused(tmp_path_factory, kind, pick):
    tmp = tmp_path_factory.mktemp("paint")
    folder = tmp / "AA39"
    shutil.copytree(PAINT, folder)
    shutil.copy(SHARED_DATA / "paint" / "tower-measurements.json", tmp / "tower-measurements.json")
    files = sorted(folder.glob("*-calibration-properties.json"))
    path = files[pick % len(files)]
    text = path.read_text()
    data = json.loads(text)
    axis = 1 + pick % 2
    if kind == "motor-high":
        data["motor_position"][f"axis_{axis}_motor_position"] = 80_000 + pick * 1000
    elif kind == "motor-low":
        data["motor_position"][f"axis_{axis}_motor_position"] = -1 - pick
    elif kind == "elevation":
        data["sun_elevation"] = 90.5 + pick
    elif kind == "drop-key":
        del data[("motor_position", "sun_azimuth", "sun_elevation", "focal_spot")[pick % 4]]
    elif kind == "text-number":
        data["sun_azimuth"] = "fifty"
    path.write_text(text[: len(text) * (pick % 90 + 5) // 100] if kind == "truncate" else json.dumps(data, indent=2))
    with pytest.raises(FileFormatError) as info:
        px.io.read_paint(folder)
    assert path.name in str(info.value)


# ------------------------------------------------------------------ fit and inverse

TERMS = "IA IE CA NPAE AN AW TF"
values_arcsec = st.lists(st.floats(-300.0, 300.0), min_size=7, max_size=7)


def _model(values):
    return px.AltAz(px.terms.tpoint(TERMS, values={n: px.arcsec(v) for n, v in zip(TERMS.split(), values)}))


@settings(max_examples=8, deadline=None)
@given(values=values_arcsec)
def test_fit_of_exact_simulated_data_gives_the_model_back(values):
    from pointax.core.simulate import encoder_grid

    truth = _model(values)
    obs = px.simulate(truth, encoder_grid(n_az=8, elevations_deg=(15, 30, 45, 60, 75)))
    result = px.fit(_model([0.0] * 7), obs)
    assert bool(result.converged)
    assert float(result.sky_rms) < 1e-11
    assert float(np.max(np.abs(np.asarray(result.residuals)))) < 1e-10
    np.testing.assert_allclose(np.asarray(result.values), np.asarray(truth.values()), rtol=0, atol=1e-10)


@settings(max_examples=8, deadline=None)
@given(
    values=values_arcsec,
    az=st.lists(st.floats(0.0, 360.0), min_size=8, max_size=8),
    el=st.lists(st.floats(0.5, 89.0), min_size=8, max_size=8),
)
def test_forward_of_inverse_is_the_direction(values, az, el):
    model = _model(values)
    d = azel_to_enu_numpy(np.radians(az), np.radians(el))
    c = px.command(model, d)
    assert bool(np.all(np.asarray(c.ok))), c.reasons()
    assert np.all(np.asarray(c.solution) == 0)  # the normal solution unless asked
    back = np.asarray(model(np.asarray(c.reading)))
    cos = np.clip(np.sum(back * d, axis=-1), -1.0, 1.0)
    err = np.arctan2(np.linalg.norm(np.cross(back, d), axis=-1), cos)
    assert float(np.max(err)) < 1e-10
    assert np.all(np.abs(np.degrees(np.asarray(c.reading)[:, 1])) <= 90.5)
    assert math.isfinite(float(np.max(err)))

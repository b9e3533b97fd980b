"""Auxiliary readings read from files (issue 31): TPOINT's auxiliary fields and run
weather, offsets tables' named columns, gpoint's times, PAINT's sun position and time.
References: numbers read by hand from the text, astropy's Time for MJDs, the readers'
own (independently tested) positions for the sun's angles."""

from __future__ import annotations

import json
import math
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from astropy.time import Time

from pointax.io import load_run
from pointax.io.gpoint import read_gpoint
from pointax.io.offsets import OffsetsFormatError, parse_offsets
from pointax.io.paint import read_paint
from pointax.io.paint.document import PaintFormatError
from pointax.io.tpoint import TpointFormatError, parse_tpoint, read_tpoint

HERE = Path(__file__).parent
SHARED = HERE.parent.parent / "shared" / "data"
MMT_DAT = SHARED / "tpoint" / "mmt_20210821.dat"
TPOINT_FILES = sorted((SHARED / "tpoint").rglob("*.dat")) + sorted((HERE / "data" / "tpoint").glob("*.dat"))

ALTAZ = ["aux run", ": ALTAZ", "+31 41 19.6 2021 8 21 13.0 741 2608 0.75"]
ROWS = ["192.386 77.347 -167.278 77.348 5.5 -1", "193.389 77.285 -166.276 77.286 6.5 2.25"]


def _mjd(iso: str) -> float:
    return float(Time(iso, scale="utc").mjd)


# ------------------------------------------------------------------------ TPOINT


def test_tpoint_auxiliary_fields_and_run_weather_become_readings():
    run = parse_tpoint("\n".join(ALTAZ + ROWS) + "\n", "run.dat")
    r = run.observations.readings
    assert set(r) == {"aux1", "aux2", "temperature", "pressure", "humidity", "time"}
    np.testing.assert_array_equal(r["aux1"], [5.5, 6.5])  # as written
    np.testing.assert_array_equal(r["aux2"], [-1.0, 2.25])
    np.testing.assert_array_equal(r["temperature"], [13.0, 13.0])  # deg C, every record
    np.testing.assert_array_equal(r["pressure"], [741.0, 741.0])  # mB = hPa
    np.testing.assert_array_equal(r["humidity"], [0.75, 0.75])
    np.testing.assert_array_equal(r["time"], [_mjd("2021-08-21T00:00:00")] * 2)
    assert r["time"][0] == 59447.0
    assert run.readings.keys() == r.keys()
    assert any("field 5 -> aux1, field 6 -> aux2" in note for note in run.notes)


def test_tpoint_auxiliary_fields_named_by_the_caller():
    run = parse_tpoint("\n".join(ALTAZ + ROWS) + "\n", "run.dat", auxiliary=("temperature", "tilt_1"))
    r = run.readings
    np.testing.assert_array_equal(r["temperature"], [5.5, 6.5])  # the records' replace the header's
    np.testing.assert_allclose(r["tilt_1"], np.radians([-1.0, 2.25]), rtol=1e-15)  # degrees -> radians
    np.testing.assert_array_equal(r["aux1"], [5.5, 6.5])  # still known by position
    assert any("replaces the run parameters' temperature" in note for note in run.notes)
    with pytest.raises(TpointFormatError, match=r"run\.dat:4: auxiliary= names 3 auxiliary readings, but the records carry 2"):
        parse_tpoint("\n".join(ALTAZ + ROWS) + "\n", "run.dat", auxiliary=("a", "b", "c"))
    with pytest.raises(ValueError, match="given twice"):
        parse_tpoint("\n".join(ALTAZ + ROWS) + "\n", auxiliary=("a", "a"))


def test_tpoint_rotator_option_gives_the_rotator_reading_in_radians():
    rows = [r.rsplit(" ", 2)[0] + " 12.5" for r in ROWS]
    with pytest.warns(UserWarning, match="reading 'rotator'"):
        run = parse_tpoint("\n".join(ALTAZ[:2] + [": ROTNR"] + ALTAZ[2:] + rows) + "\n", "run.dat")
    np.testing.assert_allclose(run.readings["rotator"], math.radians(12.5))
    np.testing.assert_array_equal(run.readings["aux1"], [12.5, 12.5])
    assert not any("position" in note for note in run.notes)  # the option names it


def test_tpoint_three_auxiliary_fields_on_equatorial_records():
    header = ["Equatorial test", ": EQUAT", "+33 21 22.0 2023 9 20 10.0 0.0"]
    rows = [
        "11 34 40.6642 +30 09 07.934 11 34 38.3798 +30 10 14.074  12 00.000  1 2 3",
        "11 59 14.8860 -00 04 58.775 11 59 12.0919 -00 03 49.158  12 00.000  4 5 6",
    ]
    run = parse_tpoint("\n".join(header + rows) + "\n")
    assert run.extra.shape == (2, 3) and len(run) == 2
    np.testing.assert_array_equal(run.readings["aux3"], [3.0, 6.0])
    np.testing.assert_array_equal(run.readings["pressure"], [0.0, 0.0])
    assert "humidity" not in run.readings  # the record does not give it
    np.testing.assert_array_equal(run.readings["time"], [_mjd("2023-09-20")] * 2)


@pytest.mark.parametrize("bad, field", [("x", 6), ("nan", 6), ("1e999", 6)])
def test_tpoint_malformed_auxiliary_value_names_file_line_and_field(bad, field):
    rows = [ROWS[0], ROWS[1].rsplit(" ", 1)[0] + " " + bad]
    with pytest.raises(TpointFormatError, match=rf"run\.dat:5: observation record: field {field} \(auxiliary reading 2\)"):
        parse_tpoint("\n".join(ALTAZ + rows) + "\n", "run.dat")


def test_tpoint_impossible_date_is_refused():
    with pytest.raises(TpointFormatError, match=r"run\.dat:3: .*2021 2 30 is not a date"):
        parse_tpoint("cap\n: ALTAZ\n+31 41 19.6 2021 2 30\n10 20 11 21\n", "run.dat")


@pytest.mark.parametrize("path", TPOINT_FILES, ids=lambda p: p.name)
def test_every_tpoint_file_at_hand_reads_with_its_run_readings(path):
    kw = {"azimuth": "S-E"} if path == MMT_DAT else {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the files' own warnings are other tests' business
        run = read_tpoint(path, **kw)
    p = run.parameters
    r = run.observations.readings
    for name, value in (("temperature", p.temperature_c), ("pressure", p.pressure_mb), ("humidity", p.humidity)):
        if value is None:
            assert name not in r
        else:
            np.testing.assert_array_equal(r[name], np.full(len(run), value))
    if p.date is not None:
        np.testing.assert_array_equal(r["time"], _mjd("{:04d}-{:02d}-{:02d}".format(*p.date)))


def test_mmt_run_readings_by_hand():
    run = read_tpoint(MMT_DAT, azimuth="S-E")  # header: +31 41 19.6 2021 8 21 13.0 741 2608.0 0.75
    assert run.readings["temperature"][0] == 13.0 and run.readings["pressure"][0] == 741.0
    assert run.readings["humidity"][0] == 0.75 and run.readings["time"][0] == _mjd("2021-08-21")
    assert not any(k.startswith("aux") for k in run.readings)


def test_load_run_passes_auxiliary_names(tmp_path):
    path = tmp_path / "run.dat"
    path.write_text("\n".join(ALTAZ + ROWS) + "\n")
    run = load_run(path, auxiliary=("temperature",))
    np.testing.assert_array_equal(run.observations.readings["temperature"], [5.5, 6.5])


# ----------------------------------------------------------------------- offsets

TABLE = """source,Az [deg],El [deg],dXEL,dEL,T_air [K],RH,time,rot,focus [mm]
src00,184.255785,34.183387,-49.502,-15.577,280.15,45,2021-08-21T13:00:00Z,10,1.5
src01,14.255785,54.183387,-9.502,-5.577,,50,59447.5,20,2.5
src02,94.255785,24.183387,9.502,5.577,281.15,55,2021-08-21T15:30:00+02:00,30,nan
"""


def test_offsets_named_columns_become_readings():
    run = parse_offsets(TABLE, "t.csv")
    r = run.observations.readings
    assert set(r) == {"temperature", "humidity", "time", "rotator", "focus [mm]"}
    np.testing.assert_allclose(r["temperature"], [7.0, np.nan, 8.0], atol=1e-12)  # K -> deg C, empty: not recorded
    np.testing.assert_allclose(r["humidity"], [0.45, 0.50, 0.55])  # values above 1: percent
    np.testing.assert_allclose(
        r["time"], [_mjd("2021-08-21T13:00:00"), 59447.5, _mjd("2021-08-21T13:30:00")], rtol=0, atol=1e-9
    )
    np.testing.assert_allclose(r["rotator"], np.radians([10, 20, 30]), rtol=1e-15)  # degrees by default
    np.testing.assert_array_equal(r["focus [mm]"], [1.5, 2.5, np.nan])  # a user reading keeps its header name
    assert run.reading_columns["temperature"] == (6, "T_air [K]")
    assert any("column 1 (source) holds text" in n for n in run.notes)
    assert any("humidity above 1 read as percent" in n for n in run.notes)


def test_offsets_time_units_and_ambiguous_names():
    text = "az,el,dxel,del,MJD,jd_obs,temp,T_air\n10,40,1,2,59000.25,2459000.75,5,6\n20,50,1,2,59001,2459001.5,7,8\n"
    run = parse_offsets(text, "t.csv")
    r = run.readings
    np.testing.assert_array_equal(r["time"], [59000.25, 59001.0])  # MJD by its name
    np.testing.assert_array_equal(r["jd_obs"], [2459000.75, 2459001.5])  # no standard name: as written
    assert "temperature" not in r  # two columns could be it: both keep their header names
    np.testing.assert_array_equal(r["temp"], [5.0, 7.0])
    np.testing.assert_array_equal(r["T_air"], [6.0, 8.0])
    assert any("could each be 'temperature'" in n for n in run.notes)
    run = parse_offsets("az,el,dxel,del,time [jd],p_air [Pa]\n10,40,1,2,2459000.75,101325\n20,50,1,2,2459001.5,100000\n")
    np.testing.assert_allclose(run.readings["time"], [_mjd("2020-05-31T06:00:00"), 59001.0], atol=1e-9)
    np.testing.assert_allclose(run.readings["pressure"], [1013.25, 1000.0])
    run = parse_offsets("az el dxel del unix_time\n10 40 1 2 1629550800\n20 50 1 2 1629554400\n")
    np.testing.assert_allclose(run.readings["time"], [_mjd("2021-08-21T13:00:00"), _mjd("2021-08-21T14:00:00")], atol=1e-9)


@pytest.mark.parametrize(
    "row, match",
    [
        ("20,50,1,2,x", r"t\.csv:3: column 5 \(temp\): 'x' is not a number"),
        ("20,50,1,2,inf", r"t\.csv:3: column 5 \(temp\): 'inf' is not finite"),
    ],
)
def test_offsets_malformed_reading_names_file_line_and_column(row, match):
    with pytest.raises(OffsetsFormatError, match=match):
        parse_offsets("az,el,dxel,del,temp\n10,40,1,2,5\n" + row + "\n", "t.csv")
    with pytest.raises(OffsetsFormatError, match=r"t\.csv:1: column 5 \(temp \[psi\]\): unit 'psi' is not one"):
        parse_offsets("az,el,dxel,del,temp [psi]\n10,40,1,2,5\n", "t.csv")
    with pytest.raises(OffsetsFormatError, match=r"t\.csv:3: column 5 \(utc\): 'yesterday' is not an ISO 8601"):
        parse_offsets("az,el,dxel,del,utc\n10,40,1,2,2021-08-21T13:00:00\n20,50,1,2,yesterday\n", "t.csv")


def test_offsets_files_at_hand_keep_reading():
    for path in sorted((HERE / "data" / "offsets").iterdir()):
        options = {"azimuth": "S-E", "cross_elevation": False, "units": "deg"} if "plain" in path.name else {}
        run = load_run(path, format="offsets", **options)
        assert run.readings == {} and len(run.observations) == len(run)


# ------------------------------------------------------------------------ gpoint


@pytest.mark.parametrize("name", ["altaz_manual.txt", "gem.txt"])
def test_gpoint_time_is_the_mjd_of_the_files_julian_date(name):
    run = read_gpoint(HERE / "data" / "gpoint" / name)
    want = Time(run.time, format="jd", scale="utc").mjd
    np.testing.assert_allclose(run.observations.readings["time"], want, rtol=0, atol=1e-9)


def test_gpoint_time_already_an_mjd_is_kept(tmp_path):
    src = (HERE / "data" / "gpoint" / "altaz_manual.txt").read_text().splitlines()
    rows = [line.split("\t") for line in src[2:]]
    for row in rows:
        row[1] = f"{float(row[1]) - 2400000.5:.6f}"
    path = tmp_path / "mjd.txt"
    path.write_text("\n".join(src[:2] + ["\t".join(r) for r in rows]) + "\n")
    run = read_gpoint(path)
    np.testing.assert_allclose(run.readings["time"], run.time, rtol=0, atol=0)


# ------------------------------------------------------------------------- PAINT

AA39 = SHARED / "paint" / "AA39"


def test_paint_sun_position_readings_match_the_sun_directions():
    run = read_paint(AA39)
    r = run.observations.readings
    assert set(r) == {"sun_azimuth", "sun_elevation"}  # these files carry no times
    east, north, up = run.sun.T
    np.testing.assert_allclose(r["sun_elevation"], np.arcsin(up), atol=1e-12)
    np.testing.assert_allclose(np.cos(r["sun_azimuth"]), north / np.hypot(east, north), atol=1e-12)
    np.testing.assert_allclose(np.sin(r["sun_azimuth"]), east / np.hypot(east, north), atol=1e-12)
    stored = json.loads((AA39 / "151375-calibration-properties.json").read_text())
    k = run.sample_ids.index("151375")
    assert r["sun_azimuth"][k] == pytest.approx(math.radians(180.0 - stored["sun_azimuth"]), abs=1e-15)


def test_paint_time_from_the_stac_item_or_the_properties(tmp_path):
    folder = tmp_path / "AA39"
    shutil.copytree(AA39, folder)
    (folder / "151375-calibration-item-stac.json").write_text(
        json.dumps({"type": "Feature", "properties": {"datetime": "2022-06-01T10:15:00Z"}})
    )
    props = folder / "158378-calibration-properties.json"
    doc = json.loads(props.read_text())
    doc["timestamp"] = "2022-06-02T08:00:00+02:00"
    props.write_text(json.dumps(doc))
    tower = SHARED / "paint" / "tower-measurements.json"
    run = read_paint(folder, tower=tower)
    t = run.observations.readings["time"]
    ids = run.sample_ids
    assert t[ids.index("151375")] == pytest.approx(_mjd("2022-06-01T10:15:00"), abs=1e-9)
    assert t[ids.index("158378")] == pytest.approx(_mjd("2022-06-02T06:00:00"), abs=1e-9)
    assert np.isnan(t[ids.index("177577")])  # no time given: not recorded
    doc["timestamp"] = 12345
    props.write_text(json.dumps(doc))
    with pytest.raises(PaintFormatError, match=r"158378-calibration-properties\.json.*timestamp.*ISO 8601"):
        read_paint(folder, tower=tower)


def test_tpoint_auxiliary_names_that_would_clash_are_refused():
    with pytest.raises(ValueError, match="'aux2' names field 1's reading"):
        parse_tpoint("\n".join(ALTAZ + ROWS) + "\n", auxiliary=("aux2",))
    run = parse_tpoint("\n".join(ALTAZ + ROWS) + "\n", auxiliary=(None, "time"))  # an MJD per record
    np.testing.assert_array_equal(run.readings["time"], [-1.0, 2.25])
    assert not any(note.startswith("time: the run parameters' date") for note in run.notes)

"""Tests of pointax.io.offsets: tables of pointing offsets (radio telescopes, star trackers).

Independent references: the real MMT run and TPOINT's own fit of it (an offsets table
written from the TPOINT file must give the same directions and TPOINT's coefficients:
this pins the sign convention, observed minus raw, and the cross-elevation sense), a
direction worked by hand, and simulated tables (tests/data/offsets/, written from a known
model by the script described in their comments) whose terms the fit must recover.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from conftest import MMT_DAT, MMT_MOD, REPO

import pointax as px
from pointax.io.errors import FileFormatError, InputWarning
from pointax.io.offsets import OffsetsFormatError, OffsetsRun, parse_offsets, read_offsets

ARCSEC = np.pi / 648000
DATA = REPO / "tests" / "data" / "offsets"
TRUE = {"IA": 45.0, "IE": -20.0, "CA": 12.0, "NPAE": -8.0, "AN": 6.0, "AW": -4.0}
SIX = "IA IE CA NPAE AN AW"


def fit6(run: OffsetsRun):
    return px.fit(px.AltAz(px.terms.tpoint(SIX), azimuth=run.azimuth), run.observations)


# --------------------------------------------------------------------------- the real MMT run


def _mmt_table(sep=" ", xel=True, flip=False, units="arcsec"):
    """The MMT TPOINT run as an offsets table: raw az el (S-E), observed minus raw."""
    run = px.io.read_tpoint(MMT_DAT, azimuth="S-E")
    A, E = run.observed.T
    a, e = run.encoder.T
    dA = (A - a + np.pi) % (2 * np.pi) - np.pi
    d = np.column_stack([dA * np.cos(E) if xel else dA, E - e]) * (-1 if flip else 1)
    scale = {"arcsec": ARCSEC, "deg": np.pi / 180}[units]
    lines = [f"# MMT 2021-08-21 as offsets ({units})", sep.join(["az", "el", "dxel" if xel else "daz", "del"])]
    for k in range(len(a)):
        lines.append(sep.join(f"{x:.12f}" for x in (np.degrees(a[k]), np.degrees(e[k]), *(d[k] / scale))))
    return run, "\n".join(lines) + "\n"


@pytest.mark.parametrize("sep, xel, flip, units", [(",", True, False, "arcsec"), (" ", False, True, "deg")])
def test_mmt_table_matches_tpoint(sep, xel, flip, units):
    """The same run through read_tpoint and read_offsets: the same observations, and
    the fit reproduces TPOINT's own model file (values within 0.01")."""
    tpoint_run, text = _mmt_table(sep, xel, flip, units)
    run = parse_offsets(
        text, "mmt.txt", units=units, azimuth="S-E", cross_elevation=xel, sign="raw-observed" if flip else "observed-raw"
    )
    np.testing.assert_allclose(run.raw, tpoint_run.encoder, atol=1e-14)
    np.testing.assert_allclose(run.observations.target, tpoint_run.observations.target, atol=1e-12)
    diff = run.observed - tpoint_run.observed
    diff[:, 0] = (diff[:, 0] + np.pi) % (2 * np.pi) - np.pi  # raw + dA may pass 360 deg
    np.testing.assert_allclose(diff, 0, atol=1e-12)
    assert run.observations.convention == "S-E" and np.all(run.weight == 1.0) and run.errors is None
    model = px.io.read_model(MMT_MOD)
    result = px.fit(px.AltAz(px.terms.tpoint(model.names), azimuth="S-E"), run.observations)
    for term in model.terms:
        assert result.value(term.name) == pytest.approx(term.value, abs=0.01), term.name
    assert float(result.sky_rms) / ARCSEC == pytest.approx(model.sky_rms, abs=0.01)


def test_sign_convention_observed_minus_raw():
    """A source found 36" in cross-elevation and 18" below the commanded position, by
    hand: observed E = 45 deg - 18", A = 30 deg + 36" / cos E; and IA/IE then come out
    with TPOINT's sign (dA = -IA, dE = +IE)."""
    run = parse_offsets("az el dxel del\n30 45 36 -18\n")
    E = math.radians(45) - 18 * ARCSEC
    A = math.radians(30) + 36 * ARCSEC / math.cos(E)
    np.testing.assert_allclose(run.observations.target[0], [math.sin(A) * math.cos(E), math.cos(A) * math.cos(E), math.sin(E)], atol=1e-15)
    np.testing.assert_allclose(run.raw[0], np.radians([30, 45]), atol=0)
    np.testing.assert_allclose(run.offsets[0], np.array([36, -18]) * ARCSEC, atol=1e-18)
    flipped = parse_offsets("az el dxel del\n30 45 -36 18\n", sign="raw-observed")
    np.testing.assert_allclose(flipped.observations.target, run.observations.target, atol=1e-16)
    plain = parse_offsets("az el daz del\n30 45 36 -18\n", cross_elevation=False)
    np.testing.assert_allclose(plain.observed[0], [math.radians(30) + 36 * ARCSEC, E], atol=1e-15)
    # a constant offset is IA, IE: every row offset by dA cos E = -IA cos E ... fit it
    rows = ["az el daz del"] + [f"{a} {e} -30 12" for a in range(0, 360, 30) for e in (20, 50, 75)]
    run = parse_offsets("\n".join(rows), cross_elevation=False)
    result = px.fit(px.AltAz(px.terms.tpoint("IA IE")), run.observations)
    assert result.value("IA") == pytest.approx(30.0, abs=1e-6) and result.value("IE") == pytest.approx(12.0, abs=1e-6)


# --------------------------------------------------------------------------- simulated tables


def test_radio_csv_with_header_and_weights():
    run = read_offsets(DATA / "radio_xel.csv")
    assert len(run) == 60 and run.units == "arcsec" and run.cross_elevation and run.azimuth == "N-E"
    assert run.columns == {
        "azimuth": (2, "Az [deg]"),
        "elevation": (3, "El [deg]"),
        "azimuth_offset": (4, "dXEL"),
        "elevation_offset": (5, "dEL"),
        "azimuth_error": (6, "dxel_err"),
        "elevation_error": (7, "del_err"),
    }
    assert run.lines[0] == 5 and run.errors.shape == (60, 2)
    sig = np.loadtxt(DATA / "radio_xel.csv", delimiter=",", skiprows=4, usecols=(5, 6))
    w = 1 / np.mean(sig**2, axis=1)
    np.testing.assert_allclose(run.weight, w / w.mean(), rtol=1e-12)
    assert run.weight.mean() == pytest.approx(1.0)
    np.testing.assert_allclose(np.asarray(run.observations.weight), run.weight)
    result = fit6(run)
    assert result.converged
    for name, value in TRUE.items():
        assert abs(result.value(name) - value) < 4 * result.sigma(name) + 0.5, (name, result.value(name))
    assert float(result.sky_rms) / ARCSEC < 3.0
    # the weights reach the fit, and only their ratios matter (errors x 3: the same fit)
    obs = run.observations
    plain = px.fit(px.AltAz(px.terms.tpoint(SIX)), px.Observations(obs.encoder, obs.target, convention="N-E"))
    assert max(abs(plain.value(n) - result.value(n)) for n in TRUE) > 0.5
    text = (DATA / "radio_xel.csv").read_text().splitlines()
    scaled = "\n".join(text[:4] + [",".join(r.split(",")[:5] + [f"{3 * float(x)!r}" for x in r.split(",")[5:]]) for r in text[4:]])
    again = fit6(parse_offsets(scaled + "\n", "scaled.csv"))
    for n in TRUE:
        assert again.value(n) == pytest.approx(result.value(n), abs=1e-9)
        assert again.sigma(n) == pytest.approx(result.sigma(n), rel=1e-9)


def test_tracker_whitespace_positional_degrees_plain_daz():
    run = read_offsets(DATA / "tracker_plain.txt", units="deg", azimuth="S-E", cross_elevation=False)
    assert len(run) == 40 and run.columns["azimuth"] == (1, None) and run.lines[0] == 5
    result = fit6(run)
    for name, value in TRUE.items():
        assert abs(result.value(name) - value) < 4 * result.sigma(name) + 0.5, (name, result.value(name))
    # read as cross-elevation (the wrong sense) the fit is measurably worse
    wrong = fit6(read_offsets(DATA / "tracker_plain.txt", units="deg", azimuth="S-E"))
    assert float(wrong.sky_rms) > 1.5 * float(result.sky_rms)
    # read in arcsec, the offsets are tiny: a different fit, not an error
    # (a unit too large is refused, below)


def test_same_table_csv_whitespace_and_mappings(tmp_path):
    text = (DATA / "radio_xel.csv").read_text()
    ref = read_offsets(DATA / "radio_xel.csv")
    body = [line for line in text.splitlines() if line and not line.startswith("#")]
    rows = [line.split(",") for line in body[1:]]
    # whitespace, no header, own order: el az del dxel (source column dropped)
    ws = tmp_path / "t.txt"
    ws.write_text("\n".join(" ".join([r[2], r[1], r[4], r[3]]) for r in rows) + "\n")
    by_position = read_offsets(ws, columns=("elevation", "azimuth", "elevation_offset", "azimuth_offset"))
    np.testing.assert_allclose(by_position.observations.target, ref.observations.target, atol=1e-15)
    numbers = read_offsets(ws, columns={"azimuth": 2, "elevation": 1, "azimuth_offset": 4, "elevation_offset": 3})
    np.testing.assert_allclose(numbers.observations.target, ref.observations.target, atol=1e-15)
    assert numbers.columns["azimuth"] == (2, None)
    # explicit names for odd headers; other columns ignored
    odd = tmp_path / "odd.csv"
    odd.write_text("name,A,E,x,y,q\n" + "\n".join(",".join([r[0], r[1], r[2], r[3], r[4], "7"]) for r in rows) + "\n")
    named = read_offsets(odd, columns={"azimuth": "A", "elevation": "E", "azimuth_offset": "x", "elevation_offset": "y"})
    np.testing.assert_allclose(named.observations.target, ref.observations.target, atol=1e-15)
    # arcmin: the same table with offsets / 60
    am = tmp_path / "am.csv"
    am.write_text("az,el,daz,del\n" + "\n".join(f"{r[1]},{r[2]},{float(r[3]) / 60!r},{float(r[4]) / 60!r}" for r in rows) + "\n")
    np.testing.assert_allclose(read_offsets(am, units="arcmin").observations.target, ref.observations.target, atol=1e-15)


def test_common_error_column_and_default_positions():
    text = "# az el daz del err\n10 30 5 5 2\n100 40 5 5 1\n200 60 5 5 1\n"
    run = parse_offsets(text)
    assert set(run.columns) == {"azimuth", "elevation", "azimuth_offset", "elevation_offset", "error"}
    np.testing.assert_allclose(run.weight, np.array([0.25, 1, 1]) / 0.75)
    header = parse_offsets("az el daz del sigma\n10 30 5 5 2\n100 40 5 5 1\n")
    np.testing.assert_allclose(header.weight, [0.4, 1.6])
    # a plain-dA error counts as sigma cos E on the sky
    plain = parse_offsets("az el daz del daz_err del_err\n10 60 5 5 2 1\n100 0 5 5 2 1\n", cross_elevation=False)
    e = np.radians([60, 0]) + 5 * ARCSEC
    np.testing.assert_allclose(plain.errors[:, 0], 2 * ARCSEC * np.cos(e), rtol=1e-12)


# --------------------------------------------------------------------------- bad input


def _error(text, **kw) -> OffsetsFormatError:
    with pytest.raises(OffsetsFormatError) as info:
        parse_offsets(text, "t.csv", **kw)
    assert isinstance(info.value, FileFormatError)
    return info.value


def test_errors_name_file_line_and_column():
    e = _error("az,el,daz,del\n10,30,1,2\n\n# note\n20,abc,1,2\n")
    assert e.path == "t.csv" and e.line == 5 and str(e).startswith("t.csv:5: column 2 (el): 'abc' is not a number")
    e = _error("az el daz del\n10 30 1 2\n20 40 1\n")
    assert e.line == 3 and "3 columns" in str(e)
    e = _error("az,el,daz,del\n10,30,,2\n")
    assert e.line == 2 and "column 3 (daz)" in str(e) and "empty" in str(e)
    e = _error("az el daz del\n400 30 1 2\n")
    assert "column 1 (az)" in str(e) and "-360..360" in str(e)
    e = _error("az el daz del\n10 95 1 2\n")
    assert "column 2 (el)" in str(e) and "-90..90" in str(e)
    e = _error("az el daz del\n10 30 1 2\n20 40 nan 2\n")
    assert e.line == 3 and "not finite" in str(e)
    e = _error("az el daz del\n10 30 40000 2\n")
    assert "column 3 (daz)" in str(e) and "10 deg" in str(e) and "units" in str(e)
    e = _error("az el daz del err\n10 30 1 2 0\n")
    assert "column 5 (err)" in str(e) and "not positive" in str(e)
    e = _error("az el daz del\n10 -5 1 2\n")
    assert "below the horizon" in str(e)


def test_offsets_in_degrees_within_the_limit_are_read():
    run = parse_offsets("az el daz del\n10 30 1 2\n", units="deg")
    np.testing.assert_allclose(run.offsets[0], np.radians([1, 2]), rtol=1e-15)


def test_header_problems():
    e = _error("time,flux,x,y\n1,2,3,4\n")
    assert e.line == 1 and "no column for azimuth, elevation, azimuth_offset, elevation_offset" in str(e)
    e = _error("az,azimuth,el,daz,del\n1,1,30,3,4\n")
    assert "column 1 ('az'), column 2 ('azimuth')" in str(e) and "columns=" in str(e)
    e = _error("az,el,daz,del,daz_err\n1,30,3,4,1\n")
    assert "azimuth_error column without its partner" in str(e)
    e = _error("az,el,daz,del\n1,30,3,4\n", columns={"azimuth": "AZIM"})
    assert "no header column" in str(e)
    e = _error("1 30 3 4 5 6 7\n")
    assert "7 columns and no header" in str(e)
    e = _error("1 30 3 4\n", columns={"azimuth": "az"})
    assert "no header line" in str(e)
    e = _error("az el daz del\n1 30 3 4\n", columns=("azimuth", "elevation", "azimuth_offset", "elevation_offset", None))
    assert "5 columns" in str(e)
    e = _error("# only comments\n\n")
    assert e.line is None and "no data" in str(e)
    e = _error("az el daz del\n")
    assert "no data rows after the header" in str(e)
    with pytest.raises(ValueError, match="unknown column role"):
        parse_offsets("1 2 3 4\n", columns={"az": 1})
    with pytest.raises(ValueError, match="given twice"):
        parse_offsets("1 2 3 4\n", columns=("azimuth", "azimuth", "elevation", "elevation_offset"))
    with pytest.raises(ValueError, match="unit"):
        parse_offsets("1 2 3 4\n", units="mas")
    with pytest.raises(ValueError, match="sign"):
        parse_offsets("1 2 3 4\n", sign="+")
    with pytest.raises(ValueError, match="azimuth convention"):
        parse_offsets("1 2 3 4\n", azimuth="E-N")


def test_radians_and_duplicates():
    rows = "\n".join(f"{a:.4f} {e:.4f} 1 2" for a, e in [(0.1, 0.3), (1.2, 0.5), (2.5, 1.1), (4.0, 0.7)])
    e = _error("az el daz del\n" + rows + "\n")
    assert "look like radians" in str(e)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        parse_offsets("az el daz del\n10 30 1 2\n10 30 1 2\n", "dup.txt")
    hits = [w for w in caught if issubclass(w.category, InputWarning)]
    assert hits and "dup.txt:3" in str(hits[0].message)


def test_read_offsets_file_errors(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_bytes(b"\xff\xfe\x00az")
    with pytest.raises(OffsetsFormatError, match="not a text file"):
        read_offsets(p)
    with pytest.raises(OSError):
        read_offsets(tmp_path / "missing.csv")

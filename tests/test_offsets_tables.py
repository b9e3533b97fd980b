"""Offsets tables from the command line (``--columns``, ``--units``, ``--plain-daz``,
``--sign``), units in header names, and tables without a header (every row read).

References: the bundled simulated tables (tests/data/offsets/) read plainly with NumPy,
and TPOINT's linear least squares in NumPy (tests/tpoint_numpy.py, no pointax).
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import tpoint_numpy as ref
from conftest import REPO

from pointax.cli import main
from pointax.io import detect_format
from pointax.io.offset_columns import parse_columns_option, split_unit
from pointax.io.offsets import OffsetsFormatError, parse_offsets, read_offsets

DATA = REPO / "tests" / "data" / "offsets"
SIX = ["IA", "IE", "CA", "NPAE", "AN", "AW"]


@pytest.fixture(autouse=True)
def no_compilation_cache(monkeypatch):
    monkeypatch.setenv("POINTAX_JAX_CACHE", "")


def _radio_rows() -> list[list[str]]:
    """The rows of radio_xel.csv: name, az, el, dxel, del (arcsec), dxel_err, del_err."""
    lines = [x for x in (DATA / "radio_xel.csv").read_text().splitlines() if x and not x.startswith("#")]
    return [x.split(",") for x in lines[1:]]


def _reference(raw_deg, offsets_rad, cross_elevation=True, names=SIX):
    """NumPy's TPOINT least squares of a table: observed = raw + offsets (the azimuth
    offset divided by cos E_observed when it is cross-elevation)."""
    raw = np.radians(np.asarray(raw_deg, np.float64))
    off = np.asarray(offsets_rad, np.float64)
    el = raw[:, 1] + off[:, 1]
    daz = off[:, 0] / np.cos(el) if cross_elevation else off[:, 0]
    observed = np.column_stack([raw[:, 0] + daz, el])
    return dict(zip(names, ref.lstsq(names, observed, raw, np.ones(len(raw), bool)) / ref.ARCSEC))


def _fit_json(capsys, *argv):
    """``pointax fit ... --json``; the fits compared with :func:`_reference` say ``--form linear`` (its terms)."""
    code = main(["fit", *map(str, argv), "--json"])
    captured = capsys.readouterr()
    return code, (json.loads(captured.out) if captured.out.strip() else None), captured.err


def _values(out):
    return {t["name"]: t["value_arcsec"] for t in out["terms"]}


# --------------------------------------------------------------------------- no header: no row dropped


def test_a_table_with_a_name_column_and_no_header_keeps_its_first_row(tmp_path):
    rows = _radio_rows()
    table = tmp_path / "named.csv"
    table.write_text("# no header: name, az, el, dxel, del, errors\n" + "\n".join(",".join(r) for r in rows) + "\n")
    run = read_offsets(table, columns=(None, "azimuth", "elevation", "azimuth_offset", "elevation_offset", None, None))
    assert len(run) == len(rows) == 60 and run.lines[0] == 2
    assert run.raw[0, 0] == pytest.approx(np.radians(float(rows[0][1])), abs=1e-15)
    # whitespace, and names by number
    ws = tmp_path / "named.txt"
    ws.write_text("\n".join(" ".join(r[:5]) for r in rows) + "\n")
    again = read_offsets(ws, columns={"azimuth": 2, "elevation": 3, "azimuth_offset": 4, "elevation_offset": 5})
    assert len(again) == 60
    np.testing.assert_allclose(again.observations.target, run.observations.target, atol=1e-15)
    # the same table with its header: the same 60 rows
    assert len(read_offsets(DATA / "radio_xel.csv")) == 60
    # a header is a record with a word where the next has a number; a lone word line is not data
    assert len(parse_offsets("az el daz del\n10 30 1 2\n20 40 1 2\n")) == 2
    assert len(parse_offsets("10 30 1 2\n20 40 1 2\n")) == 2


def test_cli_reads_a_headerless_table_with_columns(capsys, tmp_path):
    rows = _radio_rows()
    table = tmp_path / "named.csv"
    table.write_text("\n".join(",".join(r) for r in rows) + "\n")
    code, out, err = _fit_json(
        capsys, table, "--columns", "_,az,el,dxel,del,_,skip", "--terms", ",".join(SIX), "--residuals", "tpoint",
        "--form", "linear",
    )  # fmt: skip
    assert code == 0, err
    assert out["n_obs"] == 60 and len(out["observations"]) == 60 and out["observations"][0]["line"] == 1
    raw = [[float(r[1]), float(r[2])] for r in rows]
    off = np.array([[float(r[3]), float(r[4])] for r in rows]) * ref.ARCSEC
    expected = _reference(raw, off)
    for name, value in _values(out).items():
        assert value == pytest.approx(expected[name], abs=1e-4), name
    # by number and name-free pairs: the same fit
    code, again, _ = _fit_json(
        capsys, table, "--format", "offsets", "--columns", "az=2,el=3,dxel=4,del=5", "--terms", ",".join(SIX),
        "--residuals", "tpoint", "--form", "linear",
    )  # fmt: skip
    assert code == 0 and _values(again) == pytest.approx(_values(out), abs=1e-9)


def test_cli_star_tracker_degrees_plain_daz(capsys):
    """tracker_plain.txt: no header, degrees, plain dA, azimuth S-E: --units and
    --plain-daz say so (the file's format is told by the options: four numbers per
    line are otherwise ambiguous)."""
    table = DATA / "tracker_plain.txt"
    code, out, err = _fit_json(
        capsys, table, "--units", "deg", "--plain-daz", "--azimuth", "S-E", "--terms", ",".join(SIX), "--residuals", "tpoint",
        "--form", "linear",
    )  # fmt: skip
    assert code == 0, err
    data = np.loadtxt(table, comments="!")
    assert out["n_obs"] == len(data) == 40
    expected = _reference(data[:, :2], np.radians(data[:, 2:4]), cross_elevation=False)
    for name, value in _values(out).items():
        assert value == pytest.approx(expected[name], abs=1e-4), name
    # the simulated model: IA=+45 IE=-20 CA=+12 NPAE=-8 AN=+6 AW=-4 (noise about 1")
    assert _values(out)["IA"] == pytest.approx(45, abs=5) and _values(out)["IE"] == pytest.approx(-20, abs=3)
    # --sign raw-observed reads the same numbers as corrections: every term changes sign
    code, flipped, _ = _fit_json(
        capsys, table, "--units", "deg", "--plain-daz", "--azimuth", "S-E", "--terms", ",".join(SIX),
        "--residuals", "tpoint", "--form", "linear", "--sign", "raw-observed",
    )  # fmt: skip
    assert code == 0
    for name, value in _values(flipped).items():
        assert value == pytest.approx(-_values(out)[name], abs=0.05 * abs(_values(out)[name]) + 0.05), name


# --------------------------------------------------------------------------- units in the header


@pytest.mark.parametrize(
    "dxel, del_",
    [
        ("dxel [arcmin]", "del [arcmin]"),
        ("dxel (arcmin)", "del (arcmin)"),
        ("dxel/arcmin", "del/arcmin"),
        ("dxel_arcmin", "del_arcmin"),
        ("dxel [']", "del [']"),
        ("dXEL {ARCMIN}", "dEL <arcminutes>"),
    ],
)
def test_units_in_header_names(tmp_path, dxel, del_):
    rows = _radio_rows()
    reference = read_offsets(DATA / "radio_xel.csv")
    body = "\n".join(f"{r[1]},{r[2]},{float(r[3]) / 60!r},{float(r[4]) / 60!r}" for r in rows)
    table = tmp_path / "am.csv"
    table.write_text(f"Az [deg],El [deg],{dxel},{del_}\n{body}\n")
    run = read_offsets(table)
    assert run.units == "arcmin" and run.column_units["azimuth"] == "deg" and len(run) == 60
    np.testing.assert_allclose(run.observations.target, reference.observations.target, atol=1e-15)
    np.testing.assert_allclose(run.offsets, reference.offsets, atol=1e-16)
    assert detect_format(table) == "offsets"
    # the same header, blank-separated (a unit written apart belongs to its name)
    if " " in dxel and "{" not in dxel:
        ws = tmp_path / "am.txt"
        ws.write_text(f"az [deg]  el [deg]  {dxel}  {del_}\n" + body.replace(",", " ") + "\n")
        assert detect_format(ws) == "offsets"
        np.testing.assert_allclose(read_offsets(ws).observations.target, reference.observations.target, atol=1e-15)


def test_units_column_by_column_and_positions_in_radians():
    text = 'az [rad], el [rad], dxel ["], del [arcmin], err (arcsec)\n' "0.5, 0.6, 30, 0.5, 2\n1.5, 0.9, 60, 1.0, 1\n"
    run = parse_offsets(text)
    assert run.units == "mixed" and run.column_units == {
        "azimuth": "rad", "elevation": "rad", "azimuth_offset": "arcsec", "elevation_offset": "arcmin", "error": "arcsec",
    }  # fmt: skip
    np.testing.assert_allclose(run.raw, [[0.5, 0.6], [1.5, 0.9]], rtol=1e-15)
    np.testing.assert_allclose(run.offsets, np.array([[30, 30], [60, 60]]) * ref.ARCSEC, rtol=1e-13)
    np.testing.assert_allclose(run.errors[:, 0], np.array([2, 1]) * ref.ARCSEC, rtol=1e-13)
    # units= is the unit of every offset column: a header saying another is refused
    with pytest.raises(OffsetsFormatError, match="says arcsec but units='arcmin'"):
        parse_offsets("az,el,dxel [arcsec],del\n10,30,30,0.5\n", units="arcmin")


def test_header_units_and_units_argument_disagreeing_or_unknown():
    with pytest.raises(OffsetsFormatError) as info:
        parse_offsets("# table\naz,el,dxel [arcmin],del [arcmin]\n10,30,1,2\n", "t.csv", units="arcsec")
    e = info.value
    assert e.line == 2 and "column 3 ('dxel [arcmin]')" in str(e) and "says arcmin but units='arcsec'" in str(e)
    assert parse_offsets("az,el,dxel [arcmin],del [arcmin]\n10,30,1,2\n", units="arcmin").units == "arcmin"
    with pytest.raises(OffsetsFormatError) as info:
        parse_offsets("az,el,dxel [mas],del [mas]\n10,30,1,2\n", "t.csv")
    assert "t.csv:1: column 3 ('dxel [mas]'): unknown unit 'mas'" in str(info.value)
    # with units= the bracket is a note
    assert parse_offsets("az,el,dxel [mas],del [mas]\n10,30,1,2\n", units="arcsec").units == "arcsec"
    with pytest.raises(OffsetsFormatError, match="unknown unit 'hours'"):
        parse_offsets("az [hours],el,dxel,del\n10,30,1,2\n", units="arcsec")


def test_default_units_are_arcsec_and_degrees():
    run = parse_offsets("az el dxel del\n10 30 36 18\n")
    assert run.units == "arcsec" and run.column_units["azimuth"] == "deg"
    np.testing.assert_allclose(run.offsets, [[36 * ref.ARCSEC, 18 * ref.ARCSEC]], rtol=1e-14)


def test_the_command_line_choices_equal_the_readers():
    from pointax.cli import choices
    from pointax.io.offsets import OFFSET_SIGNS, OFFSET_UNITS

    assert choices.OFFSET_UNITS == tuple(OFFSET_UNITS) and choices.OFFSET_SIGNS == OFFSET_SIGNS


def test_split_unit_and_columns_option():
    assert split_unit("dxel [arcmin]") == ("dxel", "arcmin", "arcmin")
    assert split_unit("el_deg") == ("el", "deg", "deg")
    assert split_unit("dxel_err") == ("dxel_err", None, None)
    assert split_unit("daz/arcsec") == ("daz", "arcsec", "arcsec")
    assert split_unit("x/y") == ("x/y", None, None)
    assert parse_columns_option("-,az,el,dxel,del") == (None, "azimuth", "elevation", "azimuth_offset", "elevation_offset")
    assert parse_columns_option("az el - daz del err") == ("azimuth", "elevation", None, "azimuth_offset", "elevation_offset", "error")
    assert parse_columns_option("az=2,el=El [deg],dxel=4,del=5") == {
        "azimuth": 2, "elevation": "El [deg]", "azimuth_offset": 4, "elevation_offset": 5,
    }  # fmt: skip
    for bad, message in [
        ("az,el,foo,del", "column 3: 'foo' is not a column role"),
        ("az,el,az,del", "azimuth given twice"),
        ("az=1,el", "'el' has no '='"),
        ("az=0,el=2", "numbered from 1"),
        ("", "empty"),
    ]:
        with pytest.raises(ValueError, match=message):
            parse_columns_option(bad)


# --------------------------------------------------------------------------- command-line errors


def test_cli_errors(capsys, tmp_path):
    from conftest import MMT_DAT

    # --units against the header: file, line, column
    table = tmp_path / "am.csv"
    table.write_text("az,el,dxel [arcmin],del [arcmin]\n10,30,1,2\n20,40,1,2\n30,50,1,2\n40,60,1,2\n")
    code, _, err = _fit_json(capsys, table, "--units", "arcsec")
    assert code == 2 and f"{table}:1: column 3 ('dxel [arcmin]'): the header says arcmin but units='arcsec'" in err
    # offsets options on a TPOINT run
    code, _, err = _fit_json(capsys, MMT_DAT, "--columns", "az,el,dxel,del")
    assert code == 2 and "--columns applies to offsets tables" in err and "looks like a tpoint run" in err
    # seven columns, no header, no --columns: the message says how
    seven = tmp_path / "seven.txt"
    seven.write_text("1 10 30 1 2 3 4\n2 20 40 1 2 3 4\n")
    code, _, err = _fit_json(capsys, seven, "--format", "offsets")
    assert code == 2 and "7 columns and no header" in err and "--columns" in err
    # a table without a header and no option: the format error names --format offsets and --columns
    code, _, err = _fit_json(capsys, seven)
    assert code == 2 and "--format offsets" in err and "--columns" in err


def test_bad_columns_answer_before_any_numerical_library(tmp_path):
    table = tmp_path / "t.txt"
    table.write_text("x 10 30 1 2\ny 20 40 1 2\n")
    code = (
        "import sys, json\n"
        "from pointax.cli import main\n"
        f"code = main(['fit', {str(table)!r}, '--columns', '_,az,el,dx_el,del'])\n"
        "print(json.dumps({'code': code, 'loaded': [m for m in ('jax', 'numpy') if m in sys.modules]}))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert json.loads(proc.stdout.splitlines()[-1]) == {"code": 2, "loaded": []}
    assert "--columns: column 4: 'dx_el' is not a column role" in proc.stderr

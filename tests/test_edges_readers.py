"""Issue 30, the readers' edges: units taken on trust, contradictions accepted and
refusals without place or cause.

* units: a value whose unit a reader assumes is checked for plausibility in it
  (:mod:`pointax.core.units`), a header-less offsets table in degrees is refused, a gpoint
  model value without a unit suffix beyond a pointing term's size is refused;
* contradictions: duplicate JSON keys, a row whose raw and observed positions lie
  degrees apart (TheSkyX's half-flipped rows), a misspelt mount option;
* place and cause: text decoding (:func:`pointax.io.text.read_text`: UTF-8, else
  Latin-1 with non-ASCII bytes only in comments and captions), unknown terms of a
  model file named with its file and line, every reader's error naming the file.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pointax as px
from pointax.io import FileFormatError, InputWarning

from conftest import EXAMPLES, MMT_DAT

MMT_MOD = EXAMPLES / "data" / "mmt_20210821.mod"
GPOINT_DIR = Path(__file__).parent / "data" / "gpoint"
OFFSETS_DIR = Path(__file__).parent / "data" / "offsets"

# ------------------------------------------------------------------ units taken on trust


def _offsets_rows(scale: float) -> str:
    rng = np.random.default_rng(1)
    rows = []
    for k in range(12):
        az, el = 30.0 * k, 20.0 + 5.0 * k
        rows.append(f"{az:.3f} {el:.3f} {rng.normal(0, 20) * scale:.6f} {rng.normal(0, 20) * scale:.6f}")
    return "\n".join(rows) + "\n"


def test_headerless_offsets_in_degrees_are_refused(tmp_path):
    path = tmp_path / "deg.txt"
    path.write_text(_offsets_rows(1 / 3600.0))
    with pytest.raises(px.io.OffsetsFormatError, match=r"deg\.txt:1: column 3 .*below 0\.1\".*degrees"):
        px.io.read_offsets(path)
    run = px.io.read_offsets(path, units="deg")  # stated: taken
    assert np.max(np.abs(run.offsets)) > px.arcsec(1)


def test_stated_arcsec_offsets_that_small_are_warned_of(tmp_path):
    path = tmp_path / "small.txt"
    path.write_text(_offsets_rows(1 / 3600.0))
    with pytest.warns(InputWarning, match=r"below 0\.1\""):
        px.io.read_offsets(path, units="arcsec")


def test_headerless_offsets_in_arcsec_are_read(tmp_path):
    path = tmp_path / "arcsec.txt"
    path.write_text(_offsets_rows(1.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        run = px.io.read_offsets(path)
    assert run.units == "arcsec"


def test_gpoint_model_value_without_unit_suffix_is_refused(tmp_path):
    path = tmp_path / "model.txt"
    path.write_text('RTS2_ALTAZ 120 -3.1" 0" 0" 0" 0" 0"')  # 120 meant in arcsec
    with pytest.raises(px.io.GpointFormatError, match=r"model\.txt:1: .*field 2 \(ia\).*120.*radians.*arcseconds.*120\""):
        px.io.read_gpoint_model(path)


def test_gpoint_model_value_with_suffix_or_small_radians_is_read(tmp_path):
    path = tmp_path / "model.txt"
    path.write_text('RTS2_ALTAZ 120" 0.001 0" 0" 0" 2d 0"')
    model = px.io.read_gpoint_model(path)
    assert model.values["ia"] == pytest.approx(px.arcsec(120))


# ------------------------------------------------------------------ contradictions accepted


def test_duplicate_json_key_is_refused_naming_file_and_key(tmp_path):
    from pointax.io.paint.document import JsonDocument

    path = tmp_path / "calibration-properties.json"
    path.write_text('{\n  "sun_elevation": 30.0,\n  "sun_azimuth": 10.0,\n  "sun_elevation": 31.0\n}\n')
    with pytest.raises(px.io.PaintFormatError, match=r"calibration-properties\.json.*key 'sun_elevation'.*twice"):
        JsonDocument(path)


_EQUATORIAL_HEAD = "Half-flipped run\n: EQUAT\n+40 00 00 2024 1 1 10 0 0 0\n"


def _equatorial_rows(bad: bool) -> str:
    rows = []
    for k, dec in enumerate((20.0, 35.0, 50.0, 65.0, 75.0, 82.0)):
        ra = 6.0 + 0.2 * k
        tel_dec = dec + 0.01
        if bad and dec == 82.0:
            tel_dec = 180.0 - dec  # flipped in declination, not in hour angle
        rows.append(f"{ra:.4f} {dec:.4f} {ra + 0.001:.4f} {tel_dec:.4f} 6.5000")
    return "\n".join(rows) + "\nEND\n"


def test_half_flipped_row_is_named_with_its_line(tmp_path):
    path = tmp_path / "flip.dat"
    path.write_text(_EQUATORIAL_HEAD + _equatorial_rows(bad=True))
    with pytest.warns(InputWarning, match=r"flip\.dat:9: .*line 9.*16\.\d deg"):
        px.io.read_tpoint(path)


def test_consistent_run_gets_no_row_warning(tmp_path):
    path = tmp_path / "ok.dat"
    path.write_text(_EQUATORIAL_HEAD + _equatorial_rows(bad=False))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        px.io.read_tpoint(path)


def test_misspelt_mount_option_is_named_with_a_suggestion(tmp_path):
    text = MMT_DAT.read_text().replace(": ALTAZ", ": ALTAZZ")
    path = tmp_path / "typo.dat"
    path.write_text(text)
    line = text.splitlines().index(": ALTAZZ") + 1
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        with pytest.raises(px.io.TpointFormatError, match=rf"typo\.dat:{line}: unknown option ALTAZZ on line {line}; did you mean ALTAZ\?"):
            px.io.read_tpoint(path)
    assert [str(w.message) for w in said] == []  # the error alone, not a warning of the same record first


# ------------------------------------------------------------------ place and cause


def _latin1(text: str) -> bytes:
    return text.encode("latin-1")


def test_latin1_comment_and_caption_are_read(tmp_path):
    text = MMT_DAT.read_text()
    text = "! Mesures de l'été, 12° C\n" + text.replace("MMT Pointing Data from 08/21/2021\n:", "MMT Pointing Data 08/21/2021 at 13°\n:")
    path = tmp_path / "latin1.dat"
    path.write_bytes(_latin1(text))
    run = px.io.read_tpoint(path)
    assert "°" in run.caption and len(run) > 10


def test_latin1_byte_in_a_data_field_names_line_and_column(tmp_path):
    lines = MMT_DAT.read_text().splitlines()
    lines[21] = lines[21].replace(" ", "° ", 1)
    path = tmp_path / "field.dat"
    path.write_bytes(_latin1("\n".join(lines) + "\n"))
    column = lines[21].index("°") + 1
    with pytest.raises(px.io.TpointFormatError, match=rf"field\.dat:22: column {column}: byte 0xb0"):
        px.io.read_tpoint(path)


def test_latin1_comment_in_offsets_gpoint_sun_and_xy_files(tmp_path):
    offsets = tmp_path / "o.csv"
    offsets.write_bytes(_latin1("# relevé\n" + (OFFSETS_DIR / "radio_xel.csv").read_text()))
    assert len(px.io.read_offsets(offsets)) > 5
    gpoint = tmp_path / "g.txt"
    gpoint.write_bytes(_latin1("# relevé\n" + (GPOINT_DIR / "altaz_manual.txt").read_text()))
    assert len(px.io.read_gpoint(gpoint).observations) > 5
    sun = tmp_path / "s.txt"
    sun.write_bytes(_latin1("# alpha beta sun_az sun_el, relevé\n10 20 30 40\n11 21 31 41\n12 22 32 42\n"))
    assert len(px.io.read_sun_observations(sun).observations) == 3
    xy = tmp_path / "xy.txt"
    xy.write_bytes(_latin1("# L B L0 B0, relevé\n10 20 10 20\n11 21 11 21\n"))
    assert len(px.io.read_xy_run(xy)) == 2


def test_equatorial_term_in_altaz_model_file_is_named_with_file_and_line(tmp_path):
    text = MMT_MOD.read_text()
    lines = text.splitlines()
    k = next(i for i, l in enumerate(lines) if l.split()[:1] == ["IA"])
    lines.insert(k + 1, "  IH      +10.0000     1.00000")
    path = tmp_path / "ih.mod"
    path.write_text("\n".join(lines) + "\n")
    model_file = px.io.read_model(path)
    with pytest.raises(px.io.TpointFormatError, match=rf"ih\.mod:{k + 2}: term record IH: .*equatorial term"):
        model_file.check_terms()
    with pytest.raises(px.io.TpointFormatError, match=rf"ih\.mod:{k + 2}: term record IH: .*equatorial term"):
        model_file.model()


def test_unknown_term_in_model_file_is_named_with_file_and_line(tmp_path):
    text = MMT_MOD.read_text().replace("IA ", "IAX", 1)
    path = tmp_path / "unknown.mod"
    path.write_text(text)
    with pytest.raises(px.io.TpointFormatError, match=r"unknown\.mod:\d+: term record IAX: unknown TPOINT term"):
        px.io.read_model(path).check_terms()


# ------------------------------------------------------------------ property tests

_READERS = {
    "tpoint": lambda p: px.io.read_tpoint(p, mount="altaz"),
    "model": lambda p: px.io.read_model(p).check_terms(),
    "gpoint": px.io.read_gpoint,
    "gpoint_model": px.io.read_gpoint_model,
    "offsets": px.io.read_offsets,
    "sun": px.io.read_sun_observations,
    "xy": px.io.read_xy_run,
}
_VALID = {
    "tpoint": MMT_DAT.read_bytes(),
    "model": MMT_MOD.read_bytes(),
    "gpoint": (GPOINT_DIR / "altaz_manual.txt").read_bytes(),
    "gpoint_model": b'RTS2_ALTAZ 12" -3.1" 0" 4" 0" 5" 0"\n',
    "offsets": (OFFSETS_DIR / "radio_xel.csv").read_bytes(),
    "sun": b"# alpha beta sun_az sun_el\n10 20 30 40\n11 21 31 41\n12 22 32 42\n",
    "xy": b"# L B L0 B0\n10 20 10 20\n11 21 11 21\n",
}
_UNITS = ["", '"', "'", "d", "deg", "°", "rad", "arcsec", " [arcmin]", "e3", "e-6"]


def _read_checked(reader, path: Path) -> None:
    """The reader succeeds (with or without an InputWarning) or raises its
    FileFormatError naming the file; any other exception fails the test."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            _READERS[reader](path)
        except FileFormatError as err:
            assert str(path) in str(err), f"{reader}: error without the file: {err}"
            assert str(err).startswith(str(path)), err
            return
    for w in caught:
        if issubclass(w.category, InputWarning):
            assert str(path) in str(w.message) or "Observations" in str(w.message), w.message


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(reader=st.sampled_from(sorted(_READERS)), data=st.data())
def test_random_bytes_give_only_documented_errors(tmp_path, reader, data):
    valid = _VALID[reader]
    where = data.draw(st.integers(0, len(valid)))
    junk = data.draw(st.binary(min_size=1, max_size=8))
    path = tmp_path / f"{reader}.txt"
    path.write_bytes(valid[:where] + junk + valid[where:])
    _read_checked(reader, path)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(reader=st.sampled_from(sorted(_READERS)), data=st.data())
def test_random_units_give_only_documented_errors(tmp_path, reader, data):
    text = _VALID[reader].decode("utf-8")
    lines = text.splitlines()
    k = data.draw(st.integers(0, len(lines) - 1))
    tokens = lines[k].split(" ")
    j = data.draw(st.integers(0, len(tokens) - 1))
    tokens[j] += data.draw(st.sampled_from(_UNITS))
    lines[k] = " ".join(tokens)
    path = tmp_path / f"{reader}.txt"
    encoding = data.draw(st.sampled_from(["utf-8", "latin-1"]))
    path.write_bytes("\n".join(lines).encode(encoding) + b"\n")
    _read_checked(reader, path)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(reader=st.sampled_from(sorted(_READERS)), data=st.data())
def test_random_contradictions_give_only_documented_errors(tmp_path, reader, data):
    """A line written twice, a line moved, or a mount option contradicting another."""
    lines = _VALID[reader].decode("utf-8").splitlines()
    k = data.draw(st.integers(0, len(lines) - 1))
    how = data.draw(st.sampled_from(["twice", "move", "option"]))
    if how == "twice":
        lines.insert(k, lines[k])
    elif how == "move":
        lines.insert(data.draw(st.integers(0, len(lines))), lines.pop(k))
    else:
        lines.insert(k, data.draw(st.sampled_from([": EQUAT", ": ALTAZZ", ": GERMAN", ": FORK", "# gem", "END"])))
    path = tmp_path / f"{reader}.txt"
    path.write_text("\n".join(lines) + "\n")
    _read_checked(reader, path)

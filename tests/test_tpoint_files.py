"""TPOINT files as observatories write them (issue 27): ';' comments in data files,
every option record applied or warned of, a real TheSkyX export (tests/data/tpoint/,
see PROVENANCE.txt there) and TPOINT's one-line model layout.

References are outside the reader: numbers read by hand from the files, and for the
one-line layout's fit fields a plain numpy least-squares fit with the basis functions of
../shared/DESIGN.md ("TPOINT conformance").
"""

from __future__ import annotations

import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import MMT_DAT, MMT_MOD

from pointax.io import InputWarning, TpointFormatError, parse_model, parse_tpoint, read_model, read_tpoint, write_model

DATA = Path(__file__).resolve().parent / "data" / "tpoint"
WARP = DATA / "warp-astron.dat"
ARCSEC = math.pi / 648000.0
HOUR = math.pi / 12.0
MMT_TERMS = ["IA", "IE", "NPAE", "CA", "AN", "AW", "TF", "TX"]


def write(tmp_path, lines, name="run.dat"):
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def quiet_read(path, **kw):
    """read_tpoint with every warning an error."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return read_tpoint(path, **kw)


# ------------------------------------------------------------------ ';' comments

SEMICOLON_RUN = [
    "; written by an observatory's pointing script",
    "Rotator run with comments",
    "; the mount",
    ": ALTAZ",
    "+31 41 19.6 2024 3 1 5.0 740 2608 0.3 ; latitude, date, weather",
    "; star, then raw, then rotator",
    "010.5802950 37.4249887 010.5461739 37.4892647 000.4402639 ; [0026] 2024-03-01 05:12 HD 1234",
    "   ; an indented comment between records",
    "100.25 45.5 100.2 45.6 -12.75;[0027]",
    "END ; done",
]


def test_semicolon_comments_before_after_and_between_records(tmp_path):
    run = quiet_read(write(tmp_path, SEMICOLON_RUN))
    assert run.caption == "Rotator run with comments"
    assert run.options == ("ALTAZ",) and run.parameters.humidity == 0.3
    np.testing.assert_array_equal(run.lines, [7, 9])
    np.testing.assert_allclose(run.observed, np.radians([[10.5802950, 37.4249887], [100.25, 45.5]]), rtol=1e-15)
    np.testing.assert_allclose(run.encoder, np.radians([[10.5461739, 37.4892647], [100.2, 45.6]]), rtol=1e-15)
    np.testing.assert_array_equal(run.extra, [[0.4402639], [-12.75]])  # the rotator column, as written
    assert run.rotator is None  # no rotator option: a plain extra column


def test_a_comment_does_not_hide_a_bad_field(tmp_path):
    lines = SEMICOLON_RUN[:6] + ["010.58 37.42 010.54 3x.48 ; [0026]"]
    with pytest.raises(TpointFormatError, match=r"run\.dat:7: .*field 4 \(raw elevation\)"):
        read_tpoint(write(tmp_path, lines))


def test_semicolon_after_end_is_not_a_record(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # only comments follow END: nothing to warn of
        run = parse_tpoint("\n".join(SEMICOLON_RUN + ["; trailing note", "  ; another"]) + "\n")
    assert len(run) == 2


# ---------------------------------------------------------------- option records


def _warnings_of(text, path="o.dat"):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run = parse_tpoint(text, path)
    return run, [str(w.message) for w in caught if issubclass(w.category, InputWarning)]


def test_noda_and_mount_options_are_applied_without_a_word():
    run, said = _warnings_of("cap\n:NODA\n: ALTAZ\n+31 0 0\n10 20 11 21\n")
    assert said == [] and run.mount == "altaz" and run.options == ("NODA", "ALTAZ")
    assert [(o.keyword, o.line) for o in run.option_records] == [("NODA", 2), ("ALTAZ", 3)]


def test_options_pointax_does_not_apply_are_named_with_file_and_line():
    run, said = _warnings_of("cap\n: ALTAZ\n: ALLSKY\n:frobnicate\n+31 0 0\n10 20 11 21\n")
    assert len(said) == 2
    assert re.match(r"o\.dat:3: option record ': ALLSKY': .*does not apply", said[0])
    assert re.match(r"o\.dat:4: option record ': FROBNICATE': not a TPOINT option pointax knows", said[1])
    assert run.options == ("ALTAZ", "ALLSKY", "FROBNICATE")  # kept, not dropped


def test_several_options_on_one_record():
    run, said = _warnings_of("cap\n: EQUAT NODA\n+33 21 22 2023 9 20\n11 34 40.6642 +30 09 07.934 11 34 38.3798 +30 10 14.074  12 00.000\n")
    assert said == [] and run.mount == "equatorial"
    assert [(o.keyword, o.line) for o in run.option_records] == [("EQUAT", 2), ("NODA", 2)]


@pytest.mark.parametrize(
    "options, line, match",
    [
        ([": ALTAZ", ": EQUAT"], 3, r"contradictory mount options: ALTAZ, EQUAT: ': ALTAZ' on line 2 and ': EQUAT' on line 3"),
        ([": GERMAN", "! comment", ": FORK"], 4, r"contradictory mount options: GERMAN, FORK: ': GERMAN' on line 2 and ': FORK' on line 4"),
        ([": FORK", ": ALTAZ"], 3, r"contradictory mount options: FORK, ALTAZ: ': FORK' on line 2 and ': ALTAZ' on line 3"),
        ([": ALTAZ 5"], 2, r"option record ': ALTAZ 5': option ALTAZ takes no arguments \('5' given\)"),
        ([": GIMBAL 0 90 0"], 2, r"mount option GIMBAL: pointax reads TPOINT alt-az"),
        ([":"], 2, r"option record: field 1 \(option keyword\) is missing"),
        ([": 12 ALTAZ"], 2, r"option record: field 1 \(option keyword\) '12' is a number"),
    ],
)
def test_bad_option_records_name_their_lines(options, line, match):
    with pytest.raises(TpointFormatError, match=rf"o\.dat:{line}: {match}"):
        parse_tpoint("\n".join(["cap", *options, "+31 0 0", "10 20 11 21 5"]) + "\n", "o.dat")


def test_equat_with_german_is_not_a_contradiction():
    run, said = _warnings_of("cap\n: EQUAT\n: GERMAN\n+33 21 22\n11 34 40.6642 +30 09 07.934 11 34 38.3798 +30 10 14.074  12 00.000\n")
    assert said == [] and run.mount == "equatorial"


# ------------------------------------------------- a real TheSkyX export (warp-astron)


def test_theskyx_export_reads_quietly():
    run = quiet_read(WARP)
    assert run.caption == "ASCOM Mount" and run.options == ("NODA", "EQUAT") and run.mount == "equatorial"
    assert len(run) == 98 and run.lines[0] == 6 and run.lines[-1] == 103
    assert run.parameters.date == (2026, 4, 21) and run.parameters.pressure_mb == 761.74
    assert run.latitude == pytest.approx(math.radians(39 + 26 / 3600), abs=1e-15)
    assert run.refraction_applied  # pressure given: apparent places raised to observed
    # The telescope's declination is beyond 90 deg on the other side of the pier.
    assert int(run.flipped.sum()) == 37 and run.flipped[0] and not run.flipped[2]


def test_theskyx_export_first_row_by_hand():
    run = quiet_read(WARP)
    # 14 36 55.4451 +72 03 24.120 02 50 45.3800 +105 57 19.273  10 22.219
    sidereal = (10 + 22.219 / 60) * HOUR
    star_ra = (14 + 36 / 60 + 55.4451 / 3600) * HOUR
    tel_ra = (2 + 50 / 60 + 45.38 / 3600) * HOUR
    wrap = lambda h: (h + math.pi) % (2 * math.pi) - math.pi  # noqa: E731
    assert run.sidereal_time[0] == pytest.approx(sidereal, abs=1e-15)
    assert run.observed[0, 0] == pytest.approx(wrap(sidereal - star_ra), abs=1e-14)
    assert run.observed[0, 1] == pytest.approx(math.radians(72 + 3 / 60 + 24.12 / 3600), abs=1e-15)
    assert run.encoder[0, 0] == pytest.approx(wrap(sidereal - tel_ra), abs=1e-14)
    assert run.encoder[0, 1] == pytest.approx(math.radians(105 + 57 / 60 + 19.273 / 3600), abs=1e-15)
    # A row whose sidereal minutes are written ' 0.457' (two fields, blank-padded).
    k = int(np.flatnonzero(run.lines == 57)[0])
    assert run.sidereal_time[k] == pytest.approx((11 + 0.457 / 60) * HOUR, abs=1e-15)


# --------------------------------------------------------- TPOINT's one-line layout

# The layout TPOINT wrote for the MMT (MMTObservatory/pointing_analysis, 20200708
# bino_tf_tx.mod; that repository states no licence, so its file is not copied here):
# the field widths are TPOINT's, the numbers are those of the MMT model of 2021-08-21
# (examples/data/mmt_20210821.mod), with a fixed and a parallel term added.
ONE_LINE = (
    "MMT Pointing Data from 08/21/2021|T|   80|   0.7909|   0.5310|   0.6012|   0.6812|   0.9318|   42.060|  -0.0485|"
    "         |  |IA      |+1209.2612|     1.28477|  |IE      |   -2.9933|     0.44108|"
    " =|NPAE    |   +0.0000|            |& |HSCASE3 |   -6.7565|     1.60735|3-5,9"
)


def test_one_line_layout_fields():
    m = parse_model(ONE_LINE + "\n", "one.mod")
    assert m.layout == "one-line" and m.caption == "MMT Pointing Data from 08/21/2021" and m.method == "T"
    assert (m.n_obs, m.sky_rms, m.refraction, m.xy_rms) == (80, 0.9318, (42.060, -0.0485), (0.6012, 0.6812))
    assert m.names == ["IA", "IE", "NPAE", "HSCASE3"]
    assert [(t.value, t.sigma, t.fixed, t.parallel) for t in m.terms] == [
        (1209.2612, 1.28477, False, False),
        (-2.9933, 0.44108, False, False),
        (0.0, None, True, False),
        (-6.7565, 1.60735, False, True),
    ]
    assert m.masked == (3, 4, 5, 9)
    assert m.uninterpreted == ("0.7909", "0.5310", "")


def test_one_line_layout_writes_back_byte_for_byte(tmp_path):
    m = parse_model(ONE_LINE + "\n", "one.mod")
    assert m.text() == ONE_LINE + "\n"
    # and through the line layout and back, the same model (the line layout has no
    # place for the x/y RMS, the mask and the uninterpreted fields)
    lines = parse_model(m.text("lines"))
    assert lines.layout == "lines" and lines.terms == m.terms and lines.refraction == m.refraction
    path = tmp_path / "one.mod"
    path.write_text(m.text())
    assert read_model(path) == dataclass_with_path(m, str(path))


def dataclass_with_path(m, path):
    import dataclasses

    return dataclasses.replace(m, path=path)


def test_one_line_layout_of_a_real_model_matches_the_line_layout():
    lines = read_model(MMT_MOD)
    one = parse_model(lines.text("one-line"))
    assert one.terms == lines.terms and (one.n_obs, one.sky_rms, one.refraction) == (lines.n_obs, lines.sky_rms, lines.refraction)


@pytest.mark.parametrize(
    "change, match",
    [
        (("|  |IA      |", "|x |IA      |"), r"field 12 \(flags\) 'x'"),
        (("|  |IA      |", "|  |1A      |"), r"field 13 \(term name\) '1A' is not a name"),
        (("|+1209.2612|", "|+12o9.2612|"), r"field 14 \(value \(arcsec\)\)"),
        (("|+1209.2612|", "|          |"), r"field 14 \(value of IA\) is blank"),
        (("|3-5,9", "|5-3"), r"field 28 \(masked observations\) '5-3'"),
        (("|   80|", "|  8.5|"), r"field 3 \(number of observations\) '8.5' is not a count"),
        (("|IE      |", "|IA      |"), r"term IA appears twice"),
    ],
)
def test_bad_one_line_fields_are_named(change, match):
    with pytest.raises(TpointFormatError, match=rf"one\.mod:1: .*{match}"):
        parse_model(ONE_LINE.replace(*change) + "\n", "one.mod")


def test_a_record_after_a_one_line_model_is_refused():
    with pytest.raises(TpointFormatError, match=r"one\.mod:3: a record after a one-line model"):
        parse_model("! TPOINT model\n" + ONE_LINE + "\n  IA  +1.0\n", "one.mod")


def _numpy_fit(run, weights):
    """Linear least squares of DESIGN.md's TPOINT conformance, for the MMT terms."""
    a, e = run.observed[:, 0], run.observed[:, 1]
    d_a = (run.observed[:, 0] - run.encoder[:, 0] + math.pi) % (2 * math.pi) - math.pi
    d_e = run.observed[:, 1] - run.encoder[:, 1]
    zero, one = np.zeros_like(a), np.ones_like(a)
    basis = {
        "IA": (-one, zero), "IE": (zero, one), "CA": (-1 / np.cos(e), zero), "NPAE": (-np.tan(e), zero),
        "AN": (-np.sin(a) * np.tan(e), -np.cos(a)), "AW": (-np.cos(a) * np.tan(e), np.sin(a)),
        "TF": (zero, -np.cos(e)), "TX": (zero, -1 / np.tan(e)),
    }  # fmt: skip
    design = np.column_stack([np.concatenate([fa * np.cos(e), fe]) for fa, fe in (basis[n] for n in MMT_TERMS)])
    data = np.concatenate([d_a * np.cos(e), d_e])
    keep = np.concatenate([weights, weights]) > 0
    coef = np.linalg.lstsq(design[keep], data[keep], rcond=None)[0]
    residual = (data - design @ coef).reshape(2, -1)[:, weights > 0]
    x_rms, y_rms = np.sqrt(np.mean(residual**2, axis=1))
    sky = math.hypot(x_rms, y_rms)
    return dict(zip(MMT_TERMS, coef / ARCSEC)), (x_rms / ARCSEC, y_rms / ARCSEC), sky / ARCSEC


def test_write_model_one_line_from_a_masked_fit(tmp_path):
    """pointax fit of the MMT run with observations 3-5 masked, written in the one-line
    layout: its values, Sky RMS, x and y RMS and mask against numpy's fit."""
    import pointax as px

    run = read_tpoint(MMT_DAT, azimuth="S-E")
    weights = np.ones(len(run))
    weights[2:5] = 0.0
    result = px.fit(run.model(px.terms.tpoint(MMT_TERMS), residual_form="tpoint"), run, weights=weights)
    path = tmp_path / "fit.mod"
    with pytest.warns(UserWarning, match="no run given, so the refraction constants are written as 0"):
        write_model(path, result, caption="MMT masked", layout="one-line")
    text = path.read_text()
    assert text.count("\n") == 1 and text.startswith("MMT masked|T|   77|") and text.rstrip().endswith("|3-5")
    m = read_model(path)
    values, (x_rms, y_rms), sky = _numpy_fit(run, weights)
    assert m.masked == (3, 4, 5) and m.n_obs == 77
    assert m.sky_rms == pytest.approx(sky, abs=0.001)
    assert m.xy_rms == pytest.approx((x_rms, y_rms), abs=0.001)
    for t in m.terms:
        assert t.value == pytest.approx(values[t.name], abs=0.01), t.name


def test_semicolon_files_are_told_as_tpoint(tmp_path):
    from pointax.io import detect_format, load_run

    assert detect_format(WARP) == "tpoint"
    assert detect_format(write(tmp_path, SEMICOLON_RUN)) == "tpoint"
    # no option record: a ';' comment first, a ';' comment after the run parameters
    bare = write(tmp_path, [line for line in SEMICOLON_RUN if line != ": ALTAZ"], "bare.dat")
    assert detect_format(bare) == "tpoint"
    assert len(load_run(bare, mount="altaz")) == 2


def test_model_files_read_whatever_the_term_library_knows():
    """Reading a model file does not consult pointax's terms; building its model does,
    and names the term it cannot build (TX10, NRX, NRY are being added to pointax)."""
    import pointax as px

    text = "Cap|T|   80|         |         |         |         |   0.9318|   42.060|  -0.0485|         |"
    text += "  |IA      | +120.0000|     1.00000|  |TX10    |   -2.0000|     0.30000|  |NRX     |   +5.0000|            |"
    m = parse_model(text + "\n", "n.mod")
    assert m.names == ["IA", "TX10", "NRX"] and m.xy_rms is None and m.masked == ()
    for name in ("TX10", "NRX"):
        try:
            px.terms.tpoint([name])
        except ValueError:
            with pytest.raises(TpointFormatError, match=rf"n\.mod:1: term record {name}: "):
                m.model()
            return
    assert [p.name for p in m.model().parameters] == ["IA", "TX10", "NRX"]


def test_outmod_oneline_and_fit_model_layout_write_the_fit_of_the_line_layout(tmp_path, capsys):
    """``OUTMOD FILE ONELINE`` in a session and ``pointax fit --model-layout one-line``
    write the same fit as the line layout (values, sigmas, N, Sky RMS), plus the mask."""
    from pointax.cli import main

    script = tmp_path / "steps.ptp"
    script.write_text(
        f'INDAT "{MMT_DAT}"\nUSE {" ".join(MMT_TERMS)}\nFIT\nFIT\nMASK 3-5\nFIT\nFIT\n'
        "OUTMOD one.mod oneline ; TPOINT's one-line layout\nOUTMOD lines.mod\n"
    )
    assert main(["tpoint", "--azimuth", "S-E", str(script)]) == 0
    assert main(["fit", str(MMT_DAT), "--azimuth", "S-E", "--write-model", str(tmp_path / "fit.mod"),
                 "--model-layout", "one-line"]) == 0  # fmt: skip
    assert main(["fit", str(MMT_DAT), "--azimuth", "S-E", "--write-model", str(tmp_path / "fit_lines.mod")]) == 0
    capsys.readouterr()
    for one_name, lines_name, masked in (("one.mod", "lines.mod", (3, 4, 5)), ("fit.mod", "fit_lines.mod", ())):
        one, lines = read_model(tmp_path / one_name), read_model(tmp_path / lines_name)
        assert one.layout == "one-line" and lines.layout == "lines"
        assert one.masked == masked and one.n_obs == lines.n_obs == 80 - len(masked)
        assert one.sky_rms == pytest.approx(lines.sky_rms, abs=1e-4)
        assert [t.name for t in one.terms] == [t.name for t in lines.terms] == MMT_TERMS
        for a, b in zip(one.terms, lines.terms):
            assert a.value == pytest.approx(b.value, abs=1e-4) and a.sigma == pytest.approx(b.sigma, abs=1e-5)
    assert main(["fit", str(MMT_DAT), "--model-layout", "one-line"]) == 2
    assert "give --write-model FILE too" in capsys.readouterr().err

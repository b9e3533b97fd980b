"""Tests of pointax.io.tpoint: TPOINT input files (.dat) and model files (.mod).

Every expected number comes from outside the reader: read by hand from the file text,
from ``numpy.loadtxt`` of the observation rows, or from closed-form conversions
(degrees -> radians, d m s -> degrees, arcsec -> radians = x * pi / 648000).
"""

import jax

jax.config.update("jax_enable_x64", True)

import math  # noqa: E402
import re  # noqa: E402
import shutil  # noqa: E402
from pathlib import Path  # noqa: E402

import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import pointax as px  # noqa: E402
from pointax.core.errors import InputWarning  # noqa: E402
from pointax.io import (  # noqa: E402
    ModelTerm,
    RunParameters,
    TpointFormatError,
    TpointModelFile,
    TpointRun,
    format_model,
    parse_model,
    parse_tpoint,
    read_model,
    read_tpoint,
    write_model,
)
from pointax.core.rotations import azel_to_enu  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DAT = ROOT / "examples" / "data" / "mmt_20210821.dat"
MOD = ROOT / "examples" / "data" / "mmt_20210821.mod"

RAD_PER_ARCSEC = math.pi / 648000.0
TERMS8 = "IA IE NPAE CA AN AW TF TX"

# The .mod file's terms, read by hand: name, value ("), sigma (").
MOD_TERMS = [
    ("IA", 1209.2612, 1.28477),
    ("IE", -2.9933, 0.30382),
    ("NPAE", -3.4724, 1.54670),
    ("CA", -5.9455, 1.86697),
    ("AN", 2.4950, 0.11892),
    ("AW", -10.3347, 0.11843),
    ("TF", 21.4118, 0.89062),
    ("TX", -2.7165, 0.28183),
]

# A small, valid alt-az run; line numbers are fixed (see the comments).
HEADER = [
    "! a comment line",  # 1
    "Test run",  # 2
    ": ALTAZ",  # 3
    "+31 41 19.6 2021 8 21 13.0 741 2608.0 0.75",  # 4
]
ROWS = [
    "192.386 77.347 -167.278 77.348",  # 5
    "193.389 77.285 -166.276 77.286",  # 6
    "183.794 17.903 -175.872 17.906",  # 7
]


def write(tmp_path, lines, name="run.dat"):
    path = tmp_path / name
    text = lines if isinstance(lines, str) else "\n".join(lines) + "\n"
    path.write_text(text)
    return path


def dms(d, m, s, sign=1):
    return sign * math.radians(d + m / 60.0 + s / 3600.0)


def raises_at(path, line, *patterns):
    """Context manager: TpointFormatError at ``path:line`` whose message matches each pattern."""
    where = re.escape(f"{path}:{line}:") if line is not None else re.escape(str(path))

    class _Check:
        def __enter__(self):
            self.ctx = pytest.raises(TpointFormatError, match=where)
            self.info = self.ctx.__enter__()
            return self.info

        def __exit__(self, *exc):
            suppressed = self.ctx.__exit__(*exc)
            err = self.info.value
            assert isinstance(err, ValueError)
            assert err.path == str(path)
            assert err.line == line
            msg = str(err)
            for p in patterns:
                assert re.search(p, msg), f"{p!r} not in {msg!r}"
            return suppressed

    return _Check()


# --------------------------------------------------------------------------- the MMT run


@pytest.fixture(scope="module")
def mmt_rows():
    """The 80 observation rows of the real file, by numpy alone (degrees)."""
    rows = np.loadtxt(DAT, comments="!", skiprows=20)
    assert rows.shape == (80, 4)
    return rows


@pytest.fixture(scope="module")
def mmt_se():
    return read_tpoint(DAT, azimuth="S-E")


def test_mmt_run_header(mmt_se):
    run = mmt_se
    assert isinstance(run, TpointRun)
    assert len(run) == 80
    assert len(run.observations) == 80
    assert run.path == str(DAT)
    assert run.caption == "MMT Pointing Data from 08/21/2021"
    assert run.options == ("ALTAZ",)
    p = run.parameters
    assert isinstance(p, RunParameters)
    assert p.latitude == pytest.approx(dms(31, 41, 19.6), rel=1e-15)
    assert p.latitude == pytest.approx(0.5530735082, abs=1e-10)  # 31.6887778 deg
    assert p.date == (2021, 8, 21)
    assert p.temperature_c == 13.0
    assert p.pressure_mb == 741.0
    assert p.height_m == 2608.0
    assert p.humidity == 0.75
    assert p.wavelength_um is None and p.lapse_rate is None


def test_mmt_first_and_last_rows_by_hand(mmt_se):
    run = mmt_se
    first = np.radians([192.3860283, 77.3468410111111, -167.2778909, 77.3475476])
    last = np.radians([231.9735792, 75.9554129111111, -127.6968663, 75.9549086])
    np.testing.assert_allclose(run.observed[0], first[:2], rtol=1e-14)
    np.testing.assert_allclose(run.encoder[0], first[2:], rtol=1e-14)
    np.testing.assert_allclose(run.observed[-1], last[:2], rtol=1e-14)
    np.testing.assert_allclose(run.encoder[-1], last[2:], rtol=1e-14)


def test_mmt_all_rows_match_loadtxt(mmt_se, mmt_rows):
    run = mmt_se
    assert run.observed.shape == (80, 2) and run.encoder.shape == (80, 2)
    np.testing.assert_allclose(run.observed, np.radians(mmt_rows[:, :2]), rtol=1e-14, atol=1e-16)
    np.testing.assert_allclose(run.encoder, np.radians(mmt_rows[:, 2:]), rtol=1e-14, atol=1e-16)
    assert run.extra.shape == (80, 0)


def test_mmt_line_numbers(mmt_se):
    # Lines 1-17 comments, 18 caption, 19 ': ALTAZ', 20 run parameters, 21-100 rows.
    np.testing.assert_array_equal(mmt_se.lines, np.arange(21, 101))
    text = DAT.read_text().splitlines()
    assert text[mmt_se.lines[0] - 1].startswith("192.3860283")
    assert text[mmt_se.lines[-1] - 1].startswith("231.9735792")


def test_raw_azimuth_not_wrapped(mmt_se):
    assert mmt_se.encoder[0, 0] == pytest.approx(math.radians(-167.2778909), rel=1e-14)
    assert mmt_se.encoder[0, 0] < 0
    assert np.asarray(mmt_se.observations.encoder)[0, 0] < 0
    # and an observed azimuth beyond 180 deg stays beyond pi
    assert mmt_se.observed[-1, 0] == pytest.approx(math.radians(231.9735792), rel=1e-14)
    assert (mmt_se.encoder[:, 0] < 0).sum() == int((np.loadtxt(DAT, comments="!", skiprows=20)[:, 2] < 0).sum())


@pytest.mark.parametrize(
    "azimuth, to_north_east",
    [
        ("S-E", lambda a: np.pi - a),
        ("N-E", lambda a: a),
        ("S-W", lambda a: a + np.pi),
    ],
)
def test_azimuth_conventions(mmt_rows, azimuth, to_north_east):
    run = read_tpoint(DAT, azimuth=azimuth)
    obs = run.observations
    assert run.azimuth == azimuth
    assert obs.convention == azimuth
    a, e = np.radians(mmt_rows[:, 0]), np.radians(mmt_rows[:, 1])
    expected = np.asarray(azel_to_enu(to_north_east(a), e))
    np.testing.assert_allclose(np.asarray(obs.target), expected, atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(np.asarray(obs.target), axis=1), 1.0, atol=1e-14)
    # encoder angles unchanged, radians, whatever the convention
    np.testing.assert_allclose(np.asarray(obs.encoder), np.radians(mmt_rows[:, 2:]), rtol=1e-14, atol=1e-16)
    np.testing.assert_array_equal(np.asarray(obs.weight), np.ones(80))


def test_south_east_closed_form(mmt_se):
    # 'S-E': A = 180 - A_NE, so East = sin A cos E, North = -cos A cos E.
    a, e = mmt_se.observed[0]
    t = np.asarray(mmt_se.observations.target)[0]
    np.testing.assert_allclose(t, [np.sin(a) * np.cos(e), -np.cos(a) * np.cos(e), np.sin(e)], atol=1e-15)
    # first star: A = 192.4 deg from South through East is 12.4 deg west of North
    assert t[0] < 0 and t[1] > 0
    np.testing.assert_allclose(t, np.asarray(azel_to_enu(math.radians(-12.3860283), e)), atol=1e-15)


def test_default_azimuth_is_north_east():
    assert read_tpoint(DAT).azimuth == "N-E"


def test_unknown_azimuth_convention():
    with pytest.raises(ValueError, match="azimuth convention"):
        read_tpoint(DAT, azimuth="E-N")


def test_read_accepts_str_and_shared_copy(tmp_path):
    shared = Path("/work/shared/data/tpoint/mmt_20210821.dat")
    src = shared if shared.exists() else DAT
    copy = tmp_path / "copy.dat"
    shutil.copy(src, copy)
    run = read_tpoint(str(copy), azimuth="S-E")
    assert run.path == str(copy)
    assert len(run) == 80


# --------------------------------------------------------------------------- variants


def test_latitude_only_parameters():
    run = parse_tpoint("cap\n: ALTAZ\n-24 37 38.6\n10 20 11 21\n")
    p = run.parameters
    assert p.latitude == pytest.approx(dms(24, 37, 38.6, -1), rel=1e-15)
    assert p.date is None
    assert (p.temperature_c, p.pressure_mb, p.height_m, p.humidity, p.wavelength_um, p.lapse_rate) == (None,) * 6


def test_negative_zero_latitude():
    run = parse_tpoint("cap\n: ALTAZ\n-00 30 00\n10 20 11 21\n")
    assert run.parameters.latitude == pytest.approx(-math.radians(0.5), rel=1e-15)
    assert run.parameters.latitude < 0
    run = parse_tpoint("cap\n: ALTAZ\n+00 30 00\n10 20 11 21\n")
    assert run.parameters.latitude == pytest.approx(math.radians(0.5), rel=1e-15)


def test_all_twelve_run_parameters():
    run = parse_tpoint("cap\n: ALTAZ\n+31 41 19.6 2021 8 21 13.0 741 2608 0.75 0.55 0.0065\n10 20 11 21\n")
    p = run.parameters
    assert p.date == (2021, 8, 21)
    assert (p.temperature_c, p.pressure_mb, p.height_m, p.humidity) == (13.0, 741.0, 2608.0, 0.75)
    assert p.wavelength_um == 0.55 and p.lapse_rate == 0.0065


def test_option_without_space_comments_blank_lines_no_end(tmp_path):
    path = write(
        tmp_path,
        [
            "",
            "   ! indented comment",
            "",
            "My caption",
            "",
            ":altaz   ! mount option",
            "",
            "+31 41 19.6 2021 8 21   ! latitude and date",
            "",
            "10.0 20.0 11.0 21.0   ! first star",
            "! a comment between rows",
            "",
            "30.0 40.0 31.0 41.0",
        ],
    )
    run = read_tpoint(path)
    assert run.caption == "My caption"
    assert run.options == ("ALTAZ",)
    assert run.parameters.date == (2021, 8, 21)
    np.testing.assert_array_equal(run.lines, [10, 13])
    np.testing.assert_allclose(run.observed, np.radians([[10.0, 20.0], [30.0, 40.0]]), rtol=1e-15)
    np.testing.assert_allclose(run.encoder, np.radians([[11.0, 21.0], [31.0, 41.0]]), rtol=1e-15)


def test_several_option_records():
    run = parse_tpoint("cap\n: ALTAZ\n:NODA\n+31 0 0\n10 20 11 21\n")
    assert run.options == ("ALTAZ", "NODA")


def test_fifth_column_kept_as_extra(tmp_path):
    path = write(tmp_path, HEADER + ["192.386 77.347 -167.278 77.348 12.5", "193.389 77.285 -166.276 77.286 -3.25"])
    run = read_tpoint(path)
    assert run.extra.shape == (2, 1)
    np.testing.assert_array_equal(run.extra, [[12.5], [-3.25]])  # as written, not converted
    np.testing.assert_allclose(run.encoder, np.radians([[-167.278, 77.348], [-166.276, 77.286]]), rtol=1e-15)
    assert len(run.observations) == 2


def test_text_after_end_ignored(tmp_path):
    path = write(tmp_path, HEADER + ROWS + ["end", "this is not a row", "1 2", "19x 95 nan", ": EQUAT"])
    with pytest.warns(InputWarning, match=r"4 non-comment line\(s\) after END \(line 8\) were ignored \(lines 9-12\)"):
        run = read_tpoint(path)
    assert len(run) == 3
    np.testing.assert_array_equal(run.lines, [5, 6, 7])


def test_end_with_trailing_comment(tmp_path):
    with pytest.warns(InputWarning, match=r"1 non-comment line\(s\) after END \(line 6\) were ignored \(line 7\)"):
        run = read_tpoint(write(tmp_path, HEADER + ROWS[:1] + ["END ! done", "garbage"]))
    assert len(run) == 1


def test_crlf_and_tabs(tmp_path):
    path = tmp_path / "crlf.dat"
    path.write_bytes(b"cap\r\n: ALTAZ\r\n+31\t41\t19.6\r\n10.0\t20.0\t11.0\t21.0\r\nEND\r\n")
    run = read_tpoint(path)
    assert run.caption == "cap"
    assert run.parameters.latitude == pytest.approx(dms(31, 41, 19.6), rel=1e-15)
    np.testing.assert_allclose(run.encoder, np.radians([[11.0, 21.0]]), rtol=1e-15)
    np.testing.assert_array_equal(run.lines, [4])


def test_parse_tpoint_matches_read_tpoint(mmt_se):
    parsed = parse_tpoint(DAT.read_text(), path=str(DAT), azimuth="S-E")
    np.testing.assert_array_equal(parsed.encoder, mmt_se.encoder)
    np.testing.assert_array_equal(parsed.observed, mmt_se.observed)
    assert parsed.parameters == mmt_se.parameters


# --------------------------------------------------------------------------- errors


def test_error_is_value_error():
    assert issubclass(TpointFormatError, ValueError)
    assert px.io.TpointFormatError is TpointFormatError


def test_non_numeric_field(tmp_path):
    path = write(tmp_path, HEADER + [ROWS[0], "19x.3 77.285 -166.276 77.286", ROWS[2]])
    with raises_at(path, 6, r"field 1", r"observed azimuth", r"19x\.3"):
        read_tpoint(path)


def test_non_numeric_raw_elevation(tmp_path):
    path = write(tmp_path, HEADER + ROWS[:2] + ["183.794 17.903 -175.872 1o.906"])
    with raises_at(path, 7, r"field 4", r"raw elevation", r"1o\.906"):
        read_tpoint(path)


@pytest.mark.parametrize("row, n", [("192.386 77.347 -167.278", 3), ("192.386 77.347 -167.278 77.348 1 2", 6)])
def test_wrong_field_count(tmp_path, row, n):
    path = write(tmp_path, HEADER + ROWS[:1] + [row])
    with raises_at(path, 6, rf"observation record has {n} fields"):
        read_tpoint(path)


def test_mixed_four_and_five_fields(tmp_path):
    path = write(tmp_path, HEADER + ROWS[:2] + ["183.794 17.903 -175.872 17.906 12.0"])
    with raises_at(path, 7, r"has 5 fields", r"earlier records have 4"):
        read_tpoint(path)
    path = write(tmp_path, HEADER + ["192.386 77.347 -167.278 77.348 1.0", ROWS[1]], name="b.dat")
    with raises_at(path, 6, r"has 4 fields", r"earlier records have 5"):
        read_tpoint(path)


def test_observed_elevation_out_of_range(tmp_path):
    path = write(tmp_path, HEADER + ["192.386 95 -167.278 77.348"] + ROWS[1:])
    with raises_at(path, 5, r"field 2", r"observed elevation", r"95"):
        read_tpoint(path)


def test_raw_elevation_out_of_range(tmp_path):
    path = write(tmp_path, HEADER + ROWS[:1] + ["193.389 77.285 -166.276 181"])
    with raises_at(path, 6, r"field 4", r"raw elevation"):
        read_tpoint(path)


@pytest.mark.parametrize("token", ["nan", "NaN", "inf"])
def test_non_finite_field(tmp_path, token):
    path = write(tmp_path, HEADER + ROWS[:2] + [f"183.794 17.903 {token} 17.906"])
    with raises_at(path, 7, r"field 3", r"raw azimuth", re.escape(repr(token)), r"not finite"):
        read_tpoint(path)


def test_missing_altaz_option(tmp_path):
    path = write(tmp_path, ["Test run", "+31 41 19.6 2021 8 21"] + ROWS)
    with raises_at(path, 2, r"ALTAZ", r"equatorial"):
        read_tpoint(path)


def test_altaz_rows_under_an_equatorial_option_are_refused(tmp_path):
    # Four numbers under ': EQUAT' are hour angles (h) and declinations: 192.386 h is not one.
    path = write(tmp_path, ["Test run", ": EQUAT", "+31 41 19.6"] + ROWS)
    with raises_at(path, 4, r"field 1 \(star HA\) 192.386 h is outside -24..24 h"):
        read_tpoint(path)


@pytest.mark.parametrize(
    "record, n",
    [("+31 41 19.6 2021", 4), ("+31 41 19.6 2021 8", 5), ("+31 41", 2), ("+31 41 19.6 2021 8 21 13 741 2608 0.75 0.55 0.0065 9", 13)],
)
def test_run_parameters_field_count(tmp_path, record, n):
    path = write(tmp_path, HEADER[:3] + [record] + ROWS)
    with raises_at(path, 4, rf"run-parameters record has {n} fields"):
        read_tpoint(path)


def test_bad_latitude_minutes(tmp_path):
    path = write(tmp_path, HEADER[:3] + ["+31 75 19.6 2021 8 21"] + ROWS)
    with raises_at(path, 4, r"latitude", r"\+31 75 19\.6"):
        read_tpoint(path)


def test_bad_latitude_seconds_and_degrees(tmp_path):
    path = write(tmp_path, HEADER[:3] + ["+31 41 60"] + ROWS)
    with raises_at(path, 4, r"latitude"):
        read_tpoint(path)
    path = write(tmp_path, HEADER[:3] + ["+91 00 00"] + ROWS, name="b.dat")
    with raises_at(path, 4, r"latitude"):
        read_tpoint(path)


def test_non_numeric_latitude_minutes(tmp_path):
    path = write(tmp_path, HEADER[:3] + ["+31 4x 19.6"] + ROWS)
    with raises_at(path, 4, r"field 2", r"latitude minutes", r"4x"):
        read_tpoint(path)


def test_bad_date(tmp_path):
    path = write(tmp_path, HEADER[:3] + ["+31 41 19.6 2021 13 21"] + ROWS)
    with raises_at(path, 4, r"date"):
        read_tpoint(path)


def test_empty_file(tmp_path):
    path = write(tmp_path, "")
    with raises_at(path, None, r"empty"):
        read_tpoint(path)
    path = write(tmp_path, ["! only", "! comments", ""], name="comments.dat")
    with raises_at(path, None, r"empty"):
        read_tpoint(path)


def test_no_observation_rows(tmp_path):
    path = write(tmp_path, HEADER + ["END"])
    with raises_at(path, None, r"no observation records"):
        read_tpoint(path)


def test_no_run_parameters(tmp_path):
    path = write(tmp_path, HEADER[:3])
    with raises_at(path, None, r"run-parameters"):
        read_tpoint(path)


def test_option_after_run_parameters(tmp_path):
    path = write(tmp_path, HEADER + ROWS[:1] + [": NODA"] + ROWS[1:])
    with raises_at(path, 6, r"option record", r"NODA"):
        read_tpoint(path)


def test_binary_file(tmp_path):
    path = tmp_path / "bin.dat"
    path.write_bytes(b"\xff\xfe\x00\x01garbage")
    with raises_at(path, None, r"not a text file"):
        read_tpoint(path)


# --------------------------------------------------------------------------- model files

FLAGS_MODEL = """\
! a comment before the caption
Model with flags
S   12   1.5000
  IA      +1209.2612     1.28477   ! trailing comment
& HSCASE3   -6.7565     1.60735

 =NPAE      +0.0000
 = CA        +1.5000
&=TF         +2.0000
  aw        -10.3347     0.11843
END
anything after END
"""


def test_read_real_model():
    m = read_model(MOD)
    assert isinstance(m, TpointModelFile)
    assert m.path == str(MOD)
    assert m.caption == "MMT Pointing Data from 08/21/2021"
    assert m.method == "T"
    assert m.n_obs == 80
    assert m.sky_rms == 0.9318
    assert m.refraction == (42.060, -0.0485)
    assert m.names == [n for n, _, _ in MOD_TERMS]
    assert len(m.terms) == 8
    for term, (name, value, sigma) in zip(m.terms, MOD_TERMS):
        assert isinstance(term, ModelTerm)
        assert term.name == name
        assert term.value == value
        assert term.sigma == sigma
        assert not term.fixed and not term.parallel
    values = m.values()
    assert list(values) == m.names
    for name, value, _ in MOD_TERMS:
        assert values[name] == pytest.approx(value * RAD_PER_ARCSEC, rel=1e-15)


def test_model_flags_and_method_letter():
    with pytest.warns(InputWarning, match=r"flags.mod:12: 1 non-comment line\(s\) after END"):
        m = parse_model(FLAGS_MODEL, path="flags.mod")
    assert m.caption == "Model with flags"
    assert m.method == "S"
    assert m.n_obs == 12
    assert m.sky_rms == 1.5
    assert m.refraction is None
    assert m.names == ["IA", "HSCASE3", "NPAE", "CA", "TF", "AW"]
    t = {x.name: x for x in m.terms}
    assert (t["IA"].value, t["IA"].sigma, t["IA"].fixed, t["IA"].parallel) == (1209.2612, 1.28477, False, False)
    assert (t["HSCASE3"].value, t["HSCASE3"].sigma, t["HSCASE3"].fixed, t["HSCASE3"].parallel) == (-6.7565, 1.60735, False, True)
    assert (t["NPAE"].value, t["NPAE"].sigma, t["NPAE"].fixed, t["NPAE"].parallel) == (0.0, None, True, False)
    assert (t["CA"].value, t["CA"].sigma, t["CA"].fixed, t["CA"].parallel) == (1.5, None, True, False)
    assert (t["TF"].value, t["TF"].sigma, t["TF"].fixed, t["TF"].parallel) == (2.0, None, True, True)
    assert (t["AW"].value, t["AW"].sigma) == (-10.3347, 0.11843)


def test_model_without_summary_record():
    m = parse_model("cap\n  IA  +1.5  0.25\nEND\n")
    assert m.method is None and m.n_obs is None and m.sky_rms is None and m.refraction is None
    assert m.terms == (ModelTerm("IA", 1.5, 0.25),)


def _all_flag_terms():
    return [
        ModelTerm("IA", 1209.26124, 1.284771),
        ModelTerm("IE", -2.99327612, 0.30388137),
        ModelTerm("NPAE", 0.0, None, fixed=True),
        ModelTerm("HSCASE3", -6.75654, 1.607351, parallel=True),
        ModelTerm("TF", 21.4106, None, fixed=True, parallel=True),
        ModelTerm("LONGNAME99", 0.00004, 0.5),
        ModelTerm("TX", -0.0, 0.0),
    ]


def test_format_parse_round_trip():
    terms = _all_flag_terms()
    text = format_model(terms, caption="round trip", n_obs=80, sky_rms=0.93189, refraction=(42.06, -0.0485))
    assert text.endswith("END\n")
    m = parse_model(text)
    assert m.caption == "round trip"
    assert m.method == "T"
    assert m.n_obs == 80
    assert m.sky_rms == pytest.approx(0.93189, abs=1e-4)
    assert m.refraction[0] == pytest.approx(42.06, abs=1e-3)
    assert m.refraction[1] == pytest.approx(-0.0485, abs=1e-4)
    assert m.names == [t.name for t in terms]
    for got, want in zip(m.terms, terms):
        assert got.value == pytest.approx(want.value, abs=1e-4)
        assert got.fixed == want.fixed
        assert got.parallel == want.parallel
        if want.fixed:
            assert got.sigma is None
        else:
            assert got.sigma == pytest.approx(want.sigma, abs=1e-5)


def test_round_trip_of_real_model(tmp_path):
    m = read_model(MOD)
    path = tmp_path / "again.mod"
    path.write_text(format_model(m.terms, m.caption, m.n_obs, m.sky_rms, m.refraction))
    again = read_model(path)
    assert again.caption == m.caption and again.n_obs == m.n_obs
    assert again.refraction == pytest.approx(m.refraction, abs=1e-4)
    for a, b in zip(again.terms, m.terms):
        assert a.name == b.name
        assert a.value == pytest.approx(b.value, abs=1e-9)
        assert a.sigma == pytest.approx(b.sigma, abs=1e-9)


def test_format_model_without_summary():
    m = parse_model(format_model([ModelTerm("IA", 3.0, 0.5)]))
    assert m.caption == "pointax model"
    assert m.n_obs is None and m.method is None
    assert m.terms == (ModelTerm("IA", 3.0, 0.5),)


def test_model_missing_end(tmp_path):
    path = write(tmp_path, "cap\nT 80 0.93\n  IA  +1.0  0.1\n", name="m.mod")
    with raises_at(path, None, r"END"):
        read_model(path)


def test_model_non_numeric_value(tmp_path):
    path = write(tmp_path, ["cap", "T 80 0.93", "  IA  +1.0  0.1", "  IE  -2.99x3  0.3", "END"], name="m.mod")
    with raises_at(path, 4, r"IE", r"value", r"-2\.99x3", r"not a number"):
        read_model(path)


def test_model_non_numeric_sigma(tmp_path):
    path = write(tmp_path, ["cap", "  IA  +1.0  0.1s", "END"], name="m.mod")
    with raises_at(path, 2, r"IA", r"sigma"):
        read_model(path)


def test_model_duplicated_term(tmp_path):
    path = write(tmp_path, ["cap", "T 80 0.93", "  IA  +1.0  0.1", "  IE  +2.0  0.1", "& ia  +3.0  0.1", "END"], name="m.mod")
    with raises_at(path, 5, r"IA", r"twice"):
        read_model(path)


def test_model_four_fields_on_term_line(tmp_path):
    path = write(tmp_path, ["cap", "T 80 0.93", "  IA  +1.0  0.1  7", "END"], name="m.mod")
    with raises_at(path, 3, r"term record has 4 fields"):
        read_model(path)


def test_model_bad_summary_record(tmp_path):
    path = write(tmp_path, ["cap", "T 80 0.93 42.0", "  IA  +1.0  0.1", "END"], name="m.mod")
    with raises_at(path, 2, r"fit-summary record", r"4 fields"):
        read_model(path)


def test_model_flag_without_name(tmp_path):
    path = write(tmp_path, ["cap", "  IA  +1.0  0.1", "&", "END"], name="m.mod")
    with raises_at(path, 3, r"term name"):
        read_model(path)


def test_model_empty(tmp_path):
    path = write(tmp_path, "", name="m.mod")
    with raises_at(path, None, r"empty"):
        read_model(path)


# --------------------------------------------------------------------------- writing


@pytest.fixture(scope="module")
def mmt_fit():
    run = read_tpoint(DAT, azimuth="S-E")
    res = px.fit(px.AltAz(px.terms.tpoint(TERMS8), azimuth=run.azimuth), run)
    assert bool(res.converged)
    return run, res


def test_write_model_from_fit_result(tmp_path, mmt_fit):
    run, res = mmt_fit
    path = tmp_path / "fit.mod"
    with pytest.warns(UserWarning, match="no run given, so the refraction constants are written as 0"):
        write_model(path, res)
    m = read_model(path)
    assert m.caption == run.caption
    assert m.method == "T"
    assert m.n_obs == 80
    assert m.sky_rms == pytest.approx(float(res.sky_rms) / RAD_PER_ARCSEC, abs=1e-4)
    assert m.refraction == (0.0, 0.0)
    table = res.table()
    assert m.names == [row["name"] for row in table] == TERMS8.split()
    for term, row in zip(m.terms, table):
        assert row["unit"] == "arcsec"
        assert term.value == pytest.approx(row["value"], abs=1e-4)
        assert term.sigma == pytest.approx(row["sigma"], abs=1e-4)
        assert not term.fixed and not term.parallel


def test_written_fit_agrees_with_tpoint(tmp_path, mmt_fit):
    # PROVENANCE: a linear fit of the 8 terms reproduces TPOINT's .mod to within 0.01".
    _, res = mmt_fit
    path = tmp_path / "fit.mod"
    write_model(path, res, caption="pointax fit", refraction=(42.060, -0.0485))
    m = read_model(path)
    assert m.caption == "pointax fit"
    assert m.refraction == pytest.approx((42.060, -0.0485), abs=1e-4)
    assert m.sky_rms == pytest.approx(0.9318, abs=0.01)
    for term, (name, value, sigma) in zip(m.terms, MOD_TERMS):
        assert term.name == name
        assert term.value == pytest.approx(value, abs=0.01)
        assert term.sigma == pytest.approx(sigma, abs=0.01)


def test_write_model_from_model(tmp_path):
    model = px.AltAz(
        px.terms.tpoint("IA IE NPAE", values={"IA": 12.5 * RAD_PER_ARCSEC, "IE": -3.25 * RAD_PER_ARCSEC}),
        azimuth="S-E",
        fixed=["NPAE"],
    )
    path = tmp_path / "model.mod"
    write_model(path, model)
    m = read_model(path)
    assert m.caption == "pointax model"
    assert m.n_obs is None and m.method is None
    assert m.names == ["IA", "IE", "NPAE"]
    assert [t.value for t in m.terms] == pytest.approx([12.5, -3.25, 0.0], abs=1e-4)
    assert [t.sigma for t in m.terms] == [None, None, None]
    assert [t.fixed for t in m.terms] == [False, False, True]


def test_model_file_rebuilds_model():
    mf = read_model(MOD)
    model = mf.model(azimuth="S-E")
    assert isinstance(model, px.Model)
    assert model.parameter_names == [n for n, _, _ in MOD_TERMS]
    assert model.mount.convention == "S-E"
    assert model.fixed == frozenset()
    for name, value, _ in MOD_TERMS:
        assert float(model.get(name)) == pytest.approx(value * math.pi / 648000.0, rel=1e-15)
    assert mf.model().mount.convention == "N-E"
    rigorous = mf.model(form="rigorous")
    assert float(rigorous.get("IA")) == pytest.approx(1209.2612 * RAD_PER_ARCSEC, rel=1e-15)


def test_rebuilt_model_reproduces_tpoint_sky_rms(mmt_se):
    # TPOINT's own model applied to its own data gives its Sky RMS (0.9318").
    model = read_model(MOD).model(azimuth="S-E")
    r = np.asarray(px.residuals(model, mmt_se.observations))
    rms = math.sqrt(np.sum(r**2) / len(mmt_se)) / RAD_PER_ARCSEC
    assert rms == pytest.approx(0.9318, abs=0.005)


def test_model_file_fixed_terms_rebuild():
    mf = parse_model("cap\n  IA  +10.0  1.0\n =NPAE  -2.0\nEND\n")
    model = mf.model()
    assert model.fixed == frozenset({"NPAE"})
    assert float(model.get("NPAE")) == pytest.approx(-2.0 * RAD_PER_ARCSEC, rel=1e-15)


class _Tilt(px.Term):
    angle: float = px.param(0.0, unit="deg")


class _TwoParams(px.Term):
    a: float = px.param(0.0)
    b: float = px.param(0.0)


@pytest.mark.parametrize("term, name", [(_Tilt(), "_Tilt"), (_TwoParams(), r"_TwoParams\.a")])
def test_write_model_rejects_unwritable_parameters(tmp_path, term, name):
    model = px.AltAz((px.terms.tpoint("IA")[0], term))
    path = tmp_path / "bad.mod"
    with pytest.raises(ValueError, match=name):
        write_model(path, model)
    assert not path.exists()


# --------------------------------------------------------------------------- regressions
# Each covers a defect found while writing these tests, since fixed.


def test_degenerate_fit_writes_a_readable_file(tmp_path, mmt_fit):
    _, res = mmt_fit
    degenerate = eqx.tree_at(lambda r: r.sigmas, res, res.sigmas.at[2].set(jnp.inf))  # as fit() reports one
    path = tmp_path / "degenerate.mod"
    write_model(path, degenerate, refraction=(0.0, 0.0))
    m = read_model(path)
    assert m.terms[2].sigma is None and m.terms[1].sigma is not None


def test_latitude_beyond_90_rejected(tmp_path):
    path = write(tmp_path, HEADER[:3] + ["+90 30 00"] + ROWS)
    with pytest.raises(TpointFormatError, match="latitude"):
        read_tpoint(path)


def test_model_field_numbers_count_from_line_start(tmp_path):
    path = write(tmp_path, ["cap", "  IA  1.x  0.1", "END"], name="m.mod")
    with pytest.raises(TpointFormatError, match=r"field 2 \(value"):
        read_model(path)
    path = write(tmp_path, ["cap", "T 80 x", "END"], name="t.mod")
    with pytest.raises(TpointFormatError, match=r"field 3 \(Sky RMS"):
        read_model(path)


def test_long_name_large_value_round_trip():
    m = parse_model(format_model([ModelTerm("HSCASE32", 1.5e6, 1.0)]))
    assert m.names == ["HSCASE32"] and m.terms[0].value == 1.5e6


def test_comment_like_or_empty_caption_rejected():
    for caption in ("! my model", "   "):
        with pytest.raises(ValueError, match="caption"):
            format_model([ModelTerm("IA", 1.0, 0.5)], caption=caption, n_obs=5, sky_rms=1.0)


def test_byte_order_mark_is_ignored(tmp_path):
    path = tmp_path / "bom.dat"
    path.write_text("\ufeff" + "\n".join(["! a comment first"] + HEADER + ROWS) + "\n", encoding="utf-8")
    assert len(read_tpoint(path)) == len(ROWS)

"""TPOINT equatorial runs, sexagesimal records, the mount option, refraction, the
rotator column and the one-line model-file layout (pointax.io.tpoint).

References are outside the reader: the shared REFERENCE.txt figures for the TheSkyX run
(reproduced here by a plain numpy least-squares fit with its own basis functions),
numbers read by hand from the files, ERFA's refco against the constants TPOINT wrote
into the MMT model file, and closed-form conversions of h m s / d m s.
"""

from __future__ import annotations

import math
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from pointax.io import (
    InputWarning,
    MountNotGivenError,
    TpointFormatError,
    detect_format,
    format_model,
    load_run,
    parse_model,
    read_model,
    read_tpoint,
)

ROOT = Path(__file__).resolve().parents[1]
MMT_DAT = ROOT / "examples" / "data" / "mmt_20210821.dat"
MMT_MOD = ROOT / "examples" / "data" / "mmt_20210821.mod"
ARCSEC = math.pi / 648000.0
HOUR = math.pi / 12.0


@pytest.fixture(scope="module")
def equatorial_dir(shared_data_dir):
    return shared_data_dir / "tpoint" / "equatorial"


@pytest.fixture(scope="module")
def shared_data_dir():
    from conftest import SHARED_DATA

    if not SHARED_DATA.is_dir():
        pytest.skip(f"{SHARED_DATA} not found: the shared data folder is not beside this checkout")
    return SHARED_DATA


def write(tmp_path, lines, name="run.dat"):
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def enu_to_hadec(enu, lat):
    """Closed form: East-North-Up unit vectors -> hour angle (West +) and declination."""
    e, n, u = np.asarray(enu).T
    dec = np.arcsin(math.cos(lat) * n + math.sin(lat) * u)
    ha = np.arctan2(-e, -math.sin(lat) * n + math.cos(lat) * u)
    return ha, dec


# ----------------------------------------------------------------- TheSkyX export


def test_theskyx_run_is_read_with_its_pier_sides(equatorial_dir):
    run = read_tpoint(equatorial_dir / "cgx-l-data.dat")
    assert run.mount == "equatorial" and run.azimuth == "ha-dec" == run.observations.convention
    assert len(run) == 148 and int(run.flipped.sum()) == 70
    assert run.latitude == pytest.approx(math.radians(39 + 26 / 3600), abs=1e-15)
    p = run.parameters
    assert (p.temperature_c, p.pressure_mb, p.height_m, p.humidity, p.wavelength_um, p.lapse_rate) == (
        29.2, 987.0, 231.65, 0.94, 0.55, 0.0065
    )
    # First record, by hand: 21 43 18.4460 +72 29 08.368 09 28 59.9527 +109 20 06.469  16 23.130
    lst = (16 + 23.130 / 60) * HOUR
    assert run.sidereal_time[0] == pytest.approx(lst, abs=1e-14)
    ra_tel = (9 + 28 / 60 + 59.9527 / 3600) * HOUR
    assert run.encoder[0, 1] == pytest.approx(math.radians(109 + 20 / 60 + 6.469 / 3600), abs=1e-14)
    assert math.remainder(run.encoder[0, 0] - (lst - ra_tel), 2 * math.pi) == pytest.approx(0, abs=1e-14)
    assert run.flipped[0] and not run.flipped[3]  # fourth record: +82 59 13.276
    # The flipped reading (H, D) points at (H - 12 h, 180 deg - D): TPOINT's rule, here
    # through the mount's own forward model.
    from pointax.core.mounts import EquatorialMount

    mount = EquatorialMount(run.latitude)
    flipped = np.flatnonzero(run.flipped)
    direction = np.asarray([np.asarray(mount.direction(run.encoder[k])) @ np.asarray(mount.frame).T for k in flipped[:5]])
    ha, dec = enu_to_hadec(direction, run.latitude)
    d = run.encoder[flipped[:5], 1]
    np.testing.assert_allclose(dec, np.sign(d) * math.pi - d, atol=1e-12)
    np.testing.assert_allclose(np.remainder(ha - (run.encoder[flipped[:5], 0] - math.pi) + 1, 2 * math.pi) - 1, 0, atol=1e-12)


def test_theskyx_six_term_reference_figures(equatorial_dir):
    """REFERENCE.txt: refraction applied to the star place, H = LST - RA, terms at the
    star's position, ordinary least squares: Sky RMS 15,689.8" with no terms, 235.03"
    with IH ID CH NP MA ME, NP -599.2". The basis here is the numpy transcription of
    TPOINT's definitions in the mechanical angles (so the flip changes the sign of ID,
    CH and NP on the sky)."""
    run = read_tpoint(equatorial_dir / "cgx-l-data.dat")
    assert run.refraction_applied
    ha, dec = enu_to_hadec(np.asarray(run.observations.target), run.latitude)
    flip = run.flipped
    h = np.where(flip, ha + math.pi, ha)
    d = np.where(flip, np.sign(run.encoder[:, 1]) * math.pi - dec, dec)
    dh = np.remainder(h - run.encoder[:, 0] + math.pi, 2 * math.pi) - math.pi
    dd = d - run.encoder[:, 1]
    c, t = np.cos(d), np.tan(d)
    one, zero = np.ones_like(c), np.zeros_like(c)
    basis = {  # (dH, d dec) per unit coefficient
        "IH": (one, zero), "ID": (zero, one), "CH": (1 / c, zero), "NP": (t, zero),
        "MA": (-np.cos(h) * t, np.sin(h)), "ME": (np.sin(h) * t, np.cos(h)),
    }
    a = np.concatenate([np.stack([f[0] * c for f in basis.values()], 1), np.stack([f[1] for f in basis.values()], 1)])
    b = np.concatenate([dh * c, dd])
    n = len(run)
    assert math.sqrt(b @ b / n) / ARCSEC == pytest.approx(15689.8, rel=0.01)
    x = np.linalg.lstsq(a, b, rcond=None)[0]
    r = b - a @ x
    assert math.sqrt(r @ r / n) / ARCSEC == pytest.approx(235.03, rel=0.01)
    reference = {"IH": -18828.0, "ID": -3452.2, "CH": -1373.7, "NP": -599.2, "MA": -3047.8, "ME": 469.1}
    for name, value in zip(basis, x / ARCSEC):
        assert value == pytest.approx(reference[name], rel=0.01), name


def test_spk_run_has_no_refraction_and_hour_angles_from_twelve_hours(equatorial_dir):
    run = read_tpoint(equatorial_dir / "spk_5m_horseshoe.dat")
    assert len(run) == 39 and not run.flipped.any()
    assert run.refraction == (0.0, 0.0) and not run.refraction_applied  # pressure 0
    # First record: 11 34 40.6642 +30 09 07.934 11 34 38.3798 +30 10 14.074  12 00.000
    ha_star = (12 - (11 + 34 / 60 + 40.6642 / 3600)) * HOUR
    assert run.observed[0, 0] == pytest.approx(ha_star, abs=1e-14)
    assert run.observed[0, 1] == pytest.approx(math.radians(30 + 9 / 60 + 7.934 / 3600), abs=1e-14)
    ha, dec = enu_to_hadec(np.asarray(run.observations.target), run.latitude)
    np.testing.assert_allclose(ha, run.observed[:, 0], atol=1e-12)
    np.testing.assert_allclose(dec, run.observed[:, 1], atol=1e-12)


# ------------------------------------------------------------------- record layouts

EQ_HEADER = ["Equatorial test", ": EQUAT", "+33 21 22.0 2023 9 20 10.0 0.0"]
EQ_ROWS = [
    "11 34 40.6642 +30 09 07.934 11 34 38.3798 +30 10 14.074  12 00.000",
    "11 59 14.8860 -00 04 58.775 11 59 12.0919 -00 03 49.158  12 00.000",
    "13 57 34.3843 -35 11 37.036 13 57 32.4828 -35 10 20.514  12 30.500",
]


def _decimal(row: str) -> str:
    f = row.split()
    hms = lambda a, b, c: (-1 if a.startswith("-") else 1) * (abs(float(a)) + float(b) / 60 + float(c) / 3600)  # noqa: E731
    values = [hms(*f[0:3]), hms(*f[3:6]), hms(*f[6:9]), hms(*f[9:12]), float(f[12]) + float(f[13]) / 60]
    return " ".join(repr(v) for v in values)


def test_signed_zero_degrees(tmp_path):
    run = read_tpoint(write(tmp_path, EQ_HEADER + EQ_ROWS))
    assert run.observed[1, 1] == pytest.approx(-math.radians(4 / 60 + 58.775 / 3600), abs=1e-15)
    assert run.encoder[1, 1] == pytest.approx(-math.radians(3 / 60 + 49.158 / 3600), abs=1e-15)


def test_decimal_and_hour_angle_layouts_agree_with_sexagesimal(tmp_path):
    sexagesimal = read_tpoint(write(tmp_path, EQ_HEADER + EQ_ROWS, "a.dat"))
    decimal = read_tpoint(write(tmp_path, EQ_HEADER + [_decimal(r) for r in EQ_ROWS], "b.dat"))
    np.testing.assert_allclose(decimal.encoder, sexagesimal.encoder, atol=1e-13)
    np.testing.assert_allclose(decimal.observed, sexagesimal.observed, atol=1e-13)
    # Hour angles instead of RA and sidereal time: H = LST - RA, written as h m s.
    rows = []
    for row in EQ_ROWS:
        f = row.split()
        lst = float(f[12]) + float(f[13]) / 60

        def ha(h, m, s):
            x = lst - (float(h) + float(m) / 60 + float(s) / 3600)
            sign = "-" if x < 0 else "+"
            x = abs(x)
            hh, rest = int(x), (x - int(x)) * 60
            return f"{sign}{hh:02d} {int(rest):02d} {(rest - int(rest)) * 60:.10f}"

        rows.append(f"{ha(*f[0:3])} {' '.join(f[3:6])} {ha(*f[6:9])} {' '.join(f[9:12])}")
    hour_angles = read_tpoint(write(tmp_path, EQ_HEADER + rows, "c.dat"))
    assert hour_angles.sidereal_time is None
    np.testing.assert_allclose(hour_angles.encoder, sexagesimal.encoder, atol=1e-12)
    np.testing.assert_allclose(hour_angles.observed, sexagesimal.observed, atol=1e-12)


def test_sexagesimal_altaz_rows_equal_decimal_ones(tmp_path):
    decimal = read_tpoint(MMT_DAT, azimuth="S-E")

    def dms(x):
        sign = "-" if x < 0 else "+"
        x = abs(x)
        d, rest = int(x), (x - int(x)) * 60
        return f"{sign}{d} {int(rest)} {(rest - int(rest)) * 60:.9f}"

    lines = MMT_DAT.read_text().splitlines()
    out = []
    for k, line in enumerate(lines, 1):
        if k in set(decimal.lines.tolist()):
            out.append(" ".join(dms(float(v)) for v in line.split()[:4]))
        else:
            out.append(line)
    run = read_tpoint(write(tmp_path, out), azimuth="S-E")
    np.testing.assert_allclose(run.encoder, decimal.encoder, atol=1e-11)
    np.testing.assert_allclose(run.observed, decimal.observed, atol=1e-11)


@pytest.mark.parametrize(
    "row, match",
    [
        ("11 61 40.6 +30 09 07.9 11 34 38.3 +30 10 14.0  12 00.000", r"field 2 \(star RA \(minutes\)\).*not within 0..60"),
        ("11 34 40.6 +30 09 67.9 11 34 38.3 +30 10 14.0  12 00.000", r"field 6 \(star Dec \(seconds\)\).*not within 0..60"),
        ("11 34 40.6 +30 -09 07.9 11 34 38.3 +30 10 14.0  12 00.000", r"field 5 .*only the first field of an angle carries a sign"),
        ("11 34 40.6 +95 09 07.9 11 34 38.3 +30 10 14.0  12 00.000", r"field 4 \(star Dec\).*outside -90..90"),
        ("11 34 40.6 +30 09 07.9 11 34 38.3 +190 10 14.0  12 00.000", r"field 10 \(telescope Dec\).*outside -180..180"),
        ("11 34 40.6 +30 09 07.9 11 34 38.3 +30 10 14.0  25 00.000", r"field 13 \(sidereal time\).*outside 0..24"),
        ("11 34 40.6 +30 09 07.9 11 34 38.3 +30 10 x  12 00.000", r"field 12 \(telescope Dec \(seconds\)\).*not a number"),
        ("11 34 40.6 +30 09 07.9 11 34 38.3 +30 10 14.0", r"has 12 fields.*earlier records have 14"),
        ("00 00 00.0 -80 00 00.0 00 00 00.0 -80 00 00.0  12 00.000", r"below the horizon"),
    ],
)
def test_bad_equatorial_records_name_line_and_field(tmp_path, row, match):
    path = write(tmp_path, EQ_HEADER + EQ_ROWS[:1] + [row])
    with pytest.raises(TpointFormatError, match=rf"{path}:5: .*{match}"):
        read_tpoint(path)


def test_unknown_record_width_lists_the_layouts(tmp_path):
    path = write(tmp_path, EQ_HEADER + ["1 2 3 4 5 6 7 8 9 10"])  # 5 decimal fields + 3 auxiliary readings at most
    with pytest.raises(TpointFormatError, match=r"run\.dat:4: observation record has 10 fields; an equatorial record has 4 fields"):
        read_tpoint(path)


# ----------------------------------------------------------------------- the mount


def test_no_mount_option_names_tpoints_default_and_the_option(tmp_path):
    lines = [line for line in MMT_DAT.read_text().splitlines() if line.strip() != ": ALTAZ"]
    path = write(tmp_path, lines)
    with pytest.raises(MountNotGivenError, match=r"TPOINT's default is equatorial.*mount='altaz'.*--mount"):
        read_tpoint(path, azimuth="S-E")
    plain = read_tpoint(path, azimuth="S-E", mount="altaz")
    np.testing.assert_array_equal(plain.encoder, read_tpoint(MMT_DAT, azimuth="S-E").encoder)
    assert detect_format(path) == "tpoint"  # no option record, no END: still told
    assert load_run(path, azimuth="S-E", mount="altaz").mount == "altaz"


def test_mount_contradicting_the_file_is_refused(tmp_path, equatorial_dir):
    with pytest.raises(TpointFormatError, match=r"says equatorial .*mount='altaz'"):
        read_tpoint(equatorial_dir / "spk_5m_horseshoe.dat", mount="altaz")
    with pytest.raises(TpointFormatError, match=r"contradictory mount options: ALTAZ, EQUAT"):
        read_tpoint(write(tmp_path, ["caption", ": ALTAZ", ": EQUAT", "+31 41 19.6", "1 2 3 4"]))
    with pytest.raises(TpointFormatError, match=r"mount option ALTALT: pointax reads"):
        read_tpoint(write(tmp_path, ["caption", ": ALTALT", "+31 41 19.6", "1 2 3 4"]))
    with pytest.raises(ValueError, match=r"unknown mount 'fork'"):
        read_tpoint(MMT_DAT, mount="fork")


def test_german_and_fork_options_are_equatorial(tmp_path):
    for option in ("GERMAN", "FORK"):
        run = read_tpoint(write(tmp_path, [EQ_HEADER[0], f": {option}", EQ_HEADER[2]] + EQ_ROWS))
        assert run.mount == "equatorial" and option in run.options


# -------------------------------------------------------------- rotator, refraction


def test_rotator_column_is_kept_and_said(tmp_path):
    rows = [r + " 12.5" for r in EQ_ROWS]
    path = write(tmp_path, [EQ_HEADER[0], ": EQUAT ROTNR", EQ_HEADER[2]] + rows)
    with pytest.warns(InputWarning, match=r"run\.dat:4: option ROTNR: the rotator angle \(field 15\) is kept as run\.rotator"):
        run = read_tpoint(path)
    np.testing.assert_allclose(run.rotator, math.radians(12.5))
    with pytest.raises(TpointFormatError, match=r"option ROTNR says the records carry a rotator angle"):
        read_tpoint(write(tmp_path, [EQ_HEADER[0], ": EQUAT", ": ROTNR", EQ_HEADER[2]] + EQ_ROWS, "b.dat"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert read_tpoint(write(tmp_path, EQ_HEADER + rows, "c.dat")).rotator is None  # no option: plain extra


def test_refraction_constants_match_what_tpoint_wrote_for_the_mmt_run():
    """TPOINT's model file of this run says A = 42.060", B = -0.0485"; ERFA's refco from
    the run's weather gives the same to 0.01" and 0.001"."""
    run = read_tpoint(MMT_DAT, azimuth="S-E")
    assert not run.refraction_applied  # alt-az files give observed places
    a, b = (x / ARCSEC for x in run.refraction)
    mod = read_model(MMT_MOD)
    assert a == pytest.approx(mod.refraction[0], abs=0.01)
    assert b == pytest.approx(mod.refraction[1], abs=0.001)


def test_refraction_raises_the_star_by_a_tan_z(tmp_path):
    """The applied refraction equals A tan Z + B tan^3 Z at the observed zenith distance."""
    header = [EQ_HEADER[0], ": EQUAT", "+33 21 22.0 2023 9 20 10.0 800.0 0 0.5 0.55"]
    run = read_tpoint(write(tmp_path, header + EQ_ROWS))
    vacuum = read_tpoint(write(tmp_path, EQ_HEADER + EQ_ROWS, "v.dat"))
    a, b = run.refraction
    assert a > 0 and run.refraction_applied
    z_obs = np.arccos(np.asarray(run.observations.target)[:, 2])
    z_vac = np.arccos(np.asarray(vacuum.observations.target)[:, 2])
    np.testing.assert_allclose(z_vac - z_obs, a * np.tan(z_obs) + b * np.tan(z_obs) ** 3, rtol=1e-9, atol=1e-14)
    given = read_tpoint(write(tmp_path, header + EQ_ROWS, "g.dat"), refraction=(0.0, 0.0))
    np.testing.assert_allclose(np.asarray(given.observations.target), np.asarray(vacuum.observations.target), atol=1e-15)


def test_fit_writes_the_runs_refraction_constants(tmp_path):
    out = tmp_path / "fit.mod"
    code = subprocess.run(
        [sys.executable, "-m", "pointax", "fit", str(MMT_DAT), "--azimuth", "S-E", "--write-model", str(out)],
        capture_output=True, text=True, timeout=300,
    )
    assert code.returncode == 0, code.stderr
    mod = read_model(out)
    assert mod.refraction[0] == pytest.approx(42.060, abs=0.01)
    assert mod.refraction[1] == pytest.approx(-0.0485, abs=0.001)


# ------------------------------------------------------------- one-line model files


def test_one_line_model_file_reads_as_the_line_layout(tmp_path):
    lines = read_model(MMT_MOD)
    text = format_model(lines.terms, lines.caption, lines.n_obs, lines.sky_rms, lines.refraction, layout="one-line")
    # TPOINT's one-line layout: fields between '|', no END (tests/test_tpoint_files.py).
    assert text.count("\n") == 1 and text.startswith(f"{lines.caption}|T|   80|") and "END" not in text
    one = parse_model(text, "one.mod")
    assert [(t.name, t.value, t.sigma, t.fixed) for t in one.terms] == [(t.name, t.value, t.sigma, t.fixed) for t in lines.terms]
    assert (one.caption, one.n_obs, one.sky_rms, one.refraction) == (lines.caption, lines.n_obs, lines.sky_rms, lines.refraction)
    # pointax's earlier one-line form (the line layout's records between '|', END last)
    # still reads, with '=' and '&' flags.
    hand = parse_model("Caption here|T 80 0.93 42.06 -0.0485|IA +1209.2612 1.28|=IE -2.9933|&HACA2 +1.5 0.2|END", "h.mod")
    assert hand.names == ["IA", "IE", "HACA2"] and hand.terms[1].fixed and hand.terms[2].parallel
    assert hand.refraction == (42.06, -0.0485)
    # A '|' in a line-layout caption is text.
    assert parse_model("A | B caption\nIA +1.0\nEND\n").caption == "A | B caption"
    with pytest.raises(TpointFormatError, match=r"m\.mod:2: a record after a one-line model"):
        parse_model("Cap | IA +1.0 | END\nIE +2.0\n", "m.mod")
    with pytest.raises(ValueError, match="unknown model-file layout"):
        format_model(lines.terms, layout="columns")


# ------------------------------------------------ the runs through pointax's own fit

WALLACE = {"IH": -92.2155, "ID": -126.7376, "CH": 44.1696, "ME": 64.8473, "MA": -2.9882, "TF": 10.9935}
PMFIT_SIGMA = {"IH": 4.0337, "ID": 2.2735, "CH": 3.2661, "ME": 2.4953, "MA": 1.3952, "TF": 1.6465}
CGX_REFERENCE = {"IH": -18828.0, "ID": -3452.2, "CH": -1373.7, "NP": -599.2, "MA": -3047.8, "ME": 469.1}


def _fit(run, names, residual_form="tpoint", form=None):
    import pointax as px

    form = form or px.terms.DEFAULT_FORM
    terms = px.terms.tpoint(names, form=form, mount="equatorial", latitude=run.latitude)
    return px.fit(run.model(terms, residual_form=residual_form), run)


def test_wallaces_spk_fit_through_the_reader_and_px_fit(equatorial_dir):
    """Shared REFERENCE.txt: every value within 0.1" of Pmfit's, TPOINT's sigmas
    (Pmfit's / sqrt(N / (N - M)) = / 1.0871) within 0.01", Sky RMS 5.3170 within 0.01"."""
    run = read_tpoint(equatorial_dir / "spk_5m_horseshoe.dat")
    result = _fit(run, list(WALLACE))
    assert result.converged
    values = dict(zip(result.names, np.asarray(result.values) / ARCSEC))
    sigmas = dict(zip(result.names, np.asarray(result.sigmas) / ARCSEC))
    for name, value in WALLACE.items():
        assert values[name] == pytest.approx(value, abs=0.1), name
        assert sigmas[name] == pytest.approx(PMFIT_SIGMA[name] / math.sqrt(39 / 33), abs=0.01), name
    assert float(result.sky_rms) / ARCSEC == pytest.approx(5.3170, abs=0.01)


def test_theskyx_fit_through_the_reader_and_px_fit(equatorial_dir):
    """REFERENCE.txt's six-term figures within 1% (they are TPOINT's residual form);
    the run's southern flipped readings (written -180 deg - dec) included."""
    run = read_tpoint(equatorial_dir / "cgx-l-data.dat")
    assert (run.encoder[:, 1] < -math.pi / 2).any()
    result = _fit(run, list(CGX_REFERENCE), form="linear")  # REFERENCE.txt's figures: the linear form
    assert result.converged
    assert float(result.sky_rms) / ARCSEC == pytest.approx(235.03, rel=0.01)
    assert float(result.popn_sd) / ARCSEC == pytest.approx(239.94, rel=0.01)
    for name, value in zip(result.names, np.asarray(result.values) / ARCSEC):
        assert value == pytest.approx(CGX_REFERENCE[name], rel=0.01), name


def test_equatorial_runs_on_the_command_line(equatorial_dir, tmp_path, capsys):
    """pointax fit, compare and tpoint read equatorial runs as alt-az ones: the basic
    six terms by default, families by name, the SLIST listing in hour angle and
    declination, a model file with the run's refraction constants."""
    import json

    from pointax.cli import main

    cgx = str(equatorial_dir / "cgx-l-data.dat")
    out = tmp_path / "cgx.mod"
    # REFERENCE.txt's figures are the linear form's least squares: --form linear
    assert main(["fit", cgx, "--residuals", "tpoint", "--form", "linear", "--json", "--write-model", str(out)]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [t["name"] for t in data["terms"]] == list(CGX_REFERENCE)
    assert data["sky_rms_arcsec"] == pytest.approx(235.03, rel=0.01)
    first = data["observations"][0]
    assert {"observed_ha_deg", "observed_dec_deg", "raw_ha_deg", "raw_dec_deg"} <= set(first)
    assert first["raw_dec_deg"] == pytest.approx(109 + 20 / 60 + 6.469 / 3600, abs=1e-9)
    mod = read_model(out)
    assert mod.names == list(CGX_REFERENCE) and mod.refraction[0] == pytest.approx(52.845, abs=0.01)
    # Read back as an equatorial model at the run's latitude, the same values.
    run = read_tpoint(cgx)
    model = mod.model(mount="equatorial", latitude=run.latitude)
    np.testing.assert_allclose(
        np.asarray(model.values()) / ARCSEC, [t["value_arcsec"] for t in data["terms"]], atol=1e-3
    )
    with pytest.raises(ValueError, match="needs the site's latitude"):
        mod.model(mount="equatorial")

    assert main(["fit", cgx, "--residuals", "tpoint", "--form", "linear", "--list", "--terms", "IH,ID,CH,NP,MA,ME,TF,FO,DAF"]) == 0
    text = capsys.readouterr().out
    assert "HA obs   Dec obs" in text
    assert "Sky RMS =  182." in text or "Sky RMS =   182." in text

    assert main(["compare", cgx, "--families", "basic,flexure", "--folds", "0", "--json", "--quiet"]) == 0
    table = json.loads(capsys.readouterr().out)
    assert table["mount"] == "equatorial"
    rows = {row["label"]: row for row in table["families"]}
    assert rows["flexure"]["n_params"] == 9 and rows["basic"]["n_params"] == 6

    script = tmp_path / "eq.ptp"
    script.write_text(f"INDAT {cgx}\nUSE IH ID CH NP MA ME\nFIT\nFIT\nFIT\nOUTMOD {tmp_path / 'proc.mod'}\n")
    assert main(["tpoint", "--residuals", "tpoint", "--form", "linear", str(script)]) == 0
    proc = read_model(tmp_path / "proc.mod")
    assert proc.sky_rms == pytest.approx(235.03, rel=0.01)


def test_offsets_tables_are_found_and_fitted(capsys):
    import json

    from pointax.cli import main

    table = ROOT / "tests" / "data" / "offsets" / "radio_xel.csv"
    assert detect_format(table) == "offsets"
    assert main(["fit", str(table), "--terms", "IA,IE,CA,NPAE,AN,AW", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["n_obs"] == 60 and len(data["observations"]) == 60

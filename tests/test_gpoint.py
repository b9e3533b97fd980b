"""RTS2 gpoint's terms (pointax.terms.gpoint) and input files (pointax.io.gpoint).

References, outside the code under test: gpoint's formulas transcribed here line by line
in numpy from its source (RTS2/rts2 python/rts2/gpoint.py at commit 6480a7eb549d,
GPoint.model_az_hadec, model_el_hadec, cal_extra, get_extra_val); gpoint's own fit
objective (the angular separation of raw + model from the real position, minimised by
scipy's least_squares instead of lmfit); TPOINT's terms for the equivalences; columns
read with numpy.loadtxt for the reader; hand-made files for its errors.
"""

from __future__ import annotations

import re
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import least_squares

import pointax as px
from pointax.io import (
    GpointFormatError,
    GpointRun,
    parse_gpoint,
    read_gpoint,
    write_model,
)
from pointax.terms import gpoint_extra, gpoint_names, gpoint_terms

ARCSEC = np.pi / 648000
DATA = Path(__file__).resolve().parent / "data" / "gpoint"
SAMPLE = DATA / "altaz_manual.txt"
# The coefficients tests/data/gpoint/make_sample.py put into the sample (arcsec).
SAMPLE_TRUTH = {"ia": 120.0, "ie": -45.0, "tn": 15.0, "te": -22.0, "npae": 8.0, "npoa": -30.0, "tf": 35.0,
                "az:sincos:az;el:2;2": 12.0}

RNG = np.random.default_rng(11)
RAW = np.stack([RNG.uniform(0, 2 * np.pi, 12), RNG.uniform(0.15, 1.4, 12)], -1)  # az (S-W), el


# ------------------------------------------------------------------ gpoint transcribed


def gpoint_extra_value(function, variables, consts, az, el):
    """gpoint's cal_extra for an alt-az run (get_extra_val: az, el, zd = pi/2 - el)."""

    def val(k):
        return {"az": az, "el": el, "zd": (np.pi / 2) - el}[variables[k]]

    if function == "offset":
        return np.ones_like(az)
    if function == "sin":
        return np.sin(consts[0] * val(0))
    if function == "cos":
        return np.cos(consts[0] * val(0))
    if function == "abssin":
        return np.abs(np.sin(consts[0] * val(0)))
    if function == "abscos":
        return np.abs(np.cos(consts[0] * val(0)))
    if function == "tan":
        return np.tan(consts[0] * val(0))
    if function == "csc":
        return 1.0 / np.sin(consts[0] * val(0))
    if function == "sec":
        return 1.0 / np.cos(consts[0] * val(0))
    if function == "cot":
        return 1.0 / np.tan(consts[0] * val(0))
    if function == "sincos":
        return np.sin(consts[0] * val(0)) * np.cos(consts[1] * val(1))
    if function == "sinsin":
        return np.sin(consts[0] * val(0)) * np.sin(consts[1] * val(1))
    if function == "coscos":
        return np.cos(consts[0] * val(0)) * np.cos(consts[1] * val(1))
    raise AssertionError(function)


def gpoint_model(params, a_az, a_el, extras=()):
    """gpoint's model_az_hadec / model_el_hadec: params by name (radians), extras as
    (axis, function, variables, consts, value)."""
    p = {k: params.get(k, 0.0) for k in ("ia", "ie", "tn", "te", "npae", "npoa", "tf")}
    tan_el = np.tan(a_el)
    ret_az = -p["ia"] + p["tn"] * np.sin(a_az) * tan_el - p["te"] * np.cos(a_az) * tan_el - p["npae"] * tan_el \
        + p["npoa"] / np.cos(a_el)
    ret_el = -p["ie"] + p["tn"] * np.cos(a_az) + p["te"] * np.sin(a_az) + p["tf"] * np.cos(a_el)
    for axis, function, variables, consts, value in extras:
        f = value * gpoint_extra_value(function, variables, consts, a_az, a_el)
        if axis == "az":
            ret_az = ret_az + f
        else:
            ret_el = ret_el + f
    return ret_az, ret_el


def sw_to_enu(az, el):
    """Azimuth from South through West: North-East azimuth = az + 180 deg."""
    return np.stack([-np.sin(az) * np.cos(el), -np.cos(az) * np.cos(el), np.sin(el)], -1)


# ------------------------------------------------------------------ terms


@pytest.mark.parametrize("name", ["ia", "ie", "tn", "te", "npae", "npoa", "tf"])
def test_base_terms_are_gpoints_formula(name):
    coef = 37 * ARCSEC
    model = px.AltAz(gpoint_terms(name, values={name: coef}), azimuth="S-W")
    want_az, want_el = gpoint_model({name: coef}, RAW[:, 0], RAW[:, 1])
    got = np.stack([np.asarray(model.corrected_encoder(jnp.asarray(r))) for r in RAW]) - RAW
    # atol: (raw + offset) - raw is exact to an ulp of raw (~9e-16 rad near 2 pi).
    np.testing.assert_allclose(got, np.stack([want_az, want_el], -1), rtol=1e-12, atol=2e-15)
    # gpoint's prediction raw + model(raw), pointed at in East-North-Up.
    np.testing.assert_allclose(
        np.asarray(model(RAW)), sw_to_enu(RAW[:, 0] + want_az, RAW[:, 1] + want_el), atol=2e-16
    )


EXTRAS = [
    "az:offset:az:1",
    "el:offset:el:0",
    "alt:sin:el:3",
    "az:cos:az:2",
    "el:abssin:az:1.5",
    "az:abscos:zd:2",
    "el:tan:zd:0.5",
    "az:csc:el:1",
    "el:sec:az:0.3",
    "az:cot:el:1",
    "az:sincos:az;el:2;2",
    "el:sinsin:zd;az:1;3",
    "el:coscos:el;el:1;2",
]


@pytest.mark.parametrize("spec", EXTRAS)
def test_extra_terms_are_gpoints_cal_extra(spec):
    coef = 21 * ARCSEC
    axis, function, variables, consts = spec.split(":")
    axis = "el" if axis == "alt" else axis
    extra = (axis, function, variables.split(";"), [float(x) for x in consts.split(";")], coef)
    term = gpoint_extra(spec, coef)
    model = px.AltAz([term], azimuth="S-W")
    want = np.stack(gpoint_model({}, RAW[:, 0], RAW[:, 1], [extra]), -1)
    got = np.stack([np.asarray(model.corrected_encoder(jnp.asarray(r))) for r in RAW]) - RAW
    assert np.max(np.abs(want)) > 0
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=2e-15)  # see above


def test_extra_names():
    term = gpoint_extra("az:sincos:az;el:2;2")
    assert term.name == "az:sincos:az;el:2;2"
    assert term.gpoint_parname == "az_sincos_az_el_2_0_2_0"  # gpoint's ExtraParam.parname()
    assert gpoint_extra("ALT:SIN:EL:3.0").name == "el:sin:el:3"
    assert gpoint_extra("az:cos:az:0.25").gpoint_parname == "az_cos_az_0_25"


@pytest.mark.parametrize(
    "spec, message",
    [
        ("az:sin:az", r"has 3 ':'-separated fields; expected 4"),
        ("ra:sin:az:1", r"field 1 \(axis\) is 'ra'; expected az or el"),
        ("az:sine:az:1", r"field 2 \(function\) is 'sine'; expected one of offset sin"),
        ("az:sin:alt:1", r"field 3 \(variables\): 'alt' is not one of az, el, zd"),
        ("az:sin:ha:1", r"field 3 \(variables\): 'ha' needs gpoint's alt-az to equatorial conversion"),
        ("az:sincos:az:2;2", r"sincos takes 2 variable\(s\), got 1"),
        ("az:sin:az;el:2", r"sin takes 1 variable\(s\), got 2"),
        ("az:sin:az:two", r"field 4 \(multipliers\): 'two' is not a number"),
        ("az:sin:az:inf", r"field 4 \(multipliers\): 'inf' is not finite"),
        ("az:sincos:az;el:2", r"sincos takes 2 multiplier\(s\), got 1"),
        ("el:offset:az:1", r"offset is 1 only on its own axis .* no effect"),
    ],
)
def test_extra_errors_name_the_field(spec, message):
    with pytest.raises(ValueError, match=re.escape(f"gpoint extra term {spec!r}") + ".*" + message):
        gpoint_extra(spec)
    with pytest.raises(ValueError, match=message):
        gpoint_terms(f"ia,{spec}")


def test_equatorial_axis_extras_refused_in_altaz_models():
    with pytest.raises(ValueError, match=r"field 1 \(axis\) 'ha' is an equatorial axis; an alt-az model's"):
        gpoint_terms("ia,ha:sin:az:1")
    with pytest.raises(ValueError, match=r"field 1 \(axis\) 'dec' is an equatorial axis"):
        gpoint_extra("dec:sin:dec:1", mount="altaz")


# Plain numbers as values on purpose (the names, not the units, are tested here).
@pytest.mark.filterwarnings("ignore:.*most likely in degrees:pointax.core.errors.InputWarning")
def test_names_mix_gpoint_extras_and_tpoint():
    spec = "ia, ie tn,IA,haca2,az:sincos:az;el:2;2,CA"
    names = ["ia", "ie", "tn", "IA", "HACA2", "az:sincos:az;el:2;2", "CA"]
    assert gpoint_names(spec) == names
    terms = gpoint_terms(spec, values={"ie": 2.0, "HACA2": 3.0, "az:sincos:az;el:2;2": 4.0})
    assert [term.name for term in terms] == names
    assert [float(term.coef) for term in terms] == [0.0, 2.0, 0.0, 0.0, 3.0, 4.0, 0.0]
    # TPOINT names take the default form (rigorous); gpoint's terms are gpoint's formulas in either.
    assert isinstance(terms[0], px.terms.GpointTerm) and isinstance(terms[3], px.terms.rigorous.IA)
    assert isinstance(terms[4], px.terms.RigorousHarmonic) and isinstance(terms[5], px.terms.GpointExtra)
    linear = gpoint_terms("ia CA HACA2", form="linear")
    assert isinstance(linear[0], px.terms.GpointTerm) and isinstance(linear[1], px.terms.CA)
    assert isinstance(linear[2], px.terms.Harmonic)
    assert px.AltAz(terms, azimuth="S-W").parameter_names == names
    with pytest.raises(ValueError, match="unknown TPOINT term 'TN'"):
        gpoint_terms("TN")  # gpoint's names are lower-case; TN is no TPOINT name
    with pytest.raises(ValueError, match="not in the list"):
        gpoint_terms("ia", values={"IA": 1.0})
    with pytest.raises(ValueError, match="unknown term form"):
        gpoint_terms("ia", form="curvy")
    with pytest.raises(ValueError, match="unknown gpoint term"):
        px.terms.gpoint_library.gpoint_term("IA")


EXACT = [("ia", "IA", 1.0), ("ie", "IE", -1.0)]
FIRST_ORDER = [
    ("npae", "NPAE", 1.0),
    ("npoa", "CA", -1.0),
    ("tf", "TF", -1.0),
    ("tf", "ECEC", 1.0),
    ("tn", "AN", -1.0),
    ("te", "AW", 1.0),
    ("az:cos:az:2", "HACA2", -1.0),  # cos 2(180 deg - A) = cos 2A; TPOINT's dA = -coef f
    ("az:sin:az:1", "HASA1", -1.0),  # sin(180 deg - A) = sin A
    ("el:cos:az:1", "HECA1", -1.0),  # cos(180 deg - A) = -cos A; TPOINT's dE = +coef f
    ("el:sin:el:1", "HESE1", 1.0),
    ("el:cos:el:1", "HECE1", 1.0),
]


@pytest.mark.parametrize("gname, tname, factor", EXACT + FIRST_ORDER)
@pytest.mark.parametrize("form", ["linear", "rigorous"])
def test_equivalent_tpoint_terms(gname, tname, factor, form):
    """gpoint coef c == TPOINT factor * c on the same (S-W) azimuth numbers: exactly for
    the zero points, to first order otherwise (gpoint evaluates at the raw position)."""
    coef = 1.0 * ARCSEC
    ours = px.AltAz(gpoint_terms(gname, values={gpoint_names(gname)[0]: coef}), azimuth="S-W")
    theirs = px.AltAz(px.terms.tpoint(tname, form=form, values={tname: factor * coef}), azimuth="S-W")
    d_g, d_t, d_0 = ours(RAW), theirs(RAW), px.AltAz([], azimuth="S-W")(RAW)
    assert np.max(np.asarray(px.rotations.angle_between(d_g, d_0))) > 0.3 * coef
    tolerance = 1e-15 if (gname, tname, factor) in EXACT else 1e-9
    assert np.all(np.asarray(px.rotations.angle_between(d_g, d_t)) < tolerance)


def test_write_model_refuses_gpoint_terms(tmp_path):
    model = px.AltAz(gpoint_terms("IA,ie"), azimuth="S-W")
    with pytest.raises(ValueError, match=r"parameter ie cannot be written .* read back as 'IE'"):
        write_model(tmp_path / "m.mod", model)
    assert not (tmp_path / "m.mod").exists()


def _check_jacobian_against_central_differences(model, obs):
    """The autodiff Jacobian of the residuals equals central differences (steps of 1e-4
    of each value) within 1e-6 of the largest difference."""
    y0 = np.asarray(model.values())

    @jax.jit
    def residual(y):
        return px.residuals(model.with_values(y), obs).reshape(-1)

    jac = np.asarray(jax.jacfwd(residual)(jnp.asarray(y0)))
    for k in range(len(y0)):
        h = 1e-4 * abs(y0[k])
        step = np.zeros_like(y0)
        step[k] = h
        fd = (np.asarray(residual(jnp.asarray(y0 + step))) - np.asarray(residual(jnp.asarray(y0 - step)))) / (2 * h)
        np.testing.assert_allclose(jac[:, k], fd, rtol=0, atol=1e-6 * np.max(np.abs(fd)))


def test_autodiff_jacobian_matches_central_differences():
    model = px.AltAz(gpoint_terms("ia,tn,npoa,az:sincos:az;el:2;2",
                                  values={"ia": 100 * ARCSEC, "tn": 30 * ARCSEC, "npoa": -20 * ARCSEC,
                                          "az:sincos:az;el:2;2": 15 * ARCSEC}), azimuth="S-W")
    obs = px.simulate(px.AltAz([], azimuth="S-W"), RAW)
    _check_jacobian_against_central_differences(model, obs)


# ------------------------------------------------------------------ reader


@pytest.fixture(scope="module")
def sample() -> GpointRun:
    return read_gpoint(SAMPLE)


def test_sample_file(sample):
    rows = np.loadtxt(SAMPLE, comments="#")  # id jd ra dec e_alt e_az alt az
    assert rows.shape == (36, 8)
    assert isinstance(sample, GpointRun) and len(sample) == 36
    assert sample.path == str(SAMPLE) and sample.kind == "altaz-manual" and sample.azimuth == "S-W"
    assert sample.mount == "altaz" and sample.flipped is None
    assert sample.caption.startswith("model file created on Sat Dec 13 00:00:00 2014")
    assert sample.longitude == pytest.approx(np.radians(-20.8), rel=1e-15)
    assert sample.latitude == pytest.approx(np.radians(-32.53), rel=1e-15)
    assert sample.altitude_m == 1850.0
    assert sample.ids == tuple(str(k) for k in range(1, 37))
    np.testing.assert_array_equal(sample.lines, np.arange(3, 39))
    np.testing.assert_array_equal(sample.time, rows[:, 1])
    np.testing.assert_allclose(sample.encoder, np.radians(rows[:, [7, 6]]), rtol=1e-15)
    np.testing.assert_allclose(sample.observed, np.radians(rows[:, [7, 6]] + rows[:, [5, 4]]), rtol=1e-15)
    np.testing.assert_allclose(sample.columns["ra"], np.radians(rows[:, 2]), rtol=1e-15)
    np.testing.assert_allclose(sample.columns["dec"], np.radians(rows[:, 3]), rtol=1e-15)
    obs = sample.observations
    assert obs.convention == "S-W"
    np.testing.assert_array_equal(np.asarray(obs.encoder), sample.encoder)
    real = np.radians(rows[:, [7, 6]] + rows[:, [5, 4]])
    np.testing.assert_allclose(np.asarray(obs.target), sw_to_enu(real[:, 0], real[:, 1]), atol=1e-15)


def test_sample_fit_matches_gpoints_own_objective(sample):
    """pointax's fit of gpoint's terms on the sample against gpoint's fit, redone here:
    least squares on the angular separation of raw + model(raw) from the real position."""
    names = list(SAMPLE_TRUTH)
    result = px.fit(px.AltAz(gpoint_terms(names), azimuth=sample.azimuth), sample, solver="gauss-newton")
    assert bool(result.converged)
    assert list(result.names) == names
    assert result.report().splitlines()[0] == sample.caption
    a_az, a_el = sample.encoder.T
    r_az, r_el = sample.observed.T

    def chords(x):
        params = dict(zip(names[:7], x[:7]))
        extra = [("az", "sincos", ["az", "el"], [2.0, 2.0], x[7])]
        m_az, m_el = gpoint_model(params, a_az, a_el, extra)
        return sw_to_enu(a_az + m_az, a_el + m_el) - sw_to_enu(r_az, r_el)

    def separation(x):
        return 2 * np.arcsin(np.linalg.norm(chords(x), axis=-1) / 2)

    # Sum of squared separations = sum of squared chords to 1e-11 relative (separations
    # of arcseconds); the chord's three components make a smooth least-squares problem.
    ref = least_squares(lambda x: chords(x).ravel(), np.zeros(8), x_scale=ARCSEC, xtol=1e-15, ftol=1e-15, gtol=1e-15)
    np.testing.assert_allclose(np.asarray(result.values) / ARCSEC, ref.x / ARCSEC, atol=1e-5)  # seen: 4e-7"
    rms = np.sqrt(np.mean(separation(ref.x) ** 2))
    assert float(result.sky_rms) == pytest.approx(rms, rel=1e-6)
    # And the truth the file was made from, within 4 sigma (1.5" noise, 36 stars).
    for name in names:
        assert abs(result.value(name) - SAMPLE_TRUTH[name]) < 4 * result.sigma(name), name


GOOD = ["# created", "# altaz-manual 15 50 600", "1 50000.0 280.0 10.0 0.1 0.2 20.0 30.0"]


def _write(tmp_path, lines, name="run.txt"):
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def test_comments_blank_lines_and_rows_before_the_header(tmp_path):
    path = _write(tmp_path, ["", "2 50000.1 280.0 10.0 -0.1 0.0 40.0 100.0", "# just a note here", "",
                             "# altaz-manual 15 50 600 # a trailing note", "# ", GOOD[2]])
    run = read_gpoint(path)
    assert run.ids == ("2", "1") and list(run.lines) == [2, 7]
    np.testing.assert_allclose(run.observed, np.radians([[100.0, 39.9], [30.2, 20.1]]), rtol=1e-15)


def test_altaz_format(tmp_path):
    """gpoint's 'altaz' rows: id, MJD, LST, mount az, alt, axis counts, real az, alt (man page example)."""
    path = _write(tmp_path, ["# 15 degrees E, 50 degrees N, 600 m altitude", "# altaz 15 50 600",
                             "1    50000.0 280.000  10.000  20.000 -55000 55000 11.000   19.000",
                             "2    50000.1 280.100  50.000  30.000 -55100 55010 51.000   29.000"])
    run = read_gpoint(path)
    assert run.kind == "altaz" and run.azimuth == "S-W"
    np.testing.assert_allclose(run.encoder, np.radians([[10.0, 20.0], [50.0, 30.0]]), rtol=1e-15)
    np.testing.assert_allclose(run.observed, np.radians([[11.0, 19.0], [51.0, 29.0]]), rtol=1e-15)
    np.testing.assert_allclose(run.columns["lst"], np.radians([280.0, 280.1]), rtol=1e-15)
    np.testing.assert_array_equal(run.columns["axis_az"], [-55000, -55100])
    np.testing.assert_array_equal(run.columns["axis_el"], [55000, 55010])


@pytest.mark.parametrize(
    "lines, line, patterns",
    [
        (GOOD[1:], 1, [r"header .* is on line 1, which gpoint skips"]),
        (GOOD[2:] + GOOD[1:2], 1, [r"line 1 is not a comment.*would be lost"]),
        ([GOOD[0], GOOD[2]], None, [r"no header line '# altaz-manual"]),
        ([GOOD[0], "# gem 15 50 600", GOOD[2]], 3, [r"gem row has 8 fields; gpoint's gem rows have 9"]),
        ([GOOD[0], "# observatory 15 50 600", GOOD[2]], 3, [r"observatory row has 8 fields"]),
        (GOOD + ["# altaz-manual 15 50 600"], 4, [r"second header line \(the first is on line 2\)"]),
        ([GOOD[0], "# altaz-manual 15 50", GOOD[2]], 2, [r"needs longitude \(deg\), latitude \(deg\) and altitude"]),
        ([GOOD[0], "# altaz-manual 15 5O 600", GOOD[2]], 2, [r"field 3 \(latitude \(deg\)\) is '5O', not a number"]),
        ([GOOD[0], "# altaz-manual 15 95 600", GOOD[2]], 2, [r"latitude .* outside -90..90"]),
        (GOOD + ["2 50000.0 280.0 10.0 0.1 0.2 20.0"], 4, [r"altaz-manual row has 7 fields; gpoint's altaz-manual rows have 8"]),
        (GOOD + ["2 50000.0 280.0 10.0 0.1 0.2 20.0 30.0 7"], 4, [r"has 9 fields"]),
        (GOOD + ["2 50000.0 280.0 10.0 0.1x 0.2 20.0 30.0"], 4, [r"field 5 \(elevation error \(deg\)\) is '0.1x', not a number"]),
        (GOOD + ["2 50000.0 280.0 10.0 0.1 nan 20.0 30.0"], 4, [r"field 6 \(azimuth error \(deg\)\) is 'nan', not finite"]),
        (GOOD + ["2 50000.0 280.0 10.0 0.5 0.2 89.8 30.0"], 4, [r"observed elevation .* 90.300000 deg is outside -90..90"]),
        (GOOD + ["2 50000.0 280.0 10.0 -100.5 0.2 189.8 30.0"], 4, [r"mount elevation 189.800000 deg is outside"]),
        (GOOD[:2], None, [r"no observation rows"]),
        ([""], None, [r"empty file"]),
    ],
)
def test_errors_name_file_line_and_field(tmp_path, lines, line, patterns):
    path = _write(tmp_path, lines)
    with pytest.raises(GpointFormatError) as info:
        read_gpoint(path)
    err = info.value
    assert isinstance(err, ValueError) and err.path == str(path) and err.line == line
    where = f"{path}:{line}: " if line is not None else f"{path}: "
    assert str(err).startswith(where), str(err)
    for pattern in patterns:
        assert re.search(pattern, str(err)), (pattern, str(err))


def test_binary_file_and_parse_text(tmp_path):
    path = tmp_path / "bin.txt"
    path.write_bytes(b"\xff\xfe\x00\x01garbage")
    with pytest.raises(GpointFormatError, match="not a text file"):
        read_gpoint(path)
    run = parse_gpoint("\n".join(GOOD), path="x.txt")
    assert run.path == "x.txt" and len(run) == 1


# ================================================================== German equatorial (GEM)
#
# References: gpoint's model_ha / model_dec / cal_extra / equ_to_hrz (GEM branch) and
# its process_files (GEM branch: flip_ra, flip_dec) transcribed in numpy from RTS2/rts2
# python/rts2/gpoint.py at commit 6480a7eb549d; its to_string for the model file; the
# sample gem.txt made by tests/data/gpoint/make_gem_sample.py (synthetic, see
# PROVENANCE.txt there); numpy.loadtxt for the columns.

from pointax.io.gpoint_model import (  # noqa: E402
    format_gpoint_model,
    parse_gpoint_model,
    read_gpoint_model,
    write_gpoint_model,
)
from pointax.terms.gpoint import (  # noqa: E402
    GPOINT_GEM_TERMS,
    GpointGemTerm,
    classify,
    gpoint_model_terms,
    gpoint_term,
    split_names,
)

GEM_SAMPLE = DATA / "gem.txt"
GEM_TRUTH = {"ih": 150.0, "id": -80.0, "ch": 40.0, "np": -25.0, "ma": 30.0, "me": -45.0, "tf": 20.0,
             "fo": 12.0, "daf": 15.0, "ha:sin:dec:2": 9.0}
LAT = np.radians(49.9092)
# Readings on both sides of the pier: normal (|dec| < 90) and flipped (H + 180, 180 - dec).
_H = RNG.uniform(-1.5, 1.5, 10)
_D = RNG.uniform(-0.4, 1.4, 10)
GEM_RAW = np.concatenate([np.stack([_H, _D], -1), np.stack([_H + np.pi, np.pi - _D], -1)])


def gpoint_equ_to_hrz(lat, ha, dec):
    """gpoint's GPoint.equ_to_hrz (radians in; alt, az in degrees out, az in [0, 360))."""
    A = np.sin(lat) * np.sin(dec) + np.cos(lat) * np.cos(dec) * np.cos(ha)
    alt = np.arcsin(A)
    Z = np.arccos(A)
    Zs = np.sin(Z)
    As = (np.cos(dec) * np.sin(ha)) / Zs
    Ac = (np.sin(lat) * np.cos(dec) * np.cos(ha) - np.cos(lat) * np.sin(dec)) / Zs
    Aa = np.arctan2(As, Ac)
    return np.degrees(alt), (np.degrees(Aa) + 360) % 360


def gpoint_gem_extra_value(function, variables, consts, ha, dec, az, el):
    def val(k):
        return {"ha": ha, "dec": dec, "az": az, "el": el, "zd": (np.pi / 2) - el}[variables[k]]

    f = {"sin": np.sin, "cos": np.cos, "tan": np.tan, "abssin": lambda t: np.abs(np.sin(t)),
         "abscos": lambda t: np.abs(np.cos(t)), "csc": lambda t: 1.0 / np.sin(t),
         "sec": lambda t: 1.0 / np.cos(t), "cot": lambda t: 1.0 / np.tan(t)}
    if function in f:
        return f[function](consts[0] * val(0))
    first = np.cos if function == "coscos" else np.sin
    second = np.sin if function == "sinsin" else np.cos
    return first(consts[0] * val(0)) * second(consts[1] * val(1))


def gpoint_gem_model(params, lat, a_ha, a_dec, extras=()):
    """gpoint's model_ha / model_dec (radians), extras as (axis, function, variables, consts, value)."""
    p = {k: params.get(k, 0.0) for k in GPOINT_GEM_TERMS}
    ret_ha = (- p["ih"] - p["ch"] / np.cos(a_dec) - p["np"] * np.tan(a_dec)
              - (p["me"] * np.sin(a_ha) - p["ma"] * np.cos(a_ha)) * np.tan(a_dec)
              - p["tf"] * np.cos(lat) * np.sin(a_ha) / np.cos(a_dec)
              - p["daf"] * (np.sin(lat) * np.tan(a_dec) + np.cos(lat) * np.cos(a_ha)))
    ret_dec = (- p["id"] - p["me"] * np.cos(a_ha) - p["ma"] * np.sin(a_ha)
               - p["tf"] * (np.cos(lat) * np.sin(a_dec) * np.cos(a_ha) - np.sin(lat) * np.cos(a_dec))
               - p["fo"] * np.cos(a_ha))
    alt, az = gpoint_equ_to_hrz(lat, a_ha, a_dec)
    rad_az, rad_alt = np.radians(az), np.radians(alt)
    for axis, function, variables, consts, value in extras:
        f = value * gpoint_gem_extra_value(function, variables, consts, a_ha, a_dec, rad_az, rad_alt)
        if axis == "ha":
            ret_ha = ret_ha + f
        else:
            ret_dec = ret_dec + f
    return ret_ha, ret_dec


def hadec_enu(lat, ha, dec):
    """EquatorialMount's formulas (also right for flipped readings)."""
    return np.stack([-np.cos(dec) * np.sin(ha), np.cos(lat) * np.sin(dec) - np.sin(lat) * np.cos(dec) * np.cos(ha),
                     np.sin(lat) * np.sin(dec) + np.cos(lat) * np.cos(dec) * np.cos(ha)], -1)


def _gem_corrections(model, raw):
    return np.stack([np.asarray(model.corrected_encoder(jnp.asarray(r))) for r in raw]) - raw


@pytest.mark.parametrize("name", GPOINT_GEM_TERMS)
def test_gem_terms_are_gpoints_formula(name):
    coef = 37 * ARCSEC
    model = px.Equatorial(gpoint_model_terms(name, "gem", latitude=LAT, values={name: coef}), latitude=LAT)
    want_ha, want_dec = gpoint_gem_model({name: coef}, LAT, GEM_RAW[:, 0], GEM_RAW[:, 1])
    got = _gem_corrections(model, GEM_RAW)
    assert np.max(np.abs(np.stack([want_ha, want_dec]))) > 0.5 * coef
    np.testing.assert_allclose(got, np.stack([want_ha, want_dec], -1), rtol=1e-12, atol=2e-15)
    # gpoint's prediction raw + model(raw), pointed at in East-North-Up; flipped readings too.
    np.testing.assert_allclose(np.asarray(model(GEM_RAW)),
                               hadec_enu(LAT, GEM_RAW[:, 0] + want_ha, GEM_RAW[:, 1] + want_dec), atol=3e-16)


def test_gem_terms_together_and_their_classes():
    values = {k: (k_ + 1) * 11 * ARCSEC for k_, k in enumerate(GPOINT_GEM_TERMS)}
    terms = gpoint_model_terms(list(GPOINT_GEM_TERMS), "gem", latitude=LAT, values=values)
    assert all(isinstance(t, GpointGemTerm) for t in terms) and [t.name for t in terms] == list(GPOINT_GEM_TERMS)
    got = _gem_corrections(px.Equatorial(terms, latitude=LAT), GEM_RAW)
    want = np.stack(gpoint_gem_model(values, LAT, GEM_RAW[:, 0], GEM_RAW[:, 1]), -1)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=4e-15)


GEM_EXTRAS = ["ha:sin:dec:2", "dec:cos:ha:1", "ha:sincos:ha;dec:1;2", "dec:coscos:dec;ha:2;1", "ha:sinsin:ha;ha:1;3",
              "dec:abssin:ha:1.5", "ha:tan:dec:0.5", "dec:sec:ha:0.3", "ha:csc:dec:1", "ha:cot:dec:1",
              "ha:sin:az:2", "dec:cos:el:1", "dec:sincos:zd;az:1;2", "ha:abscos:az:0.5"]


@pytest.mark.parametrize("spec", GEM_EXTRAS)
def test_gem_extras_are_gpoints_cal_extra(spec):
    coef = 21 * ARCSEC
    axis, function, variables, consts = spec.split(":")
    extra = (axis, function, variables.split(";"), [float(x) for x in consts.split(";")], coef)
    model = px.Equatorial([gpoint_term(spec, coef, mount="gem", latitude=LAT)], latitude=LAT)
    want = np.stack(gpoint_gem_model({}, LAT, GEM_RAW[:, 0], GEM_RAW[:, 1], [extra]), -1)
    assert np.max(np.abs(want)) > 0
    np.testing.assert_allclose(_gem_corrections(model, GEM_RAW), want, rtol=1e-11, atol=4e-15)


def test_gem_names_and_mounts():
    assert split_names("ih,id tf ha:sin:dec:2.0 IH", mount="gem") == ["ih", "id", "tf", "ha:sin:dec:2", "IH"]
    assert classify("tf", "gem") == ("gpoint", "tf") and classify("tf") == ("gpoint", "tf")
    assert isinstance(gpoint_term("tf", mount="gem", latitude=LAT), px.terms.gpoint_library.GpointGemTF)
    assert isinstance(gpoint_term("tf"), px.terms.gpoint_library.GpointTF)
    assert gpoint_term("tf", mount="gem", latitude=LAT).latitude == LAT
    with pytest.raises(ValueError, match=r"'ma' is gpoint's GEM term, not a term of a gpoint altaz model"):
        classify("ma")
    with pytest.raises(ValueError, match=r"'ma' is gpoint's GEM term"):
        gpoint_terms("ia,ma")  # pointax.terms.gpoint_terms is the alt-az one until it takes mount=
    with pytest.raises(ValueError, match=r"'ia' is gpoint's alt-az term, not a term of a gpoint gem model"):
        gpoint_term("ia", mount="gem")
    with pytest.raises(ValueError, match=r"GEM term tf needs the site's latitude"):
        gpoint_term("tf", mount="gem")
    with pytest.raises(ValueError, match=r"GEM term daf needs the site's latitude"):
        gpoint_model_terms("ih daf", "gem")
    with pytest.raises(ValueError, match=r"latitude 49.9 rad is not within"):
        gpoint_term("tf", mount="gem", latitude=49.9)
    with pytest.raises(ValueError, match=r"unknown gpoint model 'eq'"):
        gpoint_term("tf", mount="eq")
    with pytest.raises(ValueError, match=r"'IH' is not a gpoint gem term"):
        gpoint_model_terms("ih IH", "gem")
    with pytest.raises(ValueError, match=r"'ih' is given twice"):
        gpoint_model_terms("ih ch ih", "gem")
    assert gpoint_term("ih", mount="gem").latitude is None  # ih needs none


@pytest.mark.parametrize(
    "spec, message",
    [
        ("ha:offset:ha:1", r"offset is 1 only for az:offset:az and el:offset:el .* 0 on ha and dec"),
        ("ha:sin:az:2", r"equ_to_hrz of the GEM reading, which needs the site's latitude"),
        ("dec:cos:pd:1", r"field 3 \(variables\): 'pd' is not one of ha, dec, az, el, zd"),
    ],
)
def test_gem_extra_errors(spec, message):
    with pytest.raises(ValueError, match=re.escape(f"gpoint extra term {spec!r}") + ".*" + message):
        gpoint_extra(spec)
    with pytest.raises(ValueError, match=r"'az' is an alt-az axis; a GEM model's extras correct ha or dec"):
        gpoint_term("az:sin:az:1", mount="gem", latitude=LAT)


def test_gem_autodiff_jacobian_matches_central_differences():
    values = {"ih": 100 * ARCSEC, "ch": -20 * ARCSEC, "tf": 30 * ARCSEC, "daf": 10 * ARCSEC,
              "dec:sincos:zd;az:1;2": 15 * ARCSEC}
    model = px.Equatorial(gpoint_model_terms(list(values), "gem", latitude=LAT, values=values), latitude=LAT)
    obs = px.simulate(px.Equatorial([], latitude=LAT), GEM_RAW)
    _check_jacobian_against_central_differences(model, obs)


# ------------------------------------------------------------------ GEM reader


@pytest.fixture(scope="module")
def gem_sample() -> GpointRun:
    return read_gpoint(GEM_SAMPLE)


def test_gem_sample_file(gem_sample):
    rows = np.loadtxt(GEM_SAMPLE, comments="#", usecols=range(1, 9))  # jd lst ra dec axra axdec rra rdec
    ids = [line.split()[0] for line in GEM_SAMPLE.read_text().splitlines()[2:]]
    run = gem_sample
    assert rows.shape == (60, 8) and len(run) == 60
    assert run.mount == "gem" and run.kind == "observatory" and run.azimuth is None
    assert run.caption.startswith("Observation      MJD    MNT-LST")
    assert run.latitude == pytest.approx(np.radians(49.9092), rel=1e-15)
    assert run.longitude == pytest.approx(np.radians(14.7817), rel=1e-15) and run.altitude_m == 530.0
    assert run.ids == tuple(ids)
    np.testing.assert_array_equal(run.lines, np.arange(3, 63))
    np.testing.assert_array_equal(run.time, rows[:, 0])
    jd, lst, a_ra, a_dec, ax_ra, ax_dec, r_ra, r_dec = rows.T
    flipped = np.abs(a_dec) > 90
    assert flipped.sum() == 29 and np.all(a_dec[flipped] > 90)
    np.testing.assert_array_equal(run.flipped, flipped)
    # gpoint: (lst - a_ra, a_dec, lst - flip_ra(r_ra, a_dec), flip_dec(r_dec, a_dec)), degrees
    np.testing.assert_allclose(run.encoder, np.radians(np.stack([lst - a_ra, a_dec], -1)), rtol=1e-15)
    flip_ra = np.array([(r + 180) % 360 if abs(d) > 90 else r for r, d in zip(r_ra, a_dec)])
    flip_dec = np.array([180 - r if d > 90 else (-180 - r if d < -90 else r) for r, d in zip(r_dec, a_dec)])
    np.testing.assert_allclose(run.observed, np.radians(np.stack([lst - flip_ra, flip_dec], -1)), rtol=1e-15)
    for key, col in (("lst", lst), ("ra", a_ra), ("real_ra", r_ra), ("real_dec", r_dec)):
        np.testing.assert_allclose(run.columns[key], np.radians(col), rtol=1e-15)
    np.testing.assert_array_equal(run.columns["axis_ra"], ax_ra)
    np.testing.assert_array_equal(run.columns["axis_dec"], ax_dec)
    obs = run.observations
    assert obs.convention == "ha-dec"
    np.testing.assert_array_equal(np.asarray(obs.encoder), run.encoder)
    # the real direction: the sky position, and gpoint's flipped copy of it, alike
    np.testing.assert_allclose(np.asarray(obs.target), hadec_enu(LAT, np.radians(lst - r_ra), np.radians(r_dec)), atol=1e-15)
    np.testing.assert_allclose(np.asarray(obs.target), hadec_enu(LAT, *run.observed.T), atol=2e-15)
    # the mount's readings point within the pointing error of it, on both sides
    sep = np.degrees(np.asarray(px.rotations.angle_between(jnp.asarray(hadec_enu(LAT, *run.encoder.T)), obs.target)))
    assert 0.01 < np.max(sep) < 0.2


def test_gem_sample_fit_recovers_the_simulated_terms_and_gpoints_own_fit(gem_sample):
    """pointax's fit of gpoint's GEM terms on the sample (both pier sides) against gpoint's
    own objective, redone here with scipy (the separation of raw + model(raw) from the
    real position, both in gpoint's reading of the pier side), and against the truth."""
    run = gem_sample
    names = list(GEM_TRUTH)
    terms = gpoint_model_terms(names, "gem", latitude=run.latitude)
    result = px.fit(px.Equatorial(terms, latitude=run.latitude), run, solver="gauss-newton")
    assert bool(result.converged) and list(result.names) == names
    a_ha, a_dec = run.encoder.T
    r_ha, r_dec = run.observed.T

    def chords(x):
        params = dict(zip(names[:9], x[:9]))
        m_ha, m_dec = gpoint_gem_model(params, run.latitude, a_ha, a_dec, [("ha", "sin", ["dec"], [2.0], x[9])])
        return hadec_enu(run.latitude, a_ha + m_ha, a_dec + m_dec) - hadec_enu(run.latitude, r_ha, r_dec)

    ref = least_squares(lambda x: chords(x).ravel(), np.zeros(10), x_scale=ARCSEC, xtol=1e-15, ftol=1e-15, gtol=1e-15)
    np.testing.assert_allclose(np.asarray(result.values) / ARCSEC, ref.x / ARCSEC, atol=1e-4)
    sep = 2 * np.arcsin(np.linalg.norm(chords(ref.x), axis=-1) / 2)
    assert float(result.sky_rms) == pytest.approx(np.sqrt(np.mean(sep ** 2)), rel=1e-6)
    for name in names:
        assert abs(result.value(name) - GEM_TRUTH[name]) < 4 * result.sigma(name), name
    # The flip pins ih, ch, np apart (sec d and tan d change sign across the pier): fitting
    # ih id ch np ma me to one side alone was seen to give sigmas of ~9-13" for them.
    assert result.sigma("ch") < 2.0 and result.sigma("ih") < 0.5


GEM_GOOD = ["# created", "# gem 15 50 600", "1 2457000.5 280.0 270.0 20.0 -55000 55000 270.01 20.01"]


@pytest.mark.parametrize(
    "row, line, pattern",
    [
        ("2 2457000.5 280.0 270.0 20.0 -55000 55000 270.01", 4, r"gem row has 8 fields; gpoint's gem rows have 9"),
        ("2 2457000.5 280.0 270.0 20.0 -55000 55000 270.01 20.01 7", 4, r"gem row has 10 fields"),
        ("2 2457000.5 28O.0 270.0 20.0 -55000 55000 270.01 20.01", 4,
         r"field 3 \(local sidereal time \(deg\)\) is '28O.0', not a number"),
        ("2 2457000.5 280.0 270.0 nan -55000 55000 270.01 20.01", 4, r"field 5 \(mount Dec \(deg\)\) is 'nan', not finite"),
        ("2 2457000.5 280.0 270.0 20.0 -55000 55000 270.01 95.0", 4,
         r"field 9 \(real Dec \(deg\)\) 95 is outside -90..90"),
        ("2 2457000.5 280.0 270.0 280.0 -55000 55000 270.01 20.01", 4,
         r"field 5 \(mount Dec \(deg\)\) 280 is outside -270..270"),
        ("2 2457000.5 280.0 400.0 20.0 -55000 55000 270.01 20.01", 4, r"field 4 \(mount RA \(deg\)\) 400 is outside"),
        ("2 2457000.5 280.0 90.0 -20.0 -55000 55000 100.0 -45.0", 4,
         r"elevation of the real position .* below the horizon"),
    ],
)
def test_gem_errors_name_file_line_and_field(tmp_path, row, line, pattern):
    path = _write(tmp_path, GEM_GOOD + [row])
    with pytest.raises(GpointFormatError) as info:
        read_gpoint(path)
    err = info.value
    assert err.path == str(path) and err.line == line
    assert str(err).startswith(f"{path}:{line}: "), str(err)
    assert re.search(pattern, str(err)), (pattern, str(err))


def test_gem_radians_and_far_rows(tmp_path):
    rad = ["# created", "# gem 15 50 600"] + [
        f"{k} 2457000.5 {4.0 + 0.1 * k} {3.0 + 0.1 * k} 0.5 0 0 {3.0 + 0.1 * k} 0.5" for k in range(4)]
    with pytest.raises(GpointFormatError, match=r"look like radians"):
        read_gpoint(_write(tmp_path, rad, "rad.txt"))
    # a flip written in the Dec only: the real position is far from the mount's
    far = GEM_GOOD + ["2 2457000.5 280.0 270.0 160.0 -55000 55000 270.01 20.01"]
    with pytest.warns(px.io.InputWarning, match=r"far\.txt:4: 1 of 2 rows have their real and mount positions .*more "
                      r"than 5 deg apart .*line 4: \d+\.\d deg \(real RA 270\.01 Dec 20\.01, mount RA 270 Dec 160 deg\)"):
        run = read_gpoint(_write(tmp_path, far, "far.txt"))
    assert list(run.flipped) == [False, True]


def _tampered(tmp_path, source: Path, line: int, field: int, value: str) -> Path:
    """``source`` (a bundled gpoint run) with field ``field`` (0-based) of line ``line``
    (1-based) replaced by ``value``."""
    lines = source.read_text().splitlines()
    tokens = lines[line - 1].split()
    tokens[field] = value
    lines[line - 1] = "\t".join(tokens)
    return _write(tmp_path, lines, f"tampered_{source.name}")


def _no_warnings(path):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return read_gpoint(path)


def test_altaz_row_whose_real_and_mount_positions_contradict_is_named(tmp_path):
    """An altaz-manual row whose elevation error reads 8 deg (a mistyped field): its real
    position lies 8 deg from the mount's while the others agree to arcminutes. The
    warning names the file, the line and both positions; the untouched run gets none."""
    _no_warnings(SAMPLE)
    path = _tampered(tmp_path, SAMPLE, 7, 4, "8.02062986")  # e_alt of row 5
    with pytest.warns(px.io.InputWarning) as record:
        run = read_gpoint(path)
    (w,) = [w for w in record if "deg apart" in str(w.message)]
    assert w.filename == __file__  # the user's line, not the reader's
    message = str(w.message)
    assert message.startswith(f"{path}:7: 1 of 36 rows have their real and mount positions more than 5 deg apart")
    assert re.search(r"line 7: 8\.0 deg \(real az 19\.3742 el 54\.4187, mount az 19\.4151 el 46\.3981 deg\)", message)
    assert len(run) == 36  # warned of, not dropped


def test_altaz_9_field_row_with_swapped_real_position_is_named(tmp_path):
    """An ``altaz`` (9-field) run whose real azimuth of one row is 40 deg off its mount's."""
    rows = ["# created", "# altaz 15 50 600"]
    for k in range(8):
        az, el = 20.0 + 40.0 * k, 25.0 + 6.0 * k
        real_az = az + 0.01 + (40.0 if k == 3 else 0.0)
        rows.append(f"{k} 2457000.5 100.0 {az:.3f} {el:.3f} 1000 2000 {real_az:.3f} {el + 0.02:.3f}")
    path = _write(tmp_path, rows, "altaz9.txt")
    with pytest.warns(px.io.InputWarning, match=r"altaz9\.txt:6: 1 of 8 rows .* \(line 6: 29\.0 deg \(real az 180\.01 "
                      r"el 43\.02, mount az 140 el 43 deg\)\)"):
        read_gpoint(path)


def test_gem_row_flipped_in_dec_only_is_named_with_both_positions(tmp_path):
    """The bundled GEM run with one flipped row's mount Dec written as on the other side
    of the pier (114.6649 -> 65.3351) but its RA left flipped: 49 deg off on the sky."""
    gem = DATA / "gem.txt"
    _no_warnings(gem)
    path = _tampered(tmp_path, gem, 6, 4, "65.3351")
    with pytest.warns(px.io.InputWarning) as record:
        read_gpoint(path)
    (w,) = [w for w in record if "deg apart" in str(w.message)]
    assert w.filename == __file__
    assert str(w.message).startswith(f"{path}:6: 1 of 60 rows have their real and mount positions")
    assert re.search(r"line 6: 49\.\d deg \(real RA 326\.78 Dec 65\.3233, mount RA 146\.736 Dec 65\.3351 deg\)",
                     str(w.message))


def test_gem_man_page_example(tmp_path):
    """The gpoint manual's GEM example (man/gpoint.txt) reads; its real positions are 1 deg
    off the mount's in RA and Dec, as the manual says ("only offsets in RA and DEC")."""
    text = """1    50000.0 280.000  10.000  20.000 -55000 55000 11.000   19.000
2    50000.1 280.100  50.000  30.000 -55100 55010 51.000   29.000
3    50000.2 280.200  90.000  40.000 -55200 55020 91.000   39.000
4    50000.3 280.300  140.000 50.000 -55300 55030 141.000  49.000
5    50000.4 280.400  180.000 60.000 -55400 55040 181.000  59.000
6    50000.5 280.500  220.000 70.000 -55500 55050 221.000  69.000
7    50000.6 280.600  260.000 80.000 -55600 55060 261.000  79.000
8    50000.7 280.700  300.000 70.000 -55700 55070 301.000  69.000
9    50000.8 280.800  340.000 60.000 -55800 55080 341.000  59.000
10   50000.9 280.900  0.000   50.000 -55900 55090 1.000    49.000"""
    run = read_gpoint(_write(tmp_path, ["# 15 degrees E, 50 degrees N, 600 m altitude", "# gem 15 50 600"]
                             + text.splitlines()))
    rows = np.array([[float(x) for x in line.split()[1:]] for line in text.splitlines()])
    assert run.mount == "gem" and len(run) == 10 and not run.flipped.any()
    np.testing.assert_allclose(run.encoder, np.radians(rows[:, [1, 3]] - np.c_[rows[:, 2], 0 * rows[:, 2]]), rtol=1e-15)
    np.testing.assert_allclose(run.observed - run.encoder, np.radians(np.tile([-1.0, -1.0], (10, 1))), atol=1e-13)


# ------------------------------------------------------------------ model files


def gpoint_to_string(altaz, params, extras):
    """gpoint's GPoint.to_string() (unit 'arcseconds', what save() and gpoint -o write):
    params by name (radians), extras as (axis, function, variables, consts, value)."""
    bbpn = ["ia", "tn", "te", "npae", "npoa", "ie", "tf"] if altaz else ["id", "me", "ma", "tf", "ih", "ch", "np",
                                                                         "daf", "fo"]
    bbp = [params[x] for x in bbpn]
    uv, mul = '"', 3600.0
    out = ("RTS2_ALTAZ" if altaz else "RTS2_GEM") + " " + (uv + " ").join([str(np.degrees(x) * mul) for x in bbp]) + uv
    for axis, function, variables, consts, value in extras:
        e = "{0}\t{1}\t{2}".format(function, ";".join(map(str, variables)), ";".join(map(str, consts)))
        out += ("\n{0}\t{1}" + uv + "\t{2}").format(axis.upper(), np.degrees(value) * mul, e)
    return out


def _extra_tuple(spec, value):
    axis, function, variables, consts = spec.split(":")
    return axis, function, variables.split(";"), [float(c) for c in consts.split(";")], value


def test_gem_model_file_is_gpoints_to_string(gem_sample, tmp_path):
    run = gem_sample
    names = list(GEM_TRUTH)
    result = px.fit(px.Equatorial(gpoint_model_terms(names, "gem", latitude=run.latitude), latitude=run.latitude),
                    run, solver="gauss-newton")
    values = {n: float(v) for n, v in zip(result.names, np.asarray(result.values))}  # radians
    assert result.value("ih") == pytest.approx(values["ih"] / ARCSEC)
    want = gpoint_to_string(False, values, [_extra_tuple("ha:sin:dec:2", values["ha:sin:dec:2"])])
    text = format_gpoint_model(result)
    assert text == want
    assert text.startswith("RTS2_GEM ") and text.count("\n") == 1 and not text.endswith("\n")
    assert text.splitlines()[1].startswith('HA\t') and text.splitlines()[1].endswith('"\tsin\tdec\t2.0')
    path = tmp_path / "gem.model"
    write_gpoint_model(path, result)
    assert path.read_text() == want
    back = read_gpoint_model(path)
    assert back.mount == "gem" and back.keyword == "RTS2_GEM" and back.names == list(GPOINT_GEM_TERMS) + ["ha:sin:dec:2"]
    for name, value in values.items():
        got = back.values.get(name, dict(back.extras).get(name))
        # the arcseconds are written exactly; back in radians within 2 units in the last place
        assert abs(got - value) <= 2 * np.spacing(abs(value)), name
    model = back.model(latitude=run.latitude)
    np.testing.assert_allclose(np.asarray(model(run.encoder)), np.asarray(result.model(run.encoder)), atol=1e-15)
    assert back.lines["ih"] == 1 and back.lines["ha:sin:dec:2"] == 2
    with pytest.raises(ValueError, match=r"holds no latitude; give latitude="):
        back.terms()


def test_altaz_model_file_round_trip(sample, tmp_path):
    names = list(SAMPLE_TRUTH)
    result = px.fit(px.AltAz(gpoint_terms(names), azimuth="S-W"), sample, solver="gauss-newton")
    values = {n: float(v) for n, v in zip(result.names, np.asarray(result.values))}  # radians
    text = format_gpoint_model(result)
    assert text == gpoint_to_string(True, values, [_extra_tuple("az:sincos:az;el:2;2", values["az:sincos:az;el:2;2"])])
    assert text.splitlines()[1].endswith('"\tsincos\taz;el\t2.0;2.0')
    path = tmp_path / "altaz.model"
    write_gpoint_model(path, result.model)
    back = read_gpoint_model(path)
    assert back.mount == "altaz" and back.names == list(px.terms.GPOINT_ALTAZ_TERMS) + ["az:sincos:az;el:2;2"]
    model = back.model()
    assert model.mount.azimuth == "S-W"
    np.testing.assert_allclose(np.asarray(model.values()), [values[n] for n in back.names], rtol=5e-16, atol=0)
    # a model lacking some of gpoint's base terms: they are written as 0
    short = px.AltAz(gpoint_terms("ia,tf", values={"ia": ARCSEC}), azimuth="S-W")
    assert format_gpoint_model(short) == 'RTS2_ALTAZ 1.0" 0.0" 0.0" 0.0" 0.0" 0.0" 0.0"'


def test_model_files_as_rts2_writes_them():
    """Layouts from RTS2's own tests (lib/rts2tel test files) and gpoint's load: radians
    without a suffix, d ' m \" s suffixes, RTS2_MODEL, comments, case of the function."""
    m = parse_gpoint_model("# test #1\nRTS2_MODEL 0.01 0 0 0 -0.02 0 0 0 0")
    assert m.mount == "gem" and m.keyword == "RTS2_MODEL" and m.values["id"] == 0.01 and m.values["ih"] == -0.02
    m = parse_gpoint_model("# test #2\nRTS2_ALTAZ 1.0d 0 0 0 0 -7200\" 0\n# extras..\nAZ 0.05235987755982989 SiN el 2\n"
                           "AZ 1d offset az 1\nEL 2m cos az 2\nEL 30s sin el 1\nEL 3' cot el 1\n")
    assert m.mount == "altaz"
    assert m.values["ia"] == np.radians(1.0) and m.values["ie"] == np.radians(-7200 / 3600.0)
    assert m.extras == (("az:sin:el:2", 0.05235987755982989), ("az:offset:az:1", np.radians(1.0)),
                        ("el:cos:az:2", np.radians(2 / 60.0)), ("el:sin:el:1", np.radians(30 / 3600.0)),
                        ("el:cot:el:1", np.radians(3 / 60.0)))
    terms = m.terms()
    assert [t.name for t in terms] == m.names


@pytest.mark.parametrize(
    "text, line, pattern",
    [
        ("RTS2_GEM 1 2 3", 1, r"RTS2_GEM line has 3 values; gpoint's has 9: id me ma tf ih ch np daf fo"),
        ('RTS2_ALTAZ 1" 2" 3" 4" 5" 6" x"', 1, r"RTS2_ALTAZ line: field 8 \(tf\) is 'x\"', not a number"),
        ('RTS2_ALTAZ 1" 2" 3" 4" 5" 6" 7"\nRTS2_ALTAZ 1" 2" 3" 4" 5" 6" 7"', 2, r"a second model line"),
        ('RTS2_ALTAZ 1" 2" 3" 4" 5" 6" 7"\nAZ 1" sine az 2', 2, r"field 2 \(function\) is 'sine'"),
        ('RTS2_ALTAZ 1" 2" 3" 4" 5" 6" 7"\nAZ 1q sin az 2', 2, r"field 2 \(value of az:sin:az:2\) is '1q'"),
        ('RTS2_ALTAZ 1" 2" 3" 4" 5" 6" 7"\nHA 1" sin dec 2', 2, r"corrects ha, which a RTS2_ALTAZ model does not have"),
        ('RTS2_GEM 1" 2" 3" 4" 5" 6" 7" 8" 9"\nHA 1" sin dec 2\nHA 2" sin dec 2.0', 3, r"ha:sin:dec:2 is given twice \(first on line 2\)"),
        ('RTS2_GEM 1" 2" 3" 4" 5" 6" 7" 8" 9"\nthis is not', 2, r"not a gpoint model line"),
        ("# only a comment", None, r"no model line"),
    ],
)
def test_model_file_errors_name_file_line_and_field(tmp_path, text, line, pattern):
    path = tmp_path / "bad.model"
    path.write_text(text)
    with pytest.raises(GpointFormatError) as info:
        read_gpoint_model(path)
    err = info.value
    assert err.path == str(path) and err.line == line
    assert re.search(pattern, str(err)), (pattern, str(err))


def test_writer_refuses_what_gpoint_cannot_hold(tmp_path):
    path = tmp_path / "m.model"
    cases = [
        (px.AltAz(gpoint_terms("ia,IE"), azimuth="S-W"), r"term IE \(IE\) cannot be written to a gpoint model file"),
        (px.AltAz(gpoint_terms("ia"), azimuth="N-E"), r"counts it 'N-E'"),
        (px.XY("basic"), r"mount is XYMount"),
        (px.Equatorial(gpoint_model_terms("ih tf", "gem", latitude=LAT), latitude=LAT + 1e-6),
         r"term tf was built for latitude 49.9092 deg"),
        (px.Equatorial(gpoint_terms("ia"), latitude=LAT), r"term ia \(GpointIA\) cannot be written"),
    ]
    for model, pattern in cases:
        with pytest.raises(ValueError, match=pattern):
            write_gpoint_model(path, model)
        assert not path.exists()


@pytest.mark.parametrize("name", GPOINT_GEM_TERMS)
def test_gem_terms_match_tpoint_equatorial_terms(name):
    """gpoint coef c == TPOINT -c (pointax.terms.equatorial, TPOINT's linear form): exactly
    for the zero points, to first order otherwise; on both sides of the pier. DAF is the
    exception: gpoint's daf has TPOINT's sign (Wallace's tptPterms: dh = -DAF (cos phi
    cos h + sin phi tan dec); gpoint: -daf (sin phi tan dec + cos phi cos h))."""
    coef = 1.0 * ARCSEC
    sign = 1.0 if name == "daf" else -1.0
    ours = px.Equatorial(gpoint_model_terms(name, "gem", latitude=LAT, values={name: coef}), latitude=LAT)
    theirs = px.Equatorial(px.terms.tpoint(name.upper(), mount="equatorial", latitude=LAT,
                                           values={name.upper(): sign * coef}), latitude=LAT)
    d_g, d_t, d_0 = ours(GEM_RAW), theirs(GEM_RAW), px.Equatorial([], latitude=LAT)(GEM_RAW)
    assert np.max(np.asarray(px.rotations.angle_between(d_g, d_0))) > 0.3 * coef
    tolerance = 1e-15 if name in ("ih", "id") else 1e-9
    assert np.all(np.asarray(px.rotations.angle_between(d_g, d_t)) < tolerance)
    # and with the same sign they would disagree by about twice the offset
    same = px.Equatorial(px.terms.tpoint(name.upper(), mount="equatorial", latitude=LAT,
                                         values={name.upper(): -sign * coef}), latitude=LAT)(GEM_RAW)
    assert np.max(np.asarray(px.rotations.angle_between(d_g, same))) > 0.5 * coef

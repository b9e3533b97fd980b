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
        ("ha:sin:az:1", r"field 1 \(axis\) 'ha' is an equatorial axis"),
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


def test_names_mix_gpoint_extras_and_tpoint():
    spec = "ia, ie tn,IA,haca2,az:sincos:az;el:2;2,CA"
    names = ["ia", "ie", "tn", "IA", "HACA2", "az:sincos:az;el:2;2", "CA"]
    assert gpoint_names(spec) == names
    terms = gpoint_terms(spec, values={"ie": 2.0, "HACA2": 3.0, "az:sincos:az;el:2;2": 4.0})
    assert [term.name for term in terms] == names
    assert [float(term.coef) for term in terms] == [0.0, 2.0, 0.0, 0.0, 3.0, 4.0, 0.0]
    assert isinstance(terms[0], px.terms.GpointTerm) and isinstance(terms[3], px.terms.IA)
    assert isinstance(terms[4], px.terms.Harmonic) and isinstance(terms[5], px.terms.GpointExtra)
    assert isinstance(gpoint_terms("CA", form="rigorous")[0], px.terms.rigorous.CA)
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


def test_autodiff_jacobian_matches_central_differences():
    model = px.AltAz(gpoint_terms("ia,tn,npoa,az:sincos:az;el:2;2",
                                  values={"ia": 100 * ARCSEC, "tn": 30 * ARCSEC, "npoa": -20 * ARCSEC,
                                          "az:sincos:az;el:2;2": 15 * ARCSEC}), azimuth="S-W")
    obs = px.simulate(px.AltAz([], azimuth="S-W"), RAW)
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


# ------------------------------------------------------------------ reader


@pytest.fixture(scope="module")
def sample() -> GpointRun:
    return read_gpoint(SAMPLE)


def test_sample_file(sample):
    rows = np.loadtxt(SAMPLE, comments="#")  # id jd ra dec e_alt e_az alt az
    assert rows.shape == (36, 8)
    assert isinstance(sample, GpointRun) and len(sample) == 36
    assert sample.path == str(SAMPLE) and sample.kind == "altaz-manual" and sample.azimuth == "S-W"
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
        ([GOOD[0], "# gem 15 50 600", GOOD[2]], 2, [r"equatorial \(GEM\) run"]),
        ([GOOD[0], "# observatory 15 50 600", GOOD[2]], 2, [r"equatorial"]),
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

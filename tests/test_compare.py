"""pointax.compare and pointax compare, against independent references:

* per-axis RMS (the level-mount paper's eqs 21-23, n - 1) from exact axis-angle
  differences computed here with NumPy (atan2 / asin of the directions), and the
  before-correction row from the raw readings alone;
* AIC and BIC from scipy.stats.norm log-densities;
* k-fold and holdout figures from fits of the subsets themselves (px.fit on the sliced
  observations, not the weight masks compare uses) and px.residuals on the held-back rows;
* automatic model building recovers a planted term and adds no noise term, and its
  Gauss-Newton fits agree with px.fit; the terms and folds it tries are data of its
  compiled programs (counted with JAX's compilation events);
* the command line on the bundled MMT run reproduces TPOINT's Sky RMS of the basic model.
"""

from __future__ import annotations

import argparse
import json
import math

import jax
import numpy as np
import pytest
from conftest import MMT_DAT, MMT_MOD
from scipy import stats

import pointax as px
from pointax.analysis import (
    BEFORE,
    axis_rms,
    build_model,
    compare,
    family_model,
    fold_indices,
    holdout_indices,
    information_criteria,
)
from pointax.cli.compare import add_compare_parser, parse_families, run_compare
from pointax.io.xy import XYFormatError, read_xy_run, write_xy_run
from pointax.terms import xy

ARCSEC = np.pi / 648000
SMALL = "L_zero B_zero collim"  # a three-term X-Y family: compiles fast
PLANTED = SMALL + " dL_tanL_secB"  # the truth's terms (the model automatic building finds)


def xy_angles(d):
    """(L, B) of East-North-Up directions on an X-Y mount: eq 5 inverted."""
    d = np.asarray(d)
    return np.arctan2(d[..., 0], d[..., 2]), np.arcsin(np.clip(d[..., 1], -1, 1))


def wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


@pytest.fixture(scope="module")
def tiny():
    """48 X-Y observations: readings spread over L, B in +-60 deg; truth L_zero 15",
    B_zero -20", collim 25", a planted 20" tan L / cos B in dL; 1.5" noise on the sky."""
    rng = np.random.default_rng(7)
    enc = np.stack([rng.uniform(-1.05, 1.05, 48), rng.uniform(-1.05, 1.05, 48)], axis=1)
    truth = px.XY(
        (
            xy.Basic("L_zero", coef=px.arcsec(15.0)),
            xy.Basic("B_zero", coef=px.arcsec(-20.0)),
            xy.Basic("collim", coef=px.arcsec(25.0)),
            xy.Linearised("dL_tanL_secB", coef=px.arcsec(20.0)),
        )
    )
    return px.simulate(truth, enc, noise=px.arcsec(1.5), seed=3)


# ----------------------------------------------------------------------------- statistics


def test_statistics_against_numpy_and_scipy(tiny):
    c = compare({"small": SMALL}, tiny)
    row = c["small"]
    result = px.fit(family_model(SMALL, tiny), tiny)
    n = len(tiny)

    # Eqs 21-23 from exact axis-angle differences (NumPy): the fitted model's pointing
    # against the stars, both turned into (L, B) with atan2 / asin.
    L0, B0 = xy_angles(np.asarray(tiny.target))
    Lp, Bp = xy_angles(np.asarray(result.model(np.asarray(tiny.encoder))))
    dL, dB = wrap(L0 - Lp), B0 - Bp
    want_L, want_B = math.sqrt(np.sum(dL**2) / (n - 1)), math.sqrt(np.sum(dB**2) / (n - 1))
    assert row.in_sample.n == n
    np.testing.assert_allclose([row.in_sample.axis1, row.in_sample.axis2], [want_L, want_B], rtol=1e-4)
    np.testing.assert_allclose(row.in_sample.total, math.hypot(want_L, want_B), rtol=1e-4)
    np.testing.assert_allclose(row.sky_rms, float(result.sky_rms), rtol=1e-12)

    # AIC / BIC: Gaussian log-density of the 2n residual components (arcsec) at the
    # maximum-likelihood standard deviation, k = 3 terms + the variance.
    r = np.asarray(result.residuals).reshape(-1) / ARCSEC
    log_l = stats.norm.logpdf(r, scale=np.sqrt(np.mean(r**2))).sum()
    np.testing.assert_allclose(row.log_likelihood, log_l, rtol=1e-12)
    np.testing.assert_allclose(row.aic, 2 * 4 - 2 * log_l, rtol=1e-12)
    np.testing.assert_allclose(row.bic, 4 * np.log(2 * n) - 2 * log_l, rtol=1e-12)
    assert row.n_params == 3

    # Significance is value / sigma of the fit.
    for name in result.names:
        assert row.significance[name] == pytest.approx(result.value(name) / result.sigma(name), rel=1e-12)

    # Before correction: the bare mount points at the readings, so DL = L0 - L exactly.
    before = c[BEFORE]
    dL0, dB0 = wrap(L0 - tiny.encoder[:, 0]), B0 - tiny.encoder[:, 1]
    np.testing.assert_allclose(
        [before.in_sample.axis1, before.in_sample.axis2],
        [math.sqrt(np.sum(dL0**2) / (n - 1)), math.sqrt(np.sum(dB0**2) / (n - 1))],
        rtol=2e-3,  # first-order axis-angle conversion of ~60" offsets
    )
    assert before.n_params == 0 and before.out_of_sample is None and c.scheme == "none"


def test_axis_rms_and_criteria_closed_forms():
    r = np.array([[3.0, 4.0], [0.0, 0.0], [-3.0, 4.0]]) * ARCSEC
    a = axis_rms(r)
    assert a.axis1 / ARCSEC == pytest.approx(3.0)  # sqrt(18 / 2)
    assert a.axis2 / ARCSEC == pytest.approx(4.0)  # sqrt(32 / 2)
    assert a.total / ARCSEC == pytest.approx(5.0)
    cos = np.array([0.5, 1.0, 0.5])
    assert axis_rms(r, cos).axis1 / ARCSEC == pytest.approx(6.0)  # the angle: 6" / 0.5 per row
    assert math.isnan(axis_rms(r[:1]).total)
    # s^2 = (9 + 16 + 9 + 16) / 6; ln L = -3 (ln(2 pi s^2) + 1).
    s2 = 50.0 / 6.0
    log_l, aic, bic = information_criteria(r, 2)
    assert log_l == pytest.approx(-3 * (math.log(2 * math.pi * s2) + 1))
    assert aic == pytest.approx(6 - 2 * log_l) and bic == pytest.approx(3 * math.log(6) - 2 * log_l)


def test_splits_partition_the_rows():
    folds = fold_indices(50, 4, seed=3)
    validated = np.sort(np.concatenate([v for _, v in folds]))
    np.testing.assert_array_equal(validated, np.arange(50))
    for f, v in folds:
        assert len(np.intersect1d(f, v)) == 0 and len(f) + len(v) == 50 and len(v) in (12, 13)
    fit_rows, val_rows = holdout_indices(48, 0.25, seed=1)
    assert len(val_rows) == 12 and len(fit_rows) == 36 and len(np.intersect1d(fit_rows, val_rows)) == 0
    with pytest.raises(ValueError, match="strictly between 0 and 1"):
        holdout_indices(48, 1.5)
    with pytest.raises(ValueError, match="folds=60 is more than the 48"):
        fold_indices(48, 60)


# ----------------------------------------------------------------------------- out of sample


@pytest.fixture(scope="module")
def small_model(tiny):
    return family_model(SMALL, tiny)


def test_kfold_equals_fits_of_the_manual_splits(tiny, small_model):
    c = compare({"small": small_model}, tiny, folds=4, seed=5)
    row = c["small"]
    assert c.scheme == "k-fold" and c.n_fit == 48 and c.n_validation == 48
    pieces, cosines = [], []
    for fit_rows, val_rows in fold_indices(48, 4, seed=5):
        fitted = px.fit(small_model, tiny[fit_rows])  # the subset itself, not weights
        assert bool(fitted.converged)
        pieces.append(np.asarray(px.residuals(fitted.model, tiny[val_rows])))
        _, B0 = xy_angles(np.asarray(tiny.target)[val_rows])
        cosines.append(np.cos(B0))
    r = np.concatenate(pieces)
    d1, d2 = r[:, 0] / np.concatenate(cosines), r[:, 1]
    want = [math.sqrt(np.sum(d1**2) / 47), math.sqrt(np.sum(d2**2) / 47)]
    np.testing.assert_allclose([row.out_of_sample.axis1, row.out_of_sample.axis2], want, rtol=1e-7)
    # In-sample figures come from the fit of all 48.
    whole = px.fit(small_model, tiny)
    np.testing.assert_allclose(row.sky_rms, float(whole.sky_rms), rtol=1e-10)
    assert row.out_of_sample.total > row.in_sample.total


def test_holdout_evaluates_the_fit_set_model(tiny, small_model):
    fit_rows, val_rows = holdout_indices(48, 0.25, seed=2)
    by_fraction = compare({"small": small_model}, tiny, holdout=0.25, seed=2)
    by_rows = compare({"small": small_model}, tiny, holdout=(fit_rows, val_rows))
    by_sets = compare({"small": small_model}, None, holdout=(tiny[fit_rows], tiny[val_rows]))
    by_validation = compare({"small": small_model}, tiny[fit_rows], holdout=tiny[val_rows])

    fitted = px.fit(small_model, tiny[fit_rows])
    r = np.asarray(px.residuals(fitted.model, tiny[val_rows]))
    _, B0 = xy_angles(np.asarray(tiny.target)[val_rows])
    want = axis_rms(r, np.cos(B0))
    r_in = np.asarray(fitted.residuals)
    _, B_in = xy_angles(np.asarray(tiny.target)[fit_rows])
    want_in = axis_rms(r_in, np.cos(B_in))
    for c in (by_fraction, by_rows, by_sets, by_validation):
        row = c["small"]
        assert c.n_fit == 36 and c.n_validation == 12
        assert row.out_of_sample.total == pytest.approx(want.total, rel=1e-7)
        assert row.in_sample.total == pytest.approx(want_in.total, rel=1e-7)
    # ... and not the model fitted to every star, which has seen the held-back ones.
    seen = px.fit(small_model, tiny)
    r_seen = np.asarray(px.residuals(seen.model, tiny[val_rows]))
    assert axis_rms(r_seen, np.cos(B0)).total < want.total
    assert by_fraction.scheme == "holdout" and by_rows.scheme == "split" and by_validation.scheme == "validation set"


def test_table_and_dict(tiny, small_model):
    c = compare({"small": small_model, "planted": PLANTED}, tiny, folds=3)
    assert c.labels == [BEFORE, "small", "planted"]
    text = c.table()
    lines = text.splitlines()
    body = [line.split("|")[0].strip() for line in lines if line.count("|") == 3]
    assert body[-3:] == [BEFORE, "small", "planted"]
    assert "dL" in text and "dB" in text and "AIC" in text and "BIC" in text and "out-of-sample" in text
    d = json.loads(json.dumps(c.to_dict()))
    assert [f["label"] for f in d["families"]] == [BEFORE, "small", "planted"]
    assert d["families"][2]["n_params"] == 4
    assert {t["name"] for t in d["families"][1]["terms"]} == {"L_zero", "B_zero", "collim"}
    # The family with the planted term fits to the noise (1.5" on the sky per axis);
    # the small one misses the 20" term, in and out of sample.
    assert c["planted"].sky_rms / ARCSEC == pytest.approx(1.5 * math.sqrt(2), rel=0.25)
    assert c["small"].out_of_sample.total > 3 * c["planted"].out_of_sample.total
    assert c["planted"].aic < c["small"].aic - 100 and c["planted"].bic < c["small"].bic - 100
    sky = compare({"small": small_model}, tiny, per_axis="sky")
    assert "dL cos B" in sky.table()
    assert sky["small"].in_sample.axis1 < c["small"].in_sample.axis1  # cos B < 1 shrinks it


def test_bad_input_is_named(tiny, small_model):
    with pytest.raises(ValueError, match="give holdout or folds, not both"):
        compare({"small": small_model}, tiny, holdout=0.2, folds=3)
    with pytest.raises(ValueError, match="unknown X-Y family or term 'nonsense'"):
        compare({"x": "basic nonsense"}, tiny)
    with pytest.raises(ValueError, match="weights differ"):
        compare({"small": small_model}, px.Observations(tiny.encoder, tiny.target, np.linspace(1, 2, 48), "xy"))
    with pytest.raises(ValueError, match="convention"):
        compare({"az": px.AltAz(px.terms.tpoint("IA IE"))}, tiny)
    with pytest.raises(ValueError, match="terms appear more than once"):
        family_model("basic rotation", tiny)
    names = [t.name for t in family_model("rotation dL_tanL_secB", tiny).terms]
    assert names[-1] == "dL_tanL_secB" and "tilt_rot" in names
    altaz = family_model("harmonic", px.AltAzMount(azimuth="S-E"))
    assert [t.name for t in altaz.terms][-6:] == ["HACA2", "HASA2", "HECA2", "HESA2", "HSCA2", "HSSA2"]


# ----------------------------------------------------------------------------- automatic building


def planted_candidates():
    """The planted term, five absent from the truth, and dL_1, which is the start's
    L_zero under another name (the data cannot tell them apart)."""
    return [xy.Linearised(n) for n in ("dB_secB", "dL_sinL_tanB", "dL_tanL_secB", "dB_cosL", "dL_1")] + [
        xy.SphericalHarmonic("SHL_sinB^2"),
        xy.SphericalHarmonic("SHB_sinL_cosB"),
    ]


def test_build_model_recovers_the_planted_term_and_no_noise_term(tiny):
    candidates = planted_candidates()
    build = build_model(candidates, tiny, start=SMALL, folds=4, seed=0)
    assert build.added == ["dL_tanL_secB"], build.report()
    assert build.dropped == []
    assert [s.action for s in build.path] == ["start", "add"]
    assert build.path[1].rms_out < build.path[0].rms_out
    assert "stopped:" in build.report() and "dL_tanL_secB" in build.report()
    # Its fits are least-squares fits: px.fit of the final model agrees.
    check = px.fit(build.model, tiny)
    np.testing.assert_allclose(build.values, np.asarray(check.values), rtol=0, atol=1e-6 * ARCSEC)
    np.testing.assert_allclose(build.sigmas, np.asarray(check.sigmas), rtol=1e-6)
    assert build.values[list(build.names).index("dL_tanL_secB")] / ARCSEC == pytest.approx(20.0, abs=2.0)
    L0, B0 = xy_angles(np.asarray(tiny.target))
    assert build.path[-1].rms_in == pytest.approx(axis_rms(np.asarray(check.residuals), np.cos(B0)).total, rel=1e-8)
    assert json.loads(json.dumps(build.to_dict()))["path"][1]["term"] == "dL_tanL_secB"


def test_build_model_compiles_nothing_for_the_terms_and_folds_it_tries(tiny):
    """The terms in use and the stars fitted are masks given to build_model's compiled
    programs as data: once one build of these candidates has run, builds that fit and
    screen other sets of terms on other folds compile nothing (counted with JAX's own
    compilation events). A mask made part of a program's structure (static) would
    compile once per set of terms or fold tried; a program rebuilt per build, once per build."""
    first = build_model(planted_candidates(), tiny, start=SMALL, folds=4, seed=0, add_threshold=1e6)
    assert "add" not in [s.action for s in first.path]  # it screened every candidate, added none
    compiled = []

    def count(event, duration, **kwargs):
        if event == "/jax/core/compile/backend_compile_duration":
            compiled.append(event)

    jax.monitoring.register_event_duration_secs_listener(count)
    try:
        for seed in (1, 2):  # other folds: other rows fitted; other term sets fitted and screened
            build = build_model(planted_candidates(), tiny, start=SMALL, folds=4, seed=seed)
            assert build.added == ["dL_tanL_secB"], build.report()
            assert compiled == [], (seed, len(compiled))
    finally:
        jax.monitoring.unregister_event_duration_listener(count)


# ----------------------------------------------------------------------------- command line


def parse(argv):
    parser = argparse.ArgumentParser(prog="pointax")
    add_compare_parser(parser.add_subparsers(dest="command"))
    return parser.parse_args(["compare", *argv])


def test_cli_on_the_mmt_run_reproduces_tpoints_sky_rms(capsys):
    status = run_compare(parse([str(MMT_DAT), "--azimuth", "S-E", "--families", "basic", "--folds", "4", "--json"]))
    assert status == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n_fit"] == 80 and out["n_validation"] == 80 and out["scheme"] == "k-fold"
    basic = out["families"][1]
    assert basic["label"] == "basic" and basic["n_params"] == 8
    tpoint = {line.split()[0]: float(line.split()[1]) for line in MMT_MOD.read_text().splitlines()[2:10]}
    sky_rms = float(MMT_MOD.read_text().splitlines()[1].split()[2])  # 'T 80 0.9318 ...'
    # TPOINT prints 0.9318; the least-squares optimum here is 0.93189.
    assert basic["sky_rms"] == pytest.approx(sky_rms, abs=2e-4)
    for term in basic["terms"]:
        assert term["value"] == pytest.approx(tpoint[term["name"]], abs=0.01)
    # AIC from the Sky RMS: s^2 = Sky RMS^2 / 2 over 160 components, k = 9; with
    # TPOINT's rounded Sky RMS it agrees to 320 * 1e-4 relative.
    for rms, tolerance in ((basic["sky_rms"], 1e-9), (sky_rms, 0.1)):
        log_l = -80 * (math.log(2 * math.pi * rms**2 / 2) + 1)
        assert basic["aic"] == pytest.approx(18 - 2 * log_l, abs=tolerance)
        assert basic["bic"] == pytest.approx(9 * math.log(160) - 2 * log_l, abs=tolerance)
    assert basic["out_of_sample"]["total"] > basic["in_sample"]["total"]
    assert out["families"][0]["label"] == BEFORE


def test_cli_xy_text_format_and_errors(tmp_path, tiny, capsys):
    path = tmp_path / "run.txt"
    write_xy_run(path, tiny, comments=("test run",))
    back = read_xy_run(path)
    np.testing.assert_allclose(back.encoder, tiny.encoder, atol=1e-10)
    np.testing.assert_allclose(back.target, tiny.target, atol=1e-10)
    assert run_compare(parse([str(path), "--mount", "xy", "--families", SMALL, "--folds", "4", "--seed", "5"])) == 0
    text = capsys.readouterr().out
    assert "4-fold cross-validation" in text and SMALL in text

    bad = tmp_path / "bad.txt"
    bad.write_text("# L B L0 B0\n1 2 3 4\n1 2 x 4\n")
    with pytest.raises(XYFormatError, match=r"bad.txt:3: field L0: not a number: 'x'"):
        read_xy_run(bad)
    assert run_compare(parse([str(bad), "--mount", "xy", "--families", "basic"])) == 2
    assert "bad.txt:3: field L0" in capsys.readouterr().err
    assert run_compare(parse([str(tmp_path / "missing.dat"), "--families", "basic"])) == 2
    assert "missing.dat" in capsys.readouterr().err
    assert run_compare(parse([str(MMT_DAT), "--azimuth", "S-E", "--families", "basic;IA XX"])) == 2
    assert "unknown TPOINT term 'XX'" in capsys.readouterr().err
    assert run_compare(parse([str(MMT_DAT), "--azimuth", "S-E", "--holdout", "1.5"])) == 2
    assert "strictly between 0 and 1" in capsys.readouterr().err


def test_parse_families():
    assert parse_families("basic,harmonic", None, "altaz", "tpoint") == {"basic": "basic", "harmonic": "harmonic"}
    assert parse_families("IA,IE,CA", None, "altaz", "tpoint") == {"IA,IE,CA": "IA,IE,CA"}
    assert parse_families("basic;IA IE CA TF", None, "altaz", "tpoint") == {
        "basic": "basic",
        "IA IE CA TF": "IA IE CA TF",
    }
    assert parse_families("mine=basic HACA2;basic", ["ia ie az:sincos:az;el:2;2"], "altaz", "gpoint") == {
        "mine": "basic HACA2",
        "basic": "basic",
        "ia ie az:sincos:az;el:2;2": "ia ie az:sincos:az;el:2;2",
    }
    assert parse_families("basic,rotation,linearised", None, "xy", "tpoint") == {
        "basic": "basic", "rotation": "rotation", "linearised": "linearised"
    }  # fmt: skip
    with pytest.raises(ValueError, match="given twice"):
        parse_families("basic;basic", None, "altaz", "tpoint")

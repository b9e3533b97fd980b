"""TPOINT-style FAUTO (pointax.analysis.fauto), against independent references:
* on a simulated alt-az run with the eight basic terms and two harmonics, FAUTO adds
  exactly those harmonics, every value is within 4 sigma of the truth, no term it adds
  has a column nearly collinear (NumPy's correlation of the least-squares problem) with
  another term, and the final Sky RMS and sigmas are NumPy's least squares of the chosen
  terms; the same steps come out twice;
* equatorial and X-Y runs: the planted terms found, values within 4 sigma;
* ``pointax tpoint`` FAUTO prints the step table; the '&' flags of a written model;
* SHOW names the run's mount; ``pointax compare`` names an unknown family.
"""

from __future__ import annotations

from pathlib import Path

import jax
import numpy as np
import pytest

import pointax as px
from pointax.analysis.fauto import fauto, harmonic_candidates
from pointax.cli import main
from pointax.cli.compare import parse_families
from pointax.io.tpoint_model import read_model
from pointax.terms import tpoint
from pointax.terms import xy

ARCSEC = np.pi / 648000
BASIC = ["IA", "IE", "CA", "NPAE", "AN", "AW", "TF", "TX"]
TRUTH = dict(IA=30.0, IE=-12.0, CA=8.0, NPAE=-5.0, AN=3.0, AW=-6.0, TF=10.0, TX=-2.0, HASA2=4.0, HECE3=3.0)
HERE = Path(__file__).parent


def _altaz_run(n=90, seed=5):
    truth = px.AltAz(tpoint(list(TRUTH), values={k: v * ARCSEC for k, v in TRUTH.items()}))
    rng = np.random.default_rng(seed)
    enc = np.stack(
        [rng.uniform(0, 2 * np.pi, n), np.arcsin(rng.uniform(np.sin(np.radians(15)), np.sin(np.radians(85)), n))], 1
    )
    return px.simulate(truth, enc, noise=0.5 * ARCSEC, seed=2)


@pytest.fixture(scope="module")
def altaz():
    obs = _altaz_run()
    return obs, fauto(obs)


def _numpy_design(template, names, obs, coef=None):
    """Residuals ``(2n,)`` at ``coef`` and their ``(2n, m)`` Jacobian over the terms, by
    central differences of pointax's residuals (an independent route: no compiled
    builder, no masks)."""
    coef = np.zeros(len(names)) if coef is None else coef
    model = template.set(**dict(zip(names, coef)))
    # The plain residuals, compiled once per structure (the values are data).
    residuals = jax.jit(lambda m: px.residuals(m, obs).reshape(-1))
    base = np.asarray(residuals(model))
    cols = []
    h = 1.0 * ARCSEC
    for k, n in enumerate(names):
        plus = np.asarray(residuals(model.set(**{n: coef[k] + h})))
        minus = np.asarray(residuals(model.set(**{n: coef[k] - h})))
        cols.append((plus - minus) / (2 * h))
    return base, np.stack(cols, 1)


def _numpy_fit(template, names, obs):
    """Gauss-Newton in NumPy from zero on ``template``'s structure (its mount, terms and
    residual form): values, residuals and Jacobian at the solution."""
    coef = np.zeros(len(names))
    for _ in range(4):
        base, jac = _numpy_design(template, names, obs, coef)
        coef = coef + np.linalg.lstsq(jac, -base, rcond=None)[0]
    base, jac = _numpy_design(template, names, obs, coef)
    return coef, base, jac


def test_fauto_recovers_the_planted_harmonics_and_adds_no_mimic(altaz):
    obs, f = altaz
    assert set(f.added) == {"HASA2", "HECE3"}
    assert [s.action for s in f.steps] == ["start", "add", "add"]
    for name, truth in TRUTH.items():
        k = f.names.index(name)
        assert abs(f.values[k] / ARCSEC - truth) < 4 * f.sigmas[k] / ARCSEC, name
    # No added term mimics another: NumPy's parameter correlations of the final model.
    coef, resid, jac = _numpy_fit(f.model, list(f.names), obs)
    a = jac / np.linalg.norm(jac, axis=0)
    cov = np.linalg.inv(a.T @ a)
    r = cov / np.sqrt(np.outer(np.diag(cov), np.diag(cov)))
    for name in f.added:
        k = f.names.index(name)
        others = np.delete(np.abs(r[k]), k)
        assert others.max() <= 0.99
    # Sky RMS, values and sigmas: NumPy's Gauss-Newton least squares of the chosen terms.
    n = len(resid) // 2
    sky = np.sqrt(np.sum(resid**2) / n)
    assert abs(f.sky_rms - sky) < 1e-6 * ARCSEC
    np.testing.assert_allclose(f.values, coef, atol=1e-6 * ARCSEC)
    sigmas = sky * np.sqrt(np.diag(np.linalg.inv(jac.T @ jac)))
    np.testing.assert_allclose(f.sigmas, sigmas, rtol=1e-5)
    assert abs(f.popn_sd - sky * np.sqrt(n / (n - len(f.names)))) < 1e-9 * ARCSEC
    # The harmonics that mimic a physical term are reported, not tried.
    assert any(c == "HESE2" for c, _, _ in f.mimics)


def test_fauto_is_deterministic(altaz):
    obs, f = altaz
    again = fauto(obs)
    assert again.steps == f.steps and again.names == f.names
    np.testing.assert_array_equal(again.values, f.values)


def test_fauto_reports_an_outlier_and_writes_flags(altaz, tmp_path):
    obs, _ = altaz
    target = np.array(obs.target)
    # Move star 7 by 15" in elevation (the basic model leaves about 2.3" Popn SD).
    e = np.arcsin(target[7, 2]) if obs.convention == "N-E" else None
    assert e is not None
    shift = 15 * ARCSEC
    az = np.arctan2(target[7, 0], target[7, 1])
    e2 = e + shift
    target[7] = [np.cos(e2) * np.sin(az), np.cos(e2) * np.cos(az), np.sin(e2)]
    bad = px.Observations(obs.encoder, target, convention=obs.convention)
    f = fauto(bad, max_order=0)
    assert [i for i, _ in f.outliers] == [7]
    assert f.outliers[0][1] / ARCSEC > 3 * f.popn_sd / ARCSEC
    f = fauto(obs)
    f.write_model(tmp_path / "f.mod")
    terms = read_model(tmp_path / "f.mod").terms
    assert {t.name for t in terms if t.parallel} == {"HASA2", "HECE3"}
    assert [t.name for t in terms if not t.parallel] == BASIC


def test_harmonic_candidates():
    assert len(harmonic_candidates("altaz", 2)) == 12 and "HSCE2" in harmonic_candidates("altaz", 2)
    assert "HXSH1" in harmonic_candidates("equatorial", 1)
    assert set(harmonic_candidates("xy", 1)) == {
        "SHL_1", "SHL_sinB", "SHL_cosL_cosB", "SHL_sinL_cosB", "SHB_1", "SHB_sinB", "SHB_cosL_cosB", "SHB_sinL_cosB"
    }


def test_fauto_equatorial_smoke():
    lat = np.radians(31.7)
    truth_values = dict(IH=20.0, ID=-15.0, CH=10.0, NP=5.0, MA=-8.0, ME=12.0, TF=6.0, HDSH2=4.0)
    names = list(truth_values)
    truth = px.Equatorial(
        tpoint(names, mount="equatorial", latitude=lat, values={k: v * ARCSEC for k, v in truth_values.items()}),
        latitude=lat,
    )
    rng = np.random.default_rng(4)
    enc = np.stack([rng.uniform(-1.3, 1.3, 70), rng.uniform(np.radians(-25), np.radians(70), 70)], 1)
    obs = px.simulate(truth, enc, noise=0.5 * ARCSEC, seed=1)
    start = px.Equatorial(tpoint(names[:7], mount="equatorial", latitude=lat), latitude=lat)
    f = fauto(obs, start=start, max_order=2)
    assert "HDSH2" in f.added and len(f.added) <= 2
    for name, value in truth_values.items():
        k = f.names.index(name)
        assert abs(f.values[k] / ARCSEC - value) < 4 * f.sigmas[k] / ARCSEC, name


def test_fauto_xy_smoke():
    truth = px.XY(
        tuple(xy.Basic(n, coef=v * ARCSEC) for n, v in [("L_zero", 15.0), ("B_zero", -20.0), ("collim", 25.0)])
        + (xy.SphericalHarmonic("SHB_sinL_sinB_cosB", coef=12.0 * ARCSEC),)
    )
    rng = np.random.default_rng(7)
    enc = np.stack([rng.uniform(-1.05, 1.05, 60), rng.uniform(-1.05, 1.05, 60)], axis=1)
    obs = px.simulate(truth, enc, noise=1.0 * ARCSEC, seed=3)
    f = fauto(obs, start="L_zero B_zero collim", max_order=2)
    assert f.added == ("SHB_sinL_sinB_cosB",)
    k = f.names.index("SHB_sinL_sinB_cosB")
    assert abs(f.values[k] / ARCSEC - 12.0) < 4 * f.sigmas[k] / ARCSEC


def _write_tpoint(path: Path, obs) -> None:
    """A TPOINT alt-az file (N-E azimuth, degrees) of simulated observations."""
    enc = np.degrees(np.asarray(obs.encoder))
    t = np.asarray(obs.target)
    az = np.degrees(np.arctan2(t[:, 0], t[:, 1])) % 360
    el = np.degrees(np.arcsin(np.clip(t[:, 2], -1, 1)))
    lines = ["simulated FAUTO run", ": ALTAZ", "+31 41 19.6 2021 8 21 13.0 741 2608 0.75"]
    lines += [f"{a:.9f} {e:.9f} {ea % 360:.9f} {ee:.9f}" for a, e, ea, ee in zip(az, el, enc[:, 0], enc[:, 1])]
    path.write_text("\n".join(lines + ["END"]) + "\n")


def test_tpoint_fauto_prints_the_step_table(tmp_path, capsys, altaz):
    obs, f = altaz
    _write_tpoint(tmp_path / "run.dat", obs)
    (tmp_path / "f.ptp").write_text(
        "indat run.dat\nfauto\nshow\nfit\noutmod f.mod\ninmod f.mod\nlose HASA2\noutmod g.mod\n"
    )
    assert main(["tpoint", str(tmp_path / "f.ptp")]) == 0
    out = capsys.readouterr().out
    assert "stage" in out and "Popn SD" in out and "add    HASA2" in out and "add    HECE3" in out
    assert "&HASA2" in out and "mount: altaz" in out
    # OUTMOD flags the terms FAUTO added '&'; INMOD keeps the flags; LOSE drops them.
    flagged = {t.name for t in read_model(tmp_path / "f.mod").terms if t.parallel}
    assert flagged == {"HASA2", "HECE3"}
    assert {t.name for t in read_model(tmp_path / "g.mod").terms if t.parallel} == {"HECE3"}


def test_show_names_an_equatorial_run_s_mount(tmp_path, capsys):
    (tmp_path / "s.ptp").write_text(f"indat {HERE / 'data' / 'tpoint' / 'warp-astron.dat'}\nshow\n")
    assert main(["tpoint", str(tmp_path / "s.ptp")]) == 0
    out = capsys.readouterr().out
    assert "mount: equatorial" in out and "mount: altaz" not in out


def test_compare_names_an_unknown_family():
    with pytest.raises(ValueError, match=r"unknown family 'nosuch'.*basic, fauto, harmonic"):
        parse_families("basic,nosuch", None, "altaz", "tpoint")
    with pytest.raises(ValueError, match=r"unknown family 'nosuch'.*basic, fauto, flexure, harmonic"):
        parse_families("basic,nosuch", None, "equatorial", "tpoint")
    assert parse_families("basic,HACA2", None, "altaz", "tpoint") == {"basic,HACA2": "basic,HACA2"}
    assert parse_families("basic,fauto", None, "altaz", "tpoint") == {"basic": "basic", "fauto": "fauto"}


def test_compare_cli_unknown_family_exit_2(capsys):
    from conftest import MMT_DAT

    assert main(["compare", str(MMT_DAT), "--azimuth", "S-E", "--families", "basic,nosuch"]) == 2
    err = capsys.readouterr().err
    assert "unknown family 'nosuch'" in err and "NOSUCH" not in err


def test_fauto_drops_an_insignificant_start_term_only_when_asked():
    """keep_start=False: a start term with no signal (TX, 0 in the truth) is dropped at
    the start, as TPOINT's FAUTO holds such basic terms at 0; its |value/sigma| in
    NumPy's least squares of the start terms is below 2 and the lowest of them all."""
    values = {k: v for k, v in TRUTH.items() if k in BASIC and k != "TX"}
    truth = px.AltAz(tpoint(list(values), values={k: v * ARCSEC for k, v in values.items()}))
    rng = np.random.default_rng(11)
    enc = np.stack(
        [rng.uniform(0, 2 * np.pi, 60), np.arcsin(rng.uniform(np.sin(np.radians(15)), np.sin(np.radians(85)), 60))], 1
    )
    obs = px.simulate(truth, enc, noise=0.5 * ARCSEC, seed=4)
    template = px.AltAz(tpoint(BASIC))
    coef, resid, jac = _numpy_fit(template, BASIC, obs)
    sky = np.sqrt(np.sum(resid**2) / (len(resid) // 2))
    z = np.abs(coef) / (sky * np.sqrt(np.diag(np.linalg.inv(jac.T @ jac))))
    assert BASIC[int(np.argmin(z))] == "TX" and z.min() < 2 and np.sort(z)[1] >= 2
    dropped = fauto(obs, max_order=0, further=(), keep_start=False)
    assert [(s.stage, s.action, s.term) for s in dropped.steps[1:]] == [("start", "drop", "TX")]
    assert "TX" not in dropped.names and len(dropped.names) == 7
    kept = fauto(obs, max_order=0, further=())
    assert list(kept.names) == BASIC and len(kept.steps) == 1

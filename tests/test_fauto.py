"""TPOINT-style FAUTO (pointax.analysis.fauto_search), against independent references:
* on a simulated alt-az run with the eight basic terms and two harmonics, FAUTO adds
  exactly those harmonics, every value is within 4 sigma of the truth, no term it adds
  has a column nearly collinear (NumPy's correlation of the least-squares problem) with
  another term, and the final Sky RMS and sigmas are NumPy's least squares of the chosen
  terms; the same steps come out twice;
* equatorial and X-Y runs: the planted terms found, values within 4 sigma;
* ``pointax tpoint`` FAUTO prints the step table; the '&' flags of a written model;
* SHOW names the run's mount; ``pointax compare`` names an unknown family;
* a start term with no signal is dropped when the refit without it has the lower Popn
  SD (NumPy's least squares of both models), and no other;
* a planted two-coordinate product harmonic is found by the product stage (values and
  Sky RMS: NumPy's least squares), and the vectorised screen gives the per-candidate
  compiled screen's figures;
* an exchange step swaps a stand-in (HECE2, tried first) for the planted term (HECE3)
  because Popn SD falls (NumPy's least squares of both models), and never swaps a term
  for its twin on the sky (HASA2 / HSSA2CE: NumPy's column correlation);
* a state's Jacobian is computed once, however often its screens ask for it.
"""

from __future__ import annotations

from pathlib import Path

import jax
import numpy as np
import pytest

import pointax as px
from pointax.analysis.fauto_search import fauto, harmonic_candidates
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


def test_fauto_is_deterministic(altaz, monkeypatch):
    obs, f = altaz
    import sys

    # Every candidate here has one parameter: all screened together in NumPy, none by
    # the per-candidate compiled step (the vectorised screen's speed, benchmarks/fauto_notes.md).
    calls = []
    module = sys.modules["pointax.analysis.fauto_search"]
    per_candidate = module._Search.screen
    monkeypatch.setattr(module._Search, "screen", lambda *a: calls.append(1) or per_candidate(*a))
    again = fauto(obs)
    assert not calls
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


def test_compare_passes_the_fauto_orders_to_fauto(monkeypatch):
    """`pointax compare --fauto-order N --fauto-products K`: FAUTO gets both (products
    off by default), and the family 'fauto' becomes the terms it kept."""
    import argparse
    import importlib
    import types

    from pointax.cli.compare import _fauto_families, add_compare_parser

    fauto_module = importlib.import_module("pointax.analysis.fauto_search")

    parser = argparse.ArgumentParser(prog="pointax")
    add_compare_parser(parser.add_subparsers(dest="command"))
    calls = []

    def fake_fauto(obs, **kwargs):
        calls.append(kwargs)
        return types.SimpleNamespace(model=types.SimpleNamespace(terms=[types.SimpleNamespace(name=n) for n in ("IA", "HESACE")]))

    monkeypatch.setattr(fauto_module, "fauto", fake_fauto)
    for argv, order, products in (([], 3, 0), (["--fauto-order", "5", "--fauto-products", "2"], 5, 2)):
        args = parser.parse_args(["compare", "run.dat", *argv])
        families = {"basic": "basic", "auto": "fauto"}
        _fauto_families(families, None, args)
        assert calls[-1] == {"max_order": order, "max_product_order": products, "form": args.form}
        assert families == {"basic": "basic", "auto": "IA HESACE"}


def _no_tx_run(n=60, seed=4):
    """A simulated alt-az run of the basic terms but TX (0 in the truth)."""
    values = {k: v for k, v in TRUTH.items() if k in BASIC and k != "TX"}
    truth = px.AltAz(tpoint(list(values), values={k: v * ARCSEC for k, v in values.items()}))
    rng = np.random.default_rng(11)
    enc = np.stack(
        [rng.uniform(0, 2 * np.pi, n), np.arcsin(rng.uniform(np.sin(np.radians(15)), np.sin(np.radians(85)), n))], 1
    )
    return px.simulate(truth, enc, noise=0.5 * ARCSEC, seed=seed)


def _numpy_z_popn(names, obs):
    """``|value / sigma|`` of each term and Popn SD of NumPy's least squares of ``names``."""
    coef, resid, jac = _numpy_fit(px.AltAz(tpoint(names)), names, obs)
    n = len(resid) // 2
    sky = np.sqrt(np.sum(resid**2) / n)
    z = np.abs(coef) / (sky * np.sqrt(np.diag(np.linalg.inv(jac.T @ jac))))
    return z, sky * np.sqrt(n / (n - len(names)))


def test_fauto_drops_a_start_term_without_signal_by_popn_sd():
    """The default start rule: a start term with no signal (TX, 0 in the truth) is
    dropped at the start, as TPOINT's FAUTO holds such basic terms at 0, because the
    refit without it has the lower Popn SD; then no other is (each would raise it).
    Reference: NumPy's least squares of the eight and of the seven terms."""
    obs = _no_tx_run()
    z8, popn8 = _numpy_z_popn(BASIC, obs)
    assert BASIC[int(np.argmin(z8))] == "TX"
    seven = [n for n in BASIC if n != "TX"]
    z7, popn7 = _numpy_z_popn(seven, obs)
    assert popn7 < popn8
    weakest = seven[int(np.argmin(z7))]
    _, popn6 = _numpy_z_popn([n for n in seven if n != weakest], obs)
    assert popn6 > popn7
    f = fauto(obs, max_order=0, further=())
    assert [(s.stage, s.action, s.term) for s in f.steps[1:]] == [("start", "drop", "TX")]
    assert list(f.names) == seven
    assert abs(f.popn_sd - popn7) < 1e-6 * ARCSEC and abs(f.steps[1].significance - z8.min()) < 1e-4
    kept = fauto(obs, max_order=0, further=(), start_rule="never")
    assert list(kept.names) == BASIC and len(kept.steps) == 1
    assert fauto(obs, max_order=0, further=(), keep_start=True).names == kept.names
    # The 2 sigma bar of the added terms ('significance') drops TX too, here.
    dropped = fauto(obs, max_order=0, further=(), start_rule="significance")
    assert [(s.stage, s.action, s.term) for s in dropped.steps[1:]] == [("start", "drop", "TX")]


def test_fauto_finds_a_planted_product_harmonic():
    """A 3" HSCA2CE2 (cross-elevation ~ cos 2A' cos 2E) over the basic terms: FAUTO's
    product stage adds it and nothing else; the single harmonics do not stand in for
    it; values within 4 sigma of the truth; Sky RMS and values are NumPy's least
    squares of the chosen terms. The one-parameter screen (NumPy, all candidates at
    once) gives the per-candidate compiled screen's figures at every step."""
    import sys

    module = sys.modules["pointax.analysis.fauto_search"]
    values = {**{k: TRUTH[k] for k in BASIC}, "HSCA2CE2": 3.0}
    truth = px.AltAz(tpoint(list(values), values={k: v * ARCSEC for k, v in values.items()}))
    rng = np.random.default_rng(8)
    enc = np.stack(
        [rng.uniform(0, 2 * np.pi, 70), np.arcsin(rng.uniform(np.sin(np.radians(15)), np.sin(np.radians(85)), 70))], 1
    )
    obs = px.simulate(truth, enc, noise=0.5 * ARCSEC, seed=6)
    compared = []
    vectorised = module._Search.screen_all

    def checked(self, state, ts, jac):
        out = vectorised(self, state, ts, jac)
        for t in ts:
            one = self.screen(state, t, jac)
            assert (one is None) == (out[t] is None), self.names[t]
            if one is not None:
                np.testing.assert_allclose(out[t], one, rtol=1e-6)
                compared.append(t)
        return out

    mp = pytest.MonkeyPatch()
    mp.setattr(module._Search, "screen_all", checked)
    try:
        f = fauto(obs, max_order=1, max_product_order=2, further=())
    finally:
        mp.undo()
    assert len(compared) > 50
    # A single harmonic may stand in for it first; it is dropped once the product is in.
    assert f.added == ("HSCA2CE2",) and ("product", "add", "HSCA2CE2") in [(s.stage, s.action, s.term) for s in f.steps]
    assert "HSCA2CE2" in module.product_candidates("altaz", 2)
    for name, value in values.items():
        k = f.names.index(name)
        assert abs(f.values[k] / ARCSEC - value) < 4 * f.sigmas[k] / ARCSEC, name
    coef, resid, _ = _numpy_fit(f.model, list(f.names), obs)
    assert abs(f.sky_rms - np.sqrt(np.sum(resid**2) / (len(resid) // 2))) < 1e-6 * ARCSEC
    np.testing.assert_allclose(f.values, coef, atol=1e-6 * ARCSEC)


def test_product_candidates():
    from pointax.analysis.fauto_search import product_candidates

    two = product_candidates("altaz", 2)
    assert len(two) == 12 * 4 and two[:4] == ("HASASE", "HASACE", "HACASE", "HACACE")
    assert {"HSCA2CE2", "HESA2CE", "HACASE2"} <= set(two)
    assert len(product_candidates("altaz", 8)) == 768 and "HSCA5CE8" in product_candidates("altaz", 8)
    assert "HXSH2CD" in product_candidates("equatorial", 2)
    assert product_candidates("xy", 8) == ()
    # Every name builds (TPOINT's generic grammar).
    assert len(tpoint(list(two))) == len(two)
    assert len(tpoint(list(product_candidates("equatorial", 2)), mount="equatorial", latitude=0.5)) == 48


# Order-2 harmonics tried first (as further terms), then order 3 and HSSA2CE: one
# superset, so the exchange tests below share its compiled programs.
_EXCHANGE_TRIAL = dict(further=harmonic_candidates("altaz", 2), harmonics=harmonic_candidates("altaz", 3) + ("HSSA2CE",))


def test_an_exchange_puts_the_planted_term_in_place_of_its_stand_in(altaz, monkeypatch):
    """The order-2 harmonics tried before the order-3 ones: HECE2 comes in for the
    planted HECE3, and the forward search alone leaves it there. The exchange step swaps
    HECE2 for HECE3 because Popn SD falls. Reference: NumPy's least squares of both
    models. The candidates are screened without a refit per term left out: the
    exchanges refit only the swap made (the model without HECE2, then with HECE3) and
    the start-term check after it."""
    import sys

    obs, _ = altaz
    builder = sys.modules["pointax.analysis.fauto_search"].Builder
    refits = []
    refit = builder.state
    monkeypatch.setattr(builder, "state", lambda self, active, y0: refits.append(active) or refit(self, active, y0))
    forward = fauto(obs, exchanges=False, **_EXCHANGE_TRIAL)
    assert forward.added == ("HASA2", "HECE2")
    n_forward = len(refits)
    f = fauto(obs, **_EXCHANGE_TRIAL)
    assert f.added == ("HASA2", "HECE3")
    assert len(refits) - 2 * n_forward == 3
    assert [(s.stage, s.action, s.term) for s in f.steps if s.stage == "exchange"] == [
        ("exchange", "drop", "HECE2"), ("exchange", "add", "HECE3")]
    _, popn_stand_in = _numpy_z_popn(list(forward.names), obs)
    z, popn = _numpy_z_popn(list(f.names), obs)
    assert popn < popn_stand_in
    assert abs(f.popn_sd - popn) < 1e-6 * ARCSEC and abs(forward.popn_sd - popn_stand_in) < 1e-6 * ARCSEC
    assert z[list(f.names).index("HECE3")] >= 2
    assert "then exchanges" in f.rules and "then exchanges" not in forward.rules


def test_an_exchange_never_swaps_a_term_for_one_it_cannot_be_told_apart_from(altaz, monkeypatch):
    """HSSA2CE (cross-elevation ~ sin 2A' cos E) is HASA2 (dA ~ sin 2A') on the sky; the
    rigorous forms differ in the last digits, enough for a swap to lower Popn SD by
    0.00002". FAUTO keeps HASA2 and makes no such exchange; with the twin rule switched
    off it swaps them (so the rule is what holds). Reference: NumPy's correlation of the
    two columns (central differences of the residuals)."""
    import sys

    obs, _ = altaz
    names = ["HASA2", "HSSA2CE"]
    _, jac = _numpy_design(px.AltAz(tpoint(names)), names, obs)
    a = jac / np.linalg.norm(jac, axis=0)
    assert abs(a[:, 0] @ a[:, 1]) > 0.9999
    f = fauto(obs, **_EXCHANGE_TRIAL)
    assert f.added == ("HASA2", "HECE3")
    assert "HSSA2CE" not in [s.term for s in f.steps]
    assert ("HSSA2CE", "HASA2") in [(c, t) for c, t, _ in f.mimics]
    monkeypatch.setattr(sys.modules["pointax.analysis.fauto_search"]._Search, "twins", lambda *args: set())
    swapped = fauto(obs, **_EXCHANGE_TRIAL)
    assert ("exchange", "add", "HSSA2CE") in [(s.stage, s.action, s.term) for s in swapped.steps]
    assert swapped.added == ("HECE3", "HSSA2CE")


def test_each_state_is_linearised_once_for_its_screens(altaz, monkeypatch):
    """The forward search's last screen, the exchange after it and the final report ask
    for the same state's Jacobian: it is computed once per state, not once per ask."""
    import sys

    obs, _ = altaz
    module = sys.modules["pointax.analysis.fauto_search"]
    asked, computed, inside = [], [], []
    jacobian, linearise = module._Search.jacobian, module.Builder.linearise

    def asking(self, state):
        asked.append(state)
        inside.append(True)
        try:
            return jacobian(self, state)
        finally:
            inside.pop()

    def counted(self, y):
        if inside:
            computed.append(1)
        return linearise(self, y)

    monkeypatch.setattr(module._Search, "jacobian", asking)
    monkeypatch.setattr(module.Builder, "linearise", counted)
    f = fauto(obs, **_EXCHANGE_TRIAL)
    assert [s.stage for s in f.steps].count("exchange") == 2
    distinct = len({id(s) for s in asked})
    assert len(asked) > distinct and len(computed) == distinct

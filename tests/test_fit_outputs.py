"""What a fit puts out: the default term form against TPOINT, row numbers in JSON, the
diagnosis of an absurd fit, --plot without matplotlib, the report's listing, model
files through the command line and the API, plots of failed fits, twin solutions.

References: TPOINT's own model file of the shared MMT run, P. T. Wallace's Pmfit fit of
the SPK sample (../shared/data/tpoint/equatorial/REFERENCE.txt), explicit recomputation.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import warnings

import numpy as np
import pytest
from conftest import MMT_DAT, shared_data  # noqa: F401

import pointax as px
from pointax.cli import main

ENV = {**os.environ, "POINTAX_JAX_CACHE": ""}


@pytest.fixture(autouse=True)
def no_compilation_cache(monkeypatch):
    monkeypatch.setenv("POINTAX_JAX_CACHE", "")


# ------------------------------------------------ the default form reproduces TPOINT


@pytest.mark.parametrize(("form", "tol"), [(None, 0.01), ("linear", 0.01), ("rigorous", 0.002)])
def test_forms_reproduce_tpoint_mmt(shared_data, form, tol):  # noqa: F811
    """The default (linear) to 0.01"; rigorous, TPOINT's way of applying the model, to
    0.002" (measured: 0.0028" and 0.0010")."""
    run = px.io.read_tpoint(shared_data / "tpoint" / "mmt_20210821.dat", azimuth="S-E")
    ref = px.io.read_model(shared_data / "tpoint" / "mmt_20210821.mod")
    kwargs = {} if form is None else {"form": form}
    result = px.fit(run.model(px.terms.tpoint(ref.names, **kwargs)), run)
    for term in ref.terms:
        assert result.value(term.name) == pytest.approx(term.value, abs=tol)
        assert result.sigma(term.name) == pytest.approx(term.sigma, abs=0.01)
    assert float(result.sky_rms) / px.units.ARCSEC == pytest.approx(ref.sky_rms, abs=0.01)


@pytest.mark.parametrize("form", [None, "rigorous"])
def test_forms_reproduce_pmfit_spk(shared_data, form):  # noqa: F811
    """Pmfit solves at the observed position and evaluates at the demanded one (see
    REFERENCE.txt): values to its 0.1" target, Sky RMS and sigmas to 0.01"."""
    run = px.io.read_tpoint(shared_data / "tpoint" / "equatorial" / "spk_5m_horseshoe.dat")
    pmfit = {"IH": (-92.2155, 4.0337), "ID": (-126.7376, 2.2735), "CH": (44.1696, 3.2661),
             "ME": (64.8473, 2.4953), "MA": (-2.9882, 1.3952), "TF": (10.9935, 1.6465)}  # fmt: skip
    kwargs = {} if form is None else {"form": form}
    result = px.fit(run.model(px.terms.tpoint(list(pmfit), **kwargs, **run.term_options())), run)
    factor = np.sqrt(len(run) / (len(run) - len(pmfit)))  # Pmfit's sigmas use Popn SD
    for name, (value, sigma) in pmfit.items():
        assert result.value(name) == pytest.approx(value, abs=0.1)
        assert result.sigma(name) == pytest.approx(sigma / factor, abs=0.01)
    assert float(result.sky_rms) / px.units.ARCSEC == pytest.approx(5.3170, abs=0.01)


# ------------------------------------------------ JSON rows, counted from 1


def test_json_rows_are_one_based(capsys):
    status = main(["fit", str(MMT_DAT), "--azimuth", "S-E", "--mask", "39,79", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert status == 0
    assert out["masked"] == [38, 78] and out["masked_rows"] == [39, 79]
    assert out["outliers"] == [] and out["outlier_rows"] == []
    rows = [o["row"] for o in out["observations"] if o["masked"]]
    assert rows == [39, 79]
    assert out["loo_rms_arcsec"] > out["sky_rms_arcsec"]


def test_json_outlier_rows():
    run = px.io.read_tpoint(MMT_DAT, azimuth="S-E")
    obs = run.observations
    target = np.array(obs.target)
    target[38] = target[38] + 3e-4 * np.array([1.0, 0.0, 0.0])
    target[38] /= np.linalg.norm(target[38])
    data = px.Observations(obs.encoder, target, obs.weight, obs.convention)
    result = px.fit(px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"), azimuth="S-E"), data, loss="cauchy")
    d = result.to_dict()
    assert 38 in d["outliers"]
    assert d["outlier_rows"] == [i + 1 for i in d["outliers"]]
    assert "observations " in result.report() and "39" in result.report().split("outlier(s)")[1].splitlines()[0]


# ------------------------------------------------ an absurd fit names the bad rows


def _with_bad_row(tmp_path, row: int, record: str):
    lines = MMT_DAT.read_text().splitlines()
    data = [k for k, line in enumerate(lines) if line.strip() and line.split()[0].lstrip("+-").replace(".", "").isdigit()]
    # The first numeric line is the run parameters record; observations follow.
    obs_lines = data[1:]
    lines[obs_lines[row]] = record
    path = tmp_path / "bad.dat"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize(("row", "record", "absurd_rms"), [(0, "1 2 3 4", False), (25, "1 2 3 4", False)])
def test_absurd_fit_names_the_bad_row(tmp_path, row, record, absurd_rms):
    """A corrupt record, first or later (Sky RMS some 600"): the warning names the row,
    not units."""
    path = _with_bad_row(tmp_path, row, record)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = px.io.read_tpoint(path, azimuth="S-E")
    result = px.fit(run.model(px.terms.tpoint("IA IE NPAE CA AN AW TF TX")), run)
    assert (float(result.sky_rms) > px.deg(1)) == absurd_rms
    assert float(result.sky_rms) > px.arcsec(100)
    assert result.standout_rows() == [row]
    assert any("absurd" in w for w in result.warnings())
    text = result.absurd_fit()
    assert f"observation {row + 1} (" in text and f"--mask {row + 1}" in text
    assert "wrong unit" not in text
    # Masking the row named gives a sane fit.
    weights = np.ones(len(run))
    weights[row] = 0.0
    assert float(px.fit(run.model(px.terms.tpoint("IA IE NPAE CA AN AW TF TX")), run, weights=weights).sky_rms) < px.arcsec(5)


def test_absurd_fit_of_wrong_units_still_says_units():
    run = px.io.read_tpoint(MMT_DAT, azimuth="S-E")
    obs = run.observations
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        wrong = px.Observations(np.degrees(np.asarray(obs.encoder)), obs.target, convention="S-E")
    with warnings.catch_warnings(record=True) as again:
        warnings.simplefilter("always")
        result = px.fit(px.AltAz(px.terms.tpoint("IA IE"), azimuth="S-E"), wrong)
        px.fit(px.AltAz(px.terms.tpoint("IA IE"), azimuth="S-E"), wrong, weights=np.ones(len(wrong)))
    # Warned of once, when the observations were made: the fit's padded and reweighted
    # copies are not checked again (they warned a second time, the padded copy counting
    # 249 of 256 values for 153 of 160).
    assert [str(w.message) for w in again if "look like degrees" in str(w.message)] == []
    assert "wrong unit" in result.absurd_fit() and result.standout_rows() == []


# ------------------------------------------------ --plot without matplotlib


def test_plot_without_matplotlib_prints_the_report_then_the_install_line(tmp_path):
    code = (
        "import sys; sys.modules['matplotlib'] = None\n"
        "from pointax.cli import main\n"
        f"sys.exit(main(['fit', {str(MMT_DAT)!r}, '--azimuth', 'S-E', '--plot', {str(tmp_path / 'p.png')!r}]))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=ENV, timeout=300)
    assert proc.returncode == 2, proc.stderr
    assert "Sky RMS =" in proc.stdout and "IA" in proc.stdout
    assert "pip install 'pointax[plot]'" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "p.png").exists()


# ------------------------------------------------ the same model file from CLI and API


def test_write_model_cli_and_api_give_the_same_file(tmp_path):
    cli = tmp_path / "cli.mod"
    assert main(["fit", str(MMT_DAT), "--azimuth", "S-E", "--write-model", str(cli)]) == 0
    run = px.io.read_tpoint(MMT_DAT, azimuth="S-E")
    result = px.fit(run.model(px.terms.tpoint(px.terms.BASIC_ALTAZ)), run)
    api = tmp_path / "api.mod"
    px.io.write_model(api, result, run=run)
    assert api.read_text() == cli.read_text()
    a, b = (float(x) for x in cli.read_text().splitlines()[1].split()[3:5])
    assert (a, b) == pytest.approx((42.06, -0.0485), abs=0.01)  # TPOINT's for this run
    with pytest.warns(UserWarning, match="refraction constants are written as 0"):
        px.io.write_model(tmp_path / "bare.mod", result)


# ------------------------------------------------ the report's listing says which azimuth


def test_report_listing_says_which_azimuth():
    pytest.importorskip("matplotlib")
    from pointax.plots.report import fit_report

    run = px.io.read_tpoint(MMT_DAT, azimuth="S-E")
    result = px.fit(run.model(px.terms.tpoint("IA IE NPAE CA AN AW TF TX")), run)
    page = fit_report(result, run.observations, run=run, figures=())
    assert "azimuth (deg, raw encoder, counted from South through East, as in the file)" in page
    raw = np.degrees(np.asarray(run.encoder))
    assert raw[:, 0].min() < 0  # the file's azimuths run negative: shown as written, not wrapped
    assert f"<td>{raw[0, 0]:.4f}</td>" in page
    assert "LOO RMS" in page


# ------------------------------------------------ plots of a failed fit say so


def test_plot_title_of_a_fit_that_did_not_converge():
    from pointax.plots.residuals import title_of

    run = px.io.read_tpoint(MMT_DAT, azimuth="S-E")
    result = px.fit(run.model(px.terms.tpoint("IA IE NPAE CA AN AW TF TX")), run, max_steps=1)
    assert not bool(result.converged)
    assert title_of(result).startswith("FIT NOT CONVERGED")
    good = px.fit(run.model(px.terms.tpoint("IA IE")), run)
    assert "NOT CONVERGED" not in title_of(good)


# ------------------------------------------------ turntable twins


def test_turntable_report_names_the_twin():
    from test_turntable import ALTITUDE, AZ_ENCODER, AZIMUTH, PITCH, sun_enu

    obs = px.Observations(np.deg2rad(np.stack([AZ_ENCODER, PITCH], axis=1)), sun_enu(ALTITUDE, AZIMUTH), convention="turntable")
    result = px.fit(px.Turntable("full"), obs)  # from zero: beta0 comes out near 345.9 deg
    report = result.report()
    assert "NOTE: an equivalent solution exists" in report
    beta0 = result.value("beta0")
    twin = (beta0 + 180.0) % 360.0
    assert f"beta0 = {twin:.4f} deg" in report
    # The twins named are exact: the same residuals.
    rms = float(result.sky_rms)
    values = {n: result.value(n) for n in result.names}
    for change in ({"beta0": twin}, {"alpha0": values["alpha0"] + 180, "beta0": twin, "omega0": 180 - values["omega0"]}):
        model = result.model.set(**{k: px.deg(v) for k, v in change.items()})
        r = np.asarray(px.residuals(model, obs))
        assert np.sqrt(np.mean(np.sum(r**2, axis=1))) == pytest.approx(rms, rel=1e-9)

"""pointax.fitting.statistics, the one module of every statistic pointax reports, and
every place that shows them: the fit, the model comparison, the listing, the plots'
data and the HTML report all give the same Sky RMS, Popn SD and sigmas.

Reference: an explicit NumPy computation (tests/tpoint_numpy.py, which imports nothing
of pointax): TPOINT's linear least squares of the eight basic terms on the bundled MMT
run in TPOINT's residual form, two rows masked, the Jacobian by central differences,
and TPOINT's formulas written out (Sky RMS = sqrt(sum |r|^2 / N), Popn SD = Sky RMS
sqrt(N / (N - M)), sigma = Sky RMS sqrt(diag (J^T J)^-1))."""

from __future__ import annotations

import math
import re

import jax.numpy as jnp
import numpy as np
import pytest
import tpoint_numpy as ref
from conftest import MMT_DAT

import pointax as px
from pointax.fitting.statistics import popn_sd, significance, sky_rms, statistics

EIGHT = "IA IE NPAE CA AN AW TF TX".split()
MASKED = (3, 7)  # 0-based rows given weight 0


@pytest.fixture(autouse=True)
def no_compilation_cache(monkeypatch):
    monkeypatch.setenv("POINTAX_JAX_CACHE", "")


@pytest.fixture(scope="module")
def numpy_fit():
    """(coefficients, residuals (n, 2), used, Sky RMS, Popn SD, sigmas), radians."""
    observed, raw, _ = ref.read_run(MMT_DAT)
    used = np.ones(len(observed), bool)
    used[list(MASKED)] = False
    coefs = ref.lstsq(EIGHT, observed, raw, used)
    r = ref.tpoint_residuals(EIGHT, coefs, observed, raw)

    def used_residuals(c):
        return ref.tpoint_residuals(EIGHT, c, observed, raw)[used].reshape(-1)

    h = 1e-7
    jac = np.stack([(used_residuals(coefs + h * e) - used_residuals(coefs - h * e)) / (2 * h) for e in np.eye(8)], -1)
    rms, popn, sigmas = ref.statistics(r, used, jac, len(EIGHT))
    before = ref.sky_residuals([], [], observed, raw)  # the bare mount: no terms
    return {"coefs": coefs, "r": r, "used": used, "rms": rms, "popn": popn, "sigmas": sigmas, "before": before}


@pytest.fixture(scope="module")
def mmt():
    run = px.io.read_tpoint(MMT_DAT, azimuth="S-E")
    weight = np.ones(len(run))
    weight[list(MASKED)] = 0.0
    obs = px.Observations(run.observations.encoder, run.observations.target, weight, run.observations.convention)
    model = px.AltAz(px.terms.tpoint(" ".join(EIGHT), form="linear"), azimuth="S-E", residual_form="tpoint")
    return run, obs, model, px.fit(model, obs)


def test_the_fit_against_numpy(numpy_fit, mmt):
    *_, result = mmt
    assert int(result.n_obs) == 78
    np.testing.assert_allclose(np.asarray(result.values), numpy_fit["coefs"], rtol=0, atol=1e-10 * ref.ARCSEC)
    np.testing.assert_allclose(float(result.sky_rms), numpy_fit["rms"], rtol=1e-10)
    np.testing.assert_allclose(float(result.popn_sd), numpy_fit["popn"], rtol=1e-10)
    np.testing.assert_allclose(np.asarray(result.sigmas), numpy_fit["sigmas"], rtol=1e-7)  # differenced Jacobian


def test_the_comparison_against_numpy(numpy_fit, mmt):
    _, obs, model, result = mmt
    c = px.compare({"eight": model}, obs)
    row = c["eight"]
    assert c.n_dropped == 2 and row.in_sample.n == 78
    np.testing.assert_allclose(row.sky_rms, numpy_fit["rms"], rtol=1e-10)
    np.testing.assert_allclose(row.sky_rms, float(result.sky_rms), rtol=1e-12)
    z = numpy_fit["coefs"] / numpy_fit["sigmas"]
    np.testing.assert_allclose([row.significance[n] for n in EIGHT], z, rtol=1e-7)
    # Before correction: TPOINT's Sky RMS of the raw readings against the stars.
    used = numpy_fit["used"]
    before = math.sqrt(np.sum(numpy_fit["before"][used] ** 2) / used.sum())
    np.testing.assert_allclose(c["before correction"].sky_rms, before, rtol=1e-9)


def test_the_report_listing_and_plot_data_show_the_fits_figures(numpy_fit, mmt):
    from pointax.analysis.listing import format_listing
    from pointax.plots.data import residual_data
    from pointax.plots.report import fit_report

    run, obs, _, result = mmt
    arcsec = ref.ARCSEC
    page = fit_report(result, obs, run=run, figures=())  # no figure: no matplotlib needed
    shown = dict(re.findall(r"<th class=\"name\">(Sky RMS|Popn SD) \(arcsec\)</th><td class=\"name\">([-+0-9.]+)<", page))
    assert float(shown["Sky RMS"]) == pytest.approx(numpy_fit["rms"] / arcsec, abs=6e-5)  # printed to 4 decimals
    assert float(shown["Popn SD"]) == pytest.approx(numpy_fit["popn"] / arcsec, abs=6e-5)
    masked = np.zeros(len(run), bool)
    masked[list(MASKED)] = True
    listing = format_listing(run, result, masked)
    (rms,) = re.findall(r"Sky RMS of the used observations = ([0-9.]+)", listing)
    assert float(rms) == pytest.approx(numpy_fit["rms"] / arcsec, abs=6e-5)
    data = residual_data(result, obs)
    assert data.sky_rms == float(result.sky_rms) / px.units.ARCSEC
    # Every row's residual in the fit's (TPOINT's) form, masked ones included.
    np.testing.assert_allclose(data.residuals, numpy_fit["r"] / arcsec, rtol=0, atol=1e-8)


def test_sky_rms_and_popn_sd_closed_forms():
    weighted = jnp.array([[3.0, 4.0], [jnp.nan, 7.0], [0.0, 0.0]])  # the unused row is left out, NaN or not
    used = jnp.array([True, False, True])
    rms = sky_rms(weighted, used)
    assert float(rms) == pytest.approx(math.sqrt(25.0 / 2))
    assert float(popn_sd(rms, 2, 1)) == pytest.approx(math.sqrt(25.0 / 2) * math.sqrt(2.0))
    assert math.isinf(float(popn_sd(rms, 2, 2)))
    s = statistics(jnp.where(used[:, None], weighted, 0.0), used, 1, jnp.eye(1))
    assert float(s.sky_rms) == float(rms) and float(s.popn_sd) == float(popn_sd(rms, 2, 1))
    assert float(s.sigmas[0]) == pytest.approx(float(rms))  # (J^T J)^-1 = 1
    np.testing.assert_array_equal(significance([2.0, 1.0, 3.0], [0.5, np.inf, 0.0]), [4.0, 0.0, 0.0])

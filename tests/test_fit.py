"""Fitting: statistics, fixed parameters, weights, failures and their reports.

References: closed-form linear least squares (numpy) on simulated data, duplicate-row
equivalence for weights, and known degeneracies (ECEC is -TF by definition).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import pointax as px
from pointax.core.simulate import encoder_grid

ARCSEC = np.pi / 648000
TRUE = {"IA": 40.0, "IE": -12.0, "NPAE": 5.0, "CA": -8.0, "AN": 3.0, "AW": -6.0, "TF": 9.0}


def _truth(form="rigorous"):
    return px.AltAz(px.terms.tpoint(list(TRUE), form=form, values={k: v * ARCSEC for k, v in TRUE.items()}))


@pytest.fixture(scope="module")
def simulated():
    encoder = encoder_grid(12, (15, 30, 45, 60, 75))
    return px.simulate(_truth(), encoder, noise=1.0 * ARCSEC, seed=3)


@pytest.fixture(scope="module")
def basic_fit(simulated):
    return px.fit(px.AltAz(px.terms.tpoint(list(TRUE))), simulated)


def _design(obs, names):
    """TPOINT's linear design matrix at the observed positions (cross-el, el)."""
    az, el = np.asarray(px.rotations.enu_to_azel(jnp.asarray(obs.target)))
    s, c, t = np.sin, np.cos, np.tan
    basis = {
        "IA": (-np.ones_like(az), 0 * az),
        "IE": (0 * az, np.ones_like(az)),
        "NPAE": (-t(el), 0 * az),
        "CA": (-1 / c(el), 0 * az),
        "AN": (-s(az) * t(el), -c(az)),
        "AW": (-c(az) * t(el), s(az)),
        "TF": (0 * az, -c(el)),
    }
    J = np.array([np.concatenate([basis[n][0] * c(el), basis[n][1]]) for n in names]).T
    d_az = (az - obs.encoder[:, 0] + np.pi) % (2 * np.pi) - np.pi
    y = np.concatenate([d_az * c(el), el - obs.encoder[:, 1]])
    return J, y


def test_fit_recovers_truth_and_matches_linear_least_squares(simulated, basic_fit):
    r = basic_fit
    assert r.converged
    J, y = _design(simulated, list(TRUE))
    x, *_ = np.linalg.lstsq(J, y, rcond=None)
    np.testing.assert_allclose(np.asarray(r.values) / ARCSEC, x / ARCSEC, atol=0.01)
    for name, value in TRUE.items():
        assert abs(r.value(name) - value) < 4 * r.sigma(name), name
    n, m = 60, 7
    res = np.asarray(r.residuals)
    rms = np.sqrt(np.sum(res**2) / n)
    assert float(r.sky_rms) == pytest.approx(rms, rel=1e-12)
    assert float(r.popn_sd) == pytest.approx(rms * np.sqrt(n / (n - m)), rel=1e-12)
    # The noise was 1" per axis, so the Sky RMS (both axes) is near sqrt(2)".
    assert 1.1 < float(r.sky_rms) / ARCSEC < 1.7
    cov = rms**2 * np.linalg.inv(J.T @ J)
    np.testing.assert_allclose(np.asarray(r.sigmas), np.sqrt(np.diag(cov)), rtol=2e-3)
    corr = np.asarray(r.correlation)
    np.testing.assert_allclose(np.diag(corr), 1.0, atol=1e-12)
    np.testing.assert_allclose(corr, corr.T, atol=1e-12)
    np.testing.assert_allclose(corr, cov / np.outer(np.sqrt(np.diag(cov)), np.sqrt(np.diag(cov))), atol=2e-3)


def test_residuals_are_observed_minus_model(simulated, basic_fit):
    """A residual's sign: moving the targets by +d in elevation adds +d to it."""
    shifted = px.Observations(
        simulated.encoder,
        px.rotations.offset_direction(jnp.asarray(simulated.target), jnp.array([0.0, 5 * ARCSEC])),
        convention=simulated.convention,
    )
    before = np.asarray(px.residuals(basic_fit.model, simulated))
    after = np.asarray(px.residuals(basic_fit.model, shifted))
    np.testing.assert_allclose(after[:, 1] - before[:, 1], 5 * ARCSEC, rtol=1e-6)


def test_fixed_parameter_stays_and_others_refit(simulated):
    model = px.AltAz(px.terms.tpoint(list(TRUE)), fixed=["IA"]).set(IA=TRUE["IA"] * ARCSEC)
    r = px.fit(model, simulated)
    assert "IA" not in r.names and len(r.names) == 6
    assert float(r.model.get("IA")) == TRUE["IA"] * ARCSEC
    # Reference: least squares with the IA column moved to the data side.
    names = [n for n in TRUE if n != "IA"]
    J, y = _design(simulated, list(TRUE))
    x, *_ = np.linalg.lstsq(J[:, 1:], y - J[:, 0] * TRUE["IA"] * ARCSEC, rcond=None)
    np.testing.assert_allclose(np.asarray(r.values) / ARCSEC, x / ARCSEC, atol=0.01)
    assert "fixed" in r.report() and r.to_dict()["fixed"] == {"IA": pytest.approx(TRUE["IA"])}
    again = px.fit(px.AltAz(px.terms.tpoint(list(TRUE))).set(IA=TRUE["IA"] * ARCSEC), simulated, fixed=("IA",))
    np.testing.assert_allclose(np.asarray(again.values), np.asarray(r.values), atol=1e-14)
    assert names == list(r.names)


def test_integer_weights_equal_duplicated_observations(simulated):
    model = px.AltAz(px.terms.tpoint(list(TRUE)))
    w = np.ones(len(simulated))
    w[:10] = 3.0
    weighted = px.fit(model, simulated, weights=w)
    idx = np.concatenate([np.arange(len(simulated)), np.repeat(np.arange(10), 2)])
    duplicated = px.fit(model, simulated[idx])
    np.testing.assert_allclose(np.asarray(weighted.values), np.asarray(duplicated.values), atol=1e-13)


def test_zero_weight_equals_dropping_and_may_hide_nan(simulated):
    model = px.AltAz(px.terms.tpoint(list(TRUE)))
    encoder = np.array(simulated.encoder)
    encoder[5] = np.nan
    poisoned = px.Observations(encoder, simulated.target, convention=simulated.convention)
    w = np.ones(len(simulated))
    w[5] = 0.0
    r = px.fit(model, poisoned, weights=w)
    keep = np.arange(len(simulated)) != 5
    reference = px.fit(model, simulated[keep])
    assert r.converged and int(r.n_obs) == 59
    np.testing.assert_allclose(np.asarray(r.values), np.asarray(reference.values), atol=1e-13)
    assert float(r.sky_rms) == pytest.approx(float(reference.sky_rms), rel=1e-12)
    np.testing.assert_array_equal(np.asarray(r.residuals)[5], 0.0)


def test_nan_observation_is_reported_not_hidden(simulated):
    encoder = np.array(simulated.encoder)
    encoder[7, 1] = np.nan
    bad = px.Observations(encoder, simulated.target, convention=simulated.convention)
    r = px.fit(px.AltAz(px.terms.tpoint(list(TRUE))), bad)
    assert not r.converged
    assert "not finite" in r.message
    assert "NOT CONVERGED" in r.report() and "WARNING: the fit did not converge" in r.report()


def test_step_limit_reports_non_convergence(simulated):
    start = px.AltAz(px.terms.tpoint("IA IE", form="rigorous"))
    r = px.fit(start, simulated, max_steps=1)
    assert not r.converged and int(r.iterations) == 1
    assert "maximum number of steps" in r.message or "max" in r.message.lower()
    assert r.to_dict()["converged"] is False


def test_degenerate_parameters_are_named(simulated):
    """ECEC is -TF by definition in the linear form: the data cannot separate them (in
    the rigorous form ECEC is read at the raw elevation, TF at the sky one)."""
    model = px.AltAz(px.terms.tpoint("IA IE TF ECEC", form="linear"))
    r = px.fit(model, simulated)
    assert list(np.asarray(r.degenerate)) == [False, False, True, True]
    assert np.isinf(r.sigma("TF")) and np.isinf(r.sigma("ECEC"))
    text = r.report()
    assert "cannot tell these parameters apart" in text and "TF, ECEC" in text
    assert r.to_dict()["terms"][2]["sigma_arcsec"] is None


def test_strong_correlation_warning(simulated):
    r = px.fit(px.AltAz(px.terms.tpoint("IA IE NPAE CA")), simulated)
    pairs = {(a, b) for a, b, _ in r.correlated_pairs()}
    corr = np.asarray(r.correlation)
    names = list(r.names)
    expected = {
        (names[i], names[j]) for i in range(4) for j in range(i + 1, 4) if abs(corr[i, j]) > 0.95
    }
    assert pairs == expected and pairs  # NPAE and CA always are, on a sky like this
    for a, b in pairs:
        assert f"{a} and {b} are strongly correlated" in r.report()


def test_errors_are_clear(simulated):
    model = px.AltAz(px.terms.tpoint("IA"))
    with pytest.raises(ValueError, match="unknown solver"):
        px.fit(model, simulated, solver="newton")
    with pytest.raises(ValueError, match="weights must have shape"):
        px.fit(model, simulated, weights=np.ones(3))
    with pytest.raises(ValueError, match="non-negative"):
        px.fit(model, simulated, weights=-np.ones(len(simulated)))
    with pytest.raises(ValueError, match="no observation has a positive weight"):
        px.fit(model, simulated, weights=np.zeros(len(simulated)))
    with pytest.raises(TypeError, match="expected pointax.Observations"):
        px.fit(model, np.zeros((3, 2)))
    mirrored = px.Observations(simulated.encoder, simulated.target, convention="S-E")
    with pytest.raises(ValueError, match="'S-E' convention but the model's mount expects 'N-E'"):
        px.fit(model, mirrored)
    with pytest.raises(ValueError, match="cannot fix unknown parameters"):
        px.fit(model, simulated, fixed=("IE",))


def test_fit_is_traceable_under_vmap(simulated):
    """The core fit is pure JAX: vmap over two data sets gives the two solo fits."""
    from pointax.fitting import FitOptions, fit_model

    model = px.AltAz(px.terms.tpoint(list(TRUE)))
    model = model.with_values(model.values())
    other = px.simulate(_truth(), np.asarray(simulated.encoder), noise=1.0 * ARCSEC, seed=4)
    stack = jax.tree.map(lambda a, b: jnp.stack([jnp.asarray(a), jnp.asarray(b)]), simulated, other)
    options = FitOptions("gauss-newton", 50, 1e-10, 1e-13)
    batched = jax.jit(jax.vmap(lambda o: fit_model(model, o, options)))(stack)  # one program, not op by op
    for k, obs in enumerate([simulated, other]):
        solo = px.fit(model, obs, solver="gauss-newton", max_steps=50)
        np.testing.assert_allclose(np.asarray(batched.values[k]), np.asarray(solo.values), atol=1e-12)

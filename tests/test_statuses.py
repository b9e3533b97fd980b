"""Honest statuses: the same verdict for a site alone, padded or batched; encoder zeros
reported in their range; equivalent solutions in another branch flagged. References:
the counting rule (2 residuals per observation against the free parameters), the
turntable's exact twin (alpha0 + 180 deg, beta0 - 180 deg, omega0 -> 180 deg - omega0,
checked here on the model's own directions) and 2 pi periodicity."""

from __future__ import annotations

import numpy as np
import pytest

import pointax as px
from pointax.fitting.ranges import out_of_range, range_warning, wrap_periodic

TPOINT8 = "IA IE NPAE CA AN AW TF TX"
PAPER = dict(mu0=px.deg(0.0751), nu0=px.deg(0.0145), omega0=px.deg(-0.0947), alpha0=px.deg(60.5425), beta0=px.deg(165.8931))
RNG = np.random.default_rng(5)


def _turntable_run(n=30):
    """30 sun positions with 30" of noise (a run on which a fit started 150 deg from the
    azimuth zero ends at the twin)."""
    alpha = np.random.default_rng(0).uniform(0, 6.28, n)
    beta = px.deg(165.9) + np.random.default_rng(1).uniform(0.1, 1.3, n)
    return px.simulate(px.Turntable("full").set(**PAPER), np.stack([alpha, beta], 1), noise=px.arcsec(30), seed=2)


def test_too_few_observations_get_one_verdict_alone_padded_and_batched():
    truth = px.AltAz(px.terms.tpoint(TPOINT8, values={"IA": px.arcsec(30)}))
    model = px.AltAz(px.terms.tpoint(TPOINT8))
    few = px.simulate(truth, np.array([[1.0, 0.7], [2.0, 0.9], [3.0, 1.1]]), noise=px.arcsec(1), seed=1)  # 6 residuals, 8 parameters
    enough = px.simulate(truth, np.stack([RNG.uniform(0, 6.28, 20), RNG.uniform(0.3, 1.4, 20)], 1), noise=px.arcsec(1), seed=1)
    with pytest.raises(ValueError, match="3 observation.*6 residuals for 8 free parameters") as alone:
        px.fit(model, few)
    # One batch (one compilation): alone-and-padded, beside a clean site, 4 and 5 observations.
    sites = [few, enough, few, _take(enough, 4), _take(enough, 5)]
    statuses = px.site_statuses(px.fit_batch(model, px.stack_observations(sites, n_obs=20)))
    assert statuses[0] == statuses[2] == {"status": "failed", "reason": str(alone.value)}
    assert statuses[1]["status"] == "converged"
    # Four observations (8 residuals) for 8 parameters are still refused; five are not.
    assert statuses[3]["status"] == "failed" and "8 residuals for 8" in statuses[3]["reason"]
    assert statuses[4]["status"] != "failed"


def _take(obs, n):
    return px.Observations(np.asarray(obs.encoder)[:n], np.asarray(obs.target)[:n], convention=obs.convention)


def test_turntable_twin_is_the_same_model():
    """The exact twin that a fit started far from the encoder zeros can reach."""
    enc = np.stack([RNG.uniform(0, 2 * np.pi, 40), px.deg(165.9) + RNG.uniform(0.1, 1.3, 40)], axis=1)
    twin = dict(PAPER, alpha0=PAPER["alpha0"] + np.pi, beta0=PAPER["beta0"] - np.pi, omega0=np.pi - PAPER["omega0"])
    a = np.asarray(px.simulate(px.Turntable("full").set(**PAPER), enc).target)
    b = np.asarray(px.simulate(px.Turntable("full").set(**twin), enc).target)
    assert np.max(np.abs(a - b)) < 1e-14
    params = px.Turntable("full").free_parameters
    names = [p.name for p in params]
    assert [names[k] for k in out_of_range([twin[n] for n in names], params)] == ["omega0"]
    assert out_of_range([PAPER[n] for n in names], params) == []


def test_fit_far_from_the_zeros_is_wrapped_and_flagged():
    obs = _turntable_run()
    start = px.Turntable("full").set(**dict(PAPER, alpha0=PAPER["alpha0"] + px.deg(150)))
    result = px.fit(start, obs)
    assert bool(result.converged)
    values = dict(zip(result.names, np.asarray(result.values)))
    # Encoder zeros come back within [0, 360) deg, the model with them.
    for name in ("alpha0", "beta0"):
        assert 0 <= values[name] < 2 * np.pi
        assert float(result.model.get(name)) == values[name]
    # This start ends at the twin: omega0 near 180 deg, flagged.
    assert abs(values["omega0"]) > px.deg(170)
    assert any("outside the expected range: omega0" in w for w in result.warnings())
    assert "outside the expected range" in result.report()
    # Same residuals as the unwrapped values (periodicity), to rounding. A bare number
    # beyond a turn is refused as likely degrees; a stated unit is trusted.
    import astropy.units as u

    unwrapped = result.model.set(alpha0=(values["alpha0"] + 4 * np.pi) * u.rad)
    np.testing.assert_allclose(np.asarray(px.residuals(unwrapped, obs)), np.asarray(result.residuals), atol=1e-12)


def test_batch_reports_the_twin_in_its_reason():
    obs = _turntable_run()
    twin = dict(PAPER, alpha0=PAPER["alpha0"] + np.pi + 2 * np.pi, beta0=PAPER["beta0"] - np.pi, omega0=np.pi - PAPER["omega0"])
    model = px.Turntable("full")
    starts = np.array([[PAPER[p.name] for p in model.free_parameters], [twin[p.name] for p in model.free_parameters]])
    result = px.fit_batch(model, px.stack_observations([obs, obs]), values=starts)
    statuses = px.site_statuses(result)
    assert [s["status"] for s in statuses] == ["converged", "converged"]
    assert statuses[0]["reason"] == ""
    assert "omega0" in statuses[1]["reason"] and "another branch" in statuses[1]["reason"]
    alpha = np.asarray(result.values)[:, [p.name for p in model.free_parameters].index("alpha0")]
    assert np.all((alpha >= 0) & (alpha < 2 * np.pi))
    # Both sites fit the same data equally well: the twin is the same model.
    np.testing.assert_allclose(float(result.sky_rms[0]), float(result.sky_rms[1]), rtol=1e-9)


def test_wrap_periodic_leaves_results_without_periodic_parameters_alone():
    model = px.AltAz(px.terms.tpoint("IA IE"))
    obs = px.simulate(model.set(IA=px.arcsec(10)), np.stack([RNG.uniform(0, 6, 10), RNG.uniform(0.3, 1.2, 10)], 1), seed=1)
    result = px.fit(model, obs)
    assert wrap_periodic(result) is result
    assert range_warning(np.asarray(result.values), result.model.free_parameters) == ""

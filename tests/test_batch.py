"""Batched fits of many sites: ragged padding, per-site status, isolation of bad sites."""

from __future__ import annotations

import numpy as np
import pytest
from compile_counter import traces

import pointax as px
from pointax.terms.sun_vector import estimate_zeros


def _site(seed: int, n: int):
    """One simulated turntable site: its own geometry, n sun observations."""
    rng = np.random.default_rng(seed)
    truth = px.Turntable("full").set(
        mu0=px.deg(rng.normal(0, 0.05)),
        nu0=px.deg(rng.normal(0, 0.05)),
        omega0=px.deg(rng.normal(0, 0.1)),
        alpha0=rng.uniform(0, 2 * np.pi),
        beta0=px.deg(165 + rng.normal(0, 3)),
    )
    encoder = np.stack(
        [rng.uniform(0, 2 * np.pi, n), float(truth.get("beta0")) + np.radians(rng.uniform(15, 70, n))], axis=1
    )
    return px.simulate(truth, encoder, noise=px.deg(0.01), seed=seed)


def _padded(obs, n):
    m = len(obs)
    encoder = np.concatenate([np.asarray(obs.encoder), np.repeat(np.asarray(obs.encoder)[:1], n - m, axis=0)])
    target = np.concatenate([np.asarray(obs.target), np.repeat(np.asarray(obs.target)[:1], n - m, axis=0)])
    weight = np.concatenate([np.asarray(obs.weight), np.zeros(n - m)])
    return px.Observations(encoder, target, weight, obs.convention)


def _start(obs):
    use = np.asarray(obs.weight) > 0
    return [0.0, 0.0, 0.0, *estimate_zeros(np.asarray(obs.encoder)[use], np.asarray(obs.target)[use])]


@pytest.fixture(scope="module")
def network():
    """Six clean ragged sites and three poisoned ones."""
    clean = {k: _site(k, n) for k, n in zip(range(6), (60, 45, 52, 60, 38, 60))}
    nan_rows = _site(100, 60)
    encoder = np.array(nan_rows.encoder)
    encoder[[3, 17]] = np.nan  # used rows holding NaN
    nan_rows = px.Observations(encoder, nan_rows.target, convention="turntable")
    one_azimuth = _site(101, 60)
    encoder = np.array(one_azimuth.encoder)
    encoder[:, 0] = 1.234  # every observation at one azimuth
    one_azimuth = px.simulate(px.Turntable("full").set(alpha0=1.0, beta0=px.deg(165)), encoder, seed=3)
    wild = _site(102, 60)
    target = np.array(wild.target)
    target[::2] = -target[::2]  # half the targets on the far side of the sky
    wild = px.Observations(wild.encoder, target, convention="turntable")
    order = [clean[0], nan_rows, clean[1], clean[2], one_azimuth, clean[3], wild, clean[4], clean[5]]
    clean_rows = [0, 2, 3, 5, 7, 8]
    return order, clean_rows


@pytest.fixture(scope="module")
def batch_result(network):
    sites, _ = network
    batch = px.stack_observations(sites)
    values = np.array([_start(s) for s in sites])
    return px.fit_batch(px.Turntable("full"), batch, values=values)


def test_clean_sites_equal_their_solo_fits(network, batch_result):
    sites, clean_rows = network
    for k in clean_rows:
        solo_model = px.Turntable("full").with_values(np.array(_start(sites[k])))
        # Padded to 60 rows with weight 0 (ignored by the fit): one compilation for all.
        solo = px.fit(solo_model, _padded(sites[k], 60))
        assert bool(solo.converged)
        assert bool(batch_result.converged[k])
        np.testing.assert_allclose(np.asarray(batch_result.values[k]), np.asarray(solo.values), rtol=0, atol=1e-10)
        np.testing.assert_allclose(np.asarray(batch_result.sigmas[k]), np.asarray(solo.sigmas), rtol=1e-8)
        assert int(batch_result.n_obs[k]) == len(sites[k])
        assert float(batch_result.sky_rms[k]) == pytest.approx(float(solo.sky_rms), rel=1e-9)


def test_clean_sites_take_the_fast_path(network, batch_result):
    """Clean sites converge within the fixed Gauss-Newton steps (no fallback loop)."""
    _, clean_rows = network
    assert all(int(batch_result.iterations[k]) == 5 for k in clean_rows)
    assert int(batch_result.iterations[6]) > 5  # the wild site went on to the full loop


def test_poisoned_sites_are_flagged(batch_result):
    converged = np.asarray(batch_result.converged)
    nan_site = px.site_result(batch_result, 1)
    assert not converged[1]
    assert "not finite" in nan_site.message
    # One azimuth: the tilts, omega0 and beta0 cannot be told apart; the fit says so.
    one_azimuth = px.site_result(batch_result, 4)
    assert {"mu0", "nu0", "omega0"} <= {n for n, d in zip(one_azimuth.names, np.asarray(one_azimuth.degenerate)) if d}
    # Wild targets (half of them on the far side of the sky): not converged, and why.
    assert not converged[6]
    assert "maximum number of steps" in px.site_result(batch_result, 6).message
    statuses = px.site_statuses(batch_result)
    assert [s["status"] for s in statuses] == [
        "converged", "failed", "converged", "converged", "degenerate", "converged", "failed", "converged", "converged"
    ]
    assert "not finite" in statuses[1]["reason"] and "mu0" in statuses[4]["reason"]


def test_site_result_gives_a_report(batch_result):
    text = px.site_result(batch_result, 0).report()
    assert "mu0" in text and "converged" in text


def test_chunks_equal_one_call(network, batch_result):
    sites, _ = network
    batch = px.stack_observations(sites)
    values = np.array([_start(s) for s in sites])
    seen = []
    chunked = px.fit_batch(px.Turntable("full"), batch, values=values, chunk_size=4, progress=lambda d, t: seen.append((d, t)))
    assert seen == [(4, 9), (8, 9), (9, 9)]
    np.testing.assert_array_equal(np.asarray(chunked.converged), np.asarray(batch_result.converged))
    ok = np.asarray(batch_result.converged)
    np.testing.assert_allclose(np.asarray(chunked.values)[ok], np.asarray(batch_result.values)[ok], rtol=0, atol=1e-12)


def test_stack_and_argument_errors():
    a, b = _site(1, 10), _site(2, 12)
    batch = px.stack_observations([a, b])
    assert batch.encoder.shape == (2, 12, 2)
    assert np.asarray(batch.weight)[0, 10:].sum() == 0
    with pytest.raises(ValueError, match="no sites"):
        px.stack_observations([])
    with pytest.raises(ValueError, match="shorter than the longest"):
        px.stack_observations([a, b], n_obs=11)
    with pytest.raises(ValueError, match="mix encoder conventions"):
        px.stack_observations([a, px.Observations(a.encoder, a.target, convention="N-E")])
    with pytest.raises(ValueError, match="values must have shape"):
        px.fit_batch(px.Turntable("full"), batch, values=np.zeros((3, 5)))
    with pytest.raises(ValueError, match="stack_observations"):
        px.fit_batch(px.Turntable("full"), a)


def test_small_batches_share_one_compilation(network):
    """Batches smaller than a chunk are padded to a power of two: 9 and 13 sites (both
    16) reuse one compiled fit, and the padding changes no result."""
    sites, _ = network
    model = px.Turntable("full")
    values = np.array([_start(s) for s in sites])
    more = sites + sites[:4]
    with traces() as seen:
        nine = px.fit_batch(model, px.stack_observations(sites, n_obs=60), values=values)
        thirteen = px.fit_batch(model, px.stack_observations(more, n_obs=60), values=np.concatenate([values, values[:4]]))
    # At most one trace of the fit's program (the site data and the steps are one call;
    # an earlier test of this file may have compiled it for 16 sites already; the name
    # is checked in tests/test_network_speed.py).
    assert seen.count("_site_data_and_fits") <= 1 and "fixed_steps_fits" not in seen, seen
    np.testing.assert_array_equal(np.asarray(thirteen.values[:9]), np.asarray(nine.values))
    np.testing.assert_array_equal(np.asarray(thirteen.values[9:]), np.asarray(nine.values[:4]))

"""Compile once per model, not once per observation count: ``px.simulate`` and
``px.fit_batch`` pad the observation axis to a few bucketed sizes (weight 0), with
results equal to the unpadded ones; a compilation is named on the progress bar.

Compilations are counted from JAX's own monitoring events (a trace per new program), not
from pointax's bookkeeping; each test uses a model structure of its own, so that what it
counts is its own first call."""

from __future__ import annotations

import io

import numpy as np
import pytest
import tpoint_numpy as ref
from compile_counter import traces

import pointax as px
from pointax.fitting.batch import COMPILING, _chunk_plan, observation_bucket
from pointax.fitting.progress import progress_bar
from pointax.terms import tpoint

_FIT_PROGRAMS = {"site_data", "fixed_steps_fits", "_site_data_and_fits"}


def _encoder(rng, n):
    return np.stack([rng.uniform(0, 2 * np.pi, n), rng.uniform(np.radians(15), np.radians(80), n)], axis=1)


def _network(spec: str, sizes, seed=0):
    """Sites of an alt-az mount, TPOINT's terms in their linear forms fitted in TPOINT's
    residual form (affine in the parameters), each with its own true values and
    ``sizes[k]`` observations."""
    rng = np.random.default_rng(seed)
    model = px.AltAz(tpoint(spec, form="linear"), residual_form="tpoint")
    sites = []
    for k, n in enumerate(sizes):
        truth = model.with_values(rng.normal(0, px.arcsec(60), len(model.free_parameters)), "free")
        sites.append(px.simulate(truth, _encoder(rng, n), noise=px.arcsec(1), seed=k))
    return model, sites


def _dense_fit(spec: str, obs) -> np.ndarray:
    """The least-squares solution of one site on its own rows (no padding, no fast
    pass): NumPy's ``lstsq`` of TPOINT's design matrix (tests/tpoint_numpy.py), the
    terms' linear forms fitted in TPOINT's residual form being affine."""
    t = np.asarray(obs.target)
    observed = np.stack([np.arctan2(t[:, 0], t[:, 1]), np.arcsin(t[:, 2])], axis=-1)  # N-E azimuth
    return ref.lstsq(spec.split(), observed, np.asarray(obs.encoder), np.ones(len(obs), bool))


def test_observation_buckets():
    assert [observation_bucket(n) for n in (0, 1, 8, 9, 30, 32, 33, 63, 64, 65, 80, 81)] == [
        8, 8, 8, 9, 30, 32, 36, 64, 64, 72, 80, 88,
    ]  # fmt: skip
    sizes = set()
    for n in range(1, 3000):
        b = observation_bucket(n)
        sizes.add(b)
        assert n <= b <= max(8, 1.125 * n)  # at most an eighth of the rows padding
    assert len(sizes) <= 8 * 9  # eight sizes per doubling


def test_simulate_compiles_once_for_50_sites_of_30_to_80_observations():
    rng = np.random.default_rng(5)
    truth = px.Turntable("full").set(mu0=px.deg(0.03), omega0=px.deg(-0.05), alpha0=1.2, beta0=px.deg(160)).fix("nu0")
    with traces() as seen:
        runs = []
        for k in range(50):
            n = int(rng.integers(30, 81))
            encoder = np.stack([rng.uniform(0, 2 * np.pi, n), px.deg(160) + np.radians(rng.uniform(15, 70, n))], axis=1)
            runs.append((encoder, px.simulate(truth, encoder, noise=px.arcsec(20), seed=k)))
    assert seen.count("_noisy_directions") == 1, seen
    # The noisy targets lie at the drawn gnomonic offsets from the true directions
    # (reference: the model evaluated row by row, and the offsets' length in NumPy).
    for k, (encoder, obs) in enumerate(runs[:5]):
        offsets = np.random.default_rng(k).normal(size=(len(encoder), 2)) * px.arcsec(20)
        truth_dirs = np.stack([np.asarray(truth.direction(e)) for e in encoder])
        target = np.asarray(obs.target)
        angle = np.arctan2(np.linalg.norm(np.cross(truth_dirs, target), axis=1), np.sum(truth_dirs * target, axis=1))
        np.testing.assert_allclose(angle, np.arctan(np.hypot(*offsets.T)), rtol=1e-9, atol=1e-15)
        assert len(obs) == len(encoder)


def test_fit_batch_compiles_once_for_sizes_30_to_80_and_equals_the_dense_fits():
    rng = np.random.default_rng(7)
    sizes = [int(n) for n in rng.integers(30, 81, 50)]
    spec = "IA IE CA NPAE AN AW TF"
    model, sites = _network(spec, sizes)
    with traces() as seen:
        result = px.fit_batch(model, px.stack_observations(sites))
    fitted = [name for name in seen if name in _FIT_PROGRAMS]
    assert len(fitted) == len(set(fitted)) >= 1, seen  # each program traced once
    assert np.all(np.asarray(result.converged))
    assert np.asarray(result.residuals).shape == (50, max(sizes), 2)
    values = np.asarray(result.values)
    for k in range(0, 50, 7):
        reference = _dense_fit(spec, sites[k])
        np.testing.assert_allclose(values[k], reference, rtol=0, atol=1e-12 * np.max(np.abs(reference)) + 1e-15)
        assert int(result.n_obs[k]) == sizes[k]


def test_sites_grouped_by_size_come_back_in_order_and_equal():
    """Chunks of short sites run at fewer rows; the result equals the one-chunk fit
    (every site padded to the longest), field by field."""
    sizes = [12 if k % 2 else 64 for k in range(40)]
    model, sites = _network("IA IE CA AN AW", sizes, seed=3)
    batch = px.stack_observations(sites)
    assert batch.encoder.shape[1] == observation_bucket(64) == 64  # stacked to a bucketed length
    plan = _chunk_plan(np.asarray(sizes), 8, batch.encoder.shape[1])
    assert sorted({rows for _, rows in plan}) == [16, 64]
    assert sorted(np.concatenate([index for index, _ in plan]).tolist()) == list(range(40))
    grouped = px.fit_batch(model, batch, chunk_size=8)
    whole = px.fit_batch(model, batch, chunk_size=None)
    # (atol 1e-15 rad, 2e-10 arcsec: a value near zero may differ in its last bits)
    np.testing.assert_allclose(np.asarray(grouped.values), np.asarray(whole.values), rtol=1e-12, atol=1e-15)
    # Statistics: sums over a different number of zero rows round differently (a short
    # site's conditioning multiplies it).
    for field in ("sigmas", "covariance", "sky_rms", "popn_sd"):
        a, b = np.asarray(getattr(grouped, field)), np.asarray(getattr(whole, field))
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-300, err_msg=field)
    for field in ("residuals", "used", "outliers", "loo_residuals", "n_obs", "converged", "iterations"):
        a, b = np.asarray(getattr(grouped, field)), np.asarray(getattr(whole, field))
        assert a.shape == b.shape, field
        np.testing.assert_allclose(a.astype(float), b.astype(float), rtol=1e-9, atol=1e-15, err_msg=field)


class Terminal(io.StringIO):
    def isatty(self):
        return True


@pytest.mark.parametrize("terminal", [True, False])
def test_the_first_call_says_it_is_compiling(terminal):
    model, sites = _network("IA IE CA NPAE AW" if terminal else "IA IE CA NPAE AN", [20, 25, 31])
    stream = Terminal() if terminal else io.StringIO()
    with progress_bar(3, "fitting", "site", enabled=True, stream=stream) as bar:
        px.fit_batch(model, px.stack_observations(sites), progress=bar)
    text = stream.getvalue()
    assert (COMPILING in text) == terminal
    assert ("3/3" in text) == terminal

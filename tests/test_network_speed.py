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
    plan = _chunk_plan(batch.weight, 8, batch.encoder.shape[1])
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


def _reference_plan(lengths: np.ndarray, size: int, top: int) -> list[tuple[list[int], int]]:
    """The chunk plan by its definition, from every site's length: rows per site the
    smallest of top, top/2, top/4, ... (down to 8) that holds it; a level with fewer than
    two chunks of sites joins the next larger; chunks in order of length within a level."""
    n = len(lengths)
    if n <= size:
        return [(list(range(n)), top)]
    levels = [top]
    while levels[-1] % 2 == 0 and levels[-1] // 2 >= 8:
        levels.append(levels[-1] // 2)
    rows = [min(level for level in levels if level >= length) for length in lengths]
    for level in sorted(levels)[:-1]:
        if rows.count(level) < 2 * size:
            rows = [levels[levels.index(level) - 1] if r == level else r for r in rows]
    order = sorted(range(n), key=lambda k: (lengths[k], k))
    plan = []
    for level in sorted(set(rows)):
        members = [k for k in order if rows[k] == level] if len(set(rows)) > 1 else list(range(n))
        plan += [(members[start : start + size], level) for start in range(0, len(members), size)]
    return plan


@pytest.mark.parametrize("seed", range(12))
def test_the_chunk_plan_follows_its_definition(seed):
    """:func:`_chunk_plan` (a quick test for batches of one size, then the sites'
    lengths) against the plan written out from every site's length, on random networks
    of long and short sites."""
    rng = np.random.default_rng(seed)
    n_sites, size, top = int(rng.integers(1, 120)), int(rng.choice([4, 8, 16])), int(rng.choice([12, 16, 64, 96]))
    short = rng.random(n_sites) < rng.random()
    lengths = np.where(short, rng.integers(1, max(top // 4, 2), n_sites), rng.integers(top // 2, top + 1, n_sites))
    weight = (np.arange(top) < lengths[:, None]).astype(float)
    weight[:, 0] = np.where(rng.random(n_sites) < 0.1, 0.0, weight[:, 0])  # some first rows unused
    used_to = [max([j + 1 for j in range(top) if weight[k, j] > 0], default=0) for k in range(n_sites)]
    plan = [(index.tolist(), rows) for index, rows in _chunk_plan(weight, size, top)]
    assert plan == _reference_plan(used_to, size, top)


def test_the_host_hands_chunks_over_without_extra_work(monkeypatch):
    """fit_batch's Python between chunks takes a core from the fits running beside it
    (benchmarks/batch_fit_notes.md), so it stays small, counted here: the chunks go to
    the compiled fast pass as NumPy arrays (no ``jax.device_put`` per chunk), the
    first-call check runs once per chunk shape, and a batch of one size never computes
    its sites' lengths."""
    import jax

    from pointax.fitting import batch, batch_fast_pass

    model, sites = _network("IA IE CA", [30] * 40, seed=5)
    stacked = px.stack_observations(sites)
    counts = {"device_put": 0, "first_call": 0, "lengths": 0}
    handed = []

    def counting(name, fn):
        def wrapped(*args, **kwargs):
            counts[name] += 1
            return fn(*args, **kwargs)

        return wrapped

    monkeypatch.setattr(jax, "device_put", counting("device_put", jax.device_put))
    monkeypatch.setattr(batch_fast_pass, "first_call", counting("first_call", batch_fast_pass.first_call))
    monkeypatch.setattr(batch, "_site_lengths", counting("lengths", batch._site_lengths))
    real_call = batch_fast_pass.FastPass.__call__

    def recording(self, values, obs, notice=None):
        handed.extend(jax.tree.leaves((values, obs)))
        return real_call(self, values, obs, notice)

    monkeypatch.setattr(batch_fast_pass.FastPass, "__call__", recording)
    result = px.fit_batch(model, stacked, chunk_size=8)
    assert np.all(np.asarray(result.converged))
    assert len(handed) == 5 * 4  # five chunks: values, encoder, target, weight
    assert all(type(x) is np.ndarray for x in handed)
    assert counts == {"device_put": 1, "first_call": 1, "lengths": 0}  # device_put: the assembled result


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

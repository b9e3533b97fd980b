"""Batched fits on a Dask cluster (two worker processes) equal the single-process run.

Reference: :func:`pointax.fit_batch` in this process with the same chunk size. The
chunks reach the workers as the same arrays and run through the same compiled program,
so every output array must be identical bit for bit (NaN where NaN).
"""

from __future__ import annotations

import jax
import numpy as np
import pytest

import pointax as px

distributed = pytest.importorskip("distributed")

from test_io_sun import simulated_site  # noqa: E402

from pointax.fitting.distributed import fit_batch_distributed  # noqa: E402

CHUNK = 4
# Any solver shows the point; Gauss-Newton compiles fastest (three compilations here:
# this process and two workers).
OPTIONS = {"solver": "gauss-newton"}


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None, silence_logs=40
    ) as cluster:
        yield cluster


@pytest.fixture(scope="module")
def client(cluster):
    with distributed.Client(cluster) as client:
        client.wait_for_workers(2, timeout=120)
        yield client


def _start(obs):
    return np.asarray(px.Turntable("full", start=obs).values("free"))


@pytest.fixture(scope="module")
def network():
    """Eight clean ragged sites and one poisoned one (NaN in used rows)."""
    sites = [simulated_site(k, n)[0] for k, n in zip(range(8), (60, 45, 52, 60, 38, 60, 50, 41))]
    encoder = np.array(sites[2].encoder)
    encoder[[5, 9]] = np.nan
    sites.insert(3, px.Observations(encoder, sites[2].target, convention="turntable"))
    values = np.array([_start(s) for s in sites])
    values[3] = values[2]
    return px.stack_observations(sites), values


@pytest.fixture(scope="module")
def single_process(network):
    batch, values = network
    return px.fit_batch(px.Turntable("full"), batch, values=values, chunk_size=CHUNK, **OPTIONS)


def _assert_identical(a, b):
    leaves_a, tree_a = jax.tree.flatten(a)
    leaves_b, tree_b = jax.tree.flatten(b)
    assert tree_a == tree_b
    for x, y in zip(leaves_a, leaves_b):
        x, y = np.asarray(x), np.asarray(y)
        assert x.dtype == y.dtype and x.shape == y.shape
        np.testing.assert_array_equal(x, y)  # bit for bit; NaN equals NaN here


def test_distributed_equals_single_process_bit_for_bit(client, network, single_process):
    batch, values = network
    seen = []
    result = fit_batch_distributed(
        px.Turntable("full"),
        batch,
        client=client,
        chunk_size=CHUNK,
        values=values,
        progress=lambda d, t: seen.append((d, t)),
        timeout=300,
        **OPTIONS,
    )
    _assert_identical(result, single_process)
    # The chunks really went through the fit: clean sites converged, poisoned ones flagged.
    statuses = [s["status"] for s in px.site_statuses(result)]
    assert statuses == ["converged"] * 3 + ["failed"] + ["converged"] * 5
    # Progress: once per chunk (in any order of completion), rising to all sites.
    assert len(seen) == 3
    assert [d for d, _ in seen] == sorted(d for d, _ in seen)
    assert seen[-1] == (9, 9) and all(t == 9 for _, t in seen)
    assert sorted(np.diff([0] + [d for d, _ in seen])) == [1, 4, 4]


def test_scheduler_address_opens_its_own_client(cluster, network, single_process):
    batch, values = network
    result = fit_batch_distributed(
        px.Turntable("full"), batch, client=cluster.scheduler_address, chunk_size=CHUNK, values=values, **OPTIONS
    )
    _assert_identical(result, single_process)


def test_fit_network_on_the_cluster_equals_local(client, tmp_path, single_process):
    """`pointax fit-network --scheduler`: the example's turntables (chunks of the shape
    the workers have compiled already), one unreadable; per-site JSON identical."""
    from conftest import EXAMPLES

    from pointax.analysis.network import fit_network

    network = EXAMPLES / "data" / "network"
    rows = "".join(f"ts-0{k},{network / f'ts-0{k}.txt'},sun\n" for k in range(1, 7))
    manifest = tmp_path / "sun.csv"
    manifest.write_text("site,path,format\n" + rows)
    options = {"chunk_size": CHUNK, **OPTIONS}
    here = fit_network(manifest, **options)
    there = fit_network(manifest, client=client, **options)
    assert [d["status"] for d in here.sites] == ["converged"] * 4 + ["failed", "failed"]
    assert there.sites == here.sites


def test_errors_name_the_problem(client, network):
    batch, values = network
    with pytest.raises(ValueError, match="chunk_size"):
        fit_batch_distributed(px.Turntable("full"), batch, client=client, chunk_size=0, values=values)
    with pytest.raises(ValueError, match="unknown solver"):
        fit_batch_distributed(px.Turntable("full"), batch, client=client, chunk_size=CHUNK, values=values, solver="nope")
    with pytest.raises(TypeError, match="bogus"):
        fit_batch_distributed(px.Turntable("full"), batch, client=client, chunk_size=CHUNK, values=values, bogus=1)
    with pytest.raises(ValueError, match="values must have shape"):
        fit_batch_distributed(px.Turntable("full"), batch, client=client, chunk_size=CHUNK, values=values[:3])
    # An error raised on a worker comes back as itself, with a note naming the chunk.
    with pytest.raises(ValueError, match="convention") as info:
        fit_batch_distributed(px.AltAz(px.terms.tpoint("IA IE")), batch, client=client, chunk_size=CHUNK)
    assert any("chunk of sites" in note for note in getattr(info.value, "__notes__", []))


def test_chunks_made_on_the_workers_come_back_summarised(client, network):
    """fit_chunks_distributed: each chunk is made by ``source(k)`` on a worker and only a
    few numbers per site come back; they equal fit_batch of the same chunk here, bit for
    bit (same arrays, same compiled program)."""
    from pointax.fitting.distributed import SUMMARY_FIELDS, fit_chunks_distributed, site_summary

    batch, values = network
    chunks = [(jax.tree.map(lambda x: np.asarray(x)[4 * k : 4 * k + 4], batch), values[4 * k : 4 * k + 4]) for k in range(2)]
    seen = []
    summary = fit_chunks_distributed(
        px.Turntable("full"), lambda k: chunks[k], 2, client=client, max_in_flight=1,
        progress=lambda d, t: seen.append((d, t)), **OPTIONS,
    )  # fmt: skip
    local = [site_summary(px.fit_batch(px.Turntable("full"), obs, values=v, **OPTIONS)) for obs, v in chunks]
    for name in SUMMARY_FIELDS:
        np.testing.assert_array_equal(summary[name], np.concatenate([part[name] for part in local]), err_msg=name)
    assert summary["values"].shape == (8, 5)
    assert seen == [(1, 2), (2, 2)]

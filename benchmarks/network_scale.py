"""The first answer in seconds, and a million sites: where the time of ``pointax
fit-network`` goes with a cold and a warm cache, and Dask's rate and memory per worker.

Parts (each optional, all by default):

* ``manifest``: ``pointax fit-network examples/data/network/manifest.csv --quiet`` in a
  fresh process, first with an empty cache folder (``$POINTAX_JAX_CACHE``, cleared
  before: XLA's compiled programs and pointax's stored programs), then again with it
  (warm). Also the import alone (``python -c "import pointax.analysis.network"``).
* ``network``: the same for a simulated network of ``--sites`` (10,000) turntables
  written to a temporary folder (one sun file per site, 40 observations, a manifest).
* ``phases``: where the in-process time of the simulated network goes, in a fresh
  process with an empty cache folder: import, manifest, reading the sites' files,
  stacking, start values, ``fit_batch``, statuses, per-site dicts, observation entries
  (built for ``--json`` only) and the table; wall and CPU seconds of each
  (``python benchmarks/network_scale.py --phases-of MANIFEST`` runs one such process).
* ``dask``: ``pointax.fitting.distributed.fit_chunks_distributed`` on a
  ``LocalCluster`` (``--workers`` processes, one thread each) for each size in
  ``--dask-sites`` (100,000 and 1,000,000): each chunk of ``--chunk`` sites is simulated
  on its worker (nothing of the network lives in the client), fitted, and summarised
  (values, sigmas, statistics per site). It prints sites per second and the peak
  resident memory of each worker (``ru_maxrss``) and of this process.

Prints a table and writes ``benchmarks/results/network_scale.json``. Run under ``nice -n
19`` on a shared machine, the figures are pessimistic: say so with ``--note``.

    .venv/bin/python benchmarks/network_scale.py [--parts manifest network dask] [--note TEXT]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks" / "results" / "network_scale.json"
PAPER_DEG = np.array([0.0751, 0.0145, -0.0947, 60.5425, 165.8931])  # mu0 nu0 omega0 alpha0 beta0
BIN = Path(sys.executable).parent


def _timed(command: list[str], env: dict) -> tuple[float, int, str]:
    start = time.perf_counter()
    done = subprocess.run(command, env=env, capture_output=True, text=True, cwd=ROOT)
    return time.perf_counter() - start, done.returncode, done.stderr[-2000:]


def cold_and_warm(manifest: Path, label: str) -> dict:
    """Wall seconds of ``pointax fit-network MANIFEST --quiet`` with a cleared cache,
    then warm, and of the import alone."""
    cache = Path(tempfile.mkdtemp(prefix="pointax-cache-"))
    env = dict(os.environ, POINTAX_JAX_CACHE=str(cache))
    command = [str(BIN / "pointax"), "fit-network", str(manifest), "--quiet"]
    try:
        importing, _, _ = _timed([sys.executable, "-c", "import pointax.analysis.network"], env)
        shutil.rmtree(cache, ignore_errors=True)
        cold, code_cold, err = _timed(command, env)
        warm, code_warm, _ = _timed(command, env)
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    if code_cold not in (0, 1):
        raise RuntimeError(f"{label}: pointax fit-network failed ({code_cold}): {err}")
    return {"what": label, "import_s": importing, "cold_s": cold, "warm_s": warm, "exit": [code_cold, code_warm]}


def simulated_chunk(k: int, sites: int, n_obs: int = 40, noise_deg: float = 0.01, seed: int = 0):
    """Chunk ``k``: ``sites`` turntables near the paper's geometry (each a little
    different), ``n_obs`` sun-like observations each, Gaussian noise; the starting
    values near the truth (a refit). Vectorised: one compiled simulation per chunk size."""
    import jax

    import pointax as px
    from pointax.core.precision import float64
    from pointax.core.simulate import _noisy_directions
    from pointax.fitting.batch import batched_observations

    rng = np.random.default_rng([seed, k])
    model = px.Turntable("full")
    truth = np.radians(PAPER_DEG + rng.normal(0, [0.02, 0.02, 0.03, 5.0, 2.0], (sites, 5)))
    alpha = rng.uniform(0, 2 * np.pi, (sites, n_obs))
    beta = truth[:, 4:5] + np.radians(rng.uniform(15, 70, (sites, n_obs)))
    encoder = np.stack([alpha, beta], axis=-1)
    offsets = rng.normal(0, np.radians(noise_deg), (sites, n_obs, 2))

    @float64
    def directions():
        one = lambda y, e, o: _noisy_directions(model.with_values(y, "free"), e, o)  # noqa: E731
        return np.asarray(jax.jit(jax.vmap(one))(truth, encoder, offsets))

    obs = batched_observations(encoder, directions(), np.ones((sites, n_obs)), model.mount.convention)
    start = truth + rng.normal(0, np.radians(0.05), truth.shape)
    return obs, start


def write_network(folder: Path, sites: int, n_obs: int = 40) -> Path:
    """A manifest of ``sites`` simulated turntables (one sun file each) in ``folder``."""
    obs, _ = simulated_chunk(0, sites, n_obs)
    encoder = np.degrees(np.asarray(obs.encoder))
    target = np.asarray(obs.target)
    az = np.degrees(np.arctan2(target[..., 0], target[..., 1])) % 360
    el = np.degrees(np.arcsin(np.clip(target[..., 2], -1, 1)))
    lines = ["site, path, format, terms"]
    for s in range(sites):
        rows = np.column_stack([encoder[s, :, 0] % 360, encoder[s, :, 1], az[s], el[s]])
        text = "\n".join(" ".join(f"{x:.9f}" for x in row) for row in rows)
        (folder / f"s{s:05d}.txt").write_text("# alpha_deg beta_deg sun_az_deg sun_el_deg\n" + text + "\n")
        lines.append(f"s{s:05d}, s{s:05d}.txt, sun, full")
    manifest = folder / "manifest.csv"
    manifest.write_text("\n".join(lines) + "\n")
    return manifest


PHASES = ("import", "manifest", "read", "stack", "starts", "fit_batch", "statuses", "dicts", "observations", "table")


def phases_of(manifest: str) -> dict:
    """Wall and CPU seconds of each phase of ``fit_network``'s work on a manifest of
    turntables of one model (this process; call it in a fresh one with a cleared cache)."""
    marks = [(time.perf_counter(), time.process_time())]
    import jax

    import pointax as px
    from pointax.analysis import network
    from pointax.analysis.batch_listing import batch_observation_entries
    from pointax.core.precision import float64
    from pointax.fitting.batch_records import site_dicts, site_statuses
    from pointax.fitting.compilation_cache import enable_compilation_cache

    enable_compilation_cache()

    def mark():
        marks.append((time.perf_counter(), time.process_time()))

    mark()
    entries = network.read_manifest(manifest)
    mark()
    loaded, _ = network._read_sites(entries)
    mark()
    members = [e for e in entries if e.site in loaded]
    runs = [loaded[e.site] for e in members]

    @float64
    def work():
        model = network._batch_model(members[0])
        batch = px.stack_observations([r.observations for r in runs])
        mark()
        values = network._start_values(members, runs, model)
        mark()
        result = jax.tree.map(np.asarray, px.fit_batch(model, batch, values=values, chunk_size=1000))
        mark()
        statuses = site_statuses(result)
        mark()
        dicts = site_dicts(result)
        mark()
        batch_observation_entries(runs, result)
        mark()
        sites = [{**network._header(e), **s, **d} for e, s, d in zip(members, statuses, dicts)]
        result = network.NetworkResult(manifest, tuple(sites))
        result.table(), result.summary()
        mark()

    work()
    return {
        name: {"wall_s": b[0] - a[0], "cpu_s": b[1] - a[1]} for name, a, b in zip(PHASES, marks[:-1], marks[1:])
    }


def cold_phases(manifest: Path) -> dict:
    """:func:`phases_of` in a fresh process with an empty cache folder."""
    cache = Path(tempfile.mkdtemp(prefix="pointax-cache-"))
    env = dict(os.environ, POINTAX_JAX_CACHE=str(cache))
    try:
        done = subprocess.run([sys.executable, __file__, "--phases-of", str(manifest)], env=env, capture_output=True,
                              text=True, cwd=ROOT, check=True)  # fmt: skip
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def _worker_peak_rss_mb() -> float:
    import resource as r

    return r.getrusage(r.RUSAGE_SELF).ru_maxrss / 1024


def dask_run(n_sites: int, chunk: int, workers: int) -> dict:
    """Sites per second and peak memory of ``fit_chunks_distributed`` on a LocalCluster."""
    import functools

    from distributed import Client, LocalCluster

    import pointax as px
    from pointax.fitting.distributed import fit_chunks_distributed

    n_chunks = -(-n_sites // chunk)
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=40) as cluster:
        with Client(cluster) as client:
            client.wait_for_workers(workers, timeout=300)
            source = functools.partial(simulated_chunk, sites=chunk)
            # One chunk per worker first: compilation, reported apart from the rate.
            start = time.perf_counter()
            fit_chunks_distributed(px.Turntable("full"), source, workers, client=client)
            warmup = time.perf_counter() - start
            start = time.perf_counter()
            summary = fit_chunks_distributed(px.Turntable("full"), source, n_chunks, client=client)
            seconds = time.perf_counter() - start
            peaks = client.run(_worker_peak_rss_mb)
    converged = float(np.mean(summary["converged"]))
    return {
        "sites": n_chunks * chunk,
        "chunk": chunk,
        "workers": workers,
        "first_chunks_s": warmup,
        "seconds": seconds,
        "sites_per_s": n_chunks * chunk / seconds,
        "converged_fraction": converged,
        "worker_peak_rss_mb": sorted(peaks.values()),
        "client_peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", nargs="+", default=["manifest", "network", "phases", "dask"],
                        choices=["manifest", "network", "phases", "dask"])  # fmt: skip
    parser.add_argument("--phases-of", metavar="MANIFEST", help="print the phases of one manifest as JSON (a child process)")
    parser.add_argument("--sites", type=int, default=10_000, help="sites of the simulated manifest (default 10,000)")
    parser.add_argument("--dask-sites", type=int, nargs="+", default=[100_000, 1_000_000])
    parser.add_argument("--chunk", type=int, default=10_000, help="sites per Dask task (default 10,000)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--note", default="", help="how the machine was loaded (e.g. 'nice -n 19 beside other work')")
    args = parser.parse_args()
    if args.phases_of:
        print(json.dumps(phases_of(args.phases_of)))
        return
    out = {
        "command": " ".join([Path(sys.executable).name] + sys.argv),
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform(), "python": platform.python_version()},
        "note": args.note,
        "fit_network": [],
        "dask": [],
    }
    previous = json.loads(OUT.read_text()) if OUT.is_file() else {}
    if "manifest" in args.parts:
        out["fit_network"].append(cold_and_warm(ROOT / "examples" / "data" / "network" / "manifest.csv", "bundled manifest (7 sites)"))
    if "network" in args.parts or "phases" in args.parts:
        with tempfile.TemporaryDirectory(prefix="pointax-network-") as folder:
            start = time.perf_counter()
            manifest = write_network(Path(folder), args.sites)
            out["network_written_s"] = time.perf_counter() - start
            if "network" in args.parts:
                out["fit_network"].append(cold_and_warm(manifest, f"simulated network ({args.sites} turntables, 40 observations)"))
            if "phases" in args.parts:
                out["phases"] = {"sites": args.sites, "cold": cold_phases(manifest)}
    if "dask" in args.parts:
        for n in args.dask_sites:
            out["dask"].append(dask_run(n, args.chunk, args.workers))
    # Rows not measured this time keep their last figures.
    for key, name in (("fit_network", "what"), ("dask", "sites")):
        measured = {row[name] for row in out[key]}
        out[key] = [row for row in previous.get(key, []) if row[name] not in measured] + out[key]
        out[key].sort(key=lambda row: str(row[name]) if key == "fit_network" else row[name])
    print(f"{'pointax fit-network':52s} {'import s':>9s} {'cold s':>8s} {'warm s':>8s}")
    for row in out["fit_network"]:
        print(f"{row['what']:52s} {row['import_s']:9.1f} {row['cold_s']:8.1f} {row['warm_s']:8.1f}")
    print(f"\n{'Dask LocalCluster':20s} {'sites':>9s} {'chunk':>7s} {'sites/s':>9s} {'worker peak RSS MB':>20s} {'client MB':>10s}")
    for row in out["dask"]:
        peaks = "/".join(f"{x:.0f}" for x in row["worker_peak_rss_mb"])
        print(f"{row['workers']} workers x 1 thread {row['sites']:9d} {row['chunk']:7d} {row['sites_per_s']:9.0f} {peaks:>20s} {row['client_peak_rss_mb']:10.0f}")
    if "phases" not in out and "phases" in previous:
        out["phases"] = previous["phases"]
    if "phases" in out:
        print(f"\n{'phases, ' + str(out['phases']['sites']) + ' sites, cold':32s} {'wall s':>8s} {'CPU s':>8s}")
        for name, row in out["phases"]["cold"].items():
            print(f"{name:32s} {row['wall_s']:8.2f} {row['cpu_s']:8.2f}")
    if args.note:
        print(f"\n({args.note})")
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {OUT.relative_to(ROOT)}")


if __name__ == "__main__":
    main()

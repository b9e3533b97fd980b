"""Where the test suite's time goes: per test file, the CPU and wall time of its tests
(fixtures included), JAX's tracing, lowering and XLA compilation inside the test
processes, how many XLA compilations, and those of large programs; and the CPU time of
the Python processes the tests start.

    python benchmarks/suite_time.py [--out benchmarks/results/suite_time.json] [PYTEST ARGS...]

runs the whole suite (``pytest -q``, two workers as configured) with this module as a
pytest plugin, then prints a table and writes JSON. The suite's own time is its wall
time here; what the plugin records costs little (a listener on JAX's events). For the
target and its history: ``benchmarks/suite_time_notes.md``.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BIG = 0.5  # seconds: an XLA compilation this long is of a large program (a fit)
_EVENTS = {
    "/jax/core/compile/jaxpr_trace_duration": "trace_s",
    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower_s",
    "/jax/core/compile/backend_compile_duration": "compile_s",
    "/jax/compilation_cache/cache_retrieval_time_sec": "cache_read_s",
}

# --------------------------------------------------------------------------- the plugin

_current: dict = {"file": None}
_files: dict = collections.defaultdict(collections.Counter)


def _event(event, duration, **kwargs):
    name = _EVENTS.get(event)
    if name is None or _current["file"] is None:
        return
    row = _files[_current["file"]]
    row[name] += duration
    if name == "cache_read_s":
        row["cache_hits"] += 1  # a program read from JAX's persistent cache, not compiled
    if name == "compile_s":
        row["compilations"] += 1
        if duration >= BIG:
            row["large_compilations"] += 1
            row["large_compile_s"] += duration


def pytest_configure(config):
    import jax

    jax.monitoring.register_event_duration_secs_listener(_event)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """One test, its fixtures included, in the process that runs it (a worker)."""
    name = item.nodeid.split("::")[0]
    _current["file"] = name
    wall, cpu = time.perf_counter(), time.process_time()
    yield
    row = _files[name]
    row["wall_s"] += time.perf_counter() - wall
    row["cpu_s"] += time.process_time() - cpu
    row["tests"] += 1
    _current["file"] = None


def pytest_unconfigure(config):
    folder = os.environ.get("POINTAX_SUITE_TIME_DIR")
    if folder:
        worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
        Path(folder, f"{worker}.json").write_text(json.dumps({k: dict(v) for k, v in _files.items()}))


# --------------------------------------------------------------------------- the run

_CHILD_RECORDER = """
import atexit, json, os


def _record():
    test = os.environ.get("PYTEST_CURRENT_TEST")
    if not test:
        return
    t = os.times()
    row = {"file": test.split("::")[0], "cpu_s": t.user + t.system + t.children_user + t.children_system}
    with open(os.path.join(os.environ["POINTAX_SUITE_TIME_DIR"], "children.jsonl"), "a") as f:
        f.write(json.dumps(row) + "\\n")


atexit.register(_record)
"""


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "suite_time.json")
    args, pytest_args = parser.parse_known_args(argv)
    with tempfile.TemporaryDirectory(prefix="pointax-suite-time-") as folder:
        # A sitecustomize on the path of every process the tests start records, at its
        # exit, its CPU time (with its own children's) under the test file that started it.
        Path(folder, "sitecustomize.py").write_text(_CHILD_RECORDER)
        env = {**os.environ, "POINTAX_SUITE_TIME_DIR": folder}
        env["PYTHONPATH"] = os.pathsep.join([folder, str(Path(__file__).parent), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
        start_wall = time.perf_counter()
        start_cpu = os.times()
        proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "suite_time", *pytest_args], cwd=ROOT, env=env)
        end_cpu = os.times()
        wall = time.perf_counter() - start_wall
        cpu = (end_cpu.children_user + end_cpu.children_system) - (start_cpu.children_user + start_cpu.children_system)
        files: dict = collections.defaultdict(collections.Counter)
        for path in Path(folder).glob("*.json"):
            for name, row in json.loads(path.read_text()).items():
                files[name].update(row)
        children = Path(folder, "children.jsonl")
        if children.is_file():
            for line in children.read_text().splitlines():
                row = json.loads(line)
                files[row["file"]]["processes"] += 1
                files[row["file"]]["process_cpu_s"] += row["cpu_s"]
    totals = collections.Counter()
    for row in files.values():
        totals.update(row)
    keys = ("tests", "wall_s", "cpu_s", "trace_s", "lower_s", "compile_s", "compilations", "large_compilations",
            "large_compile_s", "cache_hits", "processes", "process_cpu_s")  # fmt: skip
    print(f"suite: {wall:.0f} s wall, {cpu:.0f} s CPU (every process), pytest exit {proc.returncode}")
    print(f"{'file':44s} " + " ".join(f"{k:>9s}" for k in ("tests", "wall", "cpu", "trace", "lower", "compile", "n_comp", "n_large", "large", "cached", "procs", "proc_cpu")))
    rows = sorted(files.items(), key=lambda kv: -(kv[1]["cpu_s"] + kv[1]["process_cpu_s"]))
    for name, row in [("all files", totals)] + rows[:40]:
        print(f"{name[-44:]:44s} " + " ".join(f"{row[k]:9.1f}" if k.endswith("_s") else f"{int(row[k]):9d}" for k in keys))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    result = {
        "wall_s": wall, "cpu_s": cpu, "pytest_exit": proc.returncode, "large_compile_threshold_s": BIG,
        "totals": {k: totals[k] for k in keys}, "files": {k: {c: v[c] for c in keys} for k, v in rows},
    }  # fmt: skip
    args.out.write_text(json.dumps(result, indent=1))
    print(f"wrote {args.out}")
    return proc.returncode


if __name__ == "__main__":
    sys.exit(main())

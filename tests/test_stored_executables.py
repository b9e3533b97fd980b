"""Compiled executables kept on disk (:mod:`pointax.fitting.stored_executables`): the
one module on JAX's experimental executable serialisation. Round trips run in fresh
processes (as they are used: a later process loads what an earlier one stored), and the
answers are checked against NumPy's."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import jax
import pytest

from pointax.fitting import stored_executables

# A function with LAPACK calls (an LU solve and a Cholesky factorisation), compiled and
# stored (``store``), or loaded (``load``, ``prefetch``) and run; the report as JSON.
_SCRIPT = """
import json, sys
from pathlib import Path
import jax, numpy as np
jax.config.update("jax_enable_x64", True)
from pointax.fitting import stored_executables as se
mode, path = sys.argv[1], Path(sys.argv[2])
a = np.array([[4.0, 1.0, 0.5], [1.0, 3.0, 0.2], [0.5, 0.2, 2.0]]); b = np.array([1.0, -2.0, 0.5])
report = {"usable": se.usable()}
if mode == "store":
    def f(a, b):
        return jax.numpy.linalg.solve(a, b), jax.lax.linalg.cholesky(a)
    compiled, report["stored"] = se.compile_and_store(jax.jit(f).lower(a, b), {}, path)
else:
    if mode == "prefetch":
        report["started"] = se.prefetch(path)
        compiled, n_out = se.take_prefetched(path)
    else:
        compiled, n_out = se.load(path)
    report["n_out"] = n_out
x, low = compiled(a, b)
report["solve"] = float(np.max(np.abs(np.asarray(x) - np.linalg.solve(a, b))))
report["cholesky"] = float(np.max(np.abs(np.asarray(low) - np.linalg.cholesky(a))))
print(json.dumps(report))
"""


def _run(*argv: str, env: dict | None = None) -> dict:
    proc = subprocess.run([sys.executable, "-c", _SCRIPT, *argv], capture_output=True, text=True, timeout=300,
                          env={**os.environ, **(env or {})})  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.splitlines()[-1])


def test_an_executable_stored_by_one_process_runs_in_another(tmp_path):
    """Stored, then loaded in a new process (read at once, or prefetched in a thread):
    it runs without being compiled and its LAPACK calls give NumPy's answers (a loaded
    executable calls LAPACK through jaxlib, which :func:`load` has prepared)."""
    path = tmp_path / "f.executable"
    stored = _run("store", str(path))
    assert stored["usable"] and stored["stored"] and path.read_bytes().startswith(b"pointax-executable 1 2 2\n")
    for mode in ("load", "prefetch"):
        loaded = _run(mode, str(path))
        assert loaded["n_out"] == 2 and loaded["solve"] < 1e-14 and loaded["cholesky"] < 1e-14, mode
        assert loaded.get("started", True)


def test_a_compilation_from_xla_s_cache_is_not_stored(tmp_path):
    """An executable that XLA's persistent cache returned has no machine code to
    serialise: :func:`compile_and_store` counts the cache's hits and stores only its own
    compilations, which it keeps out of that cache."""
    path = tmp_path / "f.executable"
    cache = tmp_path / "xla"
    code = (
        "import json, sys, jax, numpy as np\n"
        "from pathlib import Path\n"
        "from pointax.fitting import stored_executables as se\n"
        f"jax.config.update('jax_compilation_cache_dir', {str(cache)!r})\n"
        "jax.config.update('jax_persistent_cache_min_compile_time_secs', 0)\n"
        "jax.config.update('jax_persistent_cache_min_entry_size_bytes', 0)\n"
        "lowered = jax.jit(lambda x: (jax.numpy.sin(x) * 3,)).lower(np.ones(4))\n"
        "stored = None\n"
        "if sys.argv[1] == 'prime':\n"
        "    lowered.compile(compiler_options=se._OWN_COMPILATION)  # written to XLA's cache\n"
        "else:\n"
        "    _, stored = se.compile_and_store(lowered, {}, Path(sys.argv[2]))\n"
        "print(json.dumps({'stored': stored, 'threshold': jax.config.jax_persistent_cache_min_compile_time_secs}))\n"
    )

    def run(mode):
        proc = subprocess.run([sys.executable, "-c", code, mode, str(path)], capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr
        return json.loads(proc.stdout.splitlines()[-1])

    own = run("own")
    assert own == {"stored": True, "threshold": 0} and path.is_file()
    assert not cache.exists() or not any(cache.iterdir())  # nothing written to XLA's cache
    path.unlink()
    assert run("prime")["stored"] is None and any(cache.iterdir())  # (in-process, a second compile is not XLA's cache's)
    assert run("own") == {"stored": False, "threshold": 0} and not path.exists()


def test_a_file_that_is_not_an_executable_is_refused_before_it_is_loaded(tmp_path):
    """:func:`load` reads the header first: another file, or another format, raises a
    ValueError (the caller compiles the fit again and says so), never reaches XLA."""
    for content in (b"", b"not an executable\n\x00\x01", b"pointax-executable 9 2 2\n\x00"):
        path = tmp_path / "x.executable"
        path.write_bytes(content)
        with pytest.raises(ValueError, match="not a pointax executable of this format"):
            stored_executables.load(path)
    assert stored_executables.take_prefetched(tmp_path / "never.executable") is None


def test_executables_are_used_only_with_the_tested_jax(monkeypatch):
    """Stored executables are used only on the CPU with a JAX release the suite has run
    them on, whose jaxlib is the same version; otherwise never (programs are compiled)."""
    import importlib.metadata

    installed = jax.__version__
    assert importlib.metadata.version("jaxlib") == installed
    assert stored_executables._release(installed) in stored_executables.TESTED_JAX
    cases = {(installed, installed): True, ("0.99.1", "0.99.1"): False, (installed, "0.0.1"): False, ("dev", "dev"): False}
    for (version, jaxlib_version), expected in cases.items():
        monkeypatch.setattr(stored_executables, "_USABLE", [])
        monkeypatch.setattr(jax, "__version__", version)
        monkeypatch.setattr(stored_executables, "_jaxlib_version", lambda v=jaxlib_version: v)
        assert stored_executables.usable() == (expected and jax.default_backend() == "cpu"), (version, jaxlib_version)


def test_a_prefetch_prepares_lapack_beside_the_load(monkeypatch, tmp_path):
    """:func:`prefetch` loads in one thread and prepares LAPACK in another at the same
    time (the preparation imports SciPy and holds Python's lock; the load mostly does
    not): the warm ``pointax fit`` is about 0.1 s shorter (benchmarks/interactive_notes.md).
    Counted here with both steps replaced: which threads ran them."""
    import threading

    path = tmp_path / "f.executable"
    path.write_bytes(b"pointax-executable 1 0 0\n")
    ran = {}
    lapack_started = threading.Event()

    def prepare():
        ran["prepare"] = threading.current_thread().name
        lapack_started.set()

    def load(p):
        assert lapack_started.wait(10)  # started before the load, not after it
        ran["load"] = threading.current_thread().name
        return "compiled", 0

    monkeypatch.setattr(stored_executables, "_prepare_lapack_or_not", prepare)
    monkeypatch.setattr(stored_executables, "load", load)
    assert stored_executables.prefetch(path) and not stored_executables.prefetch(path)  # one load per file
    assert stored_executables.take_prefetched(path) == ("compiled", 0)
    assert ran == {"prepare": "pointax-prefetch-lapack", "load": "pointax-prefetch"}
    assert stored_executables.take_prefetched(path) is None  # taken once


def test_the_prefetch_reads_only_a_file_of_its_own_folder(monkeypatch, tmp_path):
    """``programs.prefetch(context)`` starts a load only for the executable that
    ``recent.json`` records for that context, and only a file name of the programs
    folder (not a path elsewhere, not another kind of entry); a load that fails hands
    its error to the fit, which notes it and compiles (the notes are tested with the
    fresh-process fits)."""
    from pointax.fitting import programs

    monkeypatch.setattr(programs, "_DIRECTORY", tmp_path)
    monkeypatch.setattr(programs, "_CONTEXT", [])
    good = tmp_path / "a.executable"
    good.write_bytes(b"not an executable\n")
    (tmp_path.parent / "b.executable").write_bytes(b"")
    recent = {"fit x": "a.executable", "fit y": "../b.executable", "fit z": ["a.executable"], "fit w": "recent.json"}
    (tmp_path / "recent.json").write_text(json.dumps(recent))
    for context in ("fit y", "fit z", "fit w", "fit none"):
        assert not programs.prefetch(context), context
        assert programs._CONTEXT == [context]  # remembered for what this process stores
    assert programs.prefetch("fit x")
    error = stored_executables.take_prefetched(good)
    assert isinstance(error, ValueError) and "not a pointax executable" in str(error)

"""Compiled fits kept on disk as executables (:mod:`jax.experimental.serialize_executable`),
so that a warm process runs a stored fit without lowering its program or reading XLA's
cache, and can start loading it in a background thread before it knows its data.

This is the one module that uses JAX's experimental executable serialisation. It is used
only where the suite has run it: on the CPU, with the JAX and jaxlib versions of
:data:`TESTED_JAX` (equal to each other); elsewhere :func:`usable` is False and
:mod:`pointax.fitting.programs` compiles its exported programs as before. An executable
that cannot be read is compiled again from its program, with a one-line note.

A file holds one header line (``pointax-executable <format> <inputs> <outputs>``, the
counts of the flat inputs and results) and the bytes of
:func:`jax.experimental.serialize_executable.serialize`. Loading an executable runs
machine code: like XLA's own cache, the folder must be written by no one but its user.
"""

from __future__ import annotations

import atexit
import importlib.metadata
import math
import os
import platform
import threading
from pathlib import Path

import jax

__all__ = ["TESTED_JAX", "usable", "machine", "compile_and_store", "load", "prefetch", "take_prefetched", "write_atomically"]

TESTED_JAX = ((0, 10),)
"""The JAX releases (major, minor) the suite runs stored executables on."""

_FORMAT = 1
_MAGIC = b"pointax-executable"

_OWN_COMPILATION = {"xla_embed_ir_in_executable": False}
"""XLA's default, given explicitly: XLA's cache keys these compilations apart from any
other of the same program (:func:`compile_and_store`)."""


def _release(version: str) -> tuple[int, ...]:
    return tuple(int(part) for part in version.split(".")[:2])


def _jaxlib_version() -> str:
    try:
        return importlib.metadata.version("jaxlib")
    except importlib.metadata.PackageNotFoundError:
        return "?"


_USABLE: list[bool] = []


def usable() -> bool:
    """Whether executables are stored and read in this process (see the module's
    docstring)."""
    if not _USABLE:
        try:
            ok = jax.__version__ == _jaxlib_version() and _release(jax.__version__) in TESTED_JAX
        except ValueError:  # a version string of another form
            ok = False
        _USABLE.append(ok and jax.default_backend() == "cpu")
    return _USABLE[0]


_MACHINE: list[str] = []


def machine() -> str:
    """What an executable depends on besides its program and software: the backend and
    device kind, the CPU's architecture and features (XLA compiles for the host's
    instruction set) and ``XLA_FLAGS``; part of an executable's key."""
    if not _MACHINE:
        device = jax.devices()[0]
        cpu = ""
        try:
            with open("/proc/cpuinfo") as f:
                cpu = next((line for line in f if line.startswith(("flags", "Features"))), "")
        except OSError:
            pass
        parts = [device.platform, device.device_kind, platform.machine(), cpu, os.environ.get("XLA_FLAGS", "")]
        _MACHINE.append("\n".join(parts))
    return _MACHINE[0]


_LAPACK_READY: list[bool] = []
_LAPACK_LOCK = threading.Lock()


def _prepare_lapack() -> None:
    """Have jaxlib load its LAPACK functions (from SciPy), which it does when it lowers a
    program with linear algebra: a loaded executable that calls LAPACK would otherwise
    call null pointers. Lowering a 2x2 Cholesky factorisation does it, once per process."""
    with _LAPACK_LOCK:  # (the prefetch threads may be here too)
        if not _LAPACK_READY:
            import numpy as np

            jax.jit(jax.lax.linalg.cholesky).lower(np.eye(2))
            _LAPACK_READY.append(True)


def _prepare_lapack_or_not() -> None:
    """:func:`_prepare_lapack`, its error left to :func:`load` (which tries again)."""
    try:
        _prepare_lapack()
    except Exception:
        pass


_COUNTING = threading.local()
_LISTENING: list[bool] = []
_THRESHOLD_LOCK = threading.Lock()
_RAISED = {"count": 0, "threshold": 0.0}


def _count_cache_hit(event: str, **_) -> None:
    if event == "/jax/compilation_cache/cache_hits" and getattr(_COUNTING, "hits", None) is not None:
        _COUNTING.hits += 1


def _raise_cache_threshold(up: bool) -> None:
    """Keep XLA's cache from storing compilations while any thread compiles an executable
    to store (counted, so that overlapping compilations restore it once)."""
    with _THRESHOLD_LOCK:
        if up:
            if _RAISED["count"] == 0:
                _RAISED["threshold"] = jax.config.jax_persistent_cache_min_compile_time_secs
                jax.config.update("jax_persistent_cache_min_compile_time_secs", math.inf)
            _RAISED["count"] += 1
        else:
            _RAISED["count"] -= 1
            if _RAISED["count"] == 0:
                jax.config.update("jax_persistent_cache_min_compile_time_secs", _RAISED["threshold"])


def compile_and_store(lowered: jax.stages.Lowered, options: dict, path: Path) -> tuple[jax.stages.Compiled, bool]:
    """``lowered`` compiled with XLA ``options``, its executable written to ``path``;
    returns the compiled function and whether it was written.

    An executable that XLA's persistent cache returned cannot be serialised again (its
    machine code is not kept: the next process fails with "Function ... not found"), so
    the compilation is told apart in XLA's cache by :data:`_OWN_COMPILATION`, kept out of
    that cache while it runs, and stored only when no cache hit was counted. Nothing is
    written when the executable cannot be serialised or its inputs and results are not
    flat tuples.

    Raises:
        Exception: whatever XLA raises for options it does not know (the caller compiles
            without them).
    """
    if not _LISTENING:
        jax.monitoring.register_event_listener(_count_cache_hit)
        _LISTENING.append(True)
    _raise_cache_threshold(True)
    _COUNTING.hits = 0
    try:
        compiled = lowered.compile(compiler_options={**_OWN_COMPILATION, **options})
        fresh = _COUNTING.hits == 0
    finally:
        _COUNTING.hits = None
        _raise_cache_threshold(False)
    stored = False
    if fresh:
        try:
            stored = _store(compiled, path)
        except Exception:  # not serialisable, a full disk: the program alone is kept
            pass
    return compiled, stored


def _flat_trees(n_in: int, n_out: int):
    """The input and result structures of a compiled function of ``n_in`` positional
    arrays returning a tuple of ``n_out``."""
    return jax.tree.structure(((0,) * n_in, {})), jax.tree.structure((0,) * n_out)


def _store(compiled: jax.stages.Compiled, path: Path) -> bool:
    from jax.experimental import serialize_executable

    blob, in_tree, out_tree = serialize_executable.serialize(compiled)
    n_in, n_out = in_tree.num_leaves, out_tree.num_leaves
    if (in_tree, out_tree) != _flat_trees(n_in, n_out):
        return False
    write_atomically(path, b"%s %d %d %d\n" % (_MAGIC, _FORMAT, n_in, n_out) + blob)
    return True


def load(path: Path) -> tuple[jax.stages.Compiled, int]:
    """The executable stored in ``path`` and the number of its results.

    Raises:
        OSError, ValueError: the file cannot be read, or is not an executable of this
            format.
        Exception: whatever JAX raises for bytes it cannot load.
    """
    data = path.read_bytes()
    header, _, blob = data.partition(b"\n")
    fields = header.split(b" ")
    if len(fields) != 4 or fields[0] != _MAGIC or fields[1] != b"%d" % _FORMAT:
        raise ValueError("not a pointax executable of this format")
    n_in, n_out = int(fields[2]), int(fields[3])
    from jax.experimental import serialize_executable

    compiled = serialize_executable.deserialize_and_load(blob, *_flat_trees(n_in, n_out))
    _prepare_lapack()
    return compiled, n_out


_PREFETCH: dict[Path, tuple[threading.Thread, list]] = {}
_PREFETCH_LOCK = threading.Lock()


def prefetch(path: Path) -> bool:
    """Start loading ``path`` in a background thread (:func:`take_prefetched` collects
    it). XLA releases Python's lock while it loads, so the process imports and reads its
    data meanwhile; LAPACK is prepared in a second thread at the same time (it imports
    SciPy's linear algebra, which holds Python's lock). Returns whether a load was
    started."""
    with _PREFETCH_LOCK:
        if path in _PREFETCH or not path.is_file():
            return False
        jax.devices()  # the backend, started here rather than in the thread
        box: list = []

        def run():
            threading.Thread(target=_prepare_lapack_or_not, name="pointax-prefetch-lapack", daemon=True).start()
            try:
                box.append(load(path))
            except BaseException as err:  # handed to the taker, who notes it
                box.append(err)

        thread = threading.Thread(target=run, name="pointax-prefetch", daemon=True)
        _PREFETCH[path] = (thread, box)
    thread.start()
    return True


def take_prefetched(path: Path) -> tuple[jax.stages.Compiled, int] | BaseException | None:
    """What the prefetch of ``path`` loaded (waiting for it), the error it met, or None
    when no prefetch of ``path`` was started."""
    with _PREFETCH_LOCK:
        pending = _PREFETCH.pop(path, None)
    if pending is None:
        return None
    thread, box = pending
    thread.join()
    return box[0]


def _finish_prefetches() -> None:
    """Wait for loads still running at exit (an unused prefetch): a thread inside XLA
    while the interpreter shuts down aborts the process."""
    for thread, _ in list(_PREFETCH.values()):
        thread.join()


atexit.register(_finish_prefetches)


def write_atomically(path: Path, blob: bytes) -> None:
    """Write ``blob`` to ``path`` through a temporary file and a rename: a concurrent
    reader sees all of it or nothing."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(f".{os.getpid()}.{threading.get_ident()}.tmp")
    tmp.write_bytes(blob)
    os.replace(tmp, path)

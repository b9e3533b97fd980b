"""Traced and compiled fits kept on disk between processes, so that a fresh process
neither traces nor compiles again what an earlier one did for the same model structure.

JAX's persistent compilation cache (:mod:`pointax.fitting.compilation_cache`) keeps XLA's
compiled code, but every new process still traces the fit from Python first: 2-3 s
of the 4-5 s a fresh ``pointax fit`` took with that cache warm. Here each fit is kept
twice, beside that cache:

* the traced program, exported (:mod:`jax.export`, ``<key>.program``): portable, read
  when the executable is missing or unreadable, and then compiled;
* the compiled executable (:mod:`jax.experimental.serialize_executable`,
  ``<key'>.executable``, ``key'`` adding the machine: backend, device, CPU features,
  ``XLA_FLAGS``): a later process with the same structure, options, data shapes,
  software and machine runs it without lowering the program or asking XLA's cache
  (0.1-0.15 s of a 1.7 s warm ``pointax fit``).

A command may also name its *context* (:func:`prefetch`: ``pointax fit`` names its
data file): the executable the last process of that context ran then starts loading in
a background thread at once, while the process imports the rest of pointax and reads
its data, and serves the fit if it is the one asked for.

An entry's key is a hash of the program's name, the pytree structure (every node's
class by module and qualified name, its static configuration) and shapes of its inputs,
the fit options, and the versions of pointax (the hash of its source files), JAX,
jaxlib, equinox, lineax and optimistix: a change of any of them writes a new entry,
never reads a stale one. Only programs built of pointax's own classes go to disk: the
source of a user's term class is not part of the key, so a fit with one is traced once
per process (an edited term must never run its old program). Clear the cache with
:func:`clear` (or delete the folder, ``programs`` inside ``$POINTAX_JAX_CACHE``, by
default ``~/.cache/pointax/jax/programs``).

Off until :func:`pointax.enable_compilation_cache` turns it on (the ``pointax``
command does); a program that cannot be exported or stored (say, a term class defined
inside a function, a result whose structure cannot be rebuilt) runs as an ordinary
compiled function. Executables are loaded with :mod:`pickle` and run as machine code:
like XLA's own cache, the folder must be written by no one but its user.
"""

from __future__ import annotations

import atexit
import hashlib
import importlib.metadata
import json
import math
import os
import pickle
import platform
import re
import shutil
import threading
from collections.abc import Callable
from pathlib import Path

import jax
import numpy as np

from . import xla_options

__all__ = ["set_directory", "directory", "call", "clear", "prefetch", "STATS"]

STATS = {
    "loaded": 0, "exported": 0, "stored": 0, "memory": 0, "executables_loaded": 0, "executables_stored": 0,
    "prefetch_started": 0, "prefetched": 0,
}  # fmt: skip
"""How programs were obtained in this process (for tests and benchmarks)."""

_DIRECTORY: Path | None = None
_MEMORY: dict = {}
_LOCK = threading.Lock()
_FORMAT = 2  # 1 named classes by their bare name: the linear and rigorous IA shared entries


def set_directory(path: str | os.PathLike | None) -> None:
    """Keep programs in ``path`` (None: in memory only, the default)."""
    global _DIRECTORY
    _DIRECTORY = None if path is None else Path(path)


def directory() -> Path | None:
    """Where programs are kept, or None."""
    return _DIRECTORY


def clear(path: str | os.PathLike | None = None) -> None:
    """Delete every stored program (in ``path``, default :func:`directory`) and forget
    those loaded in this process."""
    with _LOCK:
        _MEMORY.clear()
    target = Path(path) if path is not None else _DIRECTORY
    if target is not None and target.is_dir():
        shutil.rmtree(target)


def call(name: str, fn: Callable, args: tuple, static, structure: Callable, fast_compile: bool = False) -> object:
    """``fn(*args, static)`` through an exported program.

    Args:
        name: the program's name (part of the key).
        fn: the function, pure JAX.
        args: its array arguments, a pytree.
        static: its last argument, hashable with a stable ``repr`` (part of the key).
        structure: ``structure(*args, static)``, the pytree structure of ``fn``'s result
            built without tracing (a pytree structure cannot be stored: an equinox
            module's does not survive pickling); checked against the traced one before a
            program is stored.
        fast_compile: compile with :func:`pointax.fitting.xla_options.fast_compile_options`
            (part of the key).

    Falls back to an ordinary ``jax.jit`` when the program cannot be exported.
    """
    leaves, in_tree = jax.tree.flatten(args)
    avals = [jax.ShapeDtypeStruct(np.shape(x), _dtype(x)) for x in leaves]
    # In memory, the tree itself is the key: it compares classes by identity (two term
    # classes may share a name: the linear and rigorous IA do).
    memory_key = (name, in_tree, tuple((a.shape, a.dtype) for a in avals), static, jax.config.jax_enable_x64, fast_compile)
    with _LOCK:
        entry = _MEMORY.get(memory_key)
    if entry is None:
        expected = structure(*args, static)
        key = _key(name + (" fast-compile" if fast_compile else ""), in_tree, avals, static)
        entry = (key is not None and (_load_executable(key, expected) or _load(key, expected, fast_compile))) or _export(
            key, fn, in_tree, avals, static, expected, fast_compile
        )
        with _LOCK:
            _MEMORY[memory_key] = entry
    else:
        STATS["memory"] += 1
    jitted, out_tree = entry
    out = jitted(*leaves)
    return jax.tree.unflatten(out_tree[-1], out)


def _dtype(x):
    return x.dtype if hasattr(x, "dtype") else np.asarray(x).dtype


def _key(name, in_tree, avals, static) -> str | None:
    """The key of the program on disk, or None when it must not be stored
    (:func:`_describe`)."""
    tree = _describe(in_tree)
    if tree is None:
        return None
    parts = [str(_FORMAT), name, _versions(), tree, repr(static), str(jax.config.jax_enable_x64)]
    parts += [f"{a.shape}{a.dtype}" for a in avals]
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()


_STORABLE_MODULES = ("pointax", "builtins", "collections")


def _describe(treedef) -> str | None:
    """``treedef`` as text that names every node's class by module and qualified name
    with its static data (``str(treedef)`` names classes by their bare name only), or
    None when the program must not be stored: a class from outside pointax (its source
    is not in the key), or static data whose text does not identify it (an object's
    address, a NumPy array's summary)."""
    node = treedef.node_data()
    if node is None:
        return "*"
    kind, aux = node
    if kind.__module__.split(".")[0] not in _STORABLE_MODULES or "<locals>" in kind.__qualname__:
        return None
    static = repr(aux)
    if " at 0x" in static or "..." in static:
        return None
    children = [_describe(child) for child in treedef.children()]
    if any(c is None for c in children):
        return None
    return f"{kind.__module__}.{kind.__qualname__}[{static}]({', '.join(children)})"


_VERSIONS: list = []


def _versions() -> str:
    if not _VERSIONS:
        source = hashlib.sha256()
        root = Path(__file__).resolve().parent.parent
        for path in sorted(root.rglob("*.py")):
            source.update(path.relative_to(root).as_posix().encode())
            source.update(path.read_bytes())
        versions = []
        for package in ("jax", "jaxlib", "equinox", "lineax", "optimistix"):
            try:
                versions.append(f"{package}={importlib.metadata.version(package)}")
            except importlib.metadata.PackageNotFoundError:
                versions.append(f"{package}=?")
        _VERSIONS.append(" ".join(versions) + " pointax-source=" + source.hexdigest())
    return _VERSIONS[0]


def _path(key: str | None) -> Path | None:
    return None if _DIRECTORY is None or key is None else _DIRECTORY / f"{key}.program"


_MACHINE: list = []


def _machine() -> str:
    """What a compiled executable also depends on: backend, device kind, the CPU's
    features (XLA compiles for the host's instruction set), ``XLA_FLAGS``."""
    if not _MACHINE:
        device = jax.devices()[0]
        cpu = ""
        try:
            with open("/proc/cpuinfo") as f:
                cpu = next((line for line in f if line.startswith(("flags", "Features"))), "")
        except OSError:
            pass
        parts = [device.platform, device.device_kind, platform.machine(), cpu]  # (platform.processor() runs `uname -p`: 4 ms)
        _MACHINE.append("\n".join(parts + [os.environ.get("XLA_FLAGS", "")]))
    return _MACHINE[0]


def _executable_path(key: str | None) -> Path | None:
    if _DIRECTORY is None or key is None:
        return None
    return _DIRECTORY / f"{hashlib.sha256((key + _machine()).encode()).hexdigest()}.executable"


def _load_executable(key: str, out_tree):
    path = _executable_path(key)
    if path is None:
        return None
    with _LOCK:
        pending = _PREFETCH.pop(path, None)
    if pending is not None:
        thread, box = pending
        thread.join()
        loaded = box[0] if box else None
        STATS["prefetched"] += loaded is not None
    elif path.is_file():
        loaded = _read_executable(path)
    else:
        return None
    if loaded is None:  # unreadable, from another writer: compile again
        return None
    compiled, flat_out_tree = loaded
    if flat_out_tree.num_leaves != out_tree.num_leaves:
        return None
    STATS["executables_loaded"] += 1
    _remember(path)
    return compiled, [out_tree]


def _read_executable(path: Path):
    """``(compiled, its flat result structure)`` from an executable file, or None."""
    try:
        serialized, in_tree, flat_out_tree = pickle.loads(path.read_bytes())
        if jax.default_backend() == "cpu":
            _initialise_lapack()
        return _serializer().deserialize_and_load(serialized, in_tree, flat_out_tree), flat_out_tree
    except Exception:
        return None


_PREFETCH: dict[Path, tuple[threading.Thread, list]] = {}
_CONTEXT: list[str] = []
_RECENT = "recent.json"
_RECENT_KEPT = 64


def prefetch(context: str) -> bool:
    """Start loading, in a background thread, the executable that the last process of
    this ``context`` ran (the ``pointax`` command passes its subcommand and data file),
    and remember the context for the executables this process runs.

    Loading a fit's executable takes 0.1-0.15 s, and XLA releases the GIL while it does;
    a warm ``pointax fit`` spends longer than that importing equinox and pointax and
    reading the run before it knows which program it needs. The prefetched executable is
    used only if it is the one the fit then asks for (by its key); otherwise it is left
    unused. Returns whether a load was started."""
    if _DIRECTORY is None:
        return False
    _CONTEXT[:] = [context]
    name = _recent().get(context)
    path = None if name is None else _DIRECTORY / name
    if path is None or path in _PREFETCH or not path.is_file():
        return False
    jax.devices()  # the backend, started here rather than in the thread
    box: list = []
    thread = threading.Thread(target=lambda: box.append(_read_executable(path)), name="pointax-prefetch", daemon=True)
    with _LOCK:
        _PREFETCH[path] = (thread, box)
    thread.start()
    STATS["prefetch_started"] += 1
    return True


def _finish_prefetches() -> None:
    """Wait for loads still running at exit (an unused prefetch), so that none runs while
    the interpreter shuts down."""
    for thread, _ in list(_PREFETCH.values()):
        thread.join()


atexit.register(_finish_prefetches)


def _recent() -> dict:
    try:
        recent = json.loads((_DIRECTORY / _RECENT).read_text())
    except (OSError, ValueError):
        return {}
    return recent if isinstance(recent, dict) else {}


def _remember(path: Path) -> None:
    """Note ``path`` as the executable of this process's context (for :func:`prefetch`)."""
    if not _CONTEXT or _DIRECTORY is None:
        return
    recent = _recent()
    if recent.get(_CONTEXT[0]) == path.name:
        return
    recent.pop(_CONTEXT[0], None)
    recent[_CONTEXT[0]] = path.name  # the most recent last
    try:
        _write(_DIRECTORY / _RECENT, json.dumps(dict(list(recent.items())[-_RECENT_KEPT:])).encode())
    except OSError:  # a read-only folder: no prefetch next time
        pass


def _serializer():
    from jax.experimental import serialize_executable

    return serialize_executable


_LAPACK_LOCK = threading.Lock()


def _initialise_lapack() -> None:
    """Load the LAPACK routines the executable calls (from SciPy), as lowering a program
    with linear algebra does: without it, a fit's executable would call null pointers."""
    with _LAPACK_LOCK:  # (a prefetch thread may be here too)
        _load_scipy_lapack_tables()
        from jaxlib import lapack

        lapack.prepare_lapack_call("getrf_ffi", np.dtype(np.float64))


SCIPY_LAPACK_TABLES = ("cython_blas", "cython_lapack")
"""The modules of ``scipy.linalg`` whose function tables jaxlib reads for LAPACK."""


def _load_scipy_lapack_tables() -> None:
    """Load ``scipy.linalg.cython_blas`` and ``cython_lapack`` from their files without
    running ``scipy.linalg``'s ``__init__``, which jaxlib's import of them would:
    that package imports NumPy's f2py and SciPy's array-API layer, about 0.1 s of a
    0.9 s warm ``pointax fit`` for two tables of function pointers. Later imports of
    ``scipy.linalg`` are unaffected (they find these two modules already loaded; only
    the attributes ``scipy.linalg.cython_blas`` and ``.cython_lapack`` are not set on
    the package, where no Python code reads them). Where ``scipy.linalg`` is imported
    already, or the files cannot be found, it does nothing and jaxlib imports them."""
    import sys

    if "scipy.linalg" in sys.modules or all(f"scipy.linalg.{m}" in sys.modules for m in SCIPY_LAPACK_TABLES):
        return
    import importlib.machinery
    import importlib.util

    try:
        spec = importlib.util.find_spec("scipy")  # a top-level package: not imported by this
        folder = Path(spec.submodule_search_locations[0]) / "linalg"
        for module in SCIPY_LAPACK_TABLES:
            name = f"scipy.linalg.{module}"
            if name in sys.modules:
                continue
            path = next(p for p in folder.iterdir() if p.name.startswith(f"{module}.") and p.suffix in {".so", ".pyd"})
            loader = importlib.machinery.ExtensionFileLoader(name, str(path))
            loaded = importlib.util.module_from_spec(importlib.util.spec_from_file_location(name, path, loader=loader))
            loader.exec_module(loaded)
            sys.modules[name] = loaded
    except Exception:  # another layout of SciPy: jaxlib imports them the usual way
        return


_OWN_COMPILATION = {"xla_embed_ir_in_executable": False}
"""XLA's default, given explicitly: XLA's cache keys these compilations apart from any
other of the same program (:func:`_compiled`)."""

_CACHE_HITS = threading.local()
_COMPILING = threading.Lock()
_LISTENING: list = []


def _count_cache_hit(event: str, **_) -> None:
    if event == "/jax/compilation_cache/cache_hits" and getattr(_CACHE_HITS, "count", None) is not None:
        _CACHE_HITS.count += 1




def _compiled(key: str | None, exported, fast_compile: bool):
    """``exported``, compiled; its executable kept on disk where programs are.

    An executable that XLA's persistent cache returned cannot be serialised again (its
    machine code is not kept: the next process fails with "Function ... not found"), so
    the executable is stored only from a compilation of its own, told apart in XLA's
    cache by :data:`_OWN_COMPILATION` and checked by counting the cache's hits."""
    path = _executable_path(key)
    if path is None:
        return xla_options.jit(exported.call, fast_compile)
    if not _LISTENING:
        jax.monitoring.register_event_listener(_count_cache_hit)
        _LISTENING.append(True)
    lowered = jax.jit(exported.call).lower(*exported.in_avals)
    # (Asked before counting: finding whether XLA knows the fast options compiles a tiny
    # program, which may hit XLA's cache.)
    options = {**_OWN_COMPILATION, **(xla_options.fast_compile_options() if fast_compile else {})}
    with _COMPILING:
        # Nor does XLA's cache keep this compilation (it would be read, not compiled, when
        # an executable is lost): its compile-time threshold raised while it runs.
        threshold = jax.config.jax_persistent_cache_min_compile_time_secs
        jax.config.update("jax_persistent_cache_min_compile_time_secs", math.inf)
        _CACHE_HITS.count = 0
        try:
            compiled = lowered.compile(compiler_options=options)
            fresh = _CACHE_HITS.count == 0
        finally:
            _CACHE_HITS.count = None
            jax.config.update("jax_persistent_cache_min_compile_time_secs", threshold)
    if fresh:
        try:
            _write(path, pickle.dumps(_serializer().serialize(compiled)))
            STATS["executables_stored"] += 1
            _remember(path)
        except Exception:  # not serialisable, a full disk: the program alone is kept
            pass
    return compiled


def _load(key: str, out_tree, fast_compile: bool):
    path = _path(key)
    if path is None or not path.is_file():
        return None
    try:
        exported = jax.export.deserialize(bytearray(path.read_bytes()))
    except Exception:  # unreadable or from an incompatible writer: export again
        return None
    if len(exported.out_avals) != out_tree.num_leaves:
        return None
    STATS["loaded"] += 1
    return _compiled(key, exported, fast_compile), [out_tree]


def _export(key: str, fn: Callable, in_tree, avals, static, expected, fast_compile: bool):
    out_tree = []

    def flat(*leaves):
        out = fn(*jax.tree.unflatten(in_tree, leaves), static)
        out_leaves, treedef = jax.tree.flatten(out)
        out_tree.append(treedef)
        return tuple(out_leaves)

    exported = None
    allowed: set[str] = set()
    # The program's library calls (LAPACK) have no cross-version guarantee, which the key
    # makes unnecessary: an entry is only read by the same JAX and jaxlib.
    for _ in range(8):
        checks = [jax.export.DisabledSafetyCheck.custom_call(n) for n in sorted(allowed)]
        try:
            exported = jax.export.export(jax.jit(flat), disabled_checks=checks)(*avals)
            break
        except ValueError as err:
            new = set(re.findall(r"custom_call @(\w+)", str(err))) - allowed
            if not new or any("callback" in n for n in new):
                break  # a host callback holds this process's addresses: never stored
            allowed |= new
        except Exception:
            break
    if exported is None or not out_tree:
        # Not exportable: an ordinary compiled function (traced once per process; its
        # first call records the result's structure: a new function, as JAX would reuse
        # the trace of ``flat`` from the export and not run it again).
        out_tree.clear()
        return xla_options.jit(lambda *leaves: flat(*leaves), fast_compile), out_tree
    STATS["exported"] += 1
    if out_tree[-1] != expected:
        return xla_options.jit(exported.call, fast_compile), out_tree
    _store(key, exported)
    return _compiled(key, exported, fast_compile), out_tree


def _store(key: str, exported) -> None:
    path = _path(key)
    if path is None:
        return
    try:
        _write(path, bytes(exported.serialize()))
    except Exception:  # not serialisable, a full disk: keep it in memory only
        return
    STATS["stored"] += 1


def _write(path: Path, blob: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(f".{os.getpid()}.{threading.get_ident()}.tmp")
    tmp.write_bytes(blob)
    os.replace(tmp, path)  # atomic: a concurrent reader sees all of it or nothing

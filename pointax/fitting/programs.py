"""Traced fits kept on disk between processes (:mod:`jax.export`), so that a fresh process
does not trace again what an earlier one traced for the same model structure.

JAX's persistent compilation cache (:mod:`pointax.fitting.compilation_cache`) keeps XLA's
compiled code, but every new process still traces the fit from Python first, and tracing
optimistix's solver loop costs more than loading the compiled code
(``benchmarks/interactive_notes.md``). Here each fit is kept twice:

* its traced program, exported (:mod:`jax.export`, ``<key>.program``): a later process
  with the same structure reads it instead of tracing, and compiles it;
* where :func:`pointax.fitting.stored_executables.usable`, the compiled executable
  (``<key'>.executable``, ``key'`` adding the machine): a later process runs it without
  lowering the program or reading XLA's cache, which takes most of a warm fit's time
  beyond importing JAX.

A command may also name its *context* (:func:`prefetch`: ``pointax fit`` names its data
file): the executable the last process of that context ran then starts loading in a
background thread, while the process imports the rest of pointax and reads its data.

An entry's key is a hash of the program's name, the pytree structure (every node's
class by module and qualified name, its static configuration) and shapes of its inputs,
the fit options, and the versions of pointax (the hash of its source files), JAX,
jaxlib, equinox, lineax and optimistix: a change of any of them writes a new entry,
never reads a stale one. An entry that cannot be read (a truncated file, another
writer) is traced again and replaced, an executable that cannot be read is compiled again
from its program, each with a one-line :class:`RuntimeWarning`. Only
programs built of pointax's own classes go to disk: the source of a user's term class
is not part of the key, so a fit with one is traced once per process (an edited term
must never run its old program). Clear the cache with :func:`clear` (or delete the
folder, ``programs`` inside ``$POINTAX_JAX_CACHE``, by default
``~/.cache/pointax/jax/programs``).

Off until :func:`pointax.enable_compilation_cache` turns it on (the ``pointax`` command
does); a program that cannot be exported or stored (say, a term class defined inside a
function, a result whose structure cannot be rebuilt, a host callback) runs as an
ordinary compiled function.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import json
import os
import re
import shutil
import threading
import warnings
from collections.abc import Callable
from pathlib import Path

import jax
import numpy as np

from ..core import xla_options
from . import stored_executables

__all__ = ["set_directory", "directory", "call", "clear", "prefetch", "STATS"]

STATS = {
    "loaded": 0, "exported": 0, "stored": 0, "memory": 0, "unreadable": 0,
    "executables_loaded": 0, "executables_stored": 0, "executables_unreadable": 0, "prefetched": 0,
}  # fmt: skip
"""How programs were obtained in this process (for tests and benchmarks)."""

_DIRECTORY: Path | None = None
_MEMORY: dict = {}
_LOCK = threading.Lock()
_TRACING = threading.RLock()  # re-entrant: a traced function may itself call a stored program
_FORMAT = 3  # 1 named classes by their bare name; 2 kept compiled executables beside the programs


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
        fast_compile: compile with :func:`pointax.core.xla_options.fast_compile_options`
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
        entry = key is not None and (_load_executable(key, expected) or _load(key, expected, fast_compile))
        if not entry:
            # One trace at a time: tracing holds Python's lock anyway, and threads that
            # trace side by side each take as long as both (fit-network fits its model
            # groups in threads: one traces while another's program compiles).
            with _TRACING:
                entry = _export(key, fn, in_tree, avals, static, expected, fast_compile)
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
    """pointax's source hash and the installed versions of the libraries a program is
    traced with (part of every key)."""
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


def _load(key: str, out_tree, fast_compile: bool):
    path = _path(key)
    if path is None or not path.is_file():
        return None
    try:
        exported = jax.export.deserialize(bytearray(path.read_bytes()))
        if len(exported.out_avals) != out_tree.num_leaves:
            raise ValueError(f"{len(exported.out_avals)} results where the fit has {out_tree.num_leaves}")
    except Exception as err:  # truncated, or from another writer: traced again and replaced
        return _unreadable("unreadable", f"stored program {path}", err, "tracing the fit again")
    STATS["loaded"] += 1
    return _compiled(key, exported, fast_compile), [out_tree]


def _unreadable(counter: str, what: str, err: BaseException, then: str) -> None:
    """Count and note, in one line, a stored entry that cannot be read (the warning
    points at the caller of :func:`call`); returns None, what the loaders return then."""
    STATS[counter] += 1
    reason = str(err).splitlines()[0] if str(err) else type(err).__name__
    warnings.warn(f"{what} unreadable ({reason}); {then}", RuntimeWarning, stacklevel=4)


def _export(key: str | None, fn: Callable, in_tree, avals, static, expected, fast_compile: bool):
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


def _store(key: str | None, exported) -> None:
    path = _path(key)
    if path is None:
        return
    try:
        stored_executables.write_atomically(path, bytes(exported.serialize()))
    except Exception:  # not serialisable, a full disk: keep it in memory only
        return
    STATS["stored"] += 1


def _executable_path(key: str | None) -> Path | None:
    if _DIRECTORY is None or key is None or not stored_executables.usable():
        return None
    machine = hashlib.sha256((key + stored_executables.machine()).encode()).hexdigest()
    return _DIRECTORY / f"{machine}.executable"


def _compiled(key: str | None, exported, fast_compile: bool):
    """``exported`` compiled; its executable stored beside the program where
    executables are (:func:`_executable_path`)."""
    path = _executable_path(key)
    if path is not None:
        options = xla_options.fast_compile_options() if fast_compile else {}
        lowered = jax.jit(exported.call).lower(*exported.in_avals)
        try:
            compiled, stored = stored_executables.compile_and_store(lowered, options, path)
        except Exception:  # an XLA that does not know the options: compiled as usual
            return xla_options.jit(exported.call, fast_compile)
        if stored:
            STATS["executables_stored"] += 1
            _remember(path)
        return compiled
    return xla_options.jit(exported.call, fast_compile)


def _load_executable(key: str, out_tree):
    """The stored executable of ``key`` (prefetched or read now) and ``[out_tree]``, or
    None when there is none or it cannot be read (noted: compiled again)."""
    path = _executable_path(key)
    if path is None:
        return None
    loaded = stored_executables.take_prefetched(path)
    if loaded is not None:
        STATS["prefetched"] += 1
    elif not path.is_file():
        return None
    else:
        try:
            loaded = stored_executables.load(path)
        except Exception as err:
            loaded = err
    if not isinstance(loaded, BaseException) and loaded[1] != out_tree.num_leaves:
        loaded = ValueError(f"{loaded[1]} results where the fit has {out_tree.num_leaves}")
    if isinstance(loaded, BaseException):
        return _unreadable("executables_unreadable", f"stored executable {path}", loaded, "compiling the fit again")
    STATS["executables_loaded"] += 1
    _remember(path)
    return loaded[0], [out_tree]


_CONTEXT: list[str] = []
_RECENT = "recent.json"
_RECENT_KEPT = 64


def prefetch(context: str) -> bool:
    """Start loading, in a background thread, the executable that the last process of
    this ``context`` ran (``pointax fit`` passes its data file), and remember the context
    for the executables this process runs.

    The loaded executable serves a fit only if it is the one the fit asks for (by its
    key). Returns whether a load was started."""
    if _DIRECTORY is None:
        return False
    _CONTEXT[:] = [context]
    name = _recent().get(context)
    if not (isinstance(name, str) and Path(name).name == name and name.endswith(".executable")):
        return False  # none recorded, or not a file of this folder
    if not stored_executables.usable():
        return False
    return stored_executables.prefetch(_DIRECTORY / name)


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
        stored_executables.write_atomically(_DIRECTORY / _RECENT, json.dumps(dict(list(recent.items())[-_RECENT_KEPT:])).encode())
    except OSError:  # a read-only folder: no prefetch next time
        pass

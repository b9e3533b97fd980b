"""Compiled programs kept on disk between runs (JAX's persistent compilation cache).

Compiling a fit is the largest part of a fresh process's first fit; with the cache on,
the next process that fits the same structure loads the compiled program from disk
instead (figures in ``benchmarks/batch_fit_notes.md``). The ``pointax`` command turns it
on for every subcommand (``$POINTAX_JAX_CACHE``); call :func:`enable_compilation_cache`
in your own scripts, before the first computation (JAX sets its cache up at the first
compilation of a process). It sets JAX's public options only
(``jax_compilation_cache_dir``, ``jax_persistent_cache_min_compile_time_secs``).
"""

from __future__ import annotations

import os
from pathlib import Path

import jax

from . import programs

__all__ = ["default_cache_dir", "enable_compilation_cache"]


def default_cache_dir() -> Path | None:
    """``$POINTAX_JAX_CACHE`` (None when it is set empty: no cache), else
    ``$XDG_CACHE_HOME/pointax/jax``, else ``~/.cache/pointax/jax``."""
    value = os.environ.get("POINTAX_JAX_CACHE")
    if value is not None:
        return Path(value).expanduser() if value else None
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "pointax" / "jax"


def enable_compilation_cache(directory: str | os.PathLike | None = None, min_compile_seconds: float = 0.5) -> Path | None:
    """Keep XLA's compiled programs in ``directory`` (default :func:`default_cache_dir`)
    and reuse them in later processes.

    Args:
        directory: where to keep them (created if missing). Safe to share between
            processes; entries are keyed by the program and the JAX/XLA version.
        min_compile_seconds: only programs that took at least this long to compile
            are kept (the small ones are quicker to compile than to load).

    The traced fits go into its ``programs`` folder (:mod:`pointax.fitting.programs`),
    so that a later process does not trace a fit of the same structure again (and
    finds its compiled code in this cache); :func:`pointax.fitting.programs.clear`
    empties it.

    Returns:
        The directory in use, or None when ``$POINTAX_JAX_CACHE`` is empty and no
        ``directory`` is given (the cache stays off).

    Raises:
        OSError: the directory cannot be created.
    """
    path = Path(directory).expanduser() if directory is not None else default_cache_dir()
    if path is None:
        return None
    path.mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", float(min_compile_seconds))
    programs.set_directory(path / "programs")
    return path

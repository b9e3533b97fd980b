"""What the subcommands share: error messages and the check of input paths that runs
before any numerical library is imported."""

from __future__ import annotations

import errno
import os
import sys
from collections.abc import Iterable

__all__ = ["error", "missing_input", "os_error_text"]


def error(prefix: str, message: object) -> int:
    """Print ``{prefix}: error: {message}`` on standard error; the exit status 2."""
    print(f"{prefix}: error: {message}", file=sys.stderr)
    return 2


def missing_input(paths: Iterable[str | os.PathLike | None]) -> str | None:
    """``'PATH: No such file or directory'`` for the first of ``paths`` that does not
    exist (None and '-', standard input, are skipped), else None."""
    for path in paths:
        if path is None or os.fspath(path) == "-":
            continue
        if not os.path.exists(path):
            return f"{os.fspath(path)}: {os.strerror(errno.ENOENT)}"
    return None


def os_error_text(err: OSError, fallback: object) -> str:
    """``'FILE: reason'`` for an OSError (its own file name when it has one)."""
    return f"{err.filename or fallback}: {err.strerror or err}"

"""What the subcommands share: error messages, the check of input paths that runs
before any numerical library is imported, and argument types (:func:`positive_float`)."""

from __future__ import annotations

import argparse
import errno
import os
import sys
import warnings
from collections.abc import Callable, Iterable, Sequence

__all__ = [
    "error", "missing_input", "os_error_text", "guarded_run", "positive_float", "print_warnings",
    "EXIT_OK", "EXIT_SOME_FAILED", "EXIT_BAD_INPUT",
]  # fmt: skip

EXIT_OK = 0
"""Exit status: everything succeeded."""
EXIT_SOME_FAILED = 1
"""Exit status: the input was good, but some item did not succeed (a fit that did not
converge, a direction not commanded, a bad frame, a site that failed)."""
EXIT_BAD_INPUT = 2
"""Exit status: bad input (a file, option or value that could not be used); the message
names the file, line and field."""


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


def guarded_run(prefix: str, body: Callable[[object], int], args, paths: Sequence[str | os.PathLike | None]) -> int:
    """``body(args)``, once each of ``paths`` exists (:func:`missing_input`); bad input
    (ValueError, KeyError, OSError) prints ``prefix: error: ...`` and gives 2 (an
    OSError that names no file is put on ``paths[0]``)."""
    missing = missing_input(paths)
    if missing:
        return error(prefix, missing)
    try:
        return body(args)
    except (ValueError, KeyError) as err:
        return error(prefix, err)
    except OSError as err:
        return error(prefix, os_error_text(err, paths[0]))


def positive_float(text: str) -> float:
    """An ``argparse`` type: ``text`` as a finite positive float, else
    :class:`argparse.ArgumentTypeError` saying why."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"{text!r} must be a positive number")
    return value


def print_warnings(prefix: str = "pointax") -> None:
    """Print every Python warning as ``{prefix}: warning: {message}`` on standard error,
    each time it is issued (pointax's input warnings name file, line and field)."""

    def show(message, category, filename, lineno, file=None, line=None):
        print(f"{prefix}: warning: {message}", file=sys.stderr)

    from ..io.errors import PointaxWarning

    warnings.showwarning = show
    warnings.simplefilter("always", PointaxWarning)

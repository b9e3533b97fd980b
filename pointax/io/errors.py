"""The readers' error and warnings (defined in :mod:`pointax.core.errors`, where the core's
input checks use them too), and the readers' boundary (:func:`file_errors`): whatever
module an error comes from while a file is read, it leaves the reader naming the file."""

from __future__ import annotations

import functools
import os
from collections.abc import Callable

from ..core.errors import FileFormatError, InputWarning, PointaxWarning, warn_input

__all__ = ["FileFormatError", "PointaxWarning", "InputWarning", "warn_input", "file_errors", "unnamed_error_message"]

_TRACEBACK_KINDS = (ArithmeticError, IndexError, KeyError, TypeError, AttributeError, RecursionError, UnicodeError)


def unnamed_error_message(err: BaseException) -> str | None:
    """What a reader's error names when ``err``, raised while a file was read, must be
    raised again naming the file: a check of another module
    (:class:`pointax.core.units.ImplausibleValueError`, :class:`pointax.terms.NotYetInPointax`)
    or an unexpected kind (``TypeError``, ``OverflowError``, ...); None for an error that
    passes as it is (a :class:`FileFormatError`, which names its file, an ``OSError``,
    a plain ``ValueError`` of a bad argument, or anything that is no input error)."""
    if isinstance(err, (FileFormatError, OSError)):
        return None
    from ..core.units import ImplausibleValueError
    from ..terms.linear import NotYetInPointax

    if isinstance(err, ValueError) and not isinstance(err, (ImplausibleValueError, NotYetInPointax, UnicodeError)):
        return None
    if not isinstance(err, (ValueError,) + _TRACEBACK_KINDS):
        return None
    return f"{type(err).__name__}: {err}"


def file_errors(error: type[FileFormatError] | Callable[[str, int | None, str], FileFormatError]):
    """Decorate a reader ``read_x(path, ...)``: an error raised inside it that does not
    name the file (:func:`unnamed_error_message`) is raised again as ``error(path, line,
    message)`` naming the file (and the line, where the error carries one). Its own
    :class:`FileFormatError`, ``OSError`` and plain ``ValueError`` of a bad argument pass
    as they are. ``error`` is the reader's error class, or a function that builds it
    from ``(path, line, message)`` (:meth:`pointax.io.PaintFormatError.in_file`)."""

    def decorate(reader):
        @functools.wraps(reader)
        def read(path, *args, **kwargs):
            try:
                return reader(path, *args, **kwargs)
            except Exception as err:
                message = unnamed_error_message(err)
                if message is None:
                    raise
                raise error(os.fspath(path), getattr(err, "line", None), message) from err

        return read

    return decorate

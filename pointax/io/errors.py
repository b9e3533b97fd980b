"""The readers' error and warnings (defined in :mod:`pointax.core.errors`, where the core's
input checks use them too), and the readers' boundary (:func:`file_errors`): whatever
module an error comes from while a file is read, it leaves the reader naming the file."""

from __future__ import annotations

import functools
import os

from ..core.errors import FileFormatError, InputWarning, PointaxWarning, warn_input

__all__ = ["FileFormatError", "PointaxWarning", "InputWarning", "warn_input", "file_errors"]

_TRACEBACK_KINDS = (ArithmeticError, IndexError, KeyError, TypeError, AttributeError, RecursionError, UnicodeError)


def file_errors(error: type[FileFormatError]):
    """Decorate a reader ``read_x(path, ...)``: an error raised inside it that does not
    name the file (a check of another module, :class:`pointax.core.units.ImplausibleValueError`,
    :class:`pointax.terms.NotYetInPointax`, or an unexpected kind) is raised again as
    ``error`` naming the file (and the line, where the error carries one). Its own
    :class:`FileFormatError`, ``OSError`` and plain ``ValueError`` of a bad argument pass
    as they are."""

    def decorate(reader):
        @functools.wraps(reader)
        def read(path, *args, **kwargs):
            try:
                return reader(path, *args, **kwargs)
            except (FileFormatError, OSError):
                raise
            except Exception as err:
                from ..terms.linear import NotYetInPointax
                from ..core.units import ImplausibleValueError

                if isinstance(err, ValueError) and not isinstance(err, (ImplausibleValueError, NotYetInPointax, UnicodeError)):
                    raise
                if not isinstance(err, (ValueError,) + _TRACEBACK_KINDS):
                    raise
                raise error(os.fspath(path), getattr(err, "line", None), f"{type(err).__name__}: {err}") from err

        return read

    return decorate

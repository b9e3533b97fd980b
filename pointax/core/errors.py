"""The error every file reader raises for bad input, and the warning for input that is
read but looks wrong: both messages name the file, the line and, where known, the field.
Core modules (:class:`pointax.Observations`) warn with them too; the readers take them
from :mod:`pointax.io.errors`."""

from __future__ import annotations

import warnings

__all__ = ["FileFormatError", "PointaxWarning", "InputWarning", "warn_input"]


def _place(path, line: int | None, where: str | None) -> str:
    place = str(path) if line is None else f"{path}:{line}"
    if where:
        place = f"{place}: {where}"
    return place


class FileFormatError(ValueError):
    """A file could not be read; the message reads ``path:line: where: message``.

    Attributes:
        path: the file.
        line: the 1-based line of the problem, or None for the whole file.
    """

    def __init__(self, path, line: int | None, message: str, where: str | None = None):
        self.path, self.line = path, line
        super().__init__(f"{_place(path, line, where)}: {message}")


class PointaxWarning(UserWarning):
    """Base class of pointax's warnings: filter them with
    ``warnings.simplefilter("error", pointax.io.PointaxWarning)`` to make them errors."""


class InputWarning(PointaxWarning):
    """Input that was accepted but looks wrong (duplicated rows, rows after END, a
    nominal model used because none was given, angles that look like the wrong unit).
    The message reads ``path:line: where: message`` like :class:`FileFormatError`'s.

    Attributes:
        path: the file (or the argument, for input given through the API).
        line: the 1-based line, or None.
    """

    def __init__(self, path, line: int | None, message: str, where: str | None = None):
        self.path, self.line = path, line
        super().__init__(f"{_place(path, line, where)}: {message}")


def warn_input(path, line: int | None, message: str, where: str | None = None, stacklevel: int = 3) -> None:
    """Issue an :class:`InputWarning` (Python's :mod:`warnings`; the ``pointax`` command
    prints them on standard error)."""
    warnings.warn(InputWarning(path, line, message, where), stacklevel=stacklevel)

"""The error every file reader raises for bad input: the message names the file, the
line and, where known, the field."""

from __future__ import annotations

__all__ = ["FileFormatError"]


class FileFormatError(ValueError):
    """A file could not be read; the message reads ``path:line: where: message``.

    Attributes:
        path: the file.
        line: the 1-based line of the problem, or None for the whole file.
    """

    def __init__(self, path, line: int | None, message: str, where: str | None = None):
        self.path, self.line = path, line
        place = path if line is None else f"{path}:{line}"
        if where:
            place = f"{place}: {where}"
        super().__init__(f"{place}: {message}")

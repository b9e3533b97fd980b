"""What TPOINT's input files (:mod:`pointax.io.tpoint`) and model files
(:mod:`pointax.io.tpoint_model`) share: the error that names file, line and field, the
mounts pointax reads, and the record syntax.

Both kinds of file are records, one a line (a model file may also hold them all on one
line: :mod:`pointax.io.tpoint_model`): comment lines start with '!' (a '!' later on a
line starts a trailing comment), blank lines are skipped, the first record is a caption
of free text, and an END line ends the file.
"""

from __future__ import annotations

from .errors import FileFormatError
from .sanity import finite_number, warn_after_end

__all__ = ["TpointFormatError", "MOUNTS", "records", "record_numbers"]

MOUNTS = ("altaz", "equatorial")
"""The mounts of the TPOINT runs pointax reads."""


class TpointFormatError(FileFormatError):
    """A TPOINT file could not be read; the message names file, line and field."""


def records(text: str, path: str = "<string>"):
    """Yield ``(line number, text)`` for the caption (first) and each later record.

    Comment lines ('!' first), trailing '!' comments and blank lines are skipped;
    iteration stops at an END line, after yielding ``(line number, "END")``. Records
    after END are ignored, as TPOINT does, with an
    :class:`~pointax.io.errors.InputWarning` naming them.
    """
    have_caption = False
    lines = text.splitlines()
    for lineno, raw in enumerate(lines, 1):
        if raw.lstrip().startswith("!"):
            continue
        if not have_caption:
            if raw.strip():
                have_caption = True
                yield lineno, raw.strip()
            continue
        line = raw.split("!", 1)[0].strip()
        if not line:
            continue
        if line.upper() == "END":
            after = [
                k
                for k, rest in enumerate(lines[lineno:], lineno + 1)
                if rest.split("!", 1)[0].strip() and not rest.lstrip().startswith("!")
            ]
            warn_after_end(path, lineno, after)
            yield lineno, "END"
            return
        yield lineno, line


def record_numbers(
    path: str, lineno: int, tokens: list[str], names: tuple[str, ...], record: str, first: int = 1
) -> list[float]:
    """The finite numbers of ``tokens``, fields of ``record`` named by ``names``; ``first``
    is the field number of ``tokens[0]`` on its line.

    Raises:
        TpointFormatError: for a field that is not a finite number, naming the file, the
            line, the record and the field.
    """
    values = []
    for k, token in enumerate(tokens):
        field = names[k] if k < len(names) else "unnamed"
        values.append(finite_number(TpointFormatError, path, lineno, token, f"{record}: field {first + k} ({field})"))
    return values

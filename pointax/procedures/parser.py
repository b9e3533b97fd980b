"""Reading TPOINT command lines: words, arguments, abbreviations, where each line is from.

A command line is a command word and its arguments separated by blanks; ``!`` starts
a comment, as in TPOINT's files, and blank lines are skipped. Command words are
case-insensitive and may be abbreviated to any prefix of two or more letters that
names one command only (``OUTM`` is OUTMOD; ``FI`` is refused: FIT or FIX). A word
that is not a command may be a procedure's name (``PROC NAME``). Words beginning
with ``G`` other than ``GC`` are TPOINT's graphics commands (``G S A``, ``GSMAP``);
the whole line then names the plot.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Iterator
from pathlib import Path

__all__ = [
    "Line", "ProcedureError", "COMMANDS", "NOTED_SETTINGS", "PLOT_PROCEDURES", "read_script", "lines_of", "split", "resolve",
]  # fmt: skip

COMMANDS = (
    "INDAT",
    "INMOD",
    "OUTMOD",
    "USE",
    "LOSE",
    "FIX",
    "UNFIX",
    "FIT",
    "SLIST",
    "MASK",
    "UNMASK",
    "FAUTO",
    "SHOW",
    "PROC",
    "RETURN",
    "INPRO",
    "CALL",
    "GC",
    "CAPT",
    "END",
    "EXIT",
    "QUIT",
    "HELP",
)
"""The command words pointax runs (G commands besides: any word starting with G)."""

NOTED_SETTINGS = ("CLRNG", "PLTZ", "PLTE", "PLTA", "GSCALE", "GRID", "DEVICE", "PAUSE", "PLTON")
"""Display settings of TPOINT's graphics accepted with a note (they change nothing in
pointax's plots). CAPT, the caption, is honoured."""

PLOT_PROCEDURES = ("A9", "E9")
"""TPOINT's plot sets that its sessions run as procedures (``CALL A9``): built in here,
bare or called, unless a procedure of that name is defined."""


class ProcedureError(Exception):
    """An error in a command line; ``str()`` is ``'FILE:LINE: message'``."""

    def __init__(self, line: "Line | None", message: str):
        self.line = line
        self.message = message
        where = f"{line.file}:{line.number}: " if line is not None else ""
        super().__init__(f"{where}{message}")


@dataclasses.dataclass(frozen=True)
class Line:
    """One command line and where it came from.

    Attributes:
        text: the line as written (comment included).
        file: the file's name as given, or ``'<stdin>'``.
        number: line number in that file, from 1.
        folder: the folder that relative file names on this line are taken from
            (the script's folder; the working folder for standard input).
    """

    text: str
    file: str
    number: int
    folder: Path

    def path(self, name: str) -> Path:
        """``name`` taken relative to :attr:`folder` (an absolute name as it is)."""
        p = Path(name).expanduser()
        return p if p.is_absolute() else self.folder / p


def lines_of(text_lines: Iterable[str], file: str, folder: Path) -> Iterator[Line]:
    """:class:`Line` objects for ``text_lines`` of ``file`` (numbered from 1)."""
    for number, text in enumerate(text_lines, 1):
        yield Line(text.rstrip("\r\n"), file, number, folder)


def read_script(path: str | Path) -> list[Line]:
    """The lines of a command file; relative names in it are taken from its folder.

    Raises:
        OSError: the file cannot be read.
        ProcedureError: the file is not text.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as err:
        raise ProcedureError(None, f"{path}: not a text file ({err})") from None
    return list(lines_of(text.splitlines(), str(path), path.resolve().parent))


def split(text: str) -> tuple[str, list[str]] | None:
    """``(WORD, arguments)`` of a command line (word upper-cased, arguments as
    written), or None for a blank or comment line."""
    body = text.split("!", 1)[0].strip()
    if not body:
        return None
    tokens = body.split()
    return tokens[0].upper(), tokens[1:]


def resolve(word: str, procedures: Iterable[str] = ()) -> str:
    """What a command word means: a name from :data:`COMMANDS`, ``'G'`` for a graphics
    command, ``'NOTED'`` for a setting of :data:`NOTED_SETTINGS`, or ``'PROC:NAME'``
    for a defined procedure. Exact command names come first, then procedure names,
    then unambiguous abbreviations (two letters or more).

    Raises:
        ValueError: an unknown or ambiguous word (naming the candidates).
    """
    word = word.upper()
    if word in COMMANDS:
        return word
    if word in NOTED_SETTINGS:
        return "NOTED"
    procedures = {p.upper() for p in procedures}
    if word in procedures:
        return f"PROC:{word}"
    if word.startswith("G") or word in PLOT_PROCEDURES:
        return "G"
    if len(word) >= 2:
        matches = [c for c in COMMANDS if c.startswith(word)]
        if len(matches) == 1:
            return matches[0]
        if len(matches) > 1:
            raise ValueError(f"{word} is ambiguous: {', '.join(matches)}")
    known = ", ".join(COMMANDS)
    defined = f"; procedures defined: {', '.join(sorted(procedures))}" if procedures else ""
    raise ValueError(f"unknown command {word} (commands: {known}, G... graphics{defined})")

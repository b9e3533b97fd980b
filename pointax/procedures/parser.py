"""Reading TPOINT command lines: words, arguments, abbreviations, where each line is from.

A command line is a command word and its arguments separated by blanks. ``!`` and ``;``
start a comment (outside quotes), as in observatories' files; blank lines are skipped.
An argument may be quoted, ``"run.dat"`` or ``'run.dat'`` (the quotes are dropped, so a
file name may hold blanks; a quoted word is never read as a keyword: ``CAPT "ON"`` is a
caption). Command words are case-insensitive and may be abbreviated to any prefix of
two or more letters that names one command only (``OUTM`` is OUTMOD; ``FI`` is refused:
FIT or FIX). A word that is not a command may be a procedure's name (``PROC NAME``).
Words beginning with ``G`` other than ``GC`` are TPOINT's graphics commands (``G S A``,
``GSMAP``, ``GSCAT A``).

The words fall in four sets: :data:`COMMANDS` (run), :data:`NOTED_SETTINGS` (display
settings accepted with a note), :data:`NOT_IMPLEMENTED` (TPOINT commands pointax does
not run: a one-line note, and the script goes on) and graphics (:data:`GRAPHICS_NOT_DRAWN`
among them gets a note). Any other word is an error naming file and line.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Iterator
from pathlib import Path

__all__ = [
    "Line", "ProcedureError", "Quoted", "COMMANDS", "NOTED_SETTINGS", "NOT_IMPLEMENTED", "GRAPHICS_NOT_DRAWN",
    "PLOT_PROCEDURES", "read_script", "lines_of", "split", "tokens", "resolve", "known_words",
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
    "ADJUST",
    "PROC",
    "RETURN",
    "INPRO",
    "CALL",
    "GC",
    "CAPT",
    "PLTZ",
    "END",
    "EXIT",
    "QUIT",
    "HELP",
)
"""The command words pointax runs (G commands besides: any word starting with G)."""

NOTED_SETTINGS = ("CLRNG", "PLTE", "PLTA", "GSCALE", "GRID", "DEVICE", "PAUSE", "PLTON")
"""Display settings of TPOINT's graphics accepted with a note (they change nothing in
pointax's plots). CAPT (caption and caption switch) and PLTZ (panel) are honoured."""

NOT_IMPLEMENTED = {
    "OUTDAT": "write the pointing data as a TPOINT file",
    "OUTPRO": "write the defined procedures to a file",
    "CHAIN": "chain the following terms (model structure)",
    "PARALLEL": "parallel terms (model structure)",
}
"""TPOINT commands pointax does not run, with what each does in TPOINT: a script that
uses one gets a one-line note naming it and goes on."""

GRAPHICS_NOT_DRAWN = {"GHYST": "TPOINT's hysteresis plot"}
"""TPOINT graphics commands pointax does not draw: a one-line note, and the script goes on."""

PLOT_PROCEDURES = ("A9", "E9")
"""TPOINT's plot sets that its sessions run as procedures (``CALL A9``): built in here,
bare or called, unless a procedure of that name is defined."""


def known_words() -> tuple[str, ...]:
    """Every word :func:`resolve` takes (abbreviated or not), in :data:`COMMANDS` order,
    then the noted settings, then the commands not implemented."""
    return COMMANDS + NOTED_SETTINGS + tuple(NOT_IMPLEMENTED)


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


class Quoted(str):
    """An argument written in quotes (``"ON"``): text, never a keyword."""


_COMMENT = "!;"
_QUOTES = "\"'"


def tokens(text: str) -> list[str]:
    """The words of a command line: blanks separate them, ``!`` or ``;`` outside quotes
    starts a comment, and ``"..."`` or ``'...'`` is one word without its quotes (a
    :class:`Quoted`).

    Raises:
        ValueError: a quote not closed on the line.
    """
    out: list[str] = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c in _COMMENT:
            break
        if c.isspace():
            i += 1
        elif c in _QUOTES:
            close = text.find(c, i + 1)
            if close < 0:
                raise ValueError(f"the quote {c} opened at column {i + 1} is not closed")
            out.append(Quoted(text[i + 1 : close]))
            i = close + 1
        else:
            j = i
            while j < n and not text[j].isspace() and text[j] not in _COMMENT + _QUOTES:
                j += 1
            out.append(text[i:j])
            i = j
    return out


def split(text: str) -> tuple[str, list[str]] | None:
    """``(WORD, arguments)`` of a command line (word upper-cased, arguments as
    written, quoted ones as :class:`Quoted`), or None for a blank or comment line.

    Raises:
        ValueError: a quote not closed on the line.
    """
    words = tokens(text)
    if not words:
        return None
    return words[0].upper(), words[1:]


def resolve(word: str, procedures: Iterable[str] = ()) -> str:
    """What a command word means: its full name when it is one of :func:`known_words`
    (a command, a noted setting, or a TPOINT command not implemented), ``'G'`` for a
    graphics command, or ``'PROC:NAME'`` for a defined procedure. Exact names come
    first, then procedure names, then graphics words, then unambiguous abbreviations
    (two letters or more).

    Raises:
        ValueError: an unknown or ambiguous word (naming the candidates).
    """
    word = word.upper()
    known = known_words()
    if word in known:
        return word
    procedures = {p.upper() for p in procedures}
    if word in procedures:
        return f"PROC:{word}"
    if word.startswith("G") or word in PLOT_PROCEDURES:
        return "G"
    if len(word) >= 2:
        matches = [c for c in known if c.startswith(word)]
        if len(matches) == 1:
            return matches[0]
        if len(matches) > 1:
            raise ValueError(f"{word} is ambiguous: {', '.join(matches)}")
    defined = f"; procedures defined: {', '.join(sorted(procedures))}" if procedures else ""
    raise ValueError(
        f"unknown command {word} (commands: {', '.join(COMMANDS)}, G... graphics; "
        f"settings noted: {', '.join(NOTED_SETTINGS)}{defined})"
    )

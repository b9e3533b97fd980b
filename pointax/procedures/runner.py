"""Running TPOINT command lines: scripts, procedures and interactive input.

* ``PROC NAME [free text]`` ... ``RETURN`` defines a procedure (its lines are kept,
  not run; the text after the name is a comment);
  ``CALL NAME`` or ``NAME`` alone runs it; ``INPRO FILE`` reads a file of procedure
  definitions (lines outside PROC ... RETURN there are an error).
* ``END``, ``EXIT`` and ``QUIT`` stop reading the current file (or standard input).
* File names are taken relative to the folder of the file the command is in (the
  working folder for standard input).

In a script the first error stops the run with a message ``FILE:LINE: error: ...``
(procedures: the line inside the procedure, and where it was called from); an
interactive session prints the error and goes on.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TextIO

from .tpoint_commands import COMMAND_FUNCTIONS, LIGHT_COMMANDS
from .parser import PLOT_PROCEDURES, Line, ProcedureError, lines_of, read_script, resolve, split
from .session import Session

__all__ = ["Runner", "MAX_DEPTH"]

MAX_DEPTH = 32
"""Most nested CALLs (a procedure that calls itself stops here)."""

_STOP = ("END", "EXIT", "QUIT")


class _Stop(Exception):
    """END, EXIT or QUIT: stop reading the current input."""


def _split_or_none(line: Line) -> tuple[str, list[str]] | None:
    """:func:`split` of a line inside a procedure's definition; a line that cannot be
    read (an unclosed quote) is kept as it is, and its error comes when it runs."""
    try:
        return split(line.text)
    except ValueError:
        return ("", [])


class Runner:
    """Runs command lines on a :class:`Session`.

    Args:
        session: the state commands change.
        err: where errors go (standard error by default).
    """

    def __init__(self, session: Session, err: TextIO | None = None):
        self.session = session
        self.err = err if err is not None else sys.stderr
        self.depth = 0

    # ------------------------------------------------------------------ inputs

    def run_file(self, path: str | Path) -> None:
        """Run a command file.

        Raises:
            ProcedureError: at the first error, naming file and line.
        """
        try:
            lines = read_script(path)
        except OSError as err:
            raise ProcedureError(None, f"{path}: {err.strerror or err}") from None
        self.run_lines(iter(lines), interactive=False)

    def run_stream(self, stream: TextIO, interactive: bool, prompt: str = "pointax> ", name: str = "<stdin>") -> int:
        """Run lines read from ``stream`` (standard input). Interactively, each line
        is prompted for and an error is printed and passed over. Returns the number
        of errors."""
        folder = Path.cwd()

        def read() -> Iterator[str]:
            while True:
                if interactive and stream is sys.stdin:
                    try:
                        text = input(prompt) + "\n"  # line editing where readline is at hand
                    except EOFError:
                        text = ""
                else:
                    if interactive:
                        print(prompt, end="", file=self.session.out, flush=True)
                    text = stream.readline()
                if not text:
                    if interactive:
                        print(file=self.session.out)
                    return
                yield text

        return self.run_lines(lines_of(read(), name, folder), interactive=interactive)

    # ------------------------------------------------------------------ lines

    def run_lines(self, lines: Iterator[Line], interactive: bool = False) -> int:
        """Run ``lines`` (an iterator: PROC reads its body from it). Returns the number
        of errors (interactive); raises :class:`ProcedureError` at the first error
        otherwise."""
        errors = 0
        for line in lines:
            try:
                self.run_line(line, lines)
            except _Stop:
                break
            except ProcedureError as err:
                if not interactive:
                    raise
                errors += 1
                print(f"error: {err}", file=self.err)
        return errors

    def run_line(self, line: Line, rest: Iterator[Line] | None = None) -> None:
        """Run one line (``rest``: the lines after it, for PROC's body).

        Raises:
            ProcedureError: naming the line, for an unknown command or a failure.
        """
        try:
            parsed = split(line.text)
            if parsed is None:
                return
            word, args = parsed
            what = resolve(word, self.session.procedures)
        except ValueError as err:
            raise ProcedureError(line, str(err)) from None
        if what in _STOP:
            raise _Stop
        if what == "PROC":
            self._define(line, args, rest)
        elif what == "RETURN":
            raise ProcedureError(line, "RETURN outside a procedure definition (PROC NAME ... RETURN)")
        elif what == "INPRO":
            self._inpro(line, args)
        elif what == "CALL" or what.startswith("PROC:"):
            name = what[5:] if what.startswith("PROC:") else (args[0].upper() if len(args) == 1 else None)
            if name is None:
                raise ProcedureError(line, "CALL needs one procedure name")
            self._call(line, name)
        else:
            if what == "G":  # the graphics word itself names the plot (GSCAT, GAM, G)
                args = [word, *args]
            try:
                if what not in LIGHT_COMMANDS:
                    self.session.ready()
                COMMAND_FUNCTIONS[what](self.session, args, line)
            except ProcedureError:
                raise
            except (ValueError, KeyError, OSError, TypeError, ImportError) as err:
                text = f"{err.filename}: {err.strerror}" if isinstance(err, OSError) and err.filename else str(err)
                if isinstance(err, KeyError):
                    text = str(err.args[0]) if err.args else text
                raise ProcedureError(line, f"{word}: {text}") from None

    # ------------------------------------------------------------------ procedures

    def _define(self, line: Line, args: list[str], rest: Iterator[Line] | None) -> None:
        """PROC NAME [free text]: keep the lines up to RETURN as procedure NAME (the
        text after the name is a comment, as observatories write it:
        ``PROC A9   (9 favourite plots for an altaz)``)."""
        if not args:
            raise ProcedureError(line, "PROC needs a procedure name (PROC NAME [comment])")
        name = args[0].upper()
        if name not in PLOT_PROCEDURES:  # TPOINT's A9 and E9 are procedures: redefinable
            try:
                resolve(name)
            except ValueError:
                pass
            else:
                raise ProcedureError(line, f"PROC {name}: that is a command's name (or abbreviation)")
        body: list[Line] = []
        for inner in rest if rest is not None else ():
            parsed = _split_or_none(inner)
            if parsed is not None and parsed[0] == "RETURN":
                self.session.procedures[name] = body
                return
            if parsed is not None and parsed[0] == "PROC":
                raise ProcedureError(inner, f"PROC inside the definition of {name} (end it with RETURN first)")
            body.append(inner)
        raise ProcedureError(line, f"PROC {name}: no RETURN before the end of {line.file}")

    def _inpro(self, line: Line, args: list[str]) -> None:
        if len(args) != 1:
            raise ProcedureError(line, "INPRO needs one file name")
        path = line.path(args[0])
        try:
            lines = iter(read_script(path))
        except OSError as err:
            raise ProcedureError(line, f"INPRO: {path}: {err.strerror or err}") from None
        before = set(self.session.procedures)
        for inner in lines:
            try:
                parsed = split(inner.text)
            except ValueError as err:
                raise ProcedureError(inner, str(err)) from None
            if parsed is None:
                continue
            if parsed[0] != "PROC":
                raise ProcedureError(inner, f"INPRO reads procedure definitions (PROC NAME ... RETURN), not {parsed[0]}")
            self._define(inner, parsed[1], lines)
        new = sorted(set(self.session.procedures) - before)
        self.session.say(f"INPRO: {path}: procedures {' '.join(new) or '(none new)'}")

    def _call(self, line: Line, name: str) -> None:
        body = self.session.procedures.get(name)
        if body is None and name in PLOT_PROCEDURES:  # TPOINT's CALL A9: the built-in set
            self.run_line(dataclasses.replace(line, text=name))
            return
        if body is None:
            known = ", ".join(sorted(self.session.procedures)) or "none"
            raise ProcedureError(line, f"CALL {name}: no such procedure (defined: {known})")
        if self.depth >= MAX_DEPTH:
            raise ProcedureError(line, f"CALL {name}: more than {MAX_DEPTH} nested calls")
        self.depth += 1
        try:
            lines = iter(body)
            for inner in lines:
                try:
                    self.run_line(inner, lines)
                except ProcedureError as err:
                    if getattr(err, "called", False):  # the innermost call is named already
                        raise
                    where = f" (in procedure {name}, called at {line.file}:{line.number})"
                    wrapped = ProcedureError(err.line, f"{err.message}{where}")
                    wrapped.called = True
                    raise wrapped from None
        finally:
            self.depth -= 1

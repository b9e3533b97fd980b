"""What TPOINT's input files (:mod:`pointax.io.tpoint`) and model files
(:mod:`pointax.io.tpoint_model`) share: the error that names file, line and field, the
mounts pointax reads, and the record syntax.

Both kinds of file are records, one a line (a model file may also hold them all on one
line: :mod:`pointax.io.tpoint_model`): comment lines start with '!' or ';' (a '!' or ';'
later on a line starts a trailing comment, as observatories' files put them after
observation records), blank lines are skipped, the first record is a caption of free
text, and an END line ends the file.

Option records (``: ALTAZ``, ``:NODA``, ...) of input files are read into
:class:`OptionRecord` by :func:`option_records` and checked by :func:`check_options`:
each is applied by the reader or named in an :class:`~pointax.io.InputWarning`.
"""

from __future__ import annotations

import dataclasses
import re

from .errors import FileFormatError, warn_input
from .sanity import finite_number, warn_after_end
from .text import is_number

__all__ = [
    "TpointFormatError",
    "MOUNTS",
    "OptionRecord",
    "option_records",
    "check_options",
    "records",
    "record_numbers",
    "strip_comment",
]

_COMMENT = re.compile(r"[!;]")

MOUNTS = ("altaz", "equatorial")
"""The mounts of the TPOINT runs pointax reads."""


class TpointFormatError(FileFormatError):
    """A TPOINT file could not be read; the message names file, line and field."""


def records(text: str, path: str = "<string>"):
    """Yield ``(line number, text)`` for the caption (first) and each later record.

    Comment lines ('!' or ';' first), trailing '!' or ';' comments and blank lines are
    skipped (the caption is free text: it is kept whole);
    iteration stops at an END line, after yielding ``(line number, "END")``. Records
    after END are ignored, as TPOINT does, with an
    :class:`~pointax.io.errors.InputWarning` naming them.
    """
    have_caption = False
    lines = text.splitlines()
    for lineno, raw in enumerate(lines, 1):
        if raw.lstrip()[:1] in ("!", ";"):
            continue
        if not have_caption:
            if raw.strip():
                have_caption = True
                yield lineno, raw.strip()
            continue
        line = strip_comment(raw)
        if not line:
            continue
        if line.upper() == "END":
            after = [
                k
                for k, rest in enumerate(lines[lineno:], lineno + 1)
                if strip_comment(rest)
            ]
            warn_after_end(path, lineno, after)
            yield lineno, "END"
            return
        yield lineno, line


def strip_comment(line: str) -> str:
    """``line`` without its trailing '!' or ';' comment, stripped of blanks."""
    return _COMMENT.split(line, 1)[0].strip()


@dataclasses.dataclass(frozen=True)
class OptionRecord:
    """An option record of a TPOINT input file: ``: KEYWORD [arguments]``."""

    keyword: str
    """The option, upper case (TPOINT reads them case-insensitively)."""
    arguments: tuple[str, ...]
    """Any further words (``: GIMBAL 0 90 0``), as written."""
    line: int

    def __str__(self) -> str:
        return f"': {' '.join((self.keyword,) + self.arguments)}'"


def option_records(path: str, lineno: int, line: str) -> list[OptionRecord]:
    """The options of the option record ``line`` (its ':' first) read at ``lineno``:
    each word is an option keyword (``: EQUAT ROTNR`` holds two), each number an argument
    of the keyword before it (``: GIMBAL 0 90 0``).

    Raises:
        TpointFormatError: for a ':' with no keyword after it, or a number first.
    """
    words = line[1:].split()
    if not words:
        raise TpointFormatError(path, lineno, "option record: field 1 (option keyword) is missing after ':'")
    if is_number(words[0]):
        raise TpointFormatError(path, lineno, f"option record: field 1 (option keyword) {words[0]!r} is a number")
    options: list[OptionRecord] = []
    for word in words:
        if is_number(word):
            last = options[-1]
            options[-1] = dataclasses.replace(last, arguments=last.arguments + (word,))
        else:
            options.append(OptionRecord(word.upper(), (), lineno))
    return options


ALTAZ_OPTION = "ALTAZ"
EQUATORIAL_OPTIONS = frozenset({"EQUAT", "GERMAN", "FORK"})
UNSUPPORTED_MOUNT_OPTIONS = frozenset({"ALTALT", "XY", "GIMBAL"})
MOUNT_OPTIONS = frozenset({ALTAZ_OPTION}) | EQUATORIAL_OPTIONS | UNSUPPORTED_MOUNT_OPTIONS
"""The option records that say a run's mount."""
ROTATOR_OPTIONS = frozenset({"ROTTEL", "ROTNL", "ROTNR", "ROTCL", "ROTCR"})
"""Option records that say each observation record ends with a rotator angle."""
NO_DIURNAL_ABERRATION = "NODA"
"""The option that says TPOINT is not to apply diurnal aberration to the star places:
pointax never does, so it is applied as it stands."""
UNAPPLIED_OPTIONS = {
    "ALLSKY": "TPOINT's all-sky option",
}
"""Option records TPOINT defines that pointax reads but does not apply (each gets an
:class:`~pointax.io.InputWarning`), with what they say."""
OPTIONS_WITH_ARGUMENTS = frozenset({"GIMBAL"})
"""Options that take arguments (``: GIMBAL z y x``); the others take none."""


def check_options(path: str, options: list[OptionRecord]) -> None:
    """Refuse contradictory mount options and arguments where an option takes none;
    warn of each option pointax does not apply (none is dropped unsaid)."""
    for option in options:
        if option.arguments and option.keyword not in OPTIONS_WITH_ARGUMENTS:
            raise TpointFormatError(
                path, option.line, f"option record {option}: option {option.keyword} takes no arguments "
                f"({option.arguments[0]!r} given)"
            )
    _check_mounts(path, [o for o in options if o.keyword in MOUNT_OPTIONS])
    for option in options:
        if option.keyword in UNAPPLIED_OPTIONS:
            _warn_option(path, option, f"{UNAPPLIED_OPTIONS[option.keyword]}, which pointax does not apply")
        elif option.keyword not in KNOWN_OPTIONS:
            guess = suggest_option(option.keyword)
            hint = f"; did you mean {guess}?" if guess else ""
            _warn_option(path, option, f"not a TPOINT option pointax knows; it is not applied{hint}")


KNOWN_OPTIONS = MOUNT_OPTIONS | ROTATOR_OPTIONS | {NO_DIURNAL_ABERRATION} | frozenset(UNAPPLIED_OPTIONS)
"""Every option keyword pointax reads (applied, refused or warned of by name)."""


def suggest_option(keyword: str, among=None) -> str | None:
    """The known option ``keyword`` most likely misspells (``ALTAZZ`` -> ``ALTAZ``), or None."""
    import difflib

    close = difflib.get_close_matches(keyword, sorted(among or KNOWN_OPTIONS), n=1, cutoff=0.7)
    return close[0] if close else None


def misspelt_mount(path: str, options: list[OptionRecord]) -> None:
    """Refuse an unknown option that misspells a mount option (``: ALTAZZ``), naming
    it, its line and the option meant: called where a run names no mount, so that the
    typo, not a missing record, is reported."""
    for option in options:
        if option.keyword in KNOWN_OPTIONS:
            continue
        guess = suggest_option(option.keyword, MOUNT_OPTIONS)
        if guess:
            raise TpointFormatError(
                path,
                option.line,
                f"unknown option {option.keyword} on line {option.line}; did you mean {guess}? (the run names no "
                "mount otherwise)",
            )


def _check_mounts(path: str, mounts: list[OptionRecord]) -> None:
    """Refuse mounts pointax does not read, alt-az with equatorial options, and a German
    with a fork mount."""
    for option in mounts:
        if option.keyword in UNSUPPORTED_MOUNT_OPTIONS:
            raise TpointFormatError(
                path, option.line, f"mount option {option.keyword}: pointax reads TPOINT alt-az (': ALTAZ') "
                "and equatorial (': EQUAT', ': GERMAN', ': FORK') runs"
            )
    for k, later in enumerate(mounts):
        for earlier in mounts[:k]:
            pair = {earlier.keyword, later.keyword}
            altaz_and_equatorial = ALTAZ_OPTION in pair and bool(pair & EQUATORIAL_OPTIONS)
            if altaz_and_equatorial or pair == {"GERMAN", "FORK"}:
                raise TpointFormatError(
                    path, later.line, f"contradictory mount options: {earlier.keyword}, {later.keyword}: "
                    f"{earlier} on line {earlier.line} and {later} on line {later.line}"
                )


def _warn_option(path: str, option: OptionRecord, message: str) -> None:
    warn_input(path, option.line, f"option record {option}: {message}", stacklevel=6)


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

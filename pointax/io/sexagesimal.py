"""Angles written as groups of fields: ``h m s``, ``d m s``, ``d m.m`` or one decimal
number, as TPOINT files write them.

The sign belongs to the first field and is read from its text, so ``-00 30 00`` is
-0.5 (a signed zero degrees); the later fields are unsigned minutes and seconds below
60. Each malformed field raises the reader's error naming the file, the line and the
field's number and name.
"""

from __future__ import annotations

import dataclasses

from .errors import FileFormatError
from .sanity import finite_number

__all__ = ["Group", "group_value", "layout_fields"]


@dataclasses.dataclass(frozen=True)
class Group:
    """One angle of a record: how many fields it takes (1 decimal, 2 ``d m.m``, 3
    ``d m s``), its name and its unit ('h' hours, 'deg' degrees, '' a plain number)."""

    width: int
    name: str
    unit: str = "deg"


def layout_fields(layout: tuple[Group, ...]) -> int:
    """How many whitespace-separated fields a record of ``layout`` has."""
    return sum(g.width for g in layout)


def group_value(
    error: type[FileFormatError], path: str, line: int, tokens: list[str], first: int, group: Group, record: str
) -> float:
    """The value of ``group`` read from ``tokens`` (its fields), in the group's unit.

    ``first`` is the field number of ``tokens[0]`` on the line (1-based).
    """
    values = []
    for k, token in enumerate(tokens):
        part = ("", " (minutes)", " (seconds)")[k] if group.width > 1 else ""
        where = f"{record}: field {first + k} ({group.name}{part})"
        value = finite_number(error, path, line, token, where)
        if k > 0:
            if token.lstrip()[:1] in "+-":
                raise error(path, line, f"{where} is {token!r}: only the first field of an angle carries a sign")
            if not 0.0 <= value < 60.0:
                raise error(path, line, f"{where} is {token!r}, not within 0..60")
            if k == 1 and group.width == 3 and value != int(value):
                raise error(path, line, f"{where} is {token!r}: whole minutes are expected before the seconds")
        elif group.width > 1 and value != int(value):
            raise error(path, line, f"{where} is {token!r}: whole {'hours' if group.unit == 'h' else 'degrees'} are expected before the minutes")
        values.append(value)
    negative = tokens[0].lstrip().startswith("-")
    magnitude = abs(values[0]) + sum(v / 60.0**k for k, v in enumerate(values[1:], 1))
    return -magnitude if negative else magnitude

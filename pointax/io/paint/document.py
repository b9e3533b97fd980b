"""PAINT files: their names, the error every reader raises, and typed access to a
parsed JSON file that names the field and line of a bad value. See :mod:`pointax.io.paint`."""

from __future__ import annotations

import bisect
import contextlib
import json
import math
import os
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from ..errors import FileFormatError, unnamed_error_message

__all__ = [
    "FOCAL_SPOT_METHODS",
    "HELIOSTAT_FILE",
    "CALIBRATION_SUFFIX",
    "TOWER_FILE",
    "POWER_PLANT_KEY",
    "KINEMATICS_KEYS",
    "LAYOUT_CURRENT",
    "LAYOUT_SCHEMA1",
    "PaintFormatError",
    "JsonDocument",
    "describe_value",
    "frozen_array",
    "value_lines",
]

FOCAL_SPOT_METHODS = ("HeliOS", "UTIS")
"""The focal-spot centroid methods of PAINT, in fall-back order."""
HELIOSTAT_FILE = "heliostat-properties.json"
CALIBRATION_SUFFIX = "-calibration-properties.json"
TOWER_FILE = "tower-measurements.json"
POWER_PLANT_KEY = "power_plant_properties"

LAYOUT_CURRENT = "kinematics_properties (current)"
"""The layout of ``heliostat-properties.json`` in current PAINT releases: a
``kinematics_properties`` block, ``initial_orientation`` (0, -1, 0), linear actuators."""
LAYOUT_SCHEMA1 = "kinematic_properties (schema 1)"
"""The earlier layout (PAINT's first schema, e.g. ARTIST's AC43 tutorial files): a
``kinematic_properties`` block, ``initial_orientation`` (0, 0, 1), actuators typed
``"ideal"``, nonzero joint and concentrator translations."""
KINEMATICS_KEYS = {LAYOUT_CURRENT: "kinematics_properties", LAYOUT_SCHEMA1: "kinematic_properties"}
"""The name of the kinematics block in each layout."""


class PaintFormatError(FileFormatError):
    """A PAINT JSON file could not be read.

    Attributes:
        path: the file (or folder).
        field: JSON path of the offending field, e.g.
            ``kinematics_properties.actuators[1].increment`` (``None`` for whole-file
            problems such as malformed JSON).
        line: line in the file of that field (of the enclosing object when the field
            is missing; of the syntax error for malformed JSON), or ``None``.
        message: what is wrong.
    """

    def __init__(self, path: str, field: str | None, message: str, line: int | None = None):
        self.field, self.message = field, message
        super().__init__(path, line, message, f"field {field}" if field else None)

    @classmethod
    def in_file(cls, path: str, line: int | None, message: str) -> "PaintFormatError":
        """The error for ``path`` (and ``line``) with no field: the factory
        :func:`pointax.io.errors.file_errors` builds the PAINT readers' errors with."""
        return cls(path, None, message, line)


# --------------------------------------------------------------------------- JSON access


def describe_value(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"the boolean {json.dumps(value)}"
    if isinstance(value, str):
        return f"the string {value!r}"
    if isinstance(value, dict):
        return "an object"
    if isinstance(value, list):
        return f"an array of {len(value)}"
    return repr(value)


_LAST_PART = re.compile(r"(\.[^.\[]*|\[\d+\])$")


def value_lines(text: str) -> dict[str, int]:
    """Line number (1-based) of every value in a valid JSON text, keyed by JSON path
    (root ``""``, then ``a.b[2].c``)."""
    newlines = [m.start() for m in re.finditer("\n", text)]
    decoder = json.JSONDecoder()
    lines: dict[str, int] = {}
    space = " \t\n\r"

    def skip(i: int) -> int:
        while i < len(text) and text[i] in space:
            i += 1
        return i

    def walk(i: int, path: str) -> int:
        i = skip(i)
        lines[path] = bisect.bisect_left(newlines, i) + 1
        if text[i] == "{":
            i = skip(i + 1)
            if text[i] == "}":
                return i + 1
            while True:
                key, i = json.decoder.scanstring(text, i + 1)
                i = skip(i) + 1  # past ':'
                i = skip(walk(i, f"{path}.{key}" if path else key))
                if text[i] == "}":
                    return i + 1
                i = skip(i + 1)  # past ','
        if text[i] == "[":
            i = skip(i + 1)
            if text[i] == "]":
                return i + 1
            k = 0
            while True:
                i = skip(walk(i, f"{path}[{k}]"))
                if text[i] == "]":
                    return i + 1
                i, k = i + 1, k + 1
        return decoder.raw_decode(text, i)[1]

    walk(0, "")
    return lines


class _DuplicateKey(ValueError):
    """A key given twice in one JSON object (``args[0]``)."""


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """``json``'s ``object_pairs_hook``: the object, refusing a key given twice (the
    plain reader would keep the last one silently)."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKey(key)
        out[key] = value
    return out


class JsonDocument:
    """One parsed JSON file plus typed accessors that raise :class:`PaintFormatError`."""

    def __init__(self, path: str | os.PathLike):
        self.path = os.fspath(path)
        self.field = ""  # the JSON path last asked for: the field an unexpected error is named with
        try:
            data = Path(self.path).read_bytes()
            self.text = data.decode("utf-8-sig")
        except UnicodeDecodeError as err:
            line = data[: err.start].count(b"\n") + 1
            column = err.start - (data.rfind(b"\n", 0, err.start) + 1) + 1
            raise PaintFormatError(
                self.path, None, f"column {column}: byte 0x{data[err.start]:02x} is not UTF-8 (JSON files are UTF-8)",
                line=line,
            ) from None
        try:
            self.data = json.loads(self.text, object_pairs_hook=_unique_keys)
        except json.JSONDecodeError as err:
            raise PaintFormatError(
                self.path, None, f"malformed JSON: {err.msg} (column {err.colno})", line=err.lineno
            ) from None
        except _DuplicateKey as err:
            key = err.args[0]
            found = [self.text.count("\n", 0, m.start()) + 1 for m in re.finditer(re.escape(json.dumps(key)) + r"\s*:", self.text)]
            where = f" (lines {', '.join(map(str, found))})" if found else ""
            raise PaintFormatError(
                self.path,
                None,
                f"key {key!r} is given twice in one object{where}: JSON readers keep the last silently; "
                "remove the one that is wrong",
                line=found[-1] if found else None,
            ) from None
        except RecursionError:
            raise PaintFormatError(self.path, None, "JSON nested too deeply to read") from None
        except ValueError as err:  # e.g. an integer of more digits than Python converts
            raise PaintFormatError(self.path, None, f"unreadable JSON: {err}") from None
        self._lines: dict[str, int] | None = None

    def line_of(self, field: str) -> int | None:
        if self._lines is None:
            try:
                self._lines = value_lines(self.text)
            except (ValueError, IndexError, RecursionError):  # not expected: the JSON parsed
                self._lines = {}
        while field not in self._lines:  # a missing field: the line of its parent
            if not field:
                return None
            parent = _LAST_PART.sub("", field)
            field = "" if parent == field else parent
        return self._lines[field]

    def fail(self, field: str, message: str) -> NoReturn:
        raise PaintFormatError(self.path, field, message, self.line_of(field))

    @contextlib.contextmanager
    def named_errors(self) -> Iterator["JsonDocument"]:
        """Within it, an error that does not name this file
        (:func:`pointax.io.errors.unnamed_error_message`: a ``TypeError``, an
        ``OverflowError``, ...) is raised again as a :class:`PaintFormatError` naming the
        file and the field last read (:attr:`field`) and its line."""
        try:
            yield self
        except Exception as err:
            message = unnamed_error_message(err)
            if message is None:
                raise
            field = self.field or None
            raise PaintFormatError(
                self.path, field, f"{message} (while reading this field)" if field else message, self.line_of(self.field)
            ) from err

    @staticmethod
    def join(prefix: str, key: str | int) -> str:
        if isinstance(key, int):
            return f"{prefix}[{key}]"
        return f"{prefix}.{key}" if prefix else key

    def obj(self, value: Any, field: str) -> dict:
        self.field = field
        if not isinstance(value, dict):
            self.fail(field, f"is {describe_value(value)}, expected a JSON object")
        return value

    def get(self, parent: dict, key: str, prefix: str = "") -> tuple[Any, str]:
        field = self.field = self.join(prefix, key)
        if key not in parent:
            self.fail(field, "is missing")
        return parent[key], field

    def as_number(self, value: Any, field: str) -> float:
        self.field = field
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(field, f"is {describe_value(value)}, expected a number")
        try:
            number = float(value)
        except OverflowError:  # an integer of hundreds of digits
            digits = int(value.bit_length() * math.log10(2)) + 1
            self.fail(field, f"is an integer of about {digits} digits, beyond a float's range")
        if not math.isfinite(number):
            self.fail(field, f"is {value}, expected a finite number")
        return number

    def number(self, parent: dict, key: str, prefix: str = "", *, positive: bool = False) -> float:
        value, field = self.get(parent, key, prefix)
        x = self.as_number(value, field)
        if positive and not x > 0:
            self.fail(field, f"is {x}, expected a positive number")
        return x

    def string(self, parent: dict, key: str, prefix: str = "") -> str:
        value, field = self.get(parent, key, prefix)
        if not isinstance(value, str):
            self.fail(field, f"is {describe_value(value)}, expected a string")
        return value

    def as_vector(self, value: Any, field: str, n: int = 3) -> np.ndarray:
        self.field = field
        if not isinstance(value, list) or len(value) != n:
            self.fail(field, f"is {describe_value(value)}, expected an array of {n} numbers")
        return frozen_array(np.array([self.as_number(v, self.join(field, k)) for k, v in enumerate(value)]))

    def vector(self, parent: dict, key: str, prefix: str = "", n: int = 3) -> np.ndarray:
        value, field = self.get(parent, key, prefix)
        return self.as_vector(value, field, n)

    def geodetic(self, value: Any, field: str) -> np.ndarray:
        """A WGS84 ``[lat deg, lon deg, height m]`` triple."""
        v = self.as_vector(value, field, 3)
        if not -90.0 <= v[0] <= 90.0:
            self.fail(self.join(field, 0), f"latitude {v[0]} is outside -90..90 deg")
        if not -360.0 <= v[1] <= 360.0:
            self.fail(self.join(field, 1), f"longitude {v[1]} is outside -360..360 deg")
        return v


def frozen_array(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, np.float64)
    a.flags.writeable = False
    return a


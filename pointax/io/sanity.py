"""Plausibility checks shared by the run readers: angles in range, columns that look
like the wrong unit, rows written twice, records after END.

Each check names the file, the line and the field. Impossible values (an azimuth
beyond +-360 deg, a star below the horizon by more than refraction lifts it, a
whole column in radians where degrees are expected) raise the reader's
:class:`~pointax.io.errors.FileFormatError`; odd but possible input (rows written twice,
lines after END) gives an :class:`~pointax.io.errors.InputWarning`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..units import check_not_degrees
from .errors import FileFormatError, warn_input

__all__ = [
    "finite_number",
    "AZIMUTH_LIMIT_DEG",
    "HORIZON_DEG",
    "check_azimuth",
    "check_observed_elevation",
    "check_not_radians",
    "check_not_degrees",
    "warn_duplicates",
    "warn_after_end",
]

AZIMUTH_LIMIT_DEG = 360.0
"""An azimuth reading or position beyond +-360 deg (two turns of the axis) is refused."""

HORIZON_DEG = -1.0
"""The lowest observed (apparent) elevation accepted, deg: refraction lifts a source at
the horizon by about 0.6 deg (35'), so an apparent position below -1 deg cannot be a
source in the sky."""


def finite_number(error: type[FileFormatError], path, line: int, token: str, where: str) -> float:
    """``token`` as a finite float, else the reader's ``error`` naming ``where`` (the
    record and the field) and the token."""
    try:
        value = float(token)
    except ValueError:
        raise error(path, line, f"{where} is {token!r}, not a number") from None
    if not math.isfinite(value):
        raise error(path, line, f"{where} is {token!r}, not finite")
    return value


def check_azimuth(error: type[FileFormatError], path, line: int, value: float, where: str) -> None:
    """Refuse an azimuth (degrees) beyond +-360 deg."""
    if not -AZIMUTH_LIMIT_DEG <= value <= AZIMUTH_LIMIT_DEG:
        raise error(path, line, f"{value:g} deg is outside -360..360 deg (an azimuth in other units?)", where)


def check_observed_elevation(error: type[FileFormatError], path, line: int, value: float, where: str) -> None:
    """Refuse an observed (apparent) elevation (degrees) above 90 or below the horizon
    by more than refraction allows (:data:`HORIZON_DEG`)."""
    if value > 90.0:
        raise error(path, line, f"{value:g} deg is above 90 deg (the zenith)", where)
    if value < HORIZON_DEG:
        raise error(
            path,
            line,
            f"{value:g} deg is below the horizon by more than refraction allows (lowest accepted {HORIZON_DEG:g} deg)",
            where,
        )


def check_not_radians(
    error: type[FileFormatError], path, lines: Sequence[int], columns: dict[str, tuple[np.ndarray, float]], min_rows: int = 3
) -> None:
    """Refuse angle columns written in degrees whose values all lie within the range the
    same angles would have in radians (``min_rows`` rows or more, every named column at
    once): they look like radians.

    ``columns`` maps ``"field N (name)"`` to ``(values in degrees, limit)``, the limit
    being the angle's range in radians (pi/2 for an elevation, 2 pi for an azimuth)."""
    if len(lines) < min_rows:
        return
    for values, limit in columns.values():
        values = np.asarray(values, np.float64)
        if not np.all(np.abs(values) <= limit):
            return
    described = "; ".join(
        f"{where} within +-{limit:.4f} (largest {float(np.max(np.abs(values))):.4g})"
        for where, (values, limit) in columns.items()
    )
    raise error(
        path,
        int(lines[0]),
        f"over all {len(lines)} rows, {described}: the angles look like radians, and this format holds degrees",
    )


def warn_duplicates(path, rows: np.ndarray, lines: Sequence[int], what: str = "observation records") -> None:
    """Warn when some rows repeat an earlier row exactly, naming the lines and saying how
    they are counted (each as an observation of its own: sigmas shrink as if the data
    were independent)."""
    rows = np.asarray(rows)
    seen: dict[bytes, int] = {}
    pairs = []
    for k in range(rows.shape[0]):
        key = rows[k].tobytes()
        if key in seen:
            pairs.append((int(lines[k]), seen[key]))
        else:
            seen[key] = int(lines[k])
    if not pairs:
        return
    shown = ", ".join(f"line {a} = line {b}" for a, b in pairs[:5]) + (", ..." if len(pairs) > 5 else "")
    warn_input(
        path,
        pairs[0][0],
        f"{len(pairs)} of {rows.shape[0]} {what} repeat an earlier record exactly ({shown}); each is kept and "
        "counted as an observation of its own, which shrinks the sigmas as if they were independent data: "
        "remove them if they were written twice",
        stacklevel=4,
    )


def warn_after_end(path, end_line: int, ignored: Sequence[int]) -> None:
    """Warn that non-comment lines after END were ignored, naming them."""
    if not ignored:
        return
    span = f"line {ignored[0]}" if len(ignored) == 1 else f"lines {ignored[0]}-{ignored[-1]}"
    warn_input(
        path,
        int(ignored[0]),
        f"{len(ignored)} non-comment line(s) after END (line {end_line}) were ignored ({span})",
        stacklevel=5,
    )

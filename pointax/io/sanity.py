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

from ..core.units import check_not_degrees, offsets_scale_problem
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
    "check_offsets_scale",
    "row_separations",
    "check_row_separations",
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


def check_offsets_scale(
    error: type[FileFormatError], path, lines: Sequence[int], values_rad, where: str, unit: str, assumed: bool
) -> None:
    """Pointing offsets all below 0.1" in ``unit`` (:func:`pointax.core.units.offsets_scale_problem`):
    refused when the unit was assumed (no header unit, no ``units``), warned of when it
    was stated."""
    problem = offsets_scale_problem(values_rad, where, unit)
    if problem is None:
        return
    fix = (
        "; say the unit with units='deg' (--units deg) or in the header ('dxel [deg]')"
        if assumed
        else " (the unit was stated, so the offsets are read as given)"
    )
    if assumed:
        raise error(path, int(lines[0]), f"{problem}, and no header or units= states their unit{fix}")
    warn_input(path, int(lines[0]), problem + fix, stacklevel=5)


ROW_SEPARATION_DEG = 5.0
"""A row whose raw position lies more than this (degrees) from its observed one, after
the run's common offset (the median differences) is taken out, is named: no pointing
error differs that much from one row to the next (a row flipped in declination but not
in hour angle, a typo in a field)."""


def row_separations(observed: np.ndarray, raw: np.ndarray) -> np.ndarray:
    """``(n,)`` degrees between each row's observed position and its raw one (both
    ``(n, 2)`` longitude, latitude radians) once the median differences of the run (its
    common offset, from 3 rows on) are taken out of the raw positions."""
    observed, raw = np.asarray(observed, np.float64), np.asarray(raw, np.float64)
    if observed.shape[0] == 0:
        return np.zeros(0)
    d_lon = (raw[:, 0] - observed[:, 0] + math.pi) % (2 * math.pi) - math.pi
    d_lat = raw[:, 1] - observed[:, 1]
    lon = observed[:, 0] + d_lon - (np.median(d_lon) if len(d_lon) >= 3 else 0.0)
    lat = observed[:, 1] + d_lat - (np.median(d_lat) if len(d_lat) >= 3 else 0.0)

    def vectors(a, b):
        return np.stack([np.cos(b) * np.cos(a), np.cos(b) * np.sin(a), np.sin(b)], axis=-1)

    cosine = np.clip(np.sum(vectors(lon, lat) * vectors(observed[:, 0], observed[:, 1]), axis=1), -1.0, 1.0)
    return np.degrees(np.arccos(cosine))


def check_row_separations(
    path, lines: Sequence[int], observed: np.ndarray, raw: np.ndarray, what: str, describe=None, stacklevel: int = 5
) -> None:
    """Warn of the rows whose raw position (``raw``: longitude, latitude radians, e.g.
    azimuth and elevation, or hour angle and declination on the sky, after any pier
    flip) lies more than :data:`ROW_SEPARATION_DEG` from the observed one, once the
    median differences of the run are taken out (:func:`row_separations`); each named
    by its line and, where ``describe(k)`` is given, both its positions as written."""
    apart = row_separations(observed, raw)
    far = np.flatnonzero(apart > ROW_SEPARATION_DEG)
    if far.size == 0:
        return
    shown = ", ".join(
        f"line {int(lines[k])}: {apart[k]:.1f} deg" + (f" ({describe(int(k))})" if describe is not None else "")
        for k in far[:5]
    ) + (", ..." if far.size > 5 else "")
    warn_input(
        path,
        int(lines[far[0]]),
        f"{far.size} of {len(apart)} rows have {what} more than {ROW_SEPARATION_DEG:g} deg apart beyond the run's "
        f"common offset ({shown}): a row flipped in declination but not in hour angle (or the reverse), or a "
        "mistyped field? Such a row is fitted as it stands; correct it or mask it",
        stacklevel=stacklevel,
    )

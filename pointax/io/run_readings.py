"""Auxiliary readings as the readers give them: times as MJD (from dates, Julian dates
and ISO 8601 text), per-run values repeated for every observation, and the dict of
``(n,)`` float64 arrays that :class:`pointax.Observations` takes as ``readings``.

The names and units are :data:`pointax.core.readings.READINGS`' (``temperature`` deg C,
``pressure`` hPa, ``humidity`` 0-1, ``time`` MJD UTC days, ``rotator``, ``tilt_1``,
``tilt_2`` radians); a reader keeps any other column under its own name.
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Mapping

import numpy as np

__all__ = [
    "MJD_EPOCH",
    "JD_MINUS_MJD",
    "mjd_from_date",
    "mjd_from_datetime",
    "mjd_from_iso",
    "mjd_from_jd_or_mjd",
    "per_run",
    "as_readings",
]

MJD_EPOCH = _dt.datetime(1858, 11, 17, tzinfo=_dt.timezone.utc)
"""MJD 0: 1858-11-17 0h UTC."""
JD_MINUS_MJD = 2400000.5
"""JD = MJD + 2400000.5."""
_JD_THRESHOLD = 2_000_000.0
"""A time field above this is a Julian date (JD 2e6 is the year 763; MJD 2e6 the year 7334)."""


def mjd_from_datetime(when: _dt.datetime) -> float:
    """MJD (days, UTC) of ``when``; a naive datetime is taken as UTC."""
    if when.tzinfo is None:
        when = when.replace(tzinfo=_dt.timezone.utc)
    delta = when - MJD_EPOCH
    return delta.days + (delta.seconds + delta.microseconds * 1e-6) / 86400.0


def mjd_from_date(year: int, month: int, day: int, hours: float = 0.0) -> float:
    """MJD of ``hours`` UTC on the (proleptic Gregorian) date ``year-month-day``.

    Raises:
        ValueError: for a date that does not exist.
    """
    return float((_dt.date(int(year), int(month), int(day)) - MJD_EPOCH.date()).days) + hours / 24.0


def mjd_from_iso(text: str) -> float:
    """MJD of an ISO 8601 date or date and time (``2021-08-21``, ``2021-08-21T13:05:00Z``,
    ``2021-08-21 13:05:00+02:00``); without a zone the time is UTC.

    Raises:
        ValueError: naming the text when it is not such a time.
    """
    s = text.strip()
    if s.endswith(("Z", "z")):
        s = s[:-1] + "+00:00"
    try:
        when = _dt.datetime.fromisoformat(s)
    except ValueError:
        raise ValueError(f"{text!r} is not an ISO 8601 date and time (e.g. 2021-08-21T13:05:00Z)") from None
    return mjd_from_datetime(when)


def mjd_from_jd_or_mjd(value):
    """A time field (a number or an array) that may hold Julian dates or MJDs (gpoint's
    'MJD' column, which RTS2's writers fill with the JD): values above 2,000,000 are
    JDs. Returns float64 MJD of the same shape."""
    v = np.asarray(value, np.float64)
    return np.where(v > _JD_THRESHOLD, v - JD_MINUS_MJD, v)


def per_run(n: int, values: Mapping[str, float | None]) -> dict[str, np.ndarray]:
    """Per-run readings (one value for the whole run, e.g. a TPOINT header's weather)
    as ``(n,)`` arrays; names whose value is None are left out."""
    return {name: np.full(n, float(v)) for name, v in values.items() if v is not None and math.isfinite(float(v))}


def as_readings(readings: Mapping[str, np.ndarray], n: int) -> dict[str, np.ndarray]:
    """``readings`` as ``(n,)`` float64 arrays, sorted by name.

    Raises:
        ValueError: for an array of another length.
    """
    out = {}
    for name in sorted(readings):
        a = np.asarray(readings[name], np.float64).reshape(-1)
        if a.shape != (n,):
            raise ValueError(f"reading {name!r} has {a.size} values for {n} observations")
        out[name] = a
    return out

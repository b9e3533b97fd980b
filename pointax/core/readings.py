"""Auxiliary readings: named per-observation values (temperature, time, tilt, ...) that
terms read by name inside their hooks.

* :data:`READINGS`: the standard names and their units.
* :func:`bind_readings`: a copy of a term with one observation's readings (or a site's
  ``(n,)`` arrays, for :func:`jax.vmap`) bound to it, as :meth:`pointax.Model.at_readings`
  binds them before the hooks run.
* :func:`check_readings`: the clear error, naming the reading and the rows, when a
  model needs a reading that used observations lack (NaN, or no such column).

The values are data (pytree leaves), never configuration: a fit whose readings change
does not compile again.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

__all__ = ["READINGS", "reading_unit", "bind_readings", "readings_needed", "check_readings", "missing_readings", "model_readings"]

READINGS: dict[str, str] = {
    "temperature": "deg C: ambient (or tube) temperature",
    "pressure": "hPa: barometric pressure",
    "humidity": "fraction 0-1: relative humidity",
    "time": "days: MJD (UTC) of the observation",
    "rotator": "radians: instrument rotator angle",
    "tilt_1": "radians: tilt meter, first axis",
    "tilt_2": "radians: tilt meter, second axis",
}
"""Standard reading names -> ``"unit: description"``. Any other name is allowed (a user
reading, unit unknown)."""


def reading_unit(name: str) -> str | None:
    """The unit of the standard reading ``name`` ('deg C', 'hPa', '1', 'days', 'rad'),
    None for a user reading."""
    text = READINGS.get(name)
    if text is None:
        return None
    unit = text.split(":", 1)[0]
    return {"fraction 0-1": "1", "radians": "rad"}.get(unit, unit)


def readings_needed(terms: Iterable) -> tuple[str, ...]:
    """The sorted names of the readings ``terms`` declare (their ``readings`` class
    attribute)."""
    return tuple(sorted({name for t in terms for name in getattr(t, "readings", ())}))


def bind_readings(term, values: Mapping | None):
    """A copy of ``term`` whose :meth:`~pointax.Term.reading` returns ``values[name]``
    (scalars for one observation, or arrays of one shape). ``values`` holds at least
    the term's declared readings (KeyError naming the term and the reading otherwise);
    only those are bound. Pure: usable inside ``jit``, ``vmap`` and ``grad``."""
    if values is None:
        bound = None
    else:
        missing = [n for n in term.readings if n not in values]
        if missing:
            raise KeyError(
                f"term {term.name} reads {', '.join(map(repr, missing))}, but no such reading was given "
                f"(given: {sorted(values) or 'none'})"
            )
        bound = {n: values[n] for n in term.readings}
    # A shallow copy with one field replaced: a term may define its own __init__, so
    # dataclasses.replace (which calls it) cannot be used.
    copy = object.__new__(type(term))
    copy.__dict__.update(term.__dict__)
    object.__setattr__(copy, "_bound_readings", bound)
    return copy


def missing_readings(needed: Iterable[str], readings: Mapping, used) -> dict[str, np.ndarray]:
    """Per needed reading that some ``used`` observation lacks: the 0-based rows that
    lack it (every used row when the column is absent). Concrete NumPy values only."""
    used = np.asarray(used, bool)
    rows = np.flatnonzero(used.reshape(-1))
    out = {}
    for name in needed:
        if name not in readings:
            out[name] = rows
            continue
        value = np.asarray(readings[name], np.float64).reshape(-1)
        bad = np.flatnonzero(used.reshape(-1) & ~np.isfinite(value))
        if bad.size:
            out[name] = bad
    return out


def check_readings(model, obs) -> None:
    """Raise ValueError when ``model`` needs a reading that some used observation of
    ``obs`` (weight > 0) lacks, naming the reading and the rows (counted from 1; for a
    batch ``(S, N)``, site and row). Skipped for traced values (inside ``jit``)."""
    needed = model.readings
    if not needed:
        return
    try:
        used = np.asarray(obs.weight) > 0
        readings = {k: np.asarray(v) for k, v in obs.readings.items()}
    except Exception:  # traced: checked where the values are concrete
        return
    missing = missing_readings(needed, readings, used)
    if not missing:
        return
    shape = used.shape
    parts = []
    for name, rows in missing.items():
        absent = name not in readings
        if len(shape) == 2:
            where = [f"site {r // shape[1]} row {r % shape[1] + 1}" for r in rows[:8]]
        else:
            where = [f"row {r + 1}" for r in rows[:8]]
        more = f" and {len(rows) - 8} more" if len(rows) > 8 else ""
        what = "is not among the observations' readings" if absent else "is not recorded (NaN) at " + ", ".join(where) + more
        parts.append(f"reading {name!r} {what}")
    have = sorted(readings) or "none"
    raise ValueError(
        "the model's terms need readings the observations lack: " + "; ".join(parts)
        + f" (the observations have: {have}; give them with Observations(..., readings={{...}}), "
        "or weight 0 the rows that lack them)"
    )


def model_readings(model, obs, used) -> dict:
    """The readings ``model`` reads (:attr:`pointax.Model.readings`), from ``obs``, with
    the rows not ``used`` filled (:meth:`pointax.Observations.filled_readings`); pure JAX.
    ValueError naming a reading the observations do not carry."""
    missing = [n for n in model.readings if n not in obs.readings]
    if missing:
        raise ValueError(
            f"the model's terms read {', '.join(map(repr, missing))}, which the observations do not carry "
            f"(they have: {sorted(obs.readings) or 'no readings'}); give them with Observations(..., readings={{...}})"
        )
    filled = obs.filled_readings(used)
    return {n: filled[n] for n in model.readings}

"""Angle units. Inside pointax every angle is in radians; these convert for people.

``arcsec(x)``, ``deg(x)`` and ``rad(x)`` return radians as NumPy float64 (never a JAX
array, so a value made while JAX's x64 mode is off keeps its precision).

At the API edges (observations, simulation, the inverse, model parameters, limits)
astropy objects are accepted: :func:`angles_in_radians` converts a ``Quantity`` or
``Angle``, :func:`directions_enu` a ``SkyCoord`` in an ``AltAz`` frame or azimuth and
elevation as a Quantity. A bare number stays radians; a Quantity is converted or
refused, never stripped. astropy is not imported here: an object is recognised as a
Quantity only when the caller's process has imported ``astropy.units`` already (it
cannot hold one otherwise), so ``import pointax`` stays free of astropy.
"""

from __future__ import annotations

import math
import sys

import numpy as np

__all__ = [
    "check_not_degrees",
    "ImplausibleValueError",
    "TURN",
    "POINTING_TERM_LIMIT",
    "SMALLEST_OFFSETS",
    "likely_unit",
    "angle_radians_problem",
    "check_angle_radians",
    "check_pointing_term",
    "unit_vectors_problem",
    "check_unit_vectors",
    "offsets_scale_problem",
    "ARCSEC",
    "DEG",
    "arcsec",
    "deg",
    "rad",
    "to_unit",
    "from_unit",
    "UNITS",
    "is_quantity",
    "angles_in_radians",
    "value_in_unit",
    "directions_enu",
]

ARCSEC = math.pi / (180.0 * 3600.0)
"""One arcsecond in radians."""
DEG = math.pi / 180.0
"""One degree in radians."""

UNITS = {"arcsec": ARCSEC, "deg": DEG, "mrad": 1e-3, "rad": 1.0, "1": 1.0}
"""Radians per unit for each unit name a parameter may be reported in."""


def arcsec(x) -> np.ndarray | np.float64:
    """Radians for ``x`` arcseconds."""
    return np.float64(x) * ARCSEC if np.ndim(x) == 0 else np.asarray(x, np.float64) * ARCSEC


def deg(x) -> np.ndarray | np.float64:
    """Radians for ``x`` degrees."""
    return np.float64(x) * DEG if np.ndim(x) == 0 else np.asarray(x, np.float64) * DEG


def rad(x) -> np.ndarray | np.float64:
    """Radians for ``x`` radians (as float64): for symmetry with :func:`arcsec`."""
    return np.float64(x) if np.ndim(x) == 0 else np.asarray(x, np.float64)


def to_unit(value_rad, unit: str):
    """Convert a value in internal units (radians) to ``unit`` ('arcsec', 'deg', 'rad', '1')."""
    try:
        return np.asarray(value_rad, np.float64) / UNITS[unit]
    except KeyError:
        raise ValueError(f"unknown unit {unit!r}; expected one of {sorted(UNITS)}") from None


def from_unit(value, unit: str):
    """Convert a value given in ``unit`` to internal units (radians)."""
    try:
        return np.asarray(value, np.float64) * UNITS[unit]
    except KeyError:
        raise ValueError(f"unknown unit {unit!r}; expected one of {sorted(UNITS)}") from None


# ------------------------------------------------------------------ astropy at the edges


def is_quantity(x) -> bool:
    """Whether ``x`` is an astropy ``Quantity`` (``Angle``, ``Latitude``, ...), without
    importing astropy."""
    units = sys.modules.get("astropy.units")
    return units is not None and isinstance(x, units.Quantity)


def _is_skycoord(x) -> bool:
    coordinates = sys.modules.get("astropy.coordinates")
    return coordinates is not None and isinstance(x, (coordinates.SkyCoord, coordinates.BaseCoordinateFrame))


def value_in_unit(x, unit: str, name: str = "value") -> np.ndarray:
    """``x`` as a float64 NumPy value in pointax's ``unit`` (a name of :data:`UNITS`):
    a Quantity is converted (an angle unit for 'arcsec', 'deg', 'mrad', 'rad';
    dimensionless for '1'), a bare number is taken as already in ``unit``.

    Raises:
        ValueError: for a Quantity whose unit cannot be converted, naming ``name``.
    """
    if not is_quantity(x):
        if _is_skycoord(x):
            raise ValueError(f"{name}: a SkyCoord is a direction, not an angle")
        return np.asarray(x, np.float64)
    u = sys.modules["astropy.units"]  # loaded by whoever made the Quantity x

    target = u.dimensionless_unscaled if unit == "1" else u.Unit(unit if unit != "mrad" else "mrad")
    try:
        return np.asarray(x.to_value(target), np.float64)
    except u.UnitConversionError:
        raise ValueError(f"{name}: a Quantity in {x.unit!s} cannot be converted to {unit}") from None


def angles_in_radians(x, name: str = "angles") -> np.ndarray:
    """``x`` in radians as float64 NumPy: a Quantity or Angle is converted, a bare
    number is taken as radians (pointax's convention).

    Raises:
        ValueError: for a Quantity that is not an angle, naming ``name``.
    """
    return value_in_unit(x, "rad", name)


def directions_enu(x, name: str = "directions") -> np.ndarray:
    """East-North-Up unit vectors from ``x``: an astropy ``SkyCoord`` (or frame) in
    ``AltAz``; a Quantity of shape ``(..., 2)`` holding azimuth (North through East)
    and elevation; or bare numbers, taken as East-North-Up vectors ``(..., 3)`` as they
    are.

    Raises:
        ValueError: for a SkyCoord in another frame (transform it to ``AltAz`` first:
            a direction in the sky depends on the site and the time), or a Quantity of
            another shape or unit, naming ``name``.
    """
    if _is_skycoord(x):
        frame = x.frame if hasattr(x, "frame") else x
        if type(frame).__name__ != "AltAz":
            raise ValueError(
                f"{name}: a SkyCoord in the {type(frame).__name__} frame; pointax needs local directions: "
                "transform it first, e.g. coord.transform_to(AltAz(obstime=..., location=...))"
            )
        az = np.asarray(frame.az.rad, np.float64)
        el = np.asarray(frame.alt.rad, np.float64)
        return _enu(az, el)
    if is_quantity(x):
        angles = angles_in_radians(x, name)
        if angles.shape[-1:] != (2,):
            raise ValueError(
                f"{name}: a Quantity of directions must hold azimuth and elevation (shape (..., 2)), got shape {angles.shape}"
            )
        return _enu(angles[..., 0], angles[..., 1])
    return np.asarray(x, np.float64)


def _enu(az: np.ndarray, el: np.ndarray) -> np.ndarray:
    """Unit vectors in East-North-Up for azimuth (North through East) and elevation."""
    return np.stack([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)], axis=-1)


def check_not_degrees(
    name: str, values, limit: float = 4 * math.pi, unit_hint: str = "radians"
) -> str | None:
    """A message when some of ``values`` (radians expected) lie beyond ``limit`` (two
    turns): they look like degrees. None when they do not."""
    values = np.asarray(values, np.float64)
    finite = values[np.isfinite(values)]
    if finite.size and float(np.max(np.abs(finite))) > limit:
        k = int(np.sum(np.abs(finite) > limit))
        return (
            f"{k} of {finite.size} values of {name} exceed {limit:.4g} rad in magnitude "
            f"(largest {float(np.max(np.abs(finite))):.6g}): they look like degrees; pointax takes {unit_hint} "
            "(px.deg(x) converts, or pass an astropy Quantity)"
        )
    return None


# ------------------------------------------------------------------ plausibility at the edges
#
# pointax takes radians (and East-North-Up unit vectors) everywhere inside. Where a
# value enters (a file, the command line, the Python API) and its unit is assumed
# rather than stated, the value is checked here for plausibility in that unit: a value
# that cannot be an angle in radians (beyond a turn) or a pointing term in radians
# (beyond 10 deg) is named with what was expected and the unit it most likely is in.
# Readers (:mod:`pointax.io.sanity`) add the file and line; the API raises or warns
# with the argument's name.

TURN = 2 * math.pi
"""An angle in radians beyond a full turn cannot be one (it looks like degrees or arcsec)."""

POINTING_TERM_LIMIT = 10 * DEG
"""The largest plausible pointing-term coefficient, radians (10 deg): a model term far
beyond it is a unit mistake (arcsec or degrees given where radians are expected)."""

SMALLEST_OFFSETS = 0.1 * ARCSEC
"""Offsets whose largest magnitude over a run is below this (radians, 0.1") are not
pointing offsets in the unit assumed: no pointing run measures offsets that small."""

UNIT_VECTOR_TOLERANCE = 1e-3
"""How far from 1 the length of an East-North-Up unit vector may be."""


class ImplausibleValueError(ValueError):
    """A value whose unit was assumed is implausible in that unit; the message names the
    value, what was expected and the unit it most likely is in."""


def likely_unit(value: float, limit: float) -> str:
    """Which unit ``value`` (taken as radians, beyond ``limit``) is most likely in: the
    largest of degrees, arcminutes, arcseconds that brings it within ``limit``."""
    value = abs(float(value))
    for word, scale, helper in (
        ("degrees", DEG, "px.deg(x)"),
        ("arcminutes", DEG / 60, "px.arcsec(60 * x)"),
        ("arcseconds", ARCSEC, "px.arcsec(x)"),
    ):
        if value * scale <= limit:
            return f"{word} ({value:g} {word} = {value * scale:.6g} rad; {helper} converts)"
    return "no angle unit (it is too large even in arcseconds)"


def angle_radians_problem(values, name: str, limit: float = TURN, expected: str = "an angle in radians",
                          plausible: float | None = None) -> str | None:
    """A message when some finite value of ``values`` (radians assumed) exceeds
    ``limit`` in magnitude, naming the largest, what was expected and its likely unit
    (the largest unit that brings it within ``plausible``, default ``limit``);
    None when all are plausible (or the values are not concrete, e.g. JAX tracers)."""
    try:
        array = np.asarray(values, np.float64)
    except Exception:  # a tracer or an object that is not a number: not checked here
        return None
    finite = array[np.isfinite(array)]
    if finite.size == 0:
        return None
    largest = float(finite.flat[int(np.argmax(np.abs(finite)))])
    if abs(largest) <= limit:
        return None
    count = "" if finite.size == 1 else f" ({int(np.sum(np.abs(finite) > limit))} of {finite.size} values)"
    return (
        f"{name} = {largest:g}{count}: expected {expected} (within +-{limit:.4g} rad), so it is most likely in "
        f"{likely_unit(largest, plausible or limit)}; or pass an astropy Quantity"
    )


def check_angle_radians(values, name: str, limit: float = TURN, warn_above: float | None = None,
                        expected: str = "an angle in radians", stacklevel: int = 3) -> None:
    """Refuse ``values`` (radians assumed) beyond ``limit`` (:class:`ImplausibleValueError`);
    warn (:class:`pointax.core.errors.InputWarning`) beyond ``warn_above``. Values that are
    not concrete numbers (JAX tracers) are not checked."""
    problem = angle_radians_problem(values, name, limit, expected, warn_above)
    if problem:
        raise ImplausibleValueError(problem)
    if warn_above is not None:
        problem = angle_radians_problem(values, name, warn_above, expected)
        if problem:
            from .errors import warn_input

            warn_input(name, None, problem, stacklevel=stacklevel + 1)


def check_pointing_term(values, name: str, stacklevel: int = 3) -> None:
    """A pointing-term coefficient (radians): refused beyond a turn, warned of beyond
    :data:`POINTING_TERM_LIMIT` (both say the likely unit)."""
    check_angle_radians(values, name, TURN, POINTING_TERM_LIMIT, "a pointing term in radians", stacklevel + 1)


def unit_vectors_problem(vectors, name: str, weight=None, tolerance: float = UNIT_VECTOR_TOLERANCE) -> str | None:
    """A message when some finite row of ``vectors`` ``(..., 3)`` (rows of weight 0
    skipped) is not of length 1, naming the first and what it looks like; None when all
    are unit vectors (or the values are not concrete)."""
    try:
        array = np.asarray(vectors, np.float64)
    except Exception:
        return None
    if array.ndim == 0 or array.shape[-1] != 3:
        return None
    rows = array.reshape(-1, 3)
    keep = np.all(np.isfinite(rows), axis=1)
    if weight is not None:
        try:
            w = np.broadcast_to(np.asarray(weight, np.float64), array.shape[:-1]).reshape(-1)
            keep &= w != 0
        except Exception:
            pass
    norms = np.linalg.norm(rows, axis=1)
    bad = np.flatnonzero(keep & (np.abs(norms - 1.0) > tolerance))
    if bad.size == 0:
        return None
    k = int(bad[0])
    row = ", ".join(f"{x:g}" for x in rows[k])
    looks = ""
    if norms[k] > 2.0:
        looks = (
            "; it looks like azimuth/elevation in degrees: give East-North-Up vectors "
            "(pointax.core.rotations.azel_to_enu(az, el) in radians, or an (n, 2) astropy Quantity of azimuth and elevation)"
        )
    return (
        f"{name}: {bad.size} of {rows.shape[0]} vectors are not unit vectors (row {k + 1}, counted from 1: ({row}), length "
        f"{norms[k]:.6g}); expected East-North-Up unit vectors{looks}"
    )


def check_unit_vectors(vectors, name: str, weight=None, warn: bool = False, stacklevel: int = 3,
                       tolerance: float = UNIT_VECTOR_TOLERANCE) -> None:
    """Refuse (:class:`ImplausibleValueError`), or with ``warn`` warn of, ``vectors``
    that are not East-North-Up unit vectors (az/el in degrees, say): a length more than
    ``tolerance`` from 1 (where vectors are normalised anyway, as by
    :func:`pointax.command`, ``tolerance=1`` names only lengths beyond 2)."""
    problem = unit_vectors_problem(vectors, name, weight, tolerance)
    if problem is None:
        return
    if not warn:
        raise ImplausibleValueError(problem)
    from .errors import warn_input

    warn_input(name, None, problem, stacklevel=stacklevel + 1)


def offsets_scale_problem(values_rad, name: str, unit: str) -> str | None:
    """A message when pointing offsets read in ``unit`` (converted to radians) are all
    below :data:`SMALLEST_OFFSETS` (0.1") while some is nonzero: they are in a larger
    unit (degrees read as arcsec: 0.004 deg is 14.4")."""
    array = np.asarray(values_rad, np.float64)
    finite = np.abs(array[np.isfinite(array)])
    if finite.size < 3 or not np.any(finite > 0) or float(np.max(finite)) >= SMALLEST_OFFSETS:
        return None
    largest = float(np.max(finite)) / UNITS.get(unit, ARCSEC) if unit in UNITS else float(np.max(finite)) / ARCSEC
    return (
        f"{name}: every offset is below 0.1\" read as {unit} (largest {largest:g} {unit}): no pointing run "
        f"measures offsets that small; they are most likely in degrees ({largest:g} deg = {largest * 3600:g}\") "
        "or arcminutes"
    )

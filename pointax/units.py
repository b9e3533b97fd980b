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
    import astropy.units as u

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

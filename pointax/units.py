"""Angle units. Inside pointax every angle is in radians; these convert for people.

``arcsec(x)``, ``deg(x)`` and ``rad(x)`` return radians as NumPy float64 (never a JAX
array, so a value made while JAX's x64 mode is off keeps its precision).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["ARCSEC", "DEG", "arcsec", "deg", "rad", "to_unit", "from_unit", "UNITS"]

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

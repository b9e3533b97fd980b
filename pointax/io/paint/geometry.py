"""PAINT's conventions turned into pointax's: WGS84 positions to East-North-Up metres,
sun azimuth from South to North through East, sun directions. See :mod:`pointax.io.paint`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = [
    "wgs84_to_enu",
    "paint_azimuth_to_north_east",
    "sun_enu_from_paint",
]

# --------------------------------------------------------------------------- geometry


def wgs84_to_enu(
    lat_deg: Any, lon_deg: Any, height_m: Any, origin: Sequence[float] | np.ndarray
) -> np.ndarray:
    """WGS84 geodetic positions -> local East-North-Up coordinates (m) at ``origin``.

    The points and the origin go to geocentric (ECEF) x, y, z through astropy's
    ``EarthLocation.from_geodetic`` (WGS84 ellipsoid); the difference is turned into
    the ENU frame of the origin (East along increasing longitude, Up along the
    ellipsoid normal at the origin's geodetic latitude).

    Args:
        lat_deg, lon_deg, height_m: geodetic latitude (deg), longitude (deg) and
            ellipsoidal height (m); any broadcastable shapes ``(...)``.
        origin: ``(3,)`` latitude (deg), longitude (deg), height (m) of the frame origin.

    Returns:
        ``(..., 3)`` East, North, Up in metres.
    """
    import astropy.units as u
    from astropy.coordinates import EarthLocation

    lat, lon, h = np.broadcast_arrays(*(np.asarray(x, np.float64) for x in (lat_deg, lon_deg, height_m)))
    lat0, lon0, h0 = (float(x) for x in np.asarray(origin, np.float64).reshape(3))

    def ecef(la, lo, hh):
        loc = EarthLocation.from_geodetic(lo * u.deg, la * u.deg, hh * u.m, ellipsoid="WGS84")
        return np.stack([loc.x.to_value(u.m), loc.y.to_value(u.m), loc.z.to_value(u.m)], axis=-1)

    d = ecef(lat, lon, h) - ecef(lat0, lon0, h0)
    sp, cp = math.sin(math.radians(lat0)), math.cos(math.radians(lat0))
    sl, cl = math.sin(math.radians(lon0)), math.cos(math.radians(lon0))
    rotation = np.array(
        [
            [-sl, cl, 0.0],  # East
            [-sp * cl, -sp * sl, cp],  # North
            [cp * cl, cp * sl, sp],  # Up
        ]
    )
    return d @ rotation.T


def paint_azimuth_to_north_east(azimuth_deg: Any) -> np.ndarray:
    """PAINT azimuth (South = 0, East positive, deg) -> azimuth from North through East,
    degrees in [0, 360): ``A_NE = (180 - A_paint) mod 360``."""
    return np.mod(180.0 - np.asarray(azimuth_deg, np.float64), 360.0)


def sun_enu_from_paint(azimuth_deg: Any, elevation_deg: Any) -> np.ndarray:
    """Unit sun direction in ENU from PAINT's azimuth and elevation.

    PAINT counts azimuth from South = 0, East positive (West negative), so with
    ``A = azimuth_deg``, ``E = elevation_deg`` (radians inside)::

        ENU = (sin A cos E, -cos A cos E, sin E)

    which equals pointax's ``azel_to_enu(180 deg - A, E)``. E.g. A = +45 (South-East)
    gives East > 0, North < 0.

    Args:
        azimuth_deg, elevation_deg: broadcastable shapes ``(...)``, degrees.

    Returns:
        ``(..., 3)`` unit vectors.
    """
    a = np.radians(np.asarray(azimuth_deg, np.float64))
    e = np.radians(np.asarray(elevation_deg, np.float64))
    a, e = np.broadcast_arrays(a, e)
    return np.stack([np.sin(a) * np.cos(e), -np.cos(a) * np.cos(e), np.sin(e)], axis=-1)


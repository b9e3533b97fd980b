"""Apparent places of catalogue stars: astropy's, with refraction as ERFA applies it
(:func:`apparent_altaz`, :func:`apparent_direction`), and the planner's fast
approximation (:func:`fast_altaz`). See :mod:`pointax.sky.stars`."""

from __future__ import annotations

import contextlib
import math
import warnings

import astropy.units as u
import erfa
import numpy as np
from astropy.coordinates import CIRS, EarthLocation
from astropy.time import Time
from jaxtyping import Float

from ...core.rotations import azel_to_enu_numpy
from ..sun import (
    DEFAULT_WAVELENGTH_UM,
    as_time,
    check_location,
    checked_weather,
    _altaz_radians,
    _iers_out_of_range,
    _observed_altaz,
    _offline_iers,
    _warn_outside_iers,
    refraction,
)
from .catalogue import Catalogue

__all__ = ["apparent_altaz", "apparent_direction", "checked_weather", "fast_altaz"]

_TWO_PI = 2.0 * math.pi


@contextlib.contextmanager
def _astropy_quiet():
    """Offline IERS (:mod:`pointax.sky`), and no ERFA warning for the few stars whose
    parallax ``pmsafe`` raises to keep their space velocity below 1 % of c (stars with
    a tiny or negative Hipparcos parallax; the change of place is below 0.01 mas)."""
    with _offline_iers(), warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*distance overridden", category=erfa.ErfaWarning)
        yield


def apparent_altaz(
    stars: Catalogue,
    times,
    location: EarthLocation,
    *,
    pressure_hpa=None,
    temperature_c=None,
    relative_humidity=0.0,
    wavelength_um=DEFAULT_WAVELENGTH_UM,
) -> tuple[np.ndarray, np.ndarray]:
    """Topocentric apparent azimuth and elevation of catalogue stars.

    Args:
        stars: the ``n`` stars (a :class:`Catalogue`, e.g. ``bright_stars().find("Vega")``).
        times: an :class:`astropy.time.Time` or anything ``Time(times, scale="utc")``
            reads, of a shape that broadcasts against ``(n,)``: a scalar (all stars at
            one time), ``(n,)`` (each star at its own time) or ``(m, 1)`` (every star
            at each of ``m`` times, giving ``(m, n)``).
        location: the site, a scalar :class:`~astropy.coordinates.EarthLocation`
            (:func:`pointax.sky.site`).
        pressure_hpa: station air pressure, hPa; ``None`` (default) for no refraction
            (the geometric direction).
        temperature_c: air temperature, deg C (only with a pressure; default 10 C).
        relative_humidity: ``0..1``; wavelength_um: micrometres (see
            :func:`pointax.sky.refraction`). Weather values broadcast to the output.

    Returns:
        ``(azimuth, elevation)``, float64 radians of the broadcast shape of ``times``
        and ``(n,)``; azimuth from North through East in ``[0, 2 pi)``, elevation
        observed (refracted) when a pressure is given.

    Raises:
        ValueError: an empty catalogue, times that cannot be read or do not broadcast
            against the stars, weather out of range or given without a pressure.
        TypeError: ``stars`` not a :class:`Catalogue`, ``location`` not an
            ``EarthLocation``.

    Warns:
        astropy.utils.iers.IERSDegradedAccuracyWarning: times outside the IERS table
            (see :mod:`pointax.sky`).
    """
    if not isinstance(stars, Catalogue):
        raise TypeError(f"stars must be a pointax.sky.stars.Catalogue, got {type(stars).__name__}")
    if len(stars) == 0:
        raise ValueError("the catalogue is empty: no stars to place")
    t = as_time(times)
    location = check_location(location)
    try:
        shape = np.broadcast_shapes(t.shape, (len(stars),))
    except ValueError:
        raise ValueError(
            f"times of shape {t.shape} do not broadcast against the {len(stars)} stars: give a "
            f"scalar, shape ({len(stars)},) for one time per star, or (m, 1) for every star at m times"
        ) from None
    weather = checked_weather(pressure_hpa, temperature_c, relative_humidity, wavelength_um, shape)
    index = np.broadcast_to(np.arange(len(stars)), shape)
    tb = t if t.shape == shape else np.broadcast_to(t, shape)
    with _astropy_quiet():
        outside, span = _iers_out_of_range(tb)
        coord = stars.skycoord(index).apply_space_motion(new_obstime=tb)
        az, el = _altaz_radians(coord, tb, location)
    effect = "Star positions move by up to 15 arcsec per second of UT1-UTC error"
    _warn_outside_iers(outside, span, tb.size, effect, stacklevel=2)
    return _observed_altaz(az, el, weather)


def apparent_direction(
    stars: Catalogue,
    times,
    location: EarthLocation,
    *,
    pressure_hpa=None,
    temperature_c=None,
    relative_humidity=0.0,
    wavelength_um=DEFAULT_WAVELENGTH_UM,
) -> Float[np.ndarray, "*shape 3"]:
    """East-North-Up unit vectors towards the stars' apparent places.

    Arguments as for :func:`apparent_altaz`; returns ``(*shape, 3)`` float64,
    ``azel_to_enu(*apparent_altaz(...))``.
    """
    az, el = apparent_altaz(
        stars,
        times,
        location,
        pressure_hpa=pressure_hpa,
        temperature_c=temperature_c,
        relative_humidity=relative_humidity,
        wavelength_um=wavelength_um,
    )
    return azel_to_enu_numpy(az, el)


def fast_altaz(stars: Catalogue, times: Time, location: EarthLocation, weather) -> tuple[np.ndarray, np.ndarray]:
    """``(m, n)`` azimuth and elevation of every star at each of ``m`` times, fast.

    The stars' CIRS places (astropy: space motion, precession-nutation, annual
    aberration, light deflection) are computed once, at the middle time; the hour
    angle is then ``ERA(UT1) + longitude - RA_CIRS``. Left out: the places' change
    over the run (annual aberration moves stars by under 0.5 arcsec a day), polar
    motion and diurnal aberration (each under 0.5 arcsec). Used only to choose stars;
    :func:`apparent_altaz` gives the exact places.
    """
    mid = times[len(times) // 2]
    with _astropy_quiet():
        coord = stars.skycoord().apply_space_motion(new_obstime=mid)
        cirs = coord.transform_to(CIRS(obstime=mid))
        ra = np.asarray(cirs.ra.to_value(u.rad), np.float64)
        dec = np.asarray(cirs.dec.to_value(u.rad), np.float64)
        ut1 = times.ut1
    era = erfa.era00(ut1.jd1, ut1.jd2)
    lat = float(location.lat.to_value(u.rad))
    lon = float(location.lon.to_value(u.rad))
    h = era[:, None] + lon - ra[None, :]
    sin_d, cos_d = np.sin(dec)[None, :], np.cos(dec)[None, :]
    el = np.arcsin(np.clip(math.sin(lat) * sin_d + math.cos(lat) * cos_d * np.cos(h), -1.0, 1.0))
    az = np.mod(np.arctan2(-cos_d * np.sin(h), sin_d * math.cos(lat) - cos_d * np.cos(h) * math.sin(lat)), _TWO_PI)
    if weather is not None:
        el = el + refraction(el, *(np.reshape(w, np.shape(w) + (1,) * (np.ndim(w) > 0)) for w in weather))
    return az, el

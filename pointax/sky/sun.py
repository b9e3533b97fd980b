"""Where the sun is: topocentric sun directions for a site and times, via astropy.

This is pointax's edge to astropy (and ERFA). It is plain NumPy, not JAX: it turns
times and a site into float64 arrays of sun azimuth/elevation or ENU unit vectors, which
a sun tracker's pointing model then takes as its "true" sky directions.

Conventions are those of :mod:`pointax.core.rotations`: angles in radians, azimuth from
North through East (here in ``[0, 2 pi)``), directions as unit vectors in East-North-Up
``(sin A cos E, cos A cos E, sin E)``.

Position. :func:`sun_altaz` is astropy's topocentric apparent place of the sun:
``get_body("sun", t, location, ephemeris="builtin")`` (ERFA's ``epv00`` Earth
ephemeris, light time, annual and diurnal aberration, precession-nutation, UT1 and polar
motion from the IERS tables, parallax of the site) transformed to ``AltAz(obstime=t,
location=site)``. Against NREL's SPA (Reda & Andreas 2004, through pvlib) it agrees to
0.8 arcsec over a year at three sites (``tests/test_sky.py``); SPA's own stated
uncertainty is 0.0003 deg = 1.1 arcsec. Cost: mostly ERFA's Earth ephemeris per time,
plus a fixed cost per call far larger than one time's: pass many times at once.

Refraction. Only when ``pressure_hpa`` is given, with ERFA's model, exactly as astropy's
``AltAz`` frame applies it (see :func:`refraction`).

IERS data. The functions never download anything: they run with astropy's
``iers.conf.auto_download = False`` and ``auto_max_age = None`` (temporarily, through
``iers.conf.set_temp``; a user's own settings are restored afterwards), so astropy uses
the Earth-orientation table it has (the one bundled in ``astropy-iers-data``, or one the
user loaded). Times outside that table do not raise: they warn once per call with
:class:`astropy.utils.iers.IERSDegradedAccuracyWarning`, UT1-UTC is held at the table's
last value and polar motion at astropy's 50-year mean. The effect: an error of ``dUT1``
seconds in UT1-UTC turns the sky about the Earth's axis by ``15.04 arcsec/s * dUT1``, which
moves the sun by ``15.04 arcsec/s * dUT1 * cos(declination)`` (at most 15 arcsec per
second of UT1 error; in azimuth alone divide by ``cos(elevation)``). IERS predictions are
good to about ``0.00025 s * days**0.75`` (0.02 s, i.e. 0.3 arcsec, a year ahead); in
the bundled table UT1-UTC changes by 0.03-0.3 s per year, so a frozen value costs about
0.5-4.5 arcsec per year beyond the table's end (2027-10-29 for astropy-iers-data
2026.11). A leap second that the installed tables do not know (none is announced as of
2026) shifts UTC itself by 1 s (15 arcsec). Falling back to mean polar motion moves the
direction by less than 0.6 arcsec. Update ``astropy-iers-data`` to remove both.

Note that with downloads off, plain astropy refuses (``ValueError``) any time past the
table's first predicted day once that day is more than 30 days old (``auto_max_age``);
for the bundled 2026.11 table that is already so in late November 2026. Setting
``auto_max_age = None`` here is what lets IERS-A predictions be used offline.
"""

from __future__ import annotations

import contextlib
import math
import warnings

import astropy.units as u
import erfa
import numpy as np
from astropy.coordinates import AltAz, EarthLocation, get_body
from astropy.time import Time
from astropy.utils import iers
from astropy.utils.exceptions import AstropyWarning

from ..core.rotations import azel_to_enu_numpy

__all__ = [
    "DEFAULT_TEMPERATURE_C",
    "DEFAULT_WAVELENGTH_UM",
    "as_time",
    "check_location",
    "refraction",
    "site",
    "sun_altaz",
    "sun_direction",
]

DEFAULT_TEMPERATURE_C = 10.0
"""Air temperature (deg C) assumed when a pressure but no temperature is given: the
10 C of the standard conditions (1010 hPa, 10 C) of Bennett's and Saemundsson's tables."""

DEFAULT_WAVELENGTH_UM = 0.55
"""Effective wavelength (micrometres) for refraction: visible light, near the peak of
sunlight and of the eye's and silicon cameras' response."""

_TWO_PI = 2.0 * math.pi
# ERFA's eraAtioq guards: cos(elevation) and sin(elevation) are clamped to these before
# the tan z model is evaluated (SELMIN = sin 2.87 deg: below that the model is frozen).
_CELMIN = 1e-6
_SELMIN = 0.05


# --------------------------------------------------------------------------- site


def site(
    latitude_deg: float, longitude_deg: float, height_m: float = 0.0
) -> EarthLocation:
    """An observing site from WGS84 geodetic coordinates.

    Args:
        latitude_deg: geodetic latitude, degrees North, in ``[-90, 90]`` (or an
            astropy Quantity / Angle in any angle unit; likewise the longitude and, in
            length units, the height).
        longitude_deg: longitude, degrees East, in ``[-180, 360]``.
        height_m: height above the WGS84 ellipsoid, metres (GPS height, not height
            above sea level; the two differ by the geoid undulation, up to ~100 m, which
            moves the sun direction by less than 1 microarcsecond). ``|height_m|`` must
            be below 100 km.

    Returns:
        A scalar :class:`astropy.coordinates.EarthLocation`.

    Raises:
        ValueError: an argument is not a finite real scalar or is out of range.
    """
    lat = _scalar("latitude_deg", latitude_deg, -90.0, 90.0, u.deg)
    lon = _scalar("longitude_deg", longitude_deg, -180.0, 360.0, u.deg)
    height = _scalar("height_m", height_m, -1e5, 1e5, u.m)
    return EarthLocation.from_geodetic(
        lon * u.deg, lat * u.deg, height * u.m, ellipsoid="WGS84"
    )


# --------------------------------------------------------------------------- sun


def sun_altaz(
    times,
    location: EarthLocation,
    *,
    pressure_hpa=None,
    temperature_c=None,
    relative_humidity=0.0,
    wavelength_um=DEFAULT_WAVELENGTH_UM,
) -> tuple[np.ndarray, np.ndarray]:
    """Topocentric azimuth and elevation of the sun's centre.

    Args:
        times: an :class:`astropy.time.Time` (scalar or any shape), or anything
            ``Time(times, scale="utc")`` accepts: ISO strings, ``datetime`` objects (naive
            ones are read as UTC), ``numpy.datetime64``, arrays of these.
        location: the site, a scalar :class:`~astropy.coordinates.EarthLocation` (see
            :func:`site`).
        pressure_hpa: air pressure at the site, hPa (the station pressure, not reduced
            to sea level). ``None`` (default): no refraction, the geometric
            (vacuum) direction. ``0`` also gives no refraction.
        temperature_c: air temperature at the site, deg C. Only with ``pressure_hpa``;
            defaults to :data:`DEFAULT_TEMPERATURE_C` (10 C) when a pressure is given.
        relative_humidity: relative humidity, ``0..1`` (ignored without a pressure).
        wavelength_um: effective wavelength, micrometres (ignored without a pressure;
            above 100 ERFA's radio model is used).

        The weather arguments may be scalars or arrays broadcastable to the times' shape.

    Returns:
        ``(azimuth, elevation)``: float64 arrays of the times' shape, radians; azimuth
        from North through East in ``[0, 2 pi)``, elevation observed (refracted) when a
        pressure is given and geometric otherwise. The sun below the horizon is returned
        too (with refraction frozen below 2.9 deg, see :func:`refraction`).

    Raises:
        ValueError: times that cannot be read, an ``EarthLocation`` of several sites,
            a temperature without a pressure, weather values out of range or not
            broadcastable to the times.
        TypeError: a location that is not an ``EarthLocation``.

    Warns:
        astropy.utils.iers.IERSDegradedAccuracyWarning: some times are outside the
            available IERS Earth-orientation table (see the module docstring).
    """
    return _sun_altaz(
        times, location, pressure_hpa, temperature_c, relative_humidity, wavelength_um
    )


def sun_direction(
    times,
    location: EarthLocation,
    *,
    pressure_hpa=None,
    temperature_c=None,
    relative_humidity=0.0,
    wavelength_um=DEFAULT_WAVELENGTH_UM,
) -> np.ndarray:
    """Unit vectors towards the sun in the site's East-North-Up frame.

    Arguments as for :func:`sun_altaz`.

    Returns:
        ``(*times.shape, 3)`` float64 unit vectors
        ``(sin A cos E, cos A cos E, sin E)``, the same as
        ``pointax.core.rotations.azel_to_enu(*sun_altaz(...))``.
    """
    az, el = _sun_altaz(
        times, location, pressure_hpa, temperature_c, relative_humidity, wavelength_um
    )
    return azel_to_enu_numpy(az, el)


# --------------------------------------------------------------------------- refraction


def refraction(
    elevation_rad,
    pressure_hpa,
    temperature_c=DEFAULT_TEMPERATURE_C,
    relative_humidity=0.0,
    wavelength_um=DEFAULT_WAVELENGTH_UM,
) -> np.ndarray:
    """Atmospheric refraction for a true (geometric, unrefracted) elevation.

    The model is astropy's, i.e. ERFA's: ``erfa.refco`` gives the constants of
    ``dZ = A tan Z + B tan^3 Z`` (Green 1987 eq. 4.31, with refractivity from Hohenkerk &
    Sinclair 1985 / Rueger 2002 / IAG 1999 and the scale-height ratio after Stone 1996),
    and they are applied to the true direction exactly as ``eraAtioq`` does (and so
    astropy's ``CIRS -> AltAz`` transform): with ``z = max(sin E, 0.05)``,
    ``r = max(cos E, 1e-6)``, ``t = r / z``, ``w = B t^2``::

        d = (A + w) t / (1 + (A + 3 w) / z^2)      (one Newton step, true -> observed)

    and the direction is turned upwards by ``d`` in its vertical plane (with ERFA's
    second-order ``cos d``). Returned is the resulting observed minus true elevation.

    Accuracy. ERFA states that ``refco`` matches ray tracing to 62 mas worst / 8 mas rms
    (optical) at zenith distances 15, 45 and 75 deg over its test conditions, and that
    with this ``A tan z + B tan^3 z`` model observed places are good to 0.05 arcsec
    (optical) for zenith distances below 70 deg, better than 30 arcsec at 85 deg, and
    only to about 20 arcmin at the horizon. Measured against the classical formulas
    scaled by ``(P / 1010)(283 / (273 + T))`` (dry air, 0.55 um; 600-1050 hPa, -10 to
    30 C; ``tests/test_sky.py``), the largest differences are, by elevation band:

    ============  ===========  =======  =====================
    elevation     Saemundsson  Bennett  refraction there
    ============  ===========  =======  =====================
    60-90 deg     1.6"         1.0"     0-34"
    30-60 deg     4.6"         2.8"     32-100"
    15-30 deg     8.0"         5.0"     64-212"
    10-15 deg     10"          7"       136-315"
    5-10 deg      31"          30"      200-555"
    2.9-5 deg     205"         217"     model breaks down
    0-2.9 deg     1080"        1280"    frozen near 11'
    ============  ===========  =======  =====================

    Above 15 deg the difference is mostly a 3-5 % scale (at 45 deg, 1010 hPa, 10 C:
    ERFA 58.0", Saemundsson 60.8", Bennett 59.7"; the two formulas claim only ~4"
    themselves). At the horizon ERFA gives about 11' where the real refraction is ~29-35':
    this model is not for the sun below ~5 deg (nor is any model without a measured
    temperature profile).

    Args:
        elevation_rad: true elevation, radians, any shape. Below 2.87 deg
            (``sin E < 0.05``) ERFA freezes ``z``, so the refraction stays near its
            2.87 deg value (11.2 arcmin at 1010 hPa, 10 C) down to and below the
            horizon.
        pressure_hpa: station air pressure, hPa, ``0..10000`` (0 gives zero refraction).
        temperature_c: air temperature, deg C, ``-150..200``.
        relative_humidity: ``0..1``.
        wavelength_um: micrometres, ``0.1..1e6``; above 100 ERFA's radio model.

        All arguments broadcast against each other.

    Returns:
        Refraction (observed minus true elevation), radians, float64, of the broadcast
        shape; ``>= 0``, increasing with pressure and decreasing with temperature.

    Raises:
        ValueError: a weather value out of the stated range or not finite (ERFA would
            clamp it silently).
    """
    el = np.asarray(elevation_rad, dtype=np.float64)
    p, t, rh, wl = _check_weather(
        pressure_hpa, temperature_c, relative_humidity, wavelength_um
    )
    refa, refb = erfa.refco(p, t, rh, wl)
    # The unit vector of the true direction, split into horizontal (r) and vertical (z)
    # parts, then eraAtioq's refraction step verbatim.
    r_true, z_true = np.cos(el), np.sin(el)
    r = np.maximum(r_true, _CELMIN)
    z = np.maximum(z_true, _SELMIN)
    tz = r / z
    w = refb * tz * tz
    d = (refa + w) * tz / (1.0 + (refa + 3.0 * w) / (z * z))
    cos_d = 1.0 - 0.5 * d * d
    f = cos_d - d * z / r
    observed = np.arctan2(cos_d * z_true + d * r, np.abs(r_true * f))
    # Exactly zero (not rounding noise) where there is no refraction, e.g. pressure 0.
    return np.asarray(np.where(d == 0.0, 0.0, observed - el), dtype=np.float64)


# --------------------------------------------------------------------------- helpers


def _scalar(name: str, value, lo: float, hi: float, unit=None) -> float:
    """``value`` as a float, checked to be a finite real scalar in ``[lo, hi]``; an
    astropy Quantity (or Angle) is converted to ``unit`` first."""
    if unit is not None and hasattr(value, "unit"):
        try:
            value = value.to_value(unit)
        except u.UnitConversionError:
            raise ValueError(f"{name} must be in units of {unit}, got {value!r}") from None
    if np.ndim(value) != 0 or isinstance(value, bool | np.bool_):
        raise ValueError(f"{name} must be a real scalar, got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number, got {value!r}") from None
    if not (lo <= x <= hi):  # also rejects NaN
        raise ValueError(f"{name} must lie in [{lo:g}, {hi:g}], got {value!r}")
    return x


def _array_in(name: str, value, lo: float, hi: float, unit: str) -> np.ndarray:
    """``value`` as a float64 array, every element finite and in ``[lo, hi]``."""
    try:
        x = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(
            f"{name} must be a number or an array of numbers, got {value!r}"
        ) from None
    bad = ~((x >= lo) & (x <= hi))
    if np.any(bad):
        first = x[bad].flat[0]
        raise ValueError(f"{name} must lie in [{lo:g}, {hi:g}] {unit}, got {first!r}")
    return x


def _check_weather(pressure_hpa, temperature_c, relative_humidity, wavelength_um):
    """Validated float64 arrays (pressure, temperature, humidity, wavelength)."""
    return (
        _array_in("pressure_hpa", pressure_hpa, 0.0, 10000.0, "hPa"),
        _array_in("temperature_c", temperature_c, -150.0, 200.0, "deg C"),
        _array_in(
            "relative_humidity", relative_humidity, 0.0, 1.0, "(a fraction, not %)"
        ),
        _array_in("wavelength_um", wavelength_um, 0.1, 1e6, "micrometres"),
    )


def as_time(times) -> Time:
    """``times`` as an astropy Time (UTC unless it already is a Time)."""
    if isinstance(times, Time):
        return times
    try:
        return Time(times, scale="utc")
    except Exception as exc:  # astropy raises ValueError/TypeError and others
        raise ValueError(f"times cannot be read as UTC times: {exc}") from exc


def check_location(location) -> EarthLocation:
    """``location`` if it is one site's astropy EarthLocation; TypeError or ValueError
    naming what it is otherwise."""
    if not isinstance(location, EarthLocation):
        raise TypeError(
            f"location must be an astropy EarthLocation (see pointax.sky.site), got {type(location).__name__}"
        )
    if location.shape != ():
        raise ValueError(
            f"location must be a single site, got an EarthLocation of shape {location.shape}"
        )
    return location


@contextlib.contextmanager
def _offline_iers():
    """astropy IERS settings for the duration of a call: never download, never refuse.

    Astropy's own out-of-range warnings are replaced by one from :func:`_warn_iers_range`.
    """
    with (
        iers.conf.set_temp("auto_download", False),
        iers.conf.set_temp("auto_max_age", None),
        iers.conf.set_temp("iers_degraded_accuracy", "warn"),
        warnings.catch_warnings(),
    ):
        warnings.filterwarnings(
            "ignore", message="Tried to get polar motions", category=AstropyWarning
        )
        warnings.filterwarnings("ignore", category=iers.IERSDegradedAccuracyWarning)
        yield


def _iers_out_of_range(t: Time) -> tuple[int, str]:
    """How many of ``t`` lie outside the IERS table in use, and the table's span."""
    table = iers.earth_orientation_table.get()
    _, status = table.ut1_utc(t, return_status=True)
    outside = np.count_nonzero(np.asarray(status) < 0)
    mjd = table["MJD"]
    span = f"{Time(mjd[0], format='mjd').iso[:10]} to {Time(mjd[-1], format='mjd').iso[:10]}"
    return int(outside), span


def _sun_altaz(
    times, location, pressure_hpa, temperature_c, relative_humidity, wavelength_um
):
    """Body of :func:`sun_altaz` (called directly by both public functions)."""
    t = as_time(times)
    location = check_location(location)
    weather = checked_weather(
        pressure_hpa, temperature_c, relative_humidity, wavelength_um, t.shape, "the times' shape"
    )
    with _offline_iers():
        outside, span = _iers_out_of_range(t)
        sun = get_body("sun", t, location=location, ephemeris="builtin")
        az, el = _altaz_radians(sun, t, location)
    effect = "The sun direction moves by 15 arcsec per second of UT1-UTC error (times cos declination)"
    _warn_outside_iers(outside, span, t.size, effect, stacklevel=3)
    return _observed_altaz(az, el, weather)


# Shared with :mod:`pointax.sky.stars.apparent` (the stars' apparent places).


def checked_weather(
    pressure_hpa, temperature_c, relative_humidity, wavelength_um, shape, shape_name="the shape"
):
    """Checked weather arrays ``(pressure, temperature, humidity, wavelength)``, each
    broadcastable to ``shape`` (``shape_name`` in the error), or None for no refraction
    (no pressure); the temperature defaults to :data:`DEFAULT_TEMPERATURE_C` (as
    :func:`pointax.sky.sun_altaz`)."""
    if pressure_hpa is None:
        if temperature_c is not None:
            raise ValueError(
                "temperature_c was given without pressure_hpa: refraction needs the pressure "
                "(pass pressure_hpa, or drop temperature_c for the unrefracted direction)"
            )
        return None
    if temperature_c is None:
        temperature_c = DEFAULT_TEMPERATURE_C
    weather = _check_weather(pressure_hpa, temperature_c, relative_humidity, wavelength_um)
    names = ("pressure_hpa", "temperature_c", "relative_humidity", "wavelength_um")
    for name, value in zip(names, weather, strict=True):
        try:
            np.broadcast_to(value, shape)
        except ValueError:
            raise ValueError(f"{name} of shape {value.shape} does not broadcast to {shape_name} {shape}") from None
    return weather


def _altaz_radians(coord, t: Time, location: EarthLocation) -> tuple[np.ndarray, np.ndarray]:
    """Geometric ``(azimuth, elevation)`` of ``coord`` from ``location`` at ``t``: float64
    radians from astropy's ``AltAz`` frame (no pressure: no refraction)."""
    altaz = coord.transform_to(AltAz(obstime=t, location=location))
    return np.asarray(altaz.az.to_value(u.rad), dtype=np.float64), np.asarray(altaz.alt.to_value(u.rad), dtype=np.float64)


def _observed_altaz(az, el, weather) -> tuple[np.ndarray, np.ndarray]:
    """``(azimuth in [0, 2 pi), elevation)`` float64 radians from geometric ones: the
    elevation refracted with ``weather`` (:func:`checked_weather`; None: not refracted)."""
    az = np.mod(az, _TWO_PI)
    az = np.where(az >= _TWO_PI, 0.0, az)  # mod of a tiny negative rounds up to 2 pi
    if weather is not None:
        el = el + refraction(el, *weather)
    return np.asarray(az, dtype=np.float64), np.asarray(el, dtype=np.float64)


def _warn_outside_iers(outside: int, span: str, size: int, effect: str, stacklevel: int) -> None:
    """Warn, when ``outside`` of ``size`` times lie outside the IERS table (``span``),
    what that does (``effect``, a sentence); ``stacklevel`` as the caller's own."""
    if outside:
        warnings.warn(
            f"{outside} of {size} times lie outside the IERS Earth-orientation table "
            f"({span}); UT1-UTC is held at the table's end value and polar motion at its "
            f"50-year mean. {effect}; update astropy-iers-data to fix.",
            iers.IERSDegradedAccuracyWarning,
            stacklevel=stacklevel + 1,
        )

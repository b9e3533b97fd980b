"""The star-run planner: aim points spread evenly over the sky, ordered like a real run,
and the catalogue star nearest each (:func:`plan_star_run`). See :mod:`pointax.sky.stars`."""

from __future__ import annotations

import dataclasses
import math

import astropy.units as u
import numpy as np
from astropy.coordinates import EarthLocation
from astropy.time import Time
from jaxtyping import Float, Int

from ...core.rotations import azel_to_enu_numpy
from ..sun import DEFAULT_WAVELENGTH_UM, as_time, check_location, sun_altaz
from ...core.units import ARCSEC
from .apparent import apparent_altaz, checked_weather, fast_altaz
from .catalogue import Catalogue

__all__ = ["StarPlan", "plan_star_run"]

_TWO_PI = 2.0 * math.pi

# How far (radians) the planner's fast positions may stray from the exact ones; stars
# are chosen only this far inside the elevation limits (tests/test_stars.py measures
# the fast positions to within 2 arcsec of the exact ones).
_PLAN_MARGIN = 20.0 * ARCSEC


@dataclasses.dataclass(frozen=True, eq=False)
class StarPlan:
    """A planned pointing run: which star, when, and where it appears.

    Attributes:
        stars: the ``n`` stars in observing order (a :class:`Catalogue`).
        times: ``(n,)`` UTC times of observation (:class:`astropy.time.Time`).
        azimuth, elevation: ``(n,)`` apparent places at those times, radians (azimuth
            North through East; elevation refracted when the plan has a pressure).
        direction: ``(n, 3)`` the same as East-North-Up unit vectors.
        aim_azimuth, aim_elevation: ``(n,)`` the evenly spread aim points the stars
            were chosen for, radians.
        location: the site.
        weather: ``(pressure_hpa, temperature_c, relative_humidity, wavelength_um)``
            arrays used for refraction, or None (no refraction).
    """

    stars: Catalogue
    times: Time
    azimuth: Float[np.ndarray, " n"]
    elevation: Float[np.ndarray, " n"]
    direction: Float[np.ndarray, "n 3"]
    aim_azimuth: Float[np.ndarray, " n"]
    aim_elevation: Float[np.ndarray, " n"]
    location: EarthLocation
    weather: tuple[np.ndarray, ...] | None = None

    def __len__(self) -> int:
        return len(self.stars)

    def __getitem__(self, index) -> StarPlan:
        """The observations selected by a NumPy index, mask or slice (order kept)."""
        index = index if isinstance(index, slice) else np.atleast_1d(np.asarray(index))
        weather = None
        if self.weather is not None:
            weather = tuple(np.broadcast_to(w, (len(self),))[index] for w in self.weather)
        return StarPlan(
            stars=self.stars[index],
            times=self.times[index],
            azimuth=self.azimuth[index],
            elevation=self.elevation[index],
            direction=self.direction[index],
            aim_azimuth=self.aim_azimuth[index],
            aim_elevation=self.aim_elevation[index],
            location=self.location,
            weather=weather,
        )

    @property
    def hip(self) -> Int[np.ndarray, " n"]:
        """``(n,)`` HIP numbers of the stars, in observing order."""
        return self.stars.hip

    @property
    def aim_distance(self) -> Float[np.ndarray, " n"]:
        """``(n,)`` angle (radians) between each star and its aim point."""
        return _angle(self.direction, azel_to_enu_numpy(self.aim_azimuth, self.aim_elevation))

    def slews(self) -> Float[np.ndarray, " n-1"]:
        """``(n - 1,)`` angles (radians) between consecutive stars' directions."""
        return _angle(self.direction[1:], self.direction[:-1])


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Great-circle angle between unit vectors (radians), NumPy."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def _aim_spacing(n: int, el_min: float, el_max: float) -> float:
    """Typical angle (radians) between neighbours of ``n`` points spread evenly over the
    band of sky between two elevations: the square root of the area per point."""
    return math.sqrt(_TWO_PI * (math.sin(el_max) - math.sin(el_min)) / n)


def _aim_points(n: int, el_min: float, el_max: float) -> tuple[np.ndarray, np.ndarray]:
    """``n`` aim points (azimuth, elevation), evenly spread over the band of sky between
    ``el_min`` and ``el_max`` and ordered for slewing.

    Spread: a Fibonacci lattice, i.e. equal steps in ``sin(elevation)`` (equal area)
    with azimuth advancing by the golden angle. Order: the points are cut, by
    elevation, into rings about as wide as the points' spacing; rings are visited from
    low to high, each swept in azimuth, alternately increasing and decreasing.
    """
    k = np.arange(n)
    z_lo, z_hi = math.sin(el_min), math.sin(el_max)
    el = np.arcsin(z_lo + (z_hi - z_lo) * (k + 0.5) / n)
    az = np.mod(k * math.pi * (3.0 - math.sqrt(5.0)), _TWO_PI)
    spacing = _aim_spacing(n, el_min, el_max)
    n_rings = max(1, min(n, round((el_max - el_min) / spacing)))
    rings = np.array_split(np.argsort(el, kind="stable"), n_rings)
    order = []
    for i, ring in enumerate(rings):
        ring = ring[np.argsort(az[ring], kind="stable")]
        order.append(ring[::-1] if i % 2 else ring)
    order = np.concatenate(order)
    return az[order], el[order]


def _positive_int(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def plan_star_run(
    catalogue: Catalogue,
    location: EarthLocation,
    start,
    n_stars: int,
    *,
    cadence_s: float = 120.0,
    min_elevation_deg: float = 25.0,
    max_elevation_deg: float = 90.0,
    max_magnitude: float | None = None,
    single_only: bool = True,
    pressure_hpa=None,
    temperature_c=None,
    relative_humidity=0.0,
    wavelength_um=DEFAULT_WAVELENGTH_UM,
    sun_max_elevation_deg: float | None = None,
) -> StarPlan:
    """Plan a pointing run: ``n_stars`` stars spread evenly over the visible sky.

    Star ``k`` is observed at ``start + k * cadence_s``. The ``n_stars`` aim points are
    spread evenly (equal area) over the sky between the two elevations and visited in
    rings of elevation, low to high, each ring swept in azimuth alternately up and down
    (so an alt-az mount never turns more than once around; see :func:`_aim_points`).
    For each aim point in turn the planner takes the unused star (of the catalogue,
    after the magnitude and single-star cuts) nearest to it at that time among those
    within the elevation limits, preferring stars at least half the aim points' spacing
    (:func:`_aim_spacing`) from every star already taken, where it was seen; stars are
    chosen on fast positions (see
    :func:`pointax.sky.stars.apparent.fast_altaz`, good to about an arcsecond, used with a 20 arcsec margin
    inside the limits) and returned with their exact apparent places
    (:func:`apparent_altaz`).

    Args:
        catalogue: the stars to choose from (e.g. :func:`bright_stars`).
        location: the site (:func:`pointax.sky.site`).
        start: time of the first observation (UTC: a :class:`~astropy.time.Time` or
            anything ``Time(start, scale="utc")`` reads), a scalar.
        n_stars: number of stars (observations), at least 1.
        cadence_s: seconds from one star to the next (slew, centring, reading).
        min_elevation_deg, max_elevation_deg: the band of sky to cover, degrees of
            (observed, when a pressure is given) elevation, ``0 <= min < max <= 90``.
        max_magnitude: use only stars this bright or brighter (catalogue magnitude).
        single_only: use only stars with a single-star astrometric solution
            (``components == 1``; drops Hipparcos's resolved doubles and multiples).
        pressure_hpa, temperature_c, relative_humidity, wavelength_um: weather for
            refraction, scalars or ``(n_stars,)`` arrays (see :func:`apparent_altaz`);
            no refraction without a pressure.
        sun_max_elevation_deg: if given, refuse a run during which the sun rises above
            this elevation (e.g. -12 for nautical darkness).

    Returns:
        A :class:`StarPlan` of ``n_stars`` stars in observing order.

    Raises:
        ValueError: bad arguments; the sun above ``sun_max_elevation_deg``; and, naming
            the step and time, a sky that cannot supply ``n_stars`` distinct stars
            within the limits (ask for fewer stars, wider limits, fainter stars or a
            longer run).
    """
    if not isinstance(catalogue, Catalogue):
        raise TypeError(f"catalogue must be a pointax.sky.stars.Catalogue, got {type(catalogue).__name__}")
    n = _positive_int("n_stars", n_stars)
    cadence = float(cadence_s)
    if not (math.isfinite(cadence) and cadence > 0):
        raise ValueError(f"cadence_s must be a positive number of seconds, got {cadence_s!r}")
    lo, hi = float(min_elevation_deg), float(max_elevation_deg)
    if not (0.0 <= lo < hi <= 90.0):
        raise ValueError(
            f"elevation limits must satisfy 0 <= min_elevation_deg < max_elevation_deg <= 90, got {lo!r}, {hi!r}"
        )
    t0 = as_time(start)
    if t0.shape != ():
        raise ValueError(f"start must be a single time, got shape {t0.shape}")
    location = check_location(location)
    times = t0 + np.arange(n) * cadence * u.s
    weather = checked_weather(pressure_hpa, temperature_c, relative_humidity, wavelength_um, (n,))
    if weather is not None:
        weather = tuple(np.broadcast_to(w, (n,)) for w in weather)

    candidates = catalogue.select(max_magnitude, single_only)
    if len(candidates) < n:
        raise ValueError(
            f"the catalogue has {len(candidates)} stars after the cuts (max_magnitude={max_magnitude}, "
            f"single_only={single_only}), fewer than the {n} asked for"
        )

    if sun_max_elevation_deg is not None:
        _, sun_el = sun_altaz(times, location)
        above = np.flatnonzero(sun_el > math.radians(float(sun_max_elevation_deg)))
        if above.size:
            k = int(above[0])
            raise ValueError(
                f"the sun is at {math.degrees(sun_el[k]):.1f} deg elevation at step {k} ({times[k].iso} UTC), "
                f"above sun_max_elevation_deg={sun_max_elevation_deg}: start later or plan fewer stars"
            )

    el_lo, el_hi = math.radians(lo), math.radians(hi)
    aim_az, aim_el = _aim_points(n, el_lo, el_hi)
    aim = azel_to_enu_numpy(aim_az, aim_el)
    star_az, star_el = fast_altaz(candidates, times, location, weather)
    inside = (star_el >= el_lo + _PLAN_MARGIN) & (star_el <= el_hi - _PLAN_MARGIN)
    used = np.zeros(len(candidates), bool)
    chosen = np.empty(n, np.int64)
    directions = np.empty((n, 3))
    cos_clear = math.cos(0.5 * _aim_spacing(n, el_lo, el_hi))
    for k in range(n):
        ok = inside[k] & ~used
        if not np.any(ok):
            raise ValueError(
                f"the sky cannot supply {n} stars: at step {k} ({times[k].iso} UTC) no unused star of the "
                f"{len(candidates)} candidates lies between {lo:g} and {hi:g} deg elevation "
                f"({int(np.count_nonzero(inside[k]))} lie there, all already used); ask for fewer stars, "
                "wider elevation limits, fainter stars (max_magnitude) or a longer cadence"
            )
        here = azel_to_enu_numpy(star_az[k], star_el[k])
        closeness = here @ aim[k]
        if k:
            # Keep clear of the stars already chosen (where they were seen): prefer
            # stars at least half the aim points' spacing from all of them.
            clear = np.max(here @ directions[:k].T, axis=1) <= cos_clear
            if np.any(ok & clear):
                ok = ok & clear
        j = int(np.argmax(np.where(ok, closeness, -np.inf)))
        chosen[k] = j
        used[j] = True
        directions[k] = here[j]

    stars = candidates[chosen]
    wkw = {}
    if weather is not None:
        wkw = dict(zip(("pressure_hpa", "temperature_c", "relative_humidity", "wavelength_um"), weather, strict=True))
    az, el = apparent_altaz(stars, times, location, **wkw)
    off = np.flatnonzero((el < el_lo) | (el > el_hi))
    if off.size:  # cannot happen while the fast positions are good to 20 arcsec
        k = int(off[0])
        raise RuntimeError(
            f"star HIP {stars.hip[k]} at step {k} lies at {math.degrees(el[k]):.6f} deg, outside the limits: "
            "the planner's fast positions were off by more than their margin (a bug: please report)"
        )
    return StarPlan(
        stars=stars,
        times=times,
        azimuth=az,
        elevation=el,
        direction=azel_to_enu_numpy(az, el),
        aim_azimuth=aim_az,
        aim_elevation=aim_el,
        location=location,
        weather=weather,
    )

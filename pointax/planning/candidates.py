"""Candidate observations for :func:`pointax.plan_run`: stars of the bundled catalogue
at a site and time (telescopes), sun positions over a span of days (sun trackers), or a
plain grid (mechanical tests).

A :class:`Candidates` is a set of ENU directions with a label each (HIP number, time,
grid index) and, for stars and the sun, the UTC time each is seen at. Stars are placed
at the planning time (a snapshot), kept only when within the elevation limits and far
enough from the Sun and the Moon then; they carry their catalogue entries and those
rules (:class:`StarRules`), so that :func:`place_stars` can place them again at the
times they are scheduled for (:func:`pointax.plan_run` with ``seconds_per_target``:
the sky turns 15 deg an hour). Positions are the star planner's fast ones
(:func:`pointax.sky.stars.apparent.fast_altaz`, within about an arcsecond of the exact
apparent places, refracted when a pressure is given); the Sun's and Moon's are
astropy's topocentric ones. Astropy is imported only by the functions that need it.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from jaxtyping import Float

from ..core.rotations import azel_to_enu_numpy

__all__ = [
    "Candidates",
    "StarRules",
    "star_candidates",
    "sun_candidates",
    "grid_candidates",
    "place_stars",
    "moon_direction",
    "directions_azel",
]

_TWO_PI = 2.0 * math.pi


def directions_azel(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth (North through East, ``[0, 2 pi)``) and elevation of ENU vectors."""
    d = np.asarray(d, np.float64)
    az = np.mod(np.arctan2(d[..., 0], d[..., 1]), _TWO_PI)
    el = np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1]))
    return az, el


@dataclasses.dataclass(frozen=True, eq=False)
class StarRules:
    """What made stars candidates, kept to place them again at other times
    (:func:`place_stars`).

    Attributes:
        location: the site (an astropy ``EarthLocation``).
        weather: refraction weather (:func:`pointax.sky.stars.apparent.checked_weather`'s
            arrays: pressure hPa, temperature C, humidity, wavelength um), or None.
        min_elevation_deg, max_elevation_deg: the elevation limits, degrees.
        sun_avoid_deg, moon_avoid_deg: the least angles from the Sun and the Moon,
            degrees (None: no limit).
    """

    location: object
    weather: tuple | None = None
    min_elevation_deg: float = 20.0
    max_elevation_deg: float = 85.0
    sun_avoid_deg: float | None = 30.0
    moon_avoid_deg: float | None = 15.0


@dataclasses.dataclass(frozen=True, eq=False)
class Candidates:
    """Directions one may observe.

    Attributes:
        direction: ``(n, 3)`` East-North-Up unit vectors (for a heliostat: mirror
            normals).
        label: ``(n,)`` what each is (HIP number, ISO time, grid index), as strings.
        kind: 'stars', 'sun' or 'grid'.
        time: ``(n,)`` ISO UTC times each is seen at, or None.
        magnitude: ``(n,)`` star magnitudes, or None.
        sun: ``(n, 3)`` the sun's direction at each (sun trackers), or None.
        stars: ``(n,)`` the stars' catalogue entries (a
            :class:`pointax.sky.stars.Catalogue`, from :func:`star_candidates`), or None.
        rules: the :class:`StarRules` they were chosen by (shared by all), or None.
    """

    direction: Float[np.ndarray, "n 3"]
    label: np.ndarray
    kind: str = "grid"
    time: np.ndarray | None = None
    magnitude: np.ndarray | None = None
    sun: np.ndarray | None = None
    stars: object = None
    rules: StarRules | None = None

    def __post_init__(self):
        d = np.asarray(self.direction, np.float64).reshape(-1, 3)
        object.__setattr__(self, "direction", d / np.linalg.norm(d, axis=-1, keepdims=True))
        label = np.asarray(self.label).astype(str).reshape(-1)
        if label.shape[0] != d.shape[0]:
            raise ValueError(f"{label.shape[0]} labels for {d.shape[0]} directions")
        object.__setattr__(self, "label", label)

    def __len__(self) -> int:
        return self.direction.shape[0]

    def __getitem__(self, index) -> "Candidates":
        pick = lambda x: None if x is None else np.asarray(x)[index]  # noqa: E731
        stars = None if self.stars is None else self.stars[index]
        return Candidates(self.direction[index], self.label[index], self.kind, pick(self.time), pick(self.magnitude), pick(self.sun),
                          stars, self.rules)  # fmt: skip

    @property
    def azimuth(self) -> np.ndarray:
        """``(n,)`` azimuth, radians, North through East in ``[0, 2 pi)``."""
        return directions_azel(self.direction)[0]

    @property
    def elevation(self) -> np.ndarray:
        """``(n,)`` elevation, radians."""
        return directions_azel(self.direction)[1]


def grid_candidates(
    n_az: int = 24, elevations_deg=tuple(range(15, 90, 5)), az_offset_deg: float = 0.0
) -> Candidates:
    """A plain azimuth-elevation grid: ``n_az`` azimuths at each elevation (degrees)."""
    az = np.deg2rad(np.arange(int(n_az)) * 360.0 / int(n_az) + az_offset_deg)
    el = np.deg2rad(np.asarray(elevations_deg, np.float64))
    a, e = np.meshgrid(az, el)
    return Candidates(azel_to_enu_numpy(a.ravel(), e.ravel()), np.arange(a.size), "grid")


def _clear_of(directions: np.ndarray, body: np.ndarray, avoid_deg: float | None) -> np.ndarray:
    """``(n,)`` directions ``(n, 3)`` more than ``avoid_deg`` from ``body`` (``(3,)`` or
    ``(n, 3)`` unit vectors; all when ``avoid_deg`` is None)."""
    if avoid_deg is None:
        return np.ones(directions.shape[0], bool)
    cos = np.sum(directions * np.asarray(body, np.float64), axis=-1)
    return cos < math.cos(math.radians(float(avoid_deg)))


def _avoid_angle(value, option: str) -> float | None:
    """``value`` (degrees) as a float in ``[0, 180]``, or None; ValueError naming ``option``."""
    if value is None:
        return None
    value = float(value)
    if not (0.0 <= value <= 180.0):
        raise ValueError(f"{option} must be between 0 and 180 degrees (or None), got {value!r}")
    return value


def moon_direction(times, location) -> Float[np.ndarray, "*shape 3"]:
    """``(*times.shape, 3)`` ENU unit vectors towards the Moon's centre as seen from the
    site (topocentric: the Moon's parallax reaches 1 deg): astropy's
    ``get_body("moon", t, location)`` (its built-in lunar ephemeris, good to seconds of
    arc) in ``AltAz``, unrefracted. Offline: never downloads IERS tables (times beyond
    the bundled one use its last values, degrading the place by far less than any
    avoidance angle)."""
    import warnings

    import astropy.units as u
    from astropy.coordinates import AltAz, get_body
    from astropy.utils import iers

    from ..sky.sun import as_time, check_location

    t = as_time(times)
    location = check_location(location)
    with (
        iers.conf.set_temp("auto_download", False),
        iers.conf.set_temp("auto_max_age", None),
        iers.conf.set_temp("iers_degraded_accuracy", "ignore"),
        warnings.catch_warnings(),
    ):
        warnings.simplefilter("ignore", iers.IERSDegradedAccuracyWarning)
        warnings.filterwarnings("ignore", message="Tried to get polar motions")
        moon = get_body("moon", t, location=location).transform_to(AltAz(obstime=t, location=location))
        az = np.asarray(moon.az.to_value(u.rad), np.float64)
        el = np.asarray(moon.alt.to_value(u.rad), np.float64)
    return azel_to_enu_numpy(az, el)


def star_candidates(
    location,
    time,
    *,
    catalogue=None,
    min_elevation_deg: float = 20.0,
    max_elevation_deg: float = 85.0,
    max_magnitude: float | None = None,
    single_only: bool = True,
    sun_avoid_deg: float | None = 30.0,
    moon_avoid_deg: float | None = 15.0,
    pressure_hpa=None,
    temperature_c=None,
) -> Candidates:
    """Catalogue stars visible at a site and time.

    Args:
        location: the site (:func:`pointax.sky.site`).
        time: the planning time (UTC; anything :class:`astropy.time.Time` reads).
        catalogue: the stars (default :func:`pointax.sky.stars.bright_stars`, 4559 stars).
        min_elevation_deg, max_elevation_deg: the elevation limits, degrees.
        max_magnitude, single_only: as for :func:`pointax.sky.stars.plan_star_run`.
        sun_avoid_deg: leave out stars within this angle of the Sun, degrees (None:
            keep all).
        moon_avoid_deg: leave out stars within this angle of the Moon (its topocentric
            place at ``time``, :func:`moon_direction`), degrees; whether or not the Moon
            is up, as for the Sun (None: keep all).
        pressure_hpa, temperature_c: weather for refraction (none without a pressure).

    Returns:
        :class:`Candidates` of kind 'stars', labelled by HIP number, all at ``time``,
        carrying their catalogue entries and :class:`StarRules` (for
        :func:`place_stars`).
    """
    from ..sky.sun import as_time, check_location, sun_direction
    from ..sky.stars.apparent import checked_weather, fast_altaz
    from ..sky.stars.catalogue import bright_stars

    sun_avoid_deg = _avoid_angle(sun_avoid_deg, "sun_avoid_deg")
    moon_avoid_deg = _avoid_angle(moon_avoid_deg, "moon_avoid_deg")
    full = bright_stars() if catalogue is None else catalogue
    cat = full.select(max_magnitude, single_only)
    if len(cat) == 0:
        pool = full.select(None, single_only)
        brightest = f"the brightest is magnitude {float(np.min(pool.magnitude)):.2f}" if len(pool) else "it has none"
        raise ValueError(
            f"no star of the catalogue is as bright as magnitude {max_magnitude:g}"
            + (" with a single-star solution" if single_only else "") + f" ({brightest}): raise the magnitude limit"
        )
    t = as_time(time)
    if t.shape != ():
        raise ValueError(f"time must be a single time, got shape {t.shape}")
    location = check_location(location)
    weather = checked_weather(pressure_hpa, temperature_c, 0.0, 0.55, (1,))
    az, el = fast_altaz(cat, t.reshape(1), location, weather)
    az, el = az[0], el[0]
    d = azel_to_enu_numpy(az, el)
    rules = StarRules(location, weather, float(min_elevation_deg), float(max_elevation_deg), sun_avoid_deg, moon_avoid_deg)
    sun = sun_direction(t, location)
    inside = _star_rules_broken(rules, el, d, sun, None if moon_avoid_deg is None else moon_direction(t, location)) == ""
    n = int(inside.sum())
    return Candidates(
        d[inside], cat.hip[inside], "stars", np.full(n, t.isot), np.asarray(cat.magnitude)[inside], np.broadcast_to(sun, (n, 3)),
        cat[np.flatnonzero(inside)], rules,
    )  # fmt: skip


def _star_rules_broken(rules: StarRules, el: np.ndarray, d: np.ndarray, sun: np.ndarray, moon: np.ndarray | None) -> np.ndarray:
    """``(n,)`` which of ``rules`` each star (elevation ``el`` radians, direction ``d``
    ``(n, 3)``) breaks with the Sun and Moon at ``sun``, ``moon`` (``(3,)`` or
    ``(n, 3)``; ``moon`` None when not avoided), as text ('' where none)."""
    el_deg = np.degrees(el)
    out = np.full(el.shape[0], "", dtype=object)
    low, high = el_deg < rules.min_elevation_deg, el_deg > rules.max_elevation_deg
    out[low] = [f"elevation {e:.2f} deg below {rules.min_elevation_deg:g}" for e in el_deg[low]]
    out[high] = [f"elevation {e:.2f} deg above {rules.max_elevation_deg:g}" for e in el_deg[high]]
    for body, name, avoid in ((sun, "Sun", rules.sun_avoid_deg), (moon, "Moon", rules.moon_avoid_deg)):
        if avoid is None or body is None:
            continue
        near = ~_clear_of(d, body, avoid) & (out == "")
        angle = np.degrees(np.arccos(np.clip(np.sum(d * np.asarray(body), axis=-1), -1.0, 1.0)))
        out[near] = [f"{a:.2f} deg from the {name} (within {avoid:g})" for a in angle[near]]
    return out.astype(str)


def place_stars(candidates: Candidates, times) -> tuple[Candidates, np.ndarray]:
    """Star candidates placed again, each at its own time.

    Args:
        candidates: ``n`` stars from :func:`star_candidates` (they carry their catalogue
            entries and :class:`StarRules`).
        times: ``(n,)`` UTC times (anything :class:`astropy.time.Time` reads), one per star.

    Returns:
        ``(placed, broken)``: the stars at those times (directions, ``time`` the ISO
        times, ``sun`` the Sun's direction then), and ``(n,)`` strings naming the rule
        each breaks then (elevation limits, Sun or Moon avoidance; '' where none).

    Raises:
        ValueError: candidates without catalogue entries (not from
            :func:`star_candidates`), or times not one per star.
    """
    from ..sky.sun import as_time, sun_direction
    from ..sky.stars.apparent import fast_altaz

    if candidates.stars is None or candidates.rules is None:
        raise ValueError("only candidates from star_candidates (with their catalogue entries) can be placed again")
    t = as_time(times).reshape(-1)
    n = len(candidates)
    if t.shape != (n,):
        raise ValueError(f"times: expected one time per star ({n}), got {t.shape[0]}")
    if n == 0:
        return candidates, np.zeros(0, str)
    rules = candidates.rules
    az, el = fast_altaz(candidates.stars, t, rules.location, rules.weather)  # (n times, n stars)
    az, el = np.diagonal(az).copy(), np.diagonal(el).copy()
    d = azel_to_enu_numpy(az, el)
    sun = sun_direction(t, rules.location)
    moon = None if rules.moon_avoid_deg is None else moon_direction(t, rules.location)
    broken = _star_rules_broken(rules, el, d, sun, moon)
    placed = dataclasses.replace(candidates, direction=d, time=np.asarray(t.isot).reshape(-1), sun=sun)
    return placed, broken


def sun_candidates(
    location,
    start,
    days: float,
    *,
    step_minutes: float = 10.0,
    min_elevation_deg: float = 15.0,
    max_elevation_deg: float = 90.0,
    target=None,
    pressure_hpa=None,
) -> Candidates:
    """Sun positions at a site every ``step_minutes`` over ``days`` from ``start``.

    Args:
        location: the site (:func:`pointax.sky.site`).
        start: first time (UTC).
        days: span, days.
        step_minutes: spacing of the times.
        min_elevation_deg, max_elevation_deg: the sun's elevation limits (degrees).
        target: for a heliostat, the ENU unit vector from the mirror to its receiver:
            the candidates are then the mirror normals (bisectors of sun and target,
            :func:`pointax.reflect_normal`); None (default) for a tracker that points
            at the sun (a turntable with its sun sensor along the normal).
        pressure_hpa: weather for refraction (none without it).

    :func:`pointax.plan_run` averages the predicted error of a plan from these
    candidates over their own directions by default (the sun's path over the span,
    for a heliostat the mirror normals: where the tracker will point), each standing
    for ``step_minutes`` of tracking; ``sky='grid'`` averages over the whole visible sky.
    """
    import astropy.units as u

    from ..sky.sun import as_time, check_location, sun_altaz

    t0 = as_time(start)
    step = float(step_minutes)
    if not (step > 0 and float(days) > 0):
        raise ValueError(f"days and step_minutes must be positive, got {days!r}, {step_minutes!r}")
    times = t0 + np.arange(0.0, float(days) * 1440.0, step) * u.min
    az, el = sun_altaz(times, check_location(location), pressure_hpa=pressure_hpa)
    inside = (el >= math.radians(min_elevation_deg)) & (el <= math.radians(max_elevation_deg))
    sun = azel_to_enu_numpy(az[inside], el[inside])
    iso = np.asarray(times[inside].isot)
    if target is None:
        return Candidates(sun, iso, "sun", iso, None, sun)
    tgt = np.asarray(target, np.float64)
    tgt = tgt / np.linalg.norm(tgt)
    normal = sun + tgt[None, :]
    return Candidates(normal, iso, "sun", iso, None, sun)

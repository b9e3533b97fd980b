"""Candidate observations for :func:`pointax.plan_run`: stars of the bundled catalogue
at a site and time (telescopes), sun positions over a span of days (sun trackers), or a
plain grid (mechanical tests).

A :class:`Candidates` is a set of ENU directions with a label each (HIP number, time,
grid index) and, for stars and the sun, the UTC time each is seen at. Stars are placed
at the planning time (a snapshot: the sky turns 15 deg an hour, so plan a long run in
parts, or re-plan as it goes); positions are the star planner's fast ones
(:func:`pointax.stars.apparent.fast_altaz`, within about an arcsecond of the exact
apparent places, refracted when a pressure is given). Astropy is imported only by the
functions that need it.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from jaxtyping import Float

from ..rotations import azel_to_enu_numpy

__all__ = ["Candidates", "star_candidates", "sun_candidates", "grid_candidates", "directions_azel"]

_TWO_PI = 2.0 * math.pi


def directions_azel(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth (North through East, ``[0, 2 pi)``) and elevation of ENU vectors."""
    d = np.asarray(d, np.float64)
    az = np.mod(np.arctan2(d[..., 0], d[..., 1]), _TWO_PI)
    el = np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1]))
    return az, el


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
    """

    direction: Float[np.ndarray, "n 3"]
    label: np.ndarray
    kind: str = "grid"
    time: np.ndarray | None = None
    magnitude: np.ndarray | None = None
    sun: np.ndarray | None = None

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
        return Candidates(self.direction[index], self.label[index], self.kind, pick(self.time), pick(self.magnitude), pick(self.sun))

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


def _sun_clear(directions: np.ndarray, sun: np.ndarray, avoid_deg: float | None) -> np.ndarray:
    """Directions more than ``avoid_deg`` from the sun (all when None)."""
    if avoid_deg is None:
        return np.ones(directions.shape[0], bool)
    return directions @ np.asarray(sun, np.float64) < math.cos(math.radians(float(avoid_deg)))


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
    pressure_hpa=None,
    temperature_c=None,
) -> Candidates:
    """Catalogue stars visible at a site and time.

    Args:
        location: the site (:func:`pointax.sky.site`).
        time: the planning time (UTC; anything :class:`astropy.time.Time` reads).
        catalogue: the stars (default :func:`pointax.stars.bright_stars`, 4559 stars).
        min_elevation_deg, max_elevation_deg: the elevation limits, degrees.
        max_magnitude, single_only: as for :func:`pointax.stars.plan_star_run`.
        sun_avoid_deg: leave out stars within this angle of the sun (None: keep all).
        pressure_hpa, temperature_c: weather for refraction (none without a pressure).
    """
    from ..sky import as_time, check_location, sun_direction
    from ..stars.apparent import checked_weather, fast_altaz
    from ..stars.catalogue import bright_stars

    cat = bright_stars() if catalogue is None else catalogue
    keep = np.ones(len(cat), bool)
    if max_magnitude is not None:
        keep &= cat.magnitude <= float(max_magnitude)
    if single_only:
        keep &= cat.components == 1
    cat = cat[keep]
    t = as_time(time)
    if t.shape != ():
        raise ValueError(f"time must be a single time, got shape {t.shape}")
    location = check_location(location)
    weather = checked_weather(pressure_hpa, temperature_c, 0.0, 0.55, (1,))
    az, el = fast_altaz(cat, t.reshape(1), location, weather)
    az, el = az[0], el[0]
    d = azel_to_enu_numpy(az, el)
    inside = (el >= math.radians(min_elevation_deg)) & (el <= math.radians(max_elevation_deg))
    sun = sun_direction(t, location)
    inside &= _sun_clear(d, sun, sun_avoid_deg)
    n = int(inside.sum())
    return Candidates(
        d[inside], cat.hip[inside], "stars", np.full(n, t.isot), np.asarray(cat.magnitude)[inside], np.broadcast_to(sun, (n, 3))
    )


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

    :func:`pointax.plan_run` averages the predicted error over the whole visible sky by
    default; to weigh only where a sun tracker will point, pass
    ``sky=candidates.direction`` (or sun positions over a year) to it.
    """
    import astropy.units as u

    from ..sky import as_time, check_location, sun_altaz

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

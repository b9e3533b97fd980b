"""Simulated star runs: a bright-star catalogue, apparent places, a planner, a simulator.

This is an edge module (NumPy and astropy; it calls the JAX core through
:func:`pointax.command`). A pointing run is simulated in four steps::

    import pointax as px
    from pointax import stars

    cat = stars.bright_stars()                                # 4559 Hipparcos stars, Hp <= 6
    where = px.sky.site(31.96, -111.60, 2100)
    plan = stars.plan_star_run(cat, where, "2026-03-01T03:00", 146,
                               min_elevation_deg=25, pressure_hpa=790)
    run = stars.simulate_star_run(true_model, plan, noise_arcsec=(4.1, 2.0), seed=1)
    fitting, validation = run.split(68, seed=2)               # the paper's 68 + 78 stars
    px.fit(model, fitting.observations)

Catalogue. :func:`bright_stars` reads ``pointax/data/bright_stars.csv``: every star of
the Hipparcos new reduction (van Leeuwen 2007, CDS I/311) with Hipparcos magnitude
``Hp <= 6.0`` (4559 stars, about one per 9 square degrees), fields copied verbatim from
``hip2.dat`` (provenance and extraction in ``pointax/data/PROVENANCE.txt``). Positions
are ICRS at epoch J1991.25 with parallaxes and proper motions. :data:`STAR_NAMES` gives
the HIP numbers of 52 named bright stars (``cat.find("Vega")``).

Apparent places. :func:`apparent_altaz` is astropy's: the catalogue place is carried to
the time of observation with ``SkyCoord.apply_space_motion`` (ERFA ``pmsafe``: proper
motion and parallax as straight-line space motion; radial velocity taken as 0, since
the catalogue has none: the perspective acceleration left out amounts by 2026 to about
0.1 arcsec for the nearest fast stars, 61 Cygni and alpha Centauri, far below a pointing
run's noise) and transformed to
``AltAz`` (precession-nutation, annual and diurnal aberration, light deflection, annual
parallax, UT1 and polar motion from the IERS tables). Refraction, when a pressure is
given, is :func:`pointax.sky.refraction` applied to the geometric elevation, exactly as
ERFA's ``atioq`` and astropy apply it. Stars with a parallax below 0.01 mas (18 have a
zero or negative Hipparcos parallax) are placed at 100 kpc. Checked against ERFA's
all-in-one ``atco13`` (0.03 mas apart; the test allows 1 mas) and against Meeus's
worked apparent place of theta Persei (0.5 arcsec apart, the size of the diurnal
aberration and polar motion the textbook leaves out; ``tests/test_stars.py``). IERS data are never downloaded (see
:mod:`pointax.sky`).

Planner. :func:`plan_star_run` spreads ``n`` aim points evenly (a Fibonacci lattice,
equal area) over the band of sky between two elevations, orders them like a real run
(rings of elevation from low to high, each ring swept in azimuth alternately up and
down, so an alt-az mount never winds more than a turn), and at each aim point's time
(one star every ``cadence_s`` seconds) takes the unused catalogue star nearest to it
that keeps at least half the aim points' spacing from the stars already taken (where
they were seen). For 146 stars above 25 deg (aim points 9 deg apart) this gave stars
at least 4.6-4.8 deg apart at two sites (random visible stars: 0.5 deg typical), each
within 6 deg of its aim point, with 12-13 deg slews on average (random order: 52 deg).

Simulator. :func:`simulate_star_run` asks a *true* :class:`pointax.Model` (any mount)
for the encoder readings that centre each planned star (:func:`pointax.command`, the
model's exact inverse) and adds Gaussian noise, per axis, to the readings (or on the
sky). The result's :class:`pointax.Observations` pair the noisy readings with the
apparent directions, ready for :func:`pointax.fit`.

Conventions: radians, azimuth from North through East, East-North-Up unit vectors
``(sin A cos E, cos A cos E, sin E)``; elevations are observed (refracted) when a
pressure is given and geometric otherwise.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import functools
import math
import warnings
from collections.abc import Sequence
from importlib import resources
from pathlib import Path

import astropy.units as u
import erfa
import numpy as np
from astropy.coordinates import CIRS, AltAz, EarthLocation, SkyCoord
from astropy.time import Time
from astropy.utils import iers
from jaxtyping import Float, Int

from ._x64 import float64
from .command import command
from .model import Model
from .observations import Observations
from .rotations import azel_to_enu_numpy, offset_direction
from .sky import (
    DEFAULT_TEMPERATURE_C,
    DEFAULT_WAVELENGTH_UM,
    _as_time,
    _check_location,
    _check_weather,
    _iers_out_of_range,
    _offline_iers,
    refraction,
    sun_altaz,
)

__all__ = [
    "CATALOGUE_FILE",
    "HIPPARCOS_EPOCH",
    "MIN_PARALLAX_MAS",
    "NOISE_ON",
    "STAR_NAMES",
    "Catalogue",
    "StarPlan",
    "StarRun",
    "apparent_altaz",
    "apparent_direction",
    "bright_stars",
    "plan_star_run",
    "read_catalogue",
    "simulate_star_run",
]

ARCSEC = math.pi / (180.0 * 3600.0)
_DEG = math.pi / 180.0
_TWO_PI = 2.0 * math.pi

CATALOGUE_FILE = "bright_stars.csv"
"""Name of the bundled catalogue in ``pointax/data/``."""

HIPPARCOS_EPOCH = 1991.25
"""Epoch of the Hipparcos astrometry, Julian years (TT)."""

MIN_PARALLAX_MAS = 0.01
"""Parallaxes below this (mas) are raised to it (the star placed at 100 kpc): astropy
needs a positive distance; the shift this causes is below 0.01 mas."""

# How far (radians) the planner's fast positions may stray from the exact ones; stars
# are chosen only this far inside the elevation limits (tests/test_stars.py measures
# the fast positions to within 2 arcsec of the exact ones).
_PLAN_MARGIN = 20.0 * ARCSEC

STAR_NAMES: dict[str, int] = {
    "Sirius": 32349,
    "Canopus": 30438,
    "Arcturus": 69673,
    "Rigil Kentaurus": 71683,
    "Vega": 91262,
    "Capella": 24608,
    "Rigel": 24436,
    "Procyon": 37279,
    "Achernar": 7588,
    "Betelgeuse": 27989,
    "Hadar": 68702,
    "Altair": 97649,
    "Acrux": 60718,
    "Aldebaran": 21421,
    "Antares": 80763,
    "Spica": 65474,
    "Pollux": 37826,
    "Fomalhaut": 113368,
    "Deneb": 102098,
    "Mimosa": 62434,
    "Regulus": 49669,
    "Adhara": 33579,
    "Castor": 36850,
    "Shaula": 85927,
    "Bellatrix": 25336,
    "Elnath": 25428,
    "Alnilam": 26311,
    "Alnitak": 26727,
    "Alioth": 62956,
    "Dubhe": 54061,
    "Mirfak": 15863,
    "Polaris": 11767,
    "Alphard": 46390,
    "Hamal": 9884,
    "Denebola": 57632,
    "Rasalhague": 86032,
    "Alkaid": 67301,
    "Mizar": 65378,
    "Algol": 14576,
    "Kochab": 72607,
    "Alpheratz": 677,
    "Markab": 113963,
    "Schedar": 3179,
    "Caph": 746,
    "Enif": 107315,
    "Eltanin": 87833,
    "Alphecca": 76267,
    "Sadr": 100453,
    "Menkar": 14135,
    "Mirach": 5447,
    "Almach": 9640,
    "Diphda": 3419,
}
"""Proper names (IAU) of some bright stars and their Hipparcos numbers."""

_NAMES_BY_HIP = {hip: name for name, hip in STAR_NAMES.items()}


# --------------------------------------------------------------------------- catalogue


@dataclasses.dataclass(frozen=True, eq=False)
class Catalogue:
    """Stars with ICRS astrometry at one epoch (NumPy arrays, one entry per star).

    Attributes:
        hip: ``(n,)`` identifiers (Hipparcos numbers for the bundled catalogue).
        ra, dec: ``(n,)`` ICRS right ascension and declination at ``epoch``, radians.
        parallax_mas: ``(n,)`` parallax, milliarcseconds (default 0: far away).
        pm_ra_cosdec_mas_yr: ``(n,)`` proper motion in right ascension times
            ``cos(dec)`` (mu_alpha*), mas per Julian year (default 0).
        pm_dec_mas_yr: ``(n,)`` proper motion in declination, mas/yr (default 0).
        magnitude: ``(n,)`` magnitude (Hipparcos Hp for the bundled catalogue; NaN if
            unknown).
        color_bv: ``(n,)`` B-V colour index, magnitudes (NaN if unknown).
        components: ``(n,)`` number of components in the astrometric solution (1 for
            a single star).
        epoch: epoch of the positions, Julian years (TT), e.g. 1991.25 or 2000.0.
        source: where the stars come from, in words.

    Raises:
        ValueError: arrays of different lengths, non-finite positions, a declination
            outside [-pi/2, pi/2], non-finite motions.
    """

    hip: Int[np.ndarray, " n"]
    ra: Float[np.ndarray, " n"]
    dec: Float[np.ndarray, " n"]
    parallax_mas: Float[np.ndarray, " n"] | None = None
    pm_ra_cosdec_mas_yr: Float[np.ndarray, " n"] | None = None
    pm_dec_mas_yr: Float[np.ndarray, " n"] | None = None
    magnitude: Float[np.ndarray, " n"] | None = None
    color_bv: Float[np.ndarray, " n"] | None = None
    components: Int[np.ndarray, " n"] | None = None
    epoch: float = HIPPARCOS_EPOCH
    source: str = ""

    def __post_init__(self):
        hip = np.atleast_1d(np.asarray(self.hip, np.int64))
        n = hip.shape[0]
        if hip.ndim != 1:
            raise ValueError(f"hip must be one-dimensional, got shape {hip.shape}")
        defaults = {
            "parallax_mas": 0.0,
            "pm_ra_cosdec_mas_yr": 0.0,
            "pm_dec_mas_yr": 0.0,
            "magnitude": np.nan,
            "color_bv": np.nan,
        }
        object.__setattr__(self, "hip", hip)
        for name in ("ra", "dec", *defaults):
            value = getattr(self, name)
            if value is None:
                value = np.full(n, defaults[name])
            value = np.atleast_1d(np.asarray(value, np.float64))
            if value.shape != (n,):
                raise ValueError(f"{name} must have shape ({n},) like hip, got {value.shape}")
            object.__setattr__(self, name, value)
        comps = np.ones(n, np.int64) if self.components is None else self.components
        comps = np.atleast_1d(np.asarray(comps, np.int64))
        if comps.shape != (n,):
            raise ValueError(f"components must have shape ({n},) like hip, got {comps.shape}")
        object.__setattr__(self, "components", comps)
        for name in ("ra", "dec", "parallax_mas", "pm_ra_cosdec_mas_yr", "pm_dec_mas_yr"):
            bad = ~np.isfinite(getattr(self, name))
            if np.any(bad):
                raise ValueError(f"{name} is not finite for star {hip[bad][0]}")
        bad = np.abs(self.dec) > math.pi / 2
        if np.any(bad):
            raise ValueError(f"dec of star {hip[bad][0]} lies outside [-pi/2, pi/2] radians")
        epoch = float(self.epoch)
        if not math.isfinite(epoch):
            raise ValueError(f"epoch must be a finite Julian year, got {self.epoch!r}")
        object.__setattr__(self, "epoch", epoch)

    def __len__(self) -> int:
        return self.hip.shape[0]

    def __getitem__(self, index) -> Catalogue:
        """The stars selected by a NumPy index, mask or slice (a new catalogue)."""
        index = index if isinstance(index, slice) else np.atleast_1d(np.asarray(index))
        return dataclasses.replace(
            self,
            **{
                f: getattr(self, f)[index]
                for f in (
                    "hip",
                    "ra",
                    "dec",
                    "parallax_mas",
                    "pm_ra_cosdec_mas_yr",
                    "pm_dec_mas_yr",
                    "magnitude",
                    "color_bv",
                    "components",
                )
            },
        )

    @property
    def names(self) -> list[str]:
        """Proper name of each star from :data:`STAR_NAMES`, or ``"HIP <n>"``."""
        return [_NAMES_BY_HIP.get(int(h), f"HIP {int(h)}") for h in self.hip]

    def index(self, stars: str | int | Sequence[str | int]) -> np.ndarray:
        """Positions in this catalogue of stars given by name or HIP number.

        Raises:
            KeyError: an unknown name or a star not in this catalogue.
        """
        single = isinstance(stars, str | int | np.integer)
        wanted = [stars] if single else list(stars)
        where = {int(h): i for i, h in enumerate(self.hip)}
        out = []
        for star in wanted:
            if isinstance(star, str):
                if star not in STAR_NAMES:
                    raise KeyError(f"unknown star name {star!r}; known: {', '.join(sorted(STAR_NAMES))}")
                hip = STAR_NAMES[star]
            else:
                hip = int(star)
            if hip not in where:
                raise KeyError(f"star {star!r} (HIP {hip}) is not in this catalogue ({self.source or 'no source'})")
            out.append(where[hip])
        return np.asarray(out, np.int64)

    def find(self, stars: str | int | Sequence[str | int]) -> Catalogue:
        """The stars given by name or HIP number, in the order given (a catalogue)."""
        return self[self.index(stars)]

    def brighter_than(self, magnitude: float) -> Catalogue:
        """The stars with ``magnitude <= magnitude``."""
        return self[self.magnitude <= magnitude]

    def skycoord(self) -> SkyCoord:
        """The stars as an astropy ``SkyCoord`` (ICRS, with distance and proper motion,
        radial velocity 0, ``obstime`` the epoch), shape ``(n,)``."""
        return _skycoord(self, np.arange(len(self)))


_COLUMNS = (
    ("hip", int),
    ("ra_rad", float),
    ("dec_rad", float),
    ("parallax_mas", float),
    ("pm_ra_cosdec_mas_yr", float),
    ("pm_dec_mas_yr", float),
    ("hp_mag", float),
    ("b_v_mag", float),
    ("components", int),
)


def read_catalogue(path: str | Path, *, epoch: float = HIPPARCOS_EPOCH, source: str | None = None) -> Catalogue:
    """Read a star catalogue in the bundled CSV layout.

    The file: ``#`` comment lines, then a header naming at least the columns ``hip,
    ra_rad, dec_rad, parallax_mas, pm_ra_cosdec_mas_yr, pm_dec_mas_yr, hp_mag, b_v_mag,
    components`` (any order, more allowed), then one star per line. Units as in
    :class:`Catalogue`; positions ICRS at ``epoch``.

    Args:
        path: the CSV file.
        epoch: epoch of the positions, Julian years (TT).
        source: description kept in :attr:`Catalogue.source` (default: the path).

    Raises:
        ValueError: a missing column, a field that is not a number, a declination out of
            range, a repeated HIP number; the message names the file, line and field.
    """
    path = Path(path)
    cols: dict[str, list] = {name: [] for name, _ in _COLUMNS}
    lines: list[int] = []
    with open(path, newline="") as f:
        rows = ((k, line) for k, line in enumerate(f, start=1) if line.strip() and not line.startswith("#"))
        try:
            header_line, header_text = next(rows)
        except StopIteration:
            raise ValueError(f"{path}: no header line and no stars") from None
        header = [h.strip() for h in next(csv.reader([header_text]))]
        missing = [name for name, _ in _COLUMNS if name not in header]
        if missing:
            raise ValueError(f"{path}, line {header_line}: header lacks the column(s) {', '.join(missing)}")
        where = {name: header.index(name) for name, _ in _COLUMNS}
        for lineno, text in rows:
            fields = next(csv.reader([text]))
            if len(fields) != len(header):
                raise ValueError(
                    f"{path}, line {lineno}: {len(fields)} fields, the header has {len(header)}"
                )
            for name, kind in _COLUMNS:
                raw = fields[where[name]].strip()
                try:
                    value = kind(raw)
                except ValueError:
                    raise ValueError(
                        f"{path}, line {lineno}, field {name}: {raw!r} is not {'an integer' if kind is int else 'a number'}"
                    ) from None
                if kind is float and name not in ("hp_mag", "b_v_mag") and not math.isfinite(value):
                    raise ValueError(f"{path}, line {lineno}, field {name}: {raw!r} is not finite")
                cols[name].append(value)
            if abs(cols["dec_rad"][-1]) > math.pi / 2:
                raise ValueError(f"{path}, line {lineno}, field dec_rad: {cols['dec_rad'][-1]!r} is outside [-pi/2, pi/2]")
            lines.append(lineno)
    hip = np.asarray(cols["hip"], np.int64)
    unique, counts = np.unique(hip, return_counts=True)
    if np.any(counts > 1):
        dup = unique[counts > 1][0]
        at = [lines[i] for i in np.flatnonzero(hip == dup)]
        raise ValueError(f"{path}, lines {at[0]} and {at[1]}, field hip: star {dup} appears more than once")
    return Catalogue(
        hip=hip,
        ra=cols["ra_rad"],
        dec=cols["dec_rad"],
        parallax_mas=cols["parallax_mas"],
        pm_ra_cosdec_mas_yr=cols["pm_ra_cosdec_mas_yr"],
        pm_dec_mas_yr=cols["pm_dec_mas_yr"],
        magnitude=cols["hp_mag"],
        color_bv=cols["b_v_mag"],
        components=cols["components"],
        epoch=epoch,
        source=str(path) if source is None else source,
    )


@functools.lru_cache(maxsize=1)
def _bundled() -> Catalogue:
    path = resources.files("pointax") / "data" / CATALOGUE_FILE
    with resources.as_file(path) as p:
        return read_catalogue(
            p,
            epoch=HIPPARCOS_EPOCH,
            source="Hipparcos new reduction (van Leeuwen 2007, CDS I/311), Hp <= 6.0; pointax/data/PROVENANCE.txt",
        )


def bright_stars(max_magnitude: float | None = None) -> Catalogue:
    """The bundled bright-star catalogue (4559 Hipparcos stars with ``Hp <= 6.0``).

    Args:
        max_magnitude: keep only stars with Hipparcos magnitude ``Hp`` at most this
            (``Hp`` is close to V: within 0.1 mag for ``B-V < 0.8``, up to 0.3 mag
            fainter than V for the reddest stars).

    Returns:
        A :class:`Catalogue` (positions ICRS at epoch J1991.25), sorted by HIP number.
    """
    cat = _bundled()
    return cat if max_magnitude is None else cat.brighter_than(max_magnitude)


# --------------------------------------------------------------------------- apparent places


def _skycoord(stars: Catalogue, index: np.ndarray) -> SkyCoord:
    """SkyCoord of ``stars[index]`` (``index`` of any shape) with space motion."""
    plx = np.maximum(stars.parallax_mas[index], MIN_PARALLAX_MAS)
    return SkyCoord(
        ra=stars.ra[index] * u.rad,
        dec=stars.dec[index] * u.rad,
        distance=(1000.0 / plx) * u.pc,
        pm_ra_cosdec=stars.pm_ra_cosdec_mas_yr[index] * u.mas / u.yr,
        pm_dec=stars.pm_dec_mas_yr[index] * u.mas / u.yr,
        radial_velocity=np.zeros(np.shape(index)) * u.km / u.s,
        frame="icrs",
        obstime=Time(stars.epoch, format="jyear", scale="tt"),
    )


def _weather(pressure_hpa, temperature_c, relative_humidity, wavelength_um, shape):
    """Checked weather arrays, or None for no refraction (as :func:`pointax.sky.sun_altaz`)."""
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
            raise ValueError(f"{name} of shape {value.shape} does not broadcast to the shape {shape}") from None
    return weather


def _warn_outside_iers(outside: int, span: str, size: int) -> None:
    """Warn (as :mod:`pointax.sky` does) when times lie outside the IERS table."""
    if outside:
        warnings.warn(
            f"{outside} of {size} times lie outside the IERS Earth-orientation table "
            f"({span}); UT1-UTC is held at the table's end value and polar motion at its "
            "50-year mean. Star positions move by up to 15 arcsec per second of UT1-UTC "
            "error; update astropy-iers-data to fix.",
            iers.IERSDegradedAccuracyWarning,
            stacklevel=3,
        )



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
        raise TypeError(f"stars must be a pointax.stars.Catalogue, got {type(stars).__name__}")
    if len(stars) == 0:
        raise ValueError("the catalogue is empty: no stars to place")
    t = _as_time(times)
    location = _check_location(location)
    try:
        shape = np.broadcast_shapes(t.shape, (len(stars),))
    except ValueError:
        raise ValueError(
            f"times of shape {t.shape} do not broadcast against the {len(stars)} stars: give a "
            f"scalar, shape ({len(stars)},) for one time per star, or (m, 1) for every star at m times"
        ) from None
    weather = _weather(pressure_hpa, temperature_c, relative_humidity, wavelength_um, shape)
    index = np.broadcast_to(np.arange(len(stars)), shape)
    tb = t if t.shape == shape else np.broadcast_to(t, shape)
    with _astropy_quiet():
        outside = _iers_out_of_range(tb)
        coord = _skycoord(stars, index).apply_space_motion(new_obstime=tb)
        altaz = coord.transform_to(AltAz(obstime=tb, location=location))
        az = np.asarray(altaz.az.to_value(u.rad), np.float64)
        el = np.asarray(altaz.alt.to_value(u.rad), np.float64)
    _warn_outside_iers(*outside, tb.size)
    az = np.mod(az, _TWO_PI)
    az = np.where(az >= _TWO_PI, 0.0, az)
    if weather is not None:
        el = el + refraction(el, *weather)
    return az, el


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


def _fast_altaz(stars: Catalogue, times: Time, location: EarthLocation, weather) -> tuple[np.ndarray, np.ndarray]:
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


# --------------------------------------------------------------------------- planner


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
    :func:`_fast_altaz`, good to about an arcsecond, used with a 20 arcsec margin
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
        raise TypeError(f"catalogue must be a pointax.stars.Catalogue, got {type(catalogue).__name__}")
    n = _positive_int("n_stars", n_stars)
    cadence = float(cadence_s)
    if not (math.isfinite(cadence) and cadence > 0):
        raise ValueError(f"cadence_s must be a positive number of seconds, got {cadence_s!r}")
    lo, hi = float(min_elevation_deg), float(max_elevation_deg)
    if not (0.0 <= lo < hi <= 90.0):
        raise ValueError(
            f"elevation limits must satisfy 0 <= min_elevation_deg < max_elevation_deg <= 90, got {lo!r}, {hi!r}"
        )
    t0 = _as_time(start)
    if t0.shape != ():
        raise ValueError(f"start must be a single time, got shape {t0.shape}")
    location = _check_location(location)
    times = t0 + np.arange(n) * cadence * u.s
    weather = _weather(pressure_hpa, temperature_c, relative_humidity, wavelength_um, (n,))
    if weather is not None:
        weather = tuple(np.broadcast_to(w, (n,)) for w in weather)

    keep = np.ones(len(catalogue), bool)
    if max_magnitude is not None:
        keep &= catalogue.magnitude <= float(max_magnitude)
    if single_only:
        keep &= catalogue.components == 1
    candidates = catalogue[keep]
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
    star_az, star_el = _fast_altaz(candidates, times, location, weather)
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


# --------------------------------------------------------------------------- simulator


NOISE_ON = ("encoder", "sky")
"""Values of ``simulate_star_run(..., noise_on=...)``."""


@dataclasses.dataclass(frozen=True, eq=False)
class StarRun:
    """A simulated pointing run.

    Attributes:
        observations: :class:`pointax.Observations`: the noisy encoder readings
            (``(n, 2)``, radians, the true model's mount convention) and, as targets,
            the stars' apparent directions (``(n, 3)`` ENU). Feed it to
            :func:`pointax.fit`.
        true_encoder: ``(n, 2)`` noise-free readings that centre each star exactly
            under the true model.
        plan: the :class:`StarPlan` observed (stars, times, apparent places).
        noise_arcsec: ``(2,)`` standard deviations of the noise, arcsec: per encoder
            axis (``noise_on="encoder"``) or (cross-elevation, elevation) on the sky.
        noise_on: ``"encoder"`` or ``"sky"``.
    """

    observations: Observations
    true_encoder: Float[np.ndarray, "n 2"]
    plan: StarPlan
    noise_arcsec: Float[np.ndarray, "2"]
    noise_on: str = "encoder"

    def __len__(self) -> int:
        return len(self.plan)

    def __getitem__(self, index) -> StarRun:
        """The observations selected by a NumPy index, mask or slice (order kept)."""
        index = index if isinstance(index, slice) else np.atleast_1d(np.asarray(index))
        return dataclasses.replace(
            self,
            observations=self.observations[index],
            true_encoder=self.true_encoder[index],
            plan=self.plan[index],
        )

    @property
    def hip(self) -> Int[np.ndarray, " n"]:
        """``(n,)`` HIP numbers of the stars, in observing order."""
        return self.plan.hip

    @property
    def times(self) -> Time:
        """``(n,)`` UTC times of observation."""
        return self.plan.times

    def split(self, n_fit: int, seed: int = 0) -> tuple[StarRun, StarRun]:
        """Split into a fitting set of ``n_fit`` stars, drawn at random, and a validation
        set of the rest (each kept in observing order). With an evenly spread plan both
        sets cover the sky; the paper's split is ``run.split(68)`` of 146 stars.

        Raises:
            ValueError: ``n_fit`` not in ``1 .. len(self) - 1``.
        """
        n = len(self)
        if isinstance(n_fit, bool) or not isinstance(n_fit, int | np.integer) or not 0 < n_fit < n:
            raise ValueError(f"n_fit must be an integer in 1 .. {n - 1} for a run of {n} stars, got {n_fit!r}")
        perm = np.random.default_rng(seed).permutation(n)
        return self[np.sort(perm[:n_fit])], self[np.sort(perm[n_fit:])]


def _commanded(model: Model, direction: np.ndarray, plan: StarPlan, what: str, **kwargs) -> np.ndarray:
    """Readings from :func:`pointax.command`; raises naming each star it cannot reach."""
    cmd = command(model, direction, **kwargs)
    ok = np.asarray(cmd.ok)
    if not np.all(ok):
        reasons = cmd.reasons()
        bad = np.flatnonzero(~ok)
        lines = [
            f"step {k}: HIP {plan.hip[k]} at {plan.times[k].iso} UTC "
            f"(az {math.degrees(plan.azimuth[k]):.3f}, el {math.degrees(plan.elevation[k]):.3f} deg): {reasons[k]}"
            for k in bad[:10]
        ]
        more = f"\n... and {bad.size - 10} more" if bad.size > 10 else ""
        raise ValueError(
            f"the true model cannot {what} {bad.size} of {len(plan)} planned stars "
            "(change limits or solution, or the plan):\n" + "\n".join(lines) + more
        )
    return np.asarray(cmd.reading, np.float64)


@float64
def simulate_star_run(
    model: Model,
    plan: StarPlan,
    noise_arcsec: float | tuple[float, float] = 0.0,
    *,
    seed: int = 0,
    noise_on: str = "encoder",
    solution: str = "normal",
    limits=None,
) -> StarRun:
    """The encoder readings a mount described by ``model`` reports on a star run.

    For each planned star the true model's inverse (:func:`pointax.command`) gives the
    raw readings that centre it; noise is then added. The readings are exact to
    :func:`pointax.command`'s tolerance (``model(true_encoder)`` matches the apparent
    directions to about 1e-12 rad).

    Args:
        model: the true pointing model (:class:`pointax.Model`, any mount).
        plan: the stars, times and apparent directions (:func:`plan_star_run`).
        noise_arcsec: standard deviation of Gaussian noise, arcsec: one value for both
            axes or a pair. With ``noise_on="encoder"`` (default) it is added to the
            readings of (axis 1, axis 2), e.g. ``(4.1, 2.0)`` for the paper's L and B;
            with ``"sky"`` it is a centring error (cross-elevation, elevation) in the
            tangent plane at the star, and the readings are those that point there.
        seed: seed of the NumPy random generator.
        noise_on: ``"encoder"`` or ``"sky"``.
        solution: which mechanical solution the mount uses, as in
            :func:`pointax.command` (default ``"normal"``).
        limits: axis limits in reading units, as in :func:`pointax.command` (e.g.
            ``((0, 2 * np.pi), None)`` for azimuth readings in ``[0, 2 pi)``).

    Returns:
        A :class:`StarRun`.

    Raises:
        ValueError: negative or non-finite noise, an unknown ``noise_on``, or planned
            stars the true model cannot point at within the limits (each named).
    """
    if not isinstance(plan, StarPlan):
        raise TypeError(f"plan must be a pointax.stars.StarPlan, got {type(plan).__name__}")
    if noise_on not in NOISE_ON:
        raise ValueError(f"noise_on must be one of {NOISE_ON}, got {noise_on!r}")
    try:
        sigma = np.array(np.broadcast_to(np.asarray(noise_arcsec, np.float64), (2,)))
    except ValueError:
        raise ValueError(f"noise_arcsec must be one number or a pair, got {noise_arcsec!r}") from None
    if not np.all(np.isfinite(sigma) & (sigma >= 0)):
        raise ValueError(f"noise_arcsec must be finite and non-negative, got {noise_arcsec!r}")
    kwargs = dict(solution=solution, limits=limits)
    true = _commanded(model, plan.direction, plan, "point at", **kwargs)
    draws = np.random.default_rng(seed).standard_normal((len(plan), 2)) * (sigma * ARCSEC)
    if noise_on == "encoder":
        encoder = true + draws
    else:
        aim = np.asarray(offset_direction(plan.direction, draws), np.float64)
        encoder = _commanded(model, aim, plan, "point near", near=true, **kwargs)
    observations = Observations(encoder, plan.direction, convention=model.mount.convention)
    return StarRun(observations, true, plan, sigma, noise_on)

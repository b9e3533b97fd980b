"""The bright-star catalogue: Hipparcos stars with Hp <= 6 bundled with pointax
(:func:`bright_stars`), any catalogue in the same CSV columns (:func:`read_catalogue`),
and the proper names of some bright stars (:data:`STAR_NAMES`). See :mod:`pointax.sky.stars`."""

from __future__ import annotations

import csv
import dataclasses
import functools
import math
from collections.abc import Sequence
from importlib import resources
from pathlib import Path

import astropy.units as u
import numpy as np
from astropy.coordinates import SkyCoord
from astropy.time import Time
from jaxtyping import Float, Int

__all__ = [
    "CATALOGUE_FILE",
    "HIPPARCOS_EPOCH",
    "MIN_PARALLAX_MAS",
    "STAR_NAMES",
    "Catalogue",
    "bright_stars",
    "read_catalogue",
]


CATALOGUE_FILE = "bright_stars.csv"
"""Name of the bundled catalogue in ``pointax/data/``."""

HIPPARCOS_EPOCH = 1991.25
"""Epoch of the Hipparcos astrometry, Julian years (TT)."""

MIN_PARALLAX_MAS = 0.01
"""Parallaxes below this (mas) are raised to it (the star placed at 100 kpc): astropy
needs a positive distance; the shift this causes is below 0.01 mas."""

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

    def select(self, max_magnitude: float | None = None, single_only: bool = False) -> Catalogue:
        """The stars no fainter than ``max_magnitude`` (all if None) and, with
        ``single_only``, with a single-star astrometric solution (a new catalogue)."""
        keep = np.ones(len(self), bool)
        if max_magnitude is not None:
            keep &= self.magnitude <= float(max_magnitude)
        if single_only:
            keep &= self.components == 1
        return self[keep]

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

    def skycoord(self, index=None) -> SkyCoord:
        """The stars as an astropy ``SkyCoord`` (ICRS, with distance and proper motion,
        radial velocity 0, ``obstime`` the epoch), shape ``(n,)``; with ``index`` (an
        integer array of any shape), of ``self[index]`` in that shape."""
        if index is None:
            index = np.arange(len(self))
        plx = np.maximum(self.parallax_mas[index], MIN_PARALLAX_MAS)
        return SkyCoord(
            ra=self.ra[index] * u.rad,
            dec=self.dec[index] * u.rad,
            distance=(1000.0 / plx) * u.pc,
            pm_ra_cosdec=self.pm_ra_cosdec_mas_yr[index] * u.mas / u.yr,
            pm_dec=self.pm_dec_mas_yr[index] * u.mas / u.yr,
            radial_velocity=np.zeros(np.shape(index)) * u.km / u.s,
            frame="icrs",
            obstime=Time(self.epoch, format="jyear", scale="tt"),
        )


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

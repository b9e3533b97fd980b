"""Simulated TPOINT runs of one alt-az telescope over time, written as TPOINT input files,
for the run-history tests. Pure NumPy (the reference: tests/tpoint_numpy.py's basis
functions, DESIGN.md's); nothing here imports pointax.

Each run: observed (A, E) on a fixed all-sky grid, raw = observed - model offsets at the
observed position - Gaussian noise, so TPOINT's linear least squares (residuals in
TPOINT's form) is exact for it."""

from __future__ import annotations

import datetime

import numpy as np

from tpoint_numpy import ARCSEC, lstsq, offsets, statistics, basis

TERMS = ("IA", "IE", "NPAE", "CA", "AN", "AW", "TF", "TX")
"""TPOINT's eight basic alt-az terms."""

TRUTH_ARCSEC = {"IA": 120.0, "IE": -30.0, "NPAE": 5.0, "CA": -12.0, "AN": 8.0, "AW": -6.0, "TF": 14.0, "TX": -2.0}
"""A telescope's coefficients, arcsec."""

NOISE_ARCSEC = 1.0
"""Noise per axis on the sky (dA cos E and dE), arcsec."""


def grid(n_az: int = 8, elevations=(20.0, 35.0, 50.0, 65.0, 80.0)) -> np.ndarray:
    """``(n, 2)`` observed (A, E), radians: an all-sky grid (N-E azimuth)."""
    az = np.radians(np.arange(n_az) * 360.0 / n_az + 11.0)
    el = np.radians(np.asarray(elevations))
    A, E = np.meshgrid(az, el)
    return np.stack([A.ravel(), E.ravel()], axis=-1)


def simulate_run(coefs_arcsec: dict[str, float], seed: int, observed: np.ndarray | None = None):
    """``(observed, raw)`` radians of one run with these coefficients."""
    observed = grid() if observed is None else observed
    A, E = observed[:, 0], observed[:, 1]
    names = list(coefs_arcsec)
    dA, dE = offsets(names, [coefs_arcsec[n] * ARCSEC for n in names], A, E)
    noise = np.random.default_rng(seed).normal(size=observed.shape) * NOISE_ARCSEC * ARCSEC
    raw = np.stack([A - dA - noise[:, 0] / np.cos(E), E - dE - noise[:, 1]], axis=-1)
    return observed, raw


def write_tpoint(path, observed, raw, date: datetime.date | None, caption: str = "simulated run", temperature: float | None = None) -> None:
    """A TPOINT input file: caption, ': ALTAZ', the run parameters (latitude 31 41 19.6,
    the date when given, then the temperature when given), one record per observation
    (degrees)."""
    params = "+31 41 19.6" + ("" if date is None else f" {date.year} {date.month} {date.day}")
    if temperature is not None:
        params += f" {temperature:.3f} 741"  # temperature (deg C), pressure (hPa)
    lines = [caption, ": ALTAZ", params]
    for (a, e), (ra, re) in zip(np.degrees(observed), np.degrees(raw)):
        lines.append(f"{a % 360.0:.12f} {e:.12f} {ra % 360.0:.12f} {re:.12f}")
    lines.append("END")
    path.write_text("\n".join(lines) + "\n")


def reference_fit(observed, raw):
    """TPOINT's values and sigmas (arcsec) of the eight terms by NumPy least squares."""
    used = np.ones(len(observed), bool)
    coefs = lstsq(TERMS, observed, raw, used)
    A, E = observed[:, 0], observed[:, 1]
    dA, dE = offsets(TERMS, coefs, A, E)
    wrap = lambda x: (x + np.pi) % (2 * np.pi) - np.pi  # noqa: E731
    r = np.stack([wrap(A - raw[:, 0] - dA) * np.cos(E), E - raw[:, 1] - dE], axis=-1)
    jac = np.stack([np.concatenate([basis(n, A, E)[0] * np.cos(E), basis(n, A, E)[1]]) for n in TERMS], axis=-1)
    rms, _, sigmas = statistics(r, used, jac, len(TERMS))
    return coefs / ARCSEC, sigmas / ARCSEC, rms / ARCSEC


def mjd(date: datetime.date) -> float:
    """MJD of 0h UTC on ``date`` (JD 2400000.5 is 1858-11-17 0h)."""
    return float((date - datetime.date(1858, 11, 17)).days)

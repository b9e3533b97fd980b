"""Atmospheric refraction for pointing runs: TPOINT's two constants and their use.

TPOINT models refraction as ``dZ = A tan Z + B tan^3 Z`` (``Z`` the observed zenith
distance; the observed place is higher than the vacuum place by ``dZ``) and records
``A`` and ``B`` (arcsec) in its model files. pointax computes them from a run's weather
(pressure, temperature, relative humidity, wavelength) with ERFA's ``refco``; for the
MMT run bundled in ``examples/data`` that gives A = 42.065", B = -0.0493" where
TPOINT's model file says 42.060", -0.0485".
"""

from __future__ import annotations

import numpy as np

__all__ = ["DEFAULT_WAVELENGTH_UM", "refraction_constants", "refract"]

DEFAULT_WAVELENGTH_UM = 0.55
"""Wavelength (micron) used when a run does not give one (visible light)."""


def refraction_constants(
    pressure_mb: float | None,
    temperature_c: float | None,
    humidity: float | None,
    wavelength_um: float | None,
) -> tuple[float, float]:
    """TPOINT's refraction constants ``(A, B)`` in radians from the weather (ERFA's
    ``refco``). ``(0, 0)`` when the pressure is missing or 0 (no atmosphere, as TPOINT
    reads a pressure of 0). A missing temperature is taken as 10 C, humidity as 0 and
    the wavelength as :data:`DEFAULT_WAVELENGTH_UM`."""
    if not pressure_mb:
        return 0.0, 0.0
    import erfa

    a, b = erfa.refco(
        float(pressure_mb),
        10.0 if temperature_c is None else float(temperature_c),
        0.0 if humidity is None else float(humidity),
        DEFAULT_WAVELENGTH_UM if not wavelength_um else float(wavelength_um),
    )
    return float(a), float(b)


def refract(enu: np.ndarray, a: float, b: float) -> np.ndarray:
    """Vacuum (topocentric) directions ``(n, 3)`` East-North-Up to observed ones:
    each is raised towards the zenith by ``A tan Z + B tan^3 Z`` with ``Z`` its observed
    zenith distance (solved by fixed-point iteration). Directions at or below the
    horizon are raised by the amount at 89 deg of zenith distance (the formula's
    ``tan Z`` diverges there; such rows are refused by the readers' range checks)."""
    enu = np.asarray(enu, np.float64)
    if a == 0.0 and b == 0.0:
        return enu
    horizontal = np.hypot(enu[:, 0], enu[:, 1])
    z_vacuum = np.arctan2(horizontal, enu[:, 2])
    z = z_vacuum.copy()
    limit = np.radians(89.0)
    for _ in range(4):  # the correction is < 1e-3 rad, so each pass gains ~3 digits
        t = np.tan(np.minimum(z, limit))
        z = z_vacuum - (a * t + b * t**3)
    scale = np.where(horizontal > 0, np.sin(z) / np.where(horizontal > 0, horizontal, 1.0), 0.0)
    return np.stack([enu[:, 0] * scale, enu[:, 1] * scale, np.cos(z)], axis=-1)

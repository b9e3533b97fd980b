"""What the plots draw, as plain numpy arrays: one :class:`ResidualData` per fit.

Everything here is numpy (no matplotlib), so it can be checked on its own and used by
the report. Residuals are observed minus model in the fit's own residual form, those
of :func:`pointax.fitting.masking.observation_residuals` (the listing's too), shown in
the fit's residual unit (:func:`pointax.fitting.result.residual_unit`: arcsec for
telescopes, mrad for heliostats, degrees for turntables whose parameters are all in
degrees).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..core.units import UNITS

__all__ = ["ResidualData", "residual_data", "residual_unit", "UNIT_SCALE", "component_names"]

UNIT_SCALE = {unit: UNITS[unit] for unit in ("arcsec", "mrad", "deg")}
"""Radians per residual display unit."""


def residual_unit(result) -> str:
    """The unit the fit's report prints residuals in
    (:func:`pointax.fitting.result.residual_unit` of its parameters' units)."""
    from ..fitting import residual_unit as of_units

    return of_units(getattr(result, "units", ()))


# Mount class name -> (residual component names, axis angle names, short residual symbols).
_MOUNT_NAMES = {
    "AltAzMount": (("cross-elevation", "elevation"), ("azimuth", "elevation"), ("dA cos E", "dE")),
    "EquatorialMount": (("cross-declination", "declination"), ("hour angle", "declination"), ("dH cos dec", "d dec")),
    "XYMount": (("dL cos B", "dB"), ("L", "B"), ("dL cos B", "dB")),
}


def component_names(mount) -> tuple[tuple[str, str], tuple[str, str], tuple[str, str]]:
    """``(residual component names, axis angle names, residual symbols)`` for a mount
    (alt-az: cross-elevation and elevation; equatorial: cross-declination and
    declination; other mounts: from their ``axis_names``)."""
    name = type(mount).__name__
    if name in _MOUNT_NAMES:
        return _MOUNT_NAMES[name]
    a1, a2 = getattr(mount, "axis_names", ("axis1", "axis2"))
    return (f"cross-{a2}", a2), (a1, a2), (f"d{a1} cos {a2}", f"d{a2}")


def _enu_to_azel(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth (from +y through +x) and elevation of ``(n, 3)`` unit vectors, radians."""
    az = np.arctan2(v[:, 0], v[:, 1])
    el = np.arcsin(np.clip(v[:, 2], -1.0, 1.0))
    return az, el


def _tangent_basis(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors along increasing azimuth and elevation at ``(n, 3)`` directions
    (numpy twin of :func:`pointax.core.rotations.tangent_basis`)."""
    az, el = _enu_to_azel(v)
    e_az = np.stack([np.cos(az), -np.sin(az), np.zeros_like(az)], axis=-1)
    e_el = np.stack([-np.sin(el) * np.sin(az), -np.sin(el) * np.cos(az), np.cos(el)], axis=-1)
    return e_az, e_el


@dataclasses.dataclass(frozen=True)
class ResidualData:
    """One fit's residuals and positions, ready to draw (numpy; ``n`` observations).

    Attributes:
        residuals: ``(n, 2)`` observed minus model in the mount's residual basis and
            the fit's residual form, in ``unit``, at every row, masked ones included
            (:func:`pointax.fitting.masking.observation_residuals`).
        unit: 'arcsec', 'mrad' or 'deg'.
        sky_rms: the fit's Sky RMS (``result.sky_rms``), in ``unit``.
        names: the two residual components' names (alt-az: 'cross-elevation',
            'elevation'; equatorial: 'cross-declination', 'declination').
        symbols: short forms of ``names`` ('dA cos E', 'dE').
        axis_names: the two axis angles' names ('azimuth', 'elevation').
        axis_angles: ``(n, 2)`` nominal axis angles of the raw readings
            (``mount.axis_angles(encoder)``), degrees, in the mount's convention (the
            file's azimuth convention for alt-az runs, azimuth wrapped to 0-360).
        observed_angles: ``(n, 2)`` the observed (catalogue) direction in the mount's
            own frame, degrees (alt-az: the azimuth and elevation as the file counts
            them; equatorial: hour angle and declination), or None for mounts without
            spherical angles (turntables, heliostats).
        azel: ``(n, 2)`` the observed direction's azimuth (North through East) and
            elevation, degrees.
        sky: ``(n, 2)`` the residual on the sky along increasing North-East azimuth and
            increasing elevation at the observed direction, in ``unit`` (the residual
            vector, whatever the mount, expressed in the horizon frame).
        masked: ``(n,)`` weight 0 (TPOINT's MASK; not used by the fit).
        outlier: ``(n,)`` rejected by a robust fit (or listed in ``outliers``), not masked.
        used: ``(n,)`` neither masked nor an outlier.
        mount: the mount's class name.
        convention: the azimuth convention of alt-az mounts ('N-E', 'S-E', 'S-W'), else None.
    """

    residuals: np.ndarray
    unit: str
    sky_rms: float
    names: tuple[str, str]
    symbols: tuple[str, str]
    axis_names: tuple[str, str]
    axis_angles: np.ndarray
    observed_angles: np.ndarray | None
    azel: np.ndarray
    sky: np.ndarray
    masked: np.ndarray
    outlier: np.ndarray
    used: np.ndarray
    mount: str
    convention: str | None

    def __len__(self) -> int:
        return self.residuals.shape[0]

    @property
    def distance(self) -> np.ndarray:
        """``(n,)`` the on-sky length of each residual (TPOINT's R of MASK R > x), ``unit``."""
        from ..fitting import on_sky

        return on_sky(self.residuals)

    def groups(self) -> list[tuple[str, np.ndarray]]:
        """``[('used', mask), ('outlier', mask), ('masked', mask)]``: the three kinds
        of observation, drawn as separate artists (empty ones included)."""
        return [("used", self.used), ("outlier", self.outlier), ("masked", self.masked)]


def _observations_of(observations):
    """The :class:`pointax.Observations` of a run (or the observations themselves)."""
    inner = getattr(observations, "observations", None)
    if inner is not None and hasattr(inner, "encoder"):
        return inner
    if hasattr(observations, "encoder") and hasattr(observations, "target"):
        return observations
    raise TypeError(f"expected pointax.Observations or a run with .observations, got {type(observations).__name__}")


def _axis_angles(mount, encoder: np.ndarray) -> np.ndarray:
    """Nominal axis angles (radians) of ``(n, 2)`` raw readings: the readings
    themselves for mounts whose encoders read angles, else ``mount.axis_angles``
    (a heliostat's actuator increments to joint angles)."""
    from ..core.mounts import Mount

    if type(mount).axis_angles is Mount.axis_angles:
        return np.array(encoder, float)
    import jax
    import jax.numpy as jnp

    with jax.enable_x64(True):
        return np.asarray(jnp.vectorize(mount.axis_angles, signature="(2)->(2)")(jnp.asarray(encoder)), float)


def residual_data(result, observations, outliers=None) -> ResidualData:
    """The arrays the plots draw for one fit.

    Args:
        result: a :class:`pointax.FitResult` of a single fit.
        observations: the :class:`pointax.Observations` fitted, or a run with
            ``.observations``; the rows the fit gave weight 0 are drawn as masked.
        outliers: more observations to flag as outliers (0-based indices or an
            ``(n,)`` boolean mask), besides ``result.outliers``.

    Raises:
        ValueError: shapes of result and observations differ, or a batched result.
    """
    from ..fitting import observation_residuals

    obs = _observations_of(observations)
    rows = observation_residuals(result, obs, outliers=outliers)
    res, masked, outlier, used = rows.residuals, rows.masked, rows.outlier, rows.used
    encoder = np.asarray(obs.encoder, float)
    target = np.asarray(obs.target, float)
    unit = residual_unit(result)
    scale = UNIT_SCALE[unit]
    mount = result.model.mount
    names, axis_names, symbols = component_names(mount)
    frame = np.asarray(mount.frame, float)

    # The residual vector on the sky: r1 e_az + r2 e_el in the mount frame at the
    # observed direction (the basis of Mount.axis_residuals), taken to ENU, then
    # resolved along the horizon basis at the same direction.
    target_mount = target @ frame
    e1, e2 = _tangent_basis(target_mount)
    vec_enu = (res[:, :1] * e1 + res[:, 1:] * e2) @ frame.T
    h_az, h_el = _tangent_basis(target)
    sky = np.stack([np.sum(vec_enu * h_az, axis=1), np.sum(vec_enu * h_el, axis=1)], axis=1)
    az, el = _enu_to_azel(target)
    azel = np.degrees(np.stack([np.mod(az, 2 * np.pi), el], axis=1))

    from ..core.mounts import SphericalMount

    observed = None
    if isinstance(mount, SphericalMount):
        a1, a2 = _enu_to_azel(target_mount)
        observed = np.degrees(np.stack([a1, a2], axis=1))
        if type(mount).__name__ == "AltAzMount":
            observed[:, 0] = np.mod(observed[:, 0], 360.0)
    angles = np.degrees(_axis_angles(mount, encoder))
    if type(mount).__name__ == "AltAzMount":
        angles[:, 0] = np.mod(angles[:, 0], 360.0)
    return ResidualData(
        residuals=res / scale,
        unit=unit,
        sky_rms=float(np.asarray(result.sky_rms)) / scale,
        names=names,
        symbols=symbols,
        axis_names=axis_names,
        axis_angles=angles,
        observed_angles=observed,
        azel=azel,
        sky=sky / scale,
        masked=masked,
        outlier=outlier,
        used=used,
        mount=type(mount).__name__,
        convention=getattr(mount, "azimuth", None),
    )

"""Simulated observations: a true model, encoder readings and measurement noise."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike, Float

from .compiled import compile_by_structure
from .precision import float64
from .model import Model
from .observations import Observations
from .padding import pad_rows, power_of_two
from .rotations import offset_direction
from .units import angles_in_radians

__all__ = ["simulate", "encoder_grid"]


@float64
def simulate(
    model: Model,
    encoder: Float[ArrayLike, "n 2"],
    noise: float | tuple[float, float] = 0.0,
    seed: int = 0,
    readings=None,
) -> Observations:
    """Observations that ``model`` (the truth) would produce at these encoder readings.

    Args:
        model: the true pointing model.
        encoder: ``(n, 2)`` raw encoder angles, radians (or an astropy Quantity), in
            the mount's convention.
        noise: standard deviation of Gaussian measurement noise on the sky, radians
            (or a Quantity, e.g. ``2 * u.arcsec``):
            one value for both axes or ``(across axis 1, along axis 2)`` in the mount
            frame: (cross-elevation, elevation) for alt-az, (dL cos B, dB) for X-Y.
        seed: seed of the NumPy random generator for the noise.
        readings: auxiliary readings, name -> ``(n,)`` values, that the model's terms
            read (:attr:`pointax.Model.readings`); carried by the result.

    Returns:
        :class:`Observations` with the noisy true directions as targets.
    """
    encoder = angles_in_radians(encoder, "encoder")
    if isinstance(noise, tuple):
        noise = tuple(angles_in_radians(x, "noise") for x in noise)
    sigma = np.broadcast_to(angles_in_radians(noise, "noise"), (2,))
    n = encoder.shape[0]
    offsets = np.random.default_rng(seed).normal(size=(n, 2)) * sigma
    # One compiled program per model structure and bucket of rows (padded rows repeat
    # the first reading and are dropped), not one per observation count.
    rows = simulation_bucket(n)
    pad = lambda x: pad_rows(x, rows) if n else x  # noqa: E731
    readings = {k: np.broadcast_to(np.asarray(v, np.float64), (n,)) for k, v in (readings or {}).items()}
    padded = {k: pad(v) for k, v in readings.items()}
    target = np.asarray(_noisy_directions(model, pad(np.asarray(encoder, np.float64)), pad(offsets), padded))[:n]
    return Observations(encoder, target, convention=model.mount.convention, readings=readings)


def simulation_bucket(n: int) -> int:
    """Rows :func:`simulate` evaluates for ``n`` observations: at least 128, else the
    next power of two (evaluating a model at 128 directions costs far less than
    compiling it for another size)."""
    return power_of_two(n, 128)


@compile_by_structure
def _noisy_directions(model: Model, encoder, offsets, readings):
    """``(n, 3)`` ENU directions at gnomonic ``offsets`` (mount frame) from ``model``'s
    pointing at ``encoder``: one compiled program per model structure, whether its
    values are Python numbers or arrays."""
    frame = jnp.asarray(model.mount.frame)
    truth = model(encoder, readings=readings or None) @ frame
    return offset_direction(truth, offsets) @ frame.T


def encoder_grid(n_az: int = 12, elevations_deg=(20, 35, 50, 65, 80), az_offset_deg: float = 0.0) -> np.ndarray:
    """A simple all-sky grid of ``(n_az * len(elevations), 2)`` encoder positions, radians."""
    az = np.deg2rad(np.arange(n_az) * 360.0 / n_az + az_offset_deg)
    el = np.deg2rad(np.asarray(elevations_deg, np.float64))
    grid_az, grid_el = np.meshgrid(az, el)
    return np.stack([grid_az.ravel(), grid_el.ravel()], axis=-1)

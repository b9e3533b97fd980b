"""Observations: raw encoder angles paired with the directions actually observed."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .errors import warn_input
from .units import angles_in_radians, check_not_degrees, check_unit_vectors, directions_enu

__all__ = ["Observations", "COUNTED_READINGS"]

COUNTED_READINGS = frozenset({"heliostat"})
"""Conventions whose readings are counts (a heliostat's actuator increments), not
angles: they are not checked for looking like degrees."""


class Observations(eqx.Module):
    """A set of pointing observations (a pytree: batch it, slice it, vmap over it).

    Attributes:
        encoder: ``(n, 2)`` raw encoder angles in radians, in the mount's own convention
            (alt-az: azimuth and elevation as the encoders count them). An astropy
            Quantity or Angle is converted to radians; readings beyond two turns
            (4 pi) in magnitude look like degrees and give an
            :class:`~pointax.io.InputWarning` (not for :data:`COUNTED_READINGS`).
        target: ``(n, 3)`` observed (true, catalogue) directions, unit vectors in
            East-North-Up; or an astropy ``SkyCoord`` in an ``AltAz`` frame, or an
            ``(n, 2)`` Quantity of azimuth (North through East) and elevation.
        weight: ``(n,)`` relative weights (default 1). A weight of 0 removes an
            observation from the fit without changing array shapes (used for padding).
        convention: name of the encoder angle convention (e.g. 'N-E', 'S-E' for an
            alt-az mount) or ``None``; a fit checks it against the mount's.
    """

    encoder: Float[Array, "n 2"]
    target: Float[Array, "n 3"]
    weight: Float[Array, " n"]
    convention: str | None = eqx.field(static=True, default=None)

    def __init__(self, encoder, target, weight=None, convention: str | None = None):
        encoder = angles_in_radians(encoder, "encoder") if not isinstance(encoder, jnp.ndarray) else encoder
        target = directions_enu(target, "target") if not isinstance(target, jnp.ndarray) else target
        if isinstance(encoder, np.ndarray) and convention not in COUNTED_READINGS:
            looks = check_not_degrees("the encoder readings", encoder)
            if looks:
                warn_input("Observations", None, looks, "encoder", stacklevel=3)
        if isinstance(target, np.ndarray):  # concrete vectors: az/el in degrees (say) are named here
            check_unit_vectors(target, "target", weight=weight, stacklevel=3)
        if encoder.ndim != 2 or encoder.shape[-1] != 2:
            raise ValueError(f"encoder must have shape (n, 2), got {encoder.shape}")
        if target.shape != (encoder.shape[0], 3):
            raise ValueError(f"target must have shape ({encoder.shape[0]}, 3), got {target.shape}")
        if weight is None:
            weight = np.ones(encoder.shape[0])
        elif not isinstance(weight, jnp.ndarray):
            weight = np.asarray(weight, np.float64)
        if weight.shape != (encoder.shape[0],):
            raise ValueError(f"weight must have shape ({encoder.shape[0]},), got {weight.shape}")
        self.encoder = encoder
        self.target = target
        self.weight = weight
        self.convention = convention

    def __len__(self) -> int:
        return self.encoder.shape[0]

    def __getitem__(self, index) -> "Observations":
        """A subset of the observations (numpy-style index, mask or slice)."""
        index = np.asarray(index) if not isinstance(index, slice) else index
        return Observations(self.encoder[index], self.target[index], self.weight[index], self.convention)

    def filled(self, used: Array) -> tuple[Float[Array, "n 2"], Float[Array, "n 3"]]:
        """``(encoder, target)`` with the rows not ``used`` replaced by the first used
        row (pure JAX). Unused rows may hold NaN; a model evaluated there would meet
        them, or a term's pole (zero readings put an alt-az mount on the horizon, where
        cot E is infinite), and poison derivatives that ``where`` masks only in value."""
        first = jnp.argmax(used)
        encoder, target = jnp.asarray(self.encoder), jnp.asarray(self.target)
        return (
            jnp.where(used[:, None], encoder, encoder[first]),
            jnp.where(used[:, None], target, target[first]),
        )

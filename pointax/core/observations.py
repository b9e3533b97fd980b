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
        readings: auxiliary readings, a mapping name -> ``(n,)`` float64 array, one value
            per observation (``{}`` when none): ``temperature`` (deg C), ``time`` (MJD),
            ... (:data:`pointax.core.readings.READINGS`; any other name is allowed).
            NaN means "not recorded" for that observation. Terms read them by name
            (:meth:`pointax.Term.reading`); a fit whose model needs a reading refuses
            used observations that lack it.
    """

    encoder: Float[Array, "n 2"]
    target: Float[Array, "n 3"]
    weight: Float[Array, " n"]
    convention: str | None = eqx.field(static=True, default=None)
    readings: dict[str, Float[Array, " n"]] = eqx.field(default_factory=dict)

    def __init__(self, encoder, target, weight=None, convention: str | None = None, readings=None):
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
        weight = _weights_of(weight, encoder.shape[0])
        self.encoder = encoder
        self.target = target
        self.weight = weight
        self.convention = convention
        self.readings = _readings_of(readings, encoder.shape[0])

    def __hash__(self) -> int:
        # Equinox hashes a Module by its fields; the readings' dict is hashed by its
        # items (a fit's static part, from eqx.partition, holds it with None values).
        fields = (self.encoder, self.target, self.weight, self.convention, tuple(self.readings.items()))
        return hash((type(self), fields))

    def __len__(self) -> int:
        return self.encoder.shape[0]

    def __getitem__(self, index) -> "Observations":
        """A subset of the observations (numpy-style index, mask or slice)."""
        index = np.asarray(index) if not isinstance(index, slice) else index
        readings = {k: v[index] for k, v in self.readings.items()}
        return Observations(self.encoder[index], self.target[index], self.weight[index], self.convention, readings)

    def with_weight(self, weight) -> "Observations":
        """A copy with other ``(n,)`` weights (None: all 1), readings and convention kept.
        The targets are checked again under the new weights (a row given weight must hold
        a unit vector); the encoder readings are not: they were checked, and warned of,
        when these observations were made."""
        weight = _weights_of(weight, len(self))
        if isinstance(self.target, np.ndarray):
            check_unit_vectors(self.target, "target", weight=weight, stacklevel=3)
        return eqx.tree_at(lambda o: o.weight, self, weight)

    def only_readings(self, names) -> "Observations":
        """A copy carrying only the readings called ``names`` (those a model reads,
        :attr:`pointax.Model.readings`): fits drop the rest, so that a run read with its
        weather and date compiles to the same program as one read without them."""
        names = set(names)
        if set(self.readings) <= names:
            return self
        copy = object.__new__(type(self))  # no checks again: batches (S, N) too
        copy.__dict__.update(self.__dict__)
        object.__setattr__(copy, "readings", {k: v for k, v in self.readings.items() if k in names})
        return copy

    def filled(self, used: Array) -> tuple[Float[Array, "n 2"], Float[Array, "n 3"]]:
        """``(encoder, target)`` with the rows not ``used`` replaced by the first used
        row (pure JAX). Unused rows may hold NaN; a model evaluated there would meet
        them, or a term's pole (zero readings put an alt-az mount on the horizon, where
        cot E is infinite), and poison derivatives that ``where`` masks only in value.
        :meth:`filled_readings` does the same for the auxiliary readings."""
        first = jnp.argmax(used)
        encoder, target = jnp.asarray(self.encoder), jnp.asarray(self.target)
        return (
            jnp.where(used[:, None], encoder, encoder[first]),
            jnp.where(used[:, None], target, target[first]),
        )

    def filled_readings(self, used: Array) -> dict[str, Float[Array, " n"]]:
        """:attr:`readings` with the rows not ``used`` replaced by the first used row's
        values (pure JAX; see :meth:`filled`)."""
        first = jnp.argmax(used)
        out = {}
        for name, value in self.readings.items():
            value = jnp.asarray(value)
            out[name] = jnp.where(used, value, value[first])
        return out


def _weights_of(weight, n: int):
    """``weight`` as ``(n,)`` weights (None: all 1; float64 NumPy unless already a JAX
    array); ValueError for another shape."""
    if weight is None:
        weight = np.ones(n)
    elif not isinstance(weight, jnp.ndarray):
        weight = np.asarray(weight, np.float64)
    if weight.shape != (n,):
        raise ValueError(f"weight must have shape ({n},), got {weight.shape}")
    return weight


def _readings_of(readings, n: int) -> dict:
    """``readings`` as a dict name -> ``(n,)`` array (float64 NumPy unless already a JAX
    array: traced values pass through); ValueError naming a reading of the wrong shape."""
    if readings is None:
        return {}
    if not hasattr(readings, "items"):
        raise TypeError(f"readings must be a mapping name -> (n,) array, got {type(readings).__name__}")
    out = {}
    for name, value in readings.items():
        if not isinstance(name, str) or not name:
            raise ValueError(f"reading names must be non-empty strings, got {name!r}")
        if not isinstance(value, jnp.ndarray):
            value = np.asarray(value, np.float64)
        if value.shape != (n,):
            raise ValueError(f"reading {name!r} must have shape ({n},), one value per observation, got {value.shape}")
        out[name] = value
    return dict(sorted(out.items()))

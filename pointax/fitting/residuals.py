"""The residuals a fit minimises: observed minus model on the sky, in either residual form.

Written per observation on :meth:`pointax.Model.mount_direction`, the plain forward
model: the readable definition and the oracle. Fits evaluate the same residuals over a
whole site at once (:mod:`pointax.fitting.problem`, on :mod:`pointax.fitting.fast_evaluation`), tested
against these.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ..core.compiled import compile_by_structure
from ..core.model import Model
from ..core.observations import Observations
from ..core.precision import float64
from ..core.readings import check_readings, model_readings
from ..core.rotations import tangent_offset, wrap_pi

__all__ = ["residuals", "as_observations", "check_convention"]


def as_observations(data) -> Observations:
    """Accept :class:`Observations` or anything with an ``observations`` attribute."""
    if isinstance(data, Observations):
        return data
    obs = getattr(data, "observations", None)
    if isinstance(obs, Observations):
        return obs
    raise TypeError(
        f"expected pointax.Observations or a run with .observations (e.g. from pointax.io.read_tpoint), got {type(data).__name__}"
    )


def check_convention(model: Model, obs: Observations) -> None:
    """Raise ValueError when the observations do not suit the model: their encoder
    convention is not the mount's, or a used observation lacks an auxiliary reading the
    model's terms read (:func:`pointax.core.readings.check_readings`, naming the reading
    and the rows)."""
    check_readings(model, obs)
    mine, theirs = model.mount.convention, obs.convention
    if mine is not None and theirs is not None and mine != theirs:
        raise ValueError(
            f"the observations' encoder angles follow the {theirs!r} convention but the model's "
            f"mount expects {mine!r}; build the model with the data's convention "
            f"(e.g. pointax.AltAz(terms, azimuth={theirs!r}))"
        )


@float64
def residuals(model: Model, obs) -> Float[Array, "n 2"]:
    """Observed minus model on the sky, ``(n, 2)`` (cross-elevation, elevation) radians,
    as the model's :attr:`~pointax.Model.residual_form` defines them.

    Pure JAX, float64 whether or not JAX's x64 mode is on (:mod:`pointax.core.precision`);
    observations with weight 0 give 0 (and may hold NaN). ``obs``: :class:`Observations`
    or a run that holds them (:func:`pointax.io.read_tpoint`), as :func:`pointax.fit` takes.

    Compiled once per model structure and number of observations
    (:mod:`pointax.core.compiled`).
    """
    return _residuals(model, as_observations(obs))


@compile_by_structure
def _residuals(model: Model, obs: Observations) -> Float[Array, "n 2"]:
    if model.residual_form == "tpoint":
        return _tpoint_residuals(model, obs)
    used = obs.weight > 0
    encoder = jnp.where(used[:, None], obs.encoder, 0.0)
    # Targets into the mount frame (F is orthogonal, so its inverse is its transpose).
    target = jnp.asarray(obs.target) @ model.mount.frame
    at_rest = model.mount.boresight
    target = jnp.where(used[:, None], target, at_rest)
    if model.readings:
        values = model_readings(model, obs, used)
        predicted = jax.vmap(lambda e, r: model.at_readings(r).mount_direction(e))(encoder, values)
    else:
        predicted = jax.vmap(model.mount_direction)(encoder)
    predicted = jnp.where(used[:, None], predicted, at_rest)
    r = -tangent_offset(predicted, target)
    return jnp.where(used[:, None], r, 0.0)


def _tpoint_residuals(model: Model, obs: Observations) -> Float[Array, "n 2"]:
    """TPOINT's residuals ``(dA cos E, dE)``: ``d`` = observed angles minus the chain's
    angles minus the sky offsets evaluated at the observed angles (see
    :class:`pointax.Model`)."""
    mount = model.mount
    used = obs.weight > 0
    encoder, target = obs.filled(used)
    target = target @ mount.frame

    def one(reading, direction, values):
        m = model.at_readings(values) if values is not None else model
        d, angles = m.chain_direction(reading)
        chain = mount.angles_of(d, near=angles)
        observed = mount.angles_of(direction, near=mount.axis_angles(reading))
        offset = m.sky_offset(observed)
        diff = observed - chain if offset is None else observed - chain - offset
        return jnp.stack([wrap_pi(diff[0]) * jnp.cos(observed[1]), wrap_pi(diff[1])])

    values = model_readings(model, obs, used) if model.readings else None
    r = jax.vmap(one)(encoder, target, values)
    return jnp.where(used[:, None], r, 0.0)

"""The fitting problem every fit solves: what a site's observations fix, prepared once,
and one family of residual functions of the model's parameters.

* :func:`site_data` is the one construction of a site's :class:`SiteData` (the nominal
  axis angles with their sines and cosines, the targets in the mount frame, TPOINT's
  unit sky offsets): for one site, or for a chunk of sites with a leading site axis
  (the batched and shared-parameter fits), with the choice of sine functions an
  argument (``library_trig``).
* :func:`site_residuals` is the residual family: observed minus model in either
  residual form, weighted or not, evaluated over the whole site by
  :mod:`pointax.fitting.fast_evaluation`. Its derivatives for the fits:
  :mod:`pointax.fitting.fast_jacobian`.
* :class:`Problem` and :func:`define_problem` are the solo fit's handle on the two
  (:func:`pointax.fit`, leave-one-out, the comparison folds, TPOINT's FIT, model
  building).

:meth:`pointax.Model.mount_direction` and :func:`pointax.residuals` stay the plain
forward model, the oracle these residuals are tested against (``tests/test_site.py``).
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from ..core.model import Model
from ..core.observations import Observations
from ..core.readings import model_readings
from ..core.rotations import azel_trig, wrap_pi
from ..core.term import SkyPoint
from .fast_evaluation import (
    chain_pointing,
    corrected_angles,
    in_mount_frame,
    per_observation,
    rotated,
    sine_function,
    site_pointing,
    tangent_offsets,
)

__all__ = [
    "SiteData",
    "site_data",
    "site_residuals",
    "is_affine",
    "without_pinned_singularities",
    "reading_site_residuals",
    "Problem",
    "define_problem",
]


class SiteData(eqx.Module):
    """What a site's observations fix, computed once per fit (a pytree: a leading site
    axis on every array for a chunk of sites, :func:`site_data`).

    Attributes:
        nominal: ``(n, 2)`` nominal axis angles (:meth:`pointax.Mount.axis_angles`).
        trig: four ``(n,)`` arrays: cos and sin of the nominal axis-1 angle, cos and sin
            of axis 2 (None for ``residual_form="tpoint"`` when no term turns the chain).
        target_trig: for ``residual_form="sky"`` (else None): four ``(n,)`` arrays: cos
            and sin of the observed directions' azimuth, cos and sin of their elevation,
            in the mount frame (the direction and its tangent-plane basis,
            :func:`pointax.core.rotations.tangent_basis`, follow).
        sqrt_weight: ``(n,)`` square roots of the weights normalised to mean 1 over the
            used observations (0 for unused ones).
        used: ``(n,)`` observations with positive weight.
        observed: for ``residual_form="tpoint"`` (else None): the observed directions'
            angles in the mount's convention, as two ``(n,)`` arrays, and the cosine of
            the second.
        sky_basis: for ``residual_form="tpoint"`` (else None): per parameter of the
            terms with ``linear_sky_offset``, in model order, its sky offset per unit
            at the observed angles as two ``(n,)`` arrays.
        encoder: for a model that reads auxiliary readings (else None): ``(n, 2)`` raw
            encoder readings (unused rows: the first used row's).
        readings: for a model that reads auxiliary readings (else None): per name of
            :attr:`pointax.Model.readings`, in order, its ``(n,)`` values (unused rows:
            the first used row's); a tuple, not a dict, so that the data's static part
            is hashable.
            Such a model's residuals are evaluated observation by observation
            (:meth:`pointax.Model.mount_direction` on the model bound to each row's
            readings, :func:`reading_site_residuals`), not by the fast evaluation.
        library_trig: sines and cosines (of the nominal angles, and of the sky form's
            fixed point inside every evaluation) from XLA's per-element library calls
            instead of :func:`pointax.core.trig.sincos`'s vectorised polynomials: the
            polynomials are faster over thousands of sites, the library calls make the
            smaller executable for one site (``benchmarks/interactive_notes.md``).
            Values agree to rounding.
    """

    nominal: Float[Array, "n 2"]
    trig: tuple[Float[Array, " n"], ...] | None
    target_trig: tuple[Float[Array, " n"], ...] | None
    sqrt_weight: Float[Array, " n"]
    used: Bool[Array, " n"]
    observed: tuple[Float[Array, " n"], ...] | None = None
    sky_basis: tuple[tuple[Float[Array, " n"], Float[Array, " n"]], ...] | None = None
    library_trig: bool = eqx.field(static=True, default=False)
    encoder: Float[Array, "n 2"] | None = None
    readings: tuple[Float[Array, " n"], ...] | None = None


def site_data(
    model: Model,
    obs: Observations,
    used: Bool[Array, "*sites n"] | None = None,
    library_trig: bool = False,
    free: Bool[Array, " m"] | None = None,
) -> SiteData:
    """The :class:`SiteData` of one site's observations ``(n, ...)``, or of a chunk of
    sites ``(S, n, ...)`` (every array of the result then has the leading site axis).
    Pure JAX.

    Args:
        model: the model (its mount; for ``residual_form="tpoint"`` its linear sky terms).
        obs: the observations. Rows with weight 0 may hold NaN.
        used: which observations to fit (default: weight > 0); the weights are
            normalised to mean 1 over these.
        library_trig: see :attr:`SiteData.library_trig` (one site's fit: True).
        free: ``(M,)`` which of ``model.parameters`` the fit adjusts, if known: the others
            that are 0 then add exactly nothing, even where their term is singular
            (:func:`without_pinned_singularities`).
    """
    chunk = np.ndim(obs.encoder) == 3
    geometry = lambda o, u: _site_geometry(model, o, u, library_trig)  # noqa: E731
    data, target = jax.vmap(geometry)(obs, used) if chunk else geometry(obs, used)
    if target is not None:
        # The observed point for every site at once (the mount's treatment of its pole
        # runs only when some observation of the chunk is there).
        point = model.mount.sky_point_of(target, data.nominal)
        with_basis = lambda d, p: _with_sky_basis(model, d, p)  # noqa: E731
        data = jax.vmap(with_basis)(data, point) if chunk else with_basis(data, point)
    if free is not None:
        pinned = lambda d: without_pinned_singularities(model, d, jnp.asarray(free, bool))  # noqa: E731
        data = jax.vmap(pinned)(data) if chunk else pinned(data)
    return data


def _site_geometry(model: Model, obs: Observations, used, library_trig: bool) -> tuple[SiteData, Array | None]:
    """One site's :class:`SiteData` but for what :func:`_with_sky_basis` adds, and the
    observed directions in the mount frame (None unless ``residual_form="tpoint"``)."""
    mount = model.mount
    used = obs.weight > 0 if used is None else used & (obs.weight > 0)
    reading, target = obs.filled(used)  # unused rows: the first used row's
    nominal = jax.vmap(mount.axis_angles)(reading)
    target = in_mount_frame(mount, target)
    weight = jnp.where(used, obs.weight, 0.0)
    weight = weight * jnp.sum(used) / jnp.sum(weight)
    # Only what the residual form needs (transcendentals dominate this call's cost).
    # Separate arrays, not one (4, n) array: slices of a stacked array cost copies.
    trig = target_trig = None
    tpoint = model.residual_form == "tpoint"
    encoder = readings = None
    if model.readings:  # evaluated row by row with each row's readings (reading_site_residuals)
        encoder, readings = reading, tuple(model_readings(model, obs, used).values())
    if not tpoint or model.readings or rotated(model, nominal):
        sines = sine_function(library_trig)
        (sin1, cos1), (sin2, cos2) = sines(nominal[:, 0]), sines(nominal[:, 1])
        trig = (cos1, sin1, cos2, sin2)
    if not tpoint:
        target_trig = azel_trig(target)
    data = SiteData(nominal, trig, target_trig, jnp.sqrt(weight), used, None, None, library_trig, encoder, readings)
    return data, target if tpoint else None


def _with_sky_basis(model: Model, data: SiteData, point: SkyPoint) -> SiteData:
    """``data`` with the observed angles and the unit offsets of the model's linear sky
    terms at the observed ``point`` (:meth:`pointax.Mount.sky_point_of`).

    The sines and cosines come from the directions' components, not from the angles
    (:meth:`pointax.SphericalMount.sky_point_of`), and TPOINT's terms read them from the
    point: within one computation XLA on the CPU recomputes an ``atan2``, sine or cosine
    in every output that uses it."""
    observed = (point.az, point.el, point.cos_el)
    return dataclasses.replace(data, observed=observed, sky_basis=tuple(_unit_offsets(model, point)))


def is_affine(model: Model) -> bool:
    """Whether the model's fit residuals are affine in its free parameters: TPOINT's
    residual form with every free parameter in a term whose ``linear_sky_offset``
    holds (the chain and the other terms are then fixed). Decided from the structure,
    while tracing."""
    return model.residual_form == "tpoint" and not model.readings and all(
        model.terms[p.term].linear_sky_offset for p in model.free_parameters
    )


def without_pinned_singularities(model: Model, data: SiteData, free: Bool[Array, " m"]) -> SiteData:
    """One site's ``data`` with the unit offsets of the parameters that stay at 0 in a fit
    (not ``free`` and 0 in ``model``) set to 0 where they are not finite: such a parameter
    adds nothing, but ``0 * inf`` would make the observation's residual NaN. TPOINT's
    terms are singular somewhere (NPAE, AN, AW: ``tan E`` at the zenith, where the
    observed point of a star exactly there has ``cos E = 0``), and a fit carries at 0 the
    terms its model lacks (:mod:`pointax.fitting.structure`). Done once per fit, so the
    residuals cost nothing more. ``free``: ``(M,)`` over ``model.parameters``."""
    if data.sky_basis is None:
        return data
    values = model.values("all")
    position = {(p.term, p.field): k for k, p in enumerate(model.parameters)}
    basis = []
    for key, (u1, u2) in zip(_linear_sky_parameters(model), data.sky_basis):
        k = position[key]
        pinned = ~free[k] & (values[k] == 0)
        basis.append(tuple(jnp.where(pinned & ~jnp.isfinite(u), 0.0, u) for u in (u1, u2)))
    return dataclasses.replace(data, sky_basis=tuple(basis))


def _linear_sky_parameters(model: Model) -> list[tuple[int, str]]:
    """``(term index, field)`` of every parameter of the terms with ``linear_sky_offset``
    that read no auxiliary readings."""
    # (Terms that read auxiliary readings have no unit offsets fixed by the data alone.)
    return [
        (p.term, p.field)
        for p in model.parameters
        if model.terms[p.term].linear_sky_offset and not model.terms[p.term].readings
    ]


def _unit_offsets(model: Model, point: SkyPoint):
    """Per parameter of :func:`_linear_sky_parameters`: its term's sky offset per unit
    of it at the observations' ``point`` (:meth:`pointax.Term.sky_offset_at`), ``(d axis
    1, d axis 2)``."""
    for index, field in _linear_sky_parameters(model):
        term = model.terms[index]
        value = jnp.asarray(getattr(term, field), float)

        def offset(x, p, field=field, term=term):
            out = eqx.tree_at(lambda t: getattr(t, field), term, x).sky_offset_at(p)
            if out is None:
                raise TypeError(f"{term.name} says linear_sky_offset but has no sky_offset")
            return out

        unit = jax.vmap(lambda p: jax.jvp(lambda x: offset(x, p), (value,), (jnp.ones_like(value),))[1])(point)
        yield unit[:, 0], unit[:, 1]


def site_residuals(model: Model, data: SiteData, weighted: bool = True) -> tuple[Array, Array]:
    """Observed minus model in the tangent plane, ``(cross-elevation, elevation)`` as two
    ``(n,)`` arrays (radians), times the square roots of the normalised weights unless
    ``weighted=False``; 0 for unused observations. The model's ``residual_form`` picks
    which residuals (see :func:`pointax.residuals`); ``data`` is one site's.

    A nested ``jax.jit``: a fit evaluates this function and a forward derivative of it
    per parameter, at every step; through the jit it is traced from Python once per
    model structure and data shape, and JAX differentiates the traced program."""
    return _site_residuals_jit(model, data, weighted)


def _site_residuals(model: Model, data: SiteData, weighted: bool) -> tuple[Array, Array]:
    if model.readings:
        rx, ry = reading_site_residuals(model, data)
    elif model.residual_form == "tpoint":
        rx, ry = _tpoint_site_residuals(model, data)
    else:
        rx, ry = tangent_offsets(site_pointing(model, data), data.target_trig)
    scale = data.sqrt_weight if weighted else 1.0
    return jnp.where(data.used, rx * scale, 0.0), jnp.where(data.used, ry * scale, 0.0)


_site_residuals_jit = jax.jit(_site_residuals, static_argnums=2)


def _tpoint_site_residuals(model: Model, data: SiteData) -> tuple[Array, Array]:
    """TPOINT's residuals ``(dA cos E, dE)`` unweighted (see :func:`pointax.residuals`):
    the linear sky terms from their precomputed unit offsets, the others evaluated at
    the observed angles."""
    if data.observed is None:
        raise ValueError("this SiteData was built for residual_form='sky': rebuild it with the model")
    angles, _ = corrected_angles(model, data.nominal)
    if rotated(model, angles):
        v, angles = chain_pointing(model, data)
        chain = jax.vmap(model.mount.angles_of)(jnp.stack(v, axis=-1), angles)
    else:
        chain = angles  # no rotation term in the chain: the angles are where it points
    a1, a2, cos2 = data.observed
    d1, d2 = a1 - chain[:, 0], a2 - chain[:, 1]
    linear = _linear_sky_parameters(model)
    if data.sky_basis is None or len(linear) != len(data.sky_basis):
        raise ValueError("this SiteData was built for another model: rebuild it with site_data")
    for (index, field), (u1, u2) in zip(linear, data.sky_basis):
        c = getattr(model.terms[index], field)
        d1, d2 = d1 - c * u1, d2 - c * u2
    observed = None
    for term in model.terms:
        if term.linear_sky_offset:
            continue
        if observed is None:
            observed = jnp.stack([a1, a2], axis=-1)
        off, _ = per_observation(term.sky_offset, observed)
        if off is not None:
            d1, d2 = d1 - off[..., 0], d2 - off[..., 1]
    return wrap_pi(d1) * cos2, wrap_pi(d2)  # both wrapped, as pointax.residuals (an over-the-pole axis 2)


def reading_site_residuals(model: Model, data: SiteData) -> tuple[Array, Array]:
    """The unweighted residuals of a model that reads auxiliary readings: the plain
    forward model (:meth:`pointax.Model.mount_direction`, :meth:`~pointax.Model.chain_direction`)
    ``vmap``-ped over the observations, each with the model bound to its own readings
    (:meth:`pointax.Model.at_readings`). The fast evaluation's per-site arrangement
    (rotations shared by all rows) does not hold when a term changes from row to row."""
    if data.readings is None or data.encoder is None:
        raise ValueError("this SiteData was built for a model without readings: rebuild it with site_data")
    mount = model.mount
    readings = dict(zip(model.readings, data.readings))
    if model.residual_form == "tpoint":
        if data.observed is None:
            raise ValueError("this SiteData was built for residual_form='sky': rebuild it with the model")
        a1, a2, cos2 = data.observed

        def one(reading, values, observed):
            m = model.at_readings(values)
            d, angles = m.chain_direction(reading)
            diff = observed - mount.angles_of(d, near=angles)
            offset = m.sky_offset(observed)
            return diff if offset is None else diff - offset

        diff = jax.vmap(one)(data.encoder, readings, jnp.stack([a1, a2], axis=-1))
        return wrap_pi(diff[:, 0]) * cos2, wrap_pi(diff[:, 1])
    pointing = jax.vmap(lambda e, r: model.at_readings(r).mount_direction(e))(data.encoder, readings)
    return tangent_offsets([pointing[:, 0], pointing[:, 1], pointing[:, 2]], data.target_trig)


class Problem(eqx.Module):
    """One site's least-squares problem (a pytree: ``vmap`` it over sites).

    Attributes:
        data: what the observations fix (:class:`SiteData`), for the model structure the
            problem was defined with; the parameter values are not part of it.
    """

    data: SiteData

    def residuals(self, model: Model) -> Float[Array, "n 2"]:
        """Observed minus model, ``(n, 2)`` (cross-elevation, elevation) radians, in the
        model's residual form, unweighted; 0 for observations with weight 0. Equal to
        :func:`pointax.residuals` of the same model and observations (to rounding).
        ``model`` must have the structure the problem was defined with (any values)."""
        rx, ry = site_residuals(model, self.data, weighted=False)
        return jnp.stack([rx, ry], axis=-1)


def define_problem(
    model: Model, data: Observations | Problem, free: Bool[Array, " m"] | None = None, library_trig: bool = True
) -> Problem:
    """The :class:`Problem` of fitting ``model`` (its structure) to the observations
    ``data`` (pure JAX): :func:`site_data` with ``free`` and ``library_trig`` (default
    True: one site's fit, the smaller program); a :class:`Problem` is returned as it is."""
    if isinstance(data, Problem):
        return data
    return Problem(site_data(model, data, library_trig=library_trig, free=free))

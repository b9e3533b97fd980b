"""Fits of many sites with some parameters shared by all of them (a common mount design).

Each site keeps its own parameters (its zero points, its tilts); the shared ones (a
design constant of the mount, say the axis non-perpendicularity of one production
series) are fitted jointly from every site's data::

    fit = px.fit_shared(px.Turntable("full"), batch, shared=("omega0",), values=starts)
    fit.shared_value("omega0", "deg"), fit.shared_sigma("omega0", "deg")
    fit.sites                      # FitResult per site (leading axis = site)

The joint least-squares problem has the block-arrow structure of bundle adjustment:
each site's residuals depend on its own parameters and the shared ones only. It is
solved with optimistix's Gauss-Newton on the whole network, with a linear solver
(:class:`SharedSchur`) that eliminates every site's own parameters (vectorised over
sites) and solves the small shared system that remains (the Schur complement): the
cost grows linearly with the number of sites. Each site's data and residuals are those
of the batched fit (:func:`pointax.fitting.problem.site_data` for the whole network,
:func:`pointax.fitting.fast_jacobian.residual_function` per site), and the statistics
TPOINT's (:func:`pointax.fitting.statistics.statistics`) over the whole network.

Sites whose data cannot be fitted on their own (a first pass fits every site with the
shared parameters held at their starting values) are left out of the joint fit, so
that they cannot spoil the shared values; they are reported as such.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx
from jaxtyping import Array, ArrayLike, Bool, Float

from ..core.model import Model
from ..core.observations import Observations
from ..core.precision import float64
from ..core.units import UNITS
from . import normal_equations as ne
from .batch import check_batch, fit_batch, host_batch, site_statuses, start_values
from .core import result_from_covariance
from .fast_jacobian import residual_function
from .problem import site_data, site_residuals
from .residuals import check_convention
from .result import FitResult
from .statistics import statistics

__all__ = ["fit_shared", "SharedFit"]


class SharedFit(eqx.Module):
    """The outcome of :func:`fit_shared`.

    Attributes:
        sites: per-site :class:`pointax.FitResult` (leading axis = site): the sites' own
            parameters, their sigmas (from the joint covariance), per-site Sky RMS.
            Each site's ``model`` holds the fitted shared values too.
        shared_names, shared_units: the shared parameters.
        shared_values, shared_sigmas: ``(P,)`` fitted values and standard errors
            (internal units).
        shared_covariance: ``(P, P)``.
        included: ``(S,)`` sites that took part in the joint fit (the others failed
            alone and are reported with their solo fit).
        converged: whether the joint fit met its tolerances.
        iterations: Gauss-Newton steps of the joint fit.
        sky_rms: TPOINT's Sky RMS over every included observation (radians); the
            sigmas are scaled by it.
        popn_sd: TPOINT's Popn SD of the joint fit: the Sky RMS corrected for every
            fitted parameter (each included site's own and the shared ones).
    """

    sites: FitResult
    shared_values: Float[Array, " P"]
    shared_sigmas: Float[Array, " P"]
    shared_covariance: Float[Array, "P P"]
    included: Bool[Array, " S"]
    converged: Bool[Array, ""]
    iterations: Array
    sky_rms: Float[Array, ""]
    popn_sd: Float[Array, ""]
    shared_names: tuple[str, ...] = eqx.field(static=True)
    shared_units: tuple[str, ...] = eqx.field(static=True)

    def shared_value(self, name: str, unit: str | None = None) -> float:
        """Fitted value of the shared parameter ``name`` in ``unit`` (default: its own)."""
        i = self._index(name)
        return float(self.shared_values[i]) / UNITS[unit or self.shared_units[i]]

    def shared_sigma(self, name: str, unit: str | None = None) -> float:
        """Standard error of the shared parameter ``name`` in ``unit``."""
        i = self._index(name)
        return float(self.shared_sigmas[i]) / UNITS[unit or self.shared_units[i]]

    def _index(self, name: str) -> int:
        try:
            return self.shared_names.index(name)
        except ValueError:
            raise KeyError(f"no shared parameter {name!r}; shared: {list(self.shared_names)}") from None

    def statuses(self) -> list[dict[str, str]]:
        """Per site ``{"status", "reason"}`` as :func:`pointax.site_statuses`; a site left
        out of the joint fit is "failed" with the reason its solo fit gave."""
        out = site_statuses(self.sites)
        for k, inc in enumerate(np.asarray(self.included)):
            if not inc:
                reason = out[k]["reason"] or "its solo fit did not converge"
                out[k] = {"status": "failed", "reason": f"left out of the joint fit: {reason}"}
            elif not bool(self.converged):
                out[k] = {"status": "failed", "reason": "the joint fit did not converge"}
        return out

    def report(self) -> str:
        """The shared parameters and a one-line summary of the sites."""
        n_in = int(np.sum(np.asarray(self.included)))
        status = "converged" if bool(self.converged) else "NOT CONVERGED"
        lines = [f"Joint fit of {n_in} of {len(self.included)} sites: {status} in {int(self.iterations)} iterations"]
        for k, name in enumerate(self.shared_names):
            u = self.shared_units[k]
            lines.append(f"  {name:<10s} {self.shared_value(name):+12.6f} +- {self.shared_sigma(name):.6f} {u} (shared)")
        arcsec = UNITS["arcsec"]
        lines.append(
            f"Sky RMS (all sites) = {float(self.sky_rms) / arcsec:.4f} arcsec, Popn SD = {float(self.popn_sd) / arcsec:.4f} arcsec"
        )
        return "\n".join(lines)


def _site_sums(a, b):
    """Per-site inner product of two residual pairs ``(rx, ry)`` of shape ``(S, N)``."""
    return jnp.sum(a[0] * b[0], axis=-1) + jnp.sum(a[1] * b[1], axis=-1)


class SharedSchur(lx.AbstractLinearSolver):
    """Gauss-Newton steps of the shared-parameter problem by the Schur complement.

    Unknowns: ``(Y, p)`` with ``Y`` ``(S, M)`` per-site and ``p`` ``(P,)`` shared;
    residuals: a pair of ``(S, N)`` arrays. Each site's normal block is factorised
    (written-out Cholesky, vectorised over sites); the ``P x P`` reduced system is
    solved by ``jnp.linalg``. Sites with ``inactive`` set contribute nothing."""

    inactive: Bool[Array, " S"]

    def init(self, operator: lx.AbstractLinearOperator, options: dict[str, Any]):
        del options
        y_struct, p_struct = operator.in_structure()
        n_sites, m = y_struct.shape
        p = p_struct.shape[0]
        zeros_y = jnp.zeros(y_struct.shape, y_struct.dtype)
        zeros_p = jnp.zeros(p_struct.shape, p_struct.dtype)
        own = [operator.mv((zeros_y.at[:, k].set(1.0), zeros_p)) for k in range(m)]
        common = [operator.mv((zeros_y, zeros_p.at[q].set(1.0))) for q in range(p)]
        off = jnp.where(self.inactive, 1.0, 0.0)
        a = [[_site_sums(own[i], own[j]) + (off if i == j else 0.0) for j in range(m)] for i in range(m)]
        low, _ = ne.cholesky(a)
        # A^-1 B per site: one solve per shared column.
        ainv_b = [ne.solve(low, [_site_sums(own[i], common[q]) for i in range(m)]) for q in range(p)]  # (M, S) each
        schur = jnp.stack(
            [
                jnp.stack(
                    [
                        jnp.sum(_site_sums(common[q], common[r]) - sum(
                            _site_sums(own[i], common[q]) * ainv_b[r][i] for i in range(m)
                        ))
                        for r in range(p)
                    ]
                )
                for q in range(p)
            ]
        ) if p else jnp.zeros((0, 0))
        return own, common, low, ainv_b, schur

    def compute(self, state, vector, options: dict[str, Any]):
        del options
        own, common, low, ainv_b, schur = state
        m, p = len(own), len(common)
        active = jnp.where(self.inactive, 0.0, 1.0)
        g = [_site_sums(own[i], vector) * active for i in range(m)]
        h = jnp.stack([jnp.sum(_site_sums(common[q], vector) * active) for q in range(p)]) if p else jnp.zeros((0,))
        ainv_g = ne.solve(low, g)  # (M, S)
        if p:
            rhs = h - jnp.stack([jnp.sum(sum(_site_sums(own[i], common[q]) * ainv_g[i] for i in range(m))) for q in range(p)])
            dp = jnp.linalg.solve(schur, rhs)
            dy = ainv_g - sum(ainv_b[q] * dp[q] for q in range(p))
        else:
            dp = jnp.zeros((0,))
            dy = ainv_g
        return (dy.T * active[:, None], dp), lx.RESULTS.successful, {}

    def transpose(self, state, options):
        raise NotImplementedError("SharedSchur solves least-squares systems only")

    def conj(self, state, options):
        return state, options

    def assume_full_rank(self):
        return True


def _only(active, x):
    """``x`` for the active sites, 0 (not NaN * 0) for the others: a site left out may hold NaN."""
    return jnp.where(active[:, None], x, 0.0)


def _joint_residual_function(own_params, shared_params):
    """``f((Y, p), (model, data, active)) -> (rx, ry)`` of shape ``(S, N)``: every site's
    weighted residuals with its own parameters ``Y[s]`` and the shared ones ``p``, 0 for
    the sites not ``active``; the residual function of the batched fit
    (:func:`pointax.fitting.fast_jacobian.residual_function`, whose derivative is made of
    the Jacobian's columns) for each site."""
    site_fn = residual_function(tuple(own_params) + tuple(shared_params))

    def residuals_of(yp, args):
        y, p = yp
        model, data, active = args
        rx, ry = jax.vmap(lambda ys, d: site_fn(jnp.concatenate([ys, p]), (model, d)))(y, data)
        return _only(active, rx), _only(active, ry)

    return residuals_of


@eqx.filter_jit
def _joint_fit(model, own_params, shared_params, y0, p0, obs, included, max_steps, rtol, atol):
    """The joint Gauss-Newton fit of the ``included`` sites, then TPOINT's statistics:
    the shared block of the covariance and the Sky RMS and Popn SD over every included
    observation (:func:`pointax.fitting.statistics.statistics`), and each site's
    :class:`FitResult` with its block of the joint covariance."""
    fn = _joint_residual_function(own_params, shared_params)
    data = site_data(model, obs)
    args = (model, data, included)
    solver = optx.GaussNewton(rtol=rtol, atol=atol, linear_solver=SharedSchur(~included))
    sol = optx.least_squares(fn, solver, (y0, p0), args=args, max_steps=max_steps, throw=False)
    y, p = sol.value
    # The Jacobian at the solution, linearised once (its columns computed once for all
    # the products the Schur complement takes).
    rw, linear = jax.linearize(lambda yp: fn(yp, args), (y, p))
    operator = lx.FunctionLinearOperator(linear, jax.eval_shape(lambda: (y, p)))
    _, _, low, ainv_b, schur = SharedSchur(~included).init(operator, {})
    m, n_shared, n_sites = len(own_params), len(shared_params), y.shape[0]
    schur_inv = jnp.linalg.inv(schur)
    unit = [[jnp.full((n_sites,), 1.0 if i == j else 0.0) for i in range(m)] for j in range(m)]
    a_inv = jnp.transpose(jnp.stack([ne.solve(low, e) for e in unit], axis=-1), (1, 0, 2))  # (S, M, M)
    ab = jnp.transpose(jnp.stack(ainv_b, axis=-1), (1, 0, 2))  # (S, M, P): A^-1 B per site
    site_unit_cov = a_inv + ab @ schur_inv @ jnp.swapaxes(ab, -1, -2)  # blocks of (J^T J)^-1
    # The joint fit's statistics: every included observation, every fitted parameter.
    used = data.used & included[:, None]
    weighted = jnp.stack(rw, axis=-1)  # (S, N, 2), 0 where not used
    n_free = jnp.sum(included) * m + n_shared
    joint = statistics(weighted.reshape(-1, 2), used.reshape(-1), n_free, schur_inv)
    converged = (sol.result == optx.RESULTS.successful) & jnp.isfinite(joint.sky_rms) & jnp.all(jnp.isfinite(p))
    iterations = sol.stats["num_steps"]
    params = tuple(own_params) + tuple(shared_params)
    fixed_shared = tuple(q.name for q in shared_params)

    def one(ys, unit_cov, d, rw_site):
        fitted = model.replace_parameters(params, [ys[k] for k in range(m)] + [p[q] for q in range(n_shared)])
        fitted = fitted.fix(*fixed_shared)
        r = jnp.stack(site_residuals(fitted, d, weighted=False), axis=-1)
        # Sigmas scaled by the Sky RMS of all sites together (the joint fit's).
        return result_from_covariance(
            fitted, ys, unit_cov, r, rw_site, d.used, iterations, converged, "gauss-newton", scale=joint.sky_rms
        )

    sites = jax.vmap(one)(y, site_unit_cov, data, weighted)
    return sites, p, joint, converged, iterations


@float64
def fit_shared(
    model: Model,
    observations: Observations,
    shared: Sequence[str],
    *,
    values: Float[ArrayLike, "S M"] | None = None,
    steps: int | None = None,
    max_steps: int = 64,
    rtol: float = 1e-10,
    atol: float = 1e-13,
    chunk_size: int | None = 2048,
) -> SharedFit:
    """Fit every site's own parameters and the ``shared`` ones jointly (see the module).

    Args:
        model: the model; its values of the shared parameters are their start.
        observations: ``(S, N, ...)`` from :func:`pointax.stack_observations`.
        shared: names of the parameters common to all sites (free in ``model``).
        values: ``(S, M)`` starting values of each site's own free parameters (in the
            order of ``model.free_parameters`` without the shared ones).
        steps, chunk_size: for the first pass (:func:`pointax.fit_batch`) that finds
            the sites that can be fitted alone.
        max_steps, rtol, atol: the joint Gauss-Newton fit's limit and tolerances.

    Returns:
        A :class:`SharedFit`.
    """
    shared = tuple(shared)
    free = [p.name for p in model.free_parameters]
    unknown = [n for n in shared if n not in free]
    if unknown:
        raise ValueError(f"shared parameters {unknown} are not free parameters of the model ({free})")
    if not shared:
        raise ValueError("no shared parameter given: use pointax.fit_batch")
    check_batch(observations)
    check_convention(model, observations)
    observations = observations.only_readings(model.readings)
    model = model.with_values(model.values())
    alone = model.fix(*shared)
    own_params = alone.free_parameters
    shared_params = tuple(p for p in model.free_parameters if p.name in shared)
    n_sites = observations.encoder.shape[0]
    values = start_values(alone, n_sites, values, "own free parameters")
    first = fit_batch(alone, observations, values=values, steps=steps, chunk_size=chunk_size)
    statuses = site_statuses(first)
    included = np.array([s["status"] == "converged" for s in statuses])
    if not included.any():
        raise ValueError("no site can be fitted on its own; nothing to fit jointly")
    y0 = np.where(included[:, None], np.asarray(first.values), values)
    p0 = np.asarray([model.get(p.name) for p in shared_params], np.float64)
    obs = host_batch(observations)
    sites, p, joint, converged, iterations = _joint_fit(
        model, own_params, shared_params, jnp.asarray(y0), jnp.asarray(p0), obs, jnp.asarray(included), max_steps, rtol, atol
    )
    # Sites left out keep their solo (first-pass) result.
    # The solo fits held the shared parameters fixed: same leaves, another `fixed` set.
    solo_model = jax.tree.unflatten(jax.tree.structure(sites.model), jax.tree.leaves(first.model))
    first = dataclasses.replace(first, model=solo_model, solver="gauss-newton")
    sites = jax.tree.map(
        lambda in_joint, solo: jnp.where(jnp.reshape(jnp.asarray(included), (-1,) + (1,) * (jnp.ndim(in_joint) - 1)), in_joint, solo),
        sites,
        first,
    )
    return SharedFit(
        sites=sites,
        shared_values=p,
        shared_sigmas=joint.sigmas,
        shared_covariance=joint.covariance,
        included=jnp.asarray(included),
        converged=converged,
        iterations=iterations,
        sky_rms=joint.sky_rms,
        popn_sd=joint.popn_sd,
        shared_names=tuple(q.name for q in shared_params),
        shared_units=tuple(q.unit for q in shared_params),
    )


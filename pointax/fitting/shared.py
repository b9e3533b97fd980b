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
cost grows linearly with the number of sites. Jacobians come from JAX
(:mod:`pointax.fitting.fast_evaluation`).

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
from jax.custom_derivatives import SymbolicZero
from jaxtyping import Array, ArrayLike, Bool, Float

from . import normal_equations as ne
from ..core.precision import float64
from .batch import batched_observations, check_batch, fit_batch, site_statuses, start_values
from .core import result_from_covariance
from .residuals import check_convention
from .result import FitResult
from ..core.model import Model
from ..core.observations import Observations
from .fast_evaluation import SiteData, site_data, site_residuals
from .fast_jacobian import residual_columns
from ..core.units import UNITS

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
    """

    sites: FitResult
    shared_values: Float[Array, " P"]
    shared_sigmas: Float[Array, " P"]
    shared_covariance: Float[Array, "P P"]
    included: Bool[Array, " S"]
    converged: Bool[Array, ""]
    iterations: Array
    sky_rms: Float[Array, ""]
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
        lines.append(f"Sky RMS (all sites) = {float(self.sky_rms) / UNITS['arcsec']:.4f} arcsec")
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
    return jnp.where(active[:, None] > 0, x, 0.0)


def _joint_residual_function(own_params, shared_params):
    """``f((Y, p), (model, data, active)) -> (rx, ry)`` of shape ``(S, N)``, with Jacobian
    columns from :func:`pointax.fitting.fast_jacobian.residual_columns` (a ``jax.custom_jvp``)."""
    params = tuple(own_params) + tuple(shared_params)
    m = len(own_params)

    def site_model(model, y_site, p):
        return model.replace_parameters(params, [y_site[k] for k in range(m)] + [p[q] for q in range(len(shared_params))])

    def residual(y, p, model, data, active):
        rx, ry = jax.vmap(lambda ys, d: site_residuals(site_model(model, ys, p), d))(y, data)
        return _only(active, rx), _only(active, ry)

    @jax.custom_jvp
    def fn(y, p, model, data, active):
        return residual(y, p, model, data, active)

    def fn_jvp(primals, tangents):
        y, p, model, data, active = primals
        ty, tp = tangents[0], tangents[1]
        if any(not isinstance(t, SymbolicZero) for t in jax.tree.leaves(tangents[2:], is_leaf=lambda t: isinstance(t, SymbolicZero))):
            raise NotImplementedError("derivatives of a shared fit with respect to the data or fixed parameters")
        out = residual(y, p, model, data, active)
        cols = jax.vmap(lambda ys, d: residual_columns(site_model(model, ys, p), d, params))(y, data)
        tx = jnp.zeros_like(out[0])
        ty_out = [tx, tx]
        for k, (cx, cy) in enumerate(cols):
            if k < m:
                if isinstance(ty, SymbolicZero):
                    continue
                w = ty[:, k][:, None]
            else:
                if isinstance(tp, SymbolicZero):
                    continue
                w = tp[k - m]
            ty_out = [ty_out[0] + w * cx, ty_out[1] + w * cy]
        return out, (_only(active, ty_out[0]), _only(active, ty_out[1]))

    fn.defjvp(fn_jvp, symbolic_zeros=True)

    def residuals_of(yp, args):
        y, p = yp
        model, data, active = args
        return fn(y, p, model, data, active)

    return residuals_of, site_model


@eqx.filter_jit
def _joint_fit(model, own_params, shared_params, y0, p0, obs, included, max_steps, rtol, atol):
    fn, site_model = _joint_residual_function(own_params, shared_params)
    data = jax.vmap(lambda o: site_data(model, o))(obs)
    active = jnp.where(included, 1.0, 0.0)
    args = (model, data, active)
    solver = optx.GaussNewton(rtol=rtol, atol=atol, linear_solver=SharedSchur(~included))
    sol = optx.least_squares(fn, solver, (y0, p0), args=args, max_steps=max_steps, throw=False)
    y, p = sol.value
    # Statistics at the solution: the joint covariance, per-site and shared blocks.
    operator = lx.JacobianLinearOperator(lambda yp, a: fn(yp, a), (y, p), args)
    own, common, low, ainv_b, schur = SharedSchur(~included).init(operator, {})
    rw = fn((y, p), args)
    n_all = jnp.sum(jnp.where(included[:, None], data.used, False))
    sky_rms = jnp.sqrt((jnp.sum(rw[0] ** 2) + jnp.sum(rw[1] ** 2)) / n_all)
    m, n_shared = len(own_params), len(shared_params)
    schur_inv = jnp.linalg.inv(schur) if n_shared else jnp.zeros((0, 0))
    n_sites = y.shape[0]
    unit = [[jnp.full((n_sites,), 1.0 if i == j else 0.0) for i in range(m)] for j in range(m)]
    a_inv = jnp.transpose(jnp.stack([ne.solve(low, e) for e in unit], axis=-1), (1, 0, 2))  # (S, M, M)
    ab = jnp.transpose(jnp.stack(ainv_b, axis=-1), (1, 0, 2))  # (S, M, P): A^-1 B per site
    site_cov = (a_inv + ab @ schur_inv @ jnp.swapaxes(ab, -1, -2)) * sky_rms**2
    shared_cov = schur_inv * sky_rms**2
    converged = (sol.result == optx.RESULTS.successful) & jnp.isfinite(sky_rms) & jnp.all(jnp.isfinite(p))
    return y, p, site_cov, shared_cov, sky_rms, converged, sol.stats["num_steps"], data


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
    obs = batched_observations(
        np.asarray(observations.encoder, np.float64),
        np.asarray(observations.target, np.float64),
        np.asarray(observations.weight, np.float64),
        observations.convention,
    )
    y, p, site_cov, shared_cov, sky_rms, converged, iterations, data = _joint_fit(
        model, own_params, shared_params, jnp.asarray(y0), jnp.asarray(p0), obs, jnp.asarray(included), max_steps, rtol, atol
    )
    sites = _site_results(model, own_params, shared_params, y, p, site_cov, data, converged, iterations)
    # Sites left out keep their solo (first-pass) result.
    # The solo fits held the shared parameters fixed: same leaves, another `fixed` set.
    solo_model = jax.tree.unflatten(jax.tree.structure(sites.model), jax.tree.leaves(first.model))
    first = dataclasses.replace(first, model=solo_model, solver="gauss-newton")
    sites = jax.tree.map(
        lambda joint, solo: jnp.where(jnp.reshape(jnp.asarray(included), (-1,) + (1,) * (jnp.ndim(joint) - 1)), joint, solo),
        sites,
        first,
    )
    return SharedFit(
        sites=sites,
        shared_values=p,
        shared_sigmas=jnp.sqrt(jnp.diag(shared_cov)),
        shared_covariance=shared_cov,
        included=jnp.asarray(included),
        converged=converged,
        iterations=iterations,
        sky_rms=sky_rms,
        shared_names=tuple(q.name for q in shared_params),
        shared_units=tuple(q.unit for q in shared_params),
    )


@eqx.filter_jit
def _site_results(model, own_params, shared_params, y, p, site_cov, data: SiteData, converged, iterations) -> FitResult:
    params = tuple(own_params) + tuple(shared_params)
    m = len(own_params)

    def one(ys, cov, d):
        fitted = model.replace_parameters(params, [ys[k] for k in range(m)] + [p[q] for q in range(len(shared_params))])
        fitted = fitted.fix(*(q.name for q in shared_params))
        r = site_residuals(fitted, d, weighted=False)
        rw = jnp.stack([part * d.sqrt_weight for part in r], axis=-1)
        # cov is already scaled by the Sky RMS of all sites together.
        return result_from_covariance(
            fitted, ys, cov, jnp.stack(r, axis=-1), rw, d.used, iterations, converged, "gauss-newton", scale=1.0
        )

    return jax.vmap(one)(y, site_cov, data)

"""Partial pooling of a network (:func:`fit_pooled`): every site's parameters drawn from a
population of sites of the same design, the population estimated from all of them.

    pooled = px.fit_pooled(model, batch)            # batch from px.stack_observations
    pooled.sites                   # FitResult per site: pooled values, posterior sigmas
    pooled.shrinkage               # (S, M) |pooled - independent| / independent sigma
    pooled.disagrees               # (S,) sites beyond k sigma of their population
    print(pooled.report())

The model (empirical Bayes): site ``i`` of group ``g`` has own parameters
``y_i ~ N(mu_g, Sigma_g)``, its weighted residuals are independent with variance
``s2_g`` per component, and the ``shared`` parameters (as :func:`pointax.fit_shared`) are
common to every site with a flat prior. Parameters named ``unpooled`` stay per site
with a flat prior (an encoder zero set at installation has no population).

How: each site's residuals are linearised (the Jacobian columns of the batched fit,
:func:`pointax.fitting.fast_jacobian.residuals_and_columns`, vectorised over sites), so
that the site enters as a quadratic ``q_i(y, p) = c + 2 g.d + d^T H d``. EM then runs on
these quadratics alone (``M x M`` algebra per site, the unrolled Cholesky of
:mod:`pointax.fitting.normal_equations`, no Python loop over sites): the E-step is every
site's MAP estimate and posterior covariance with the population as its prior (the
shared parameters by the Schur complement, as in :func:`pointax.fit_shared`), the
M-step ``mu_g`` = mean of the MAP estimates, ``Sigma_g`` = their scatter plus the mean
posterior covariance, ``s2_g`` = the expected residual variance. For residuals affine
in the parameters the quadratic is exact and one linearisation suffices; otherwise the
residuals are linearised again at the MAP values ``steps`` times, and two last
Gauss-Newton steps with the population held fixed check convergence.

Per site the result holds the independent estimate (the site's own least squares,
from the same quadratic: exact for affine models, one Gauss-Newton step from the
pooled values otherwise), how far the population moved it (``shrinkage``), the
fraction of the posterior precision that came from the prior (``prior_fraction``), and
the Mahalanobis distance of the independent estimate from the population
(``(y_hat - mu)^T (Sigma + C)^-1 (y_hat - mu)``, computed as the rise of the MAP
objective the prior causes, which also holds for sites whose data do not fix every
parameter), flagged beyond ``k`` sigma.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float, Int

from ..core.model import Model
from ..core.observations import Observations
from ..core.precision import float64
from ..core.units import UNITS, angles_in_radians
from . import normal_equations as ne
from .batch import check_batch, host_batch, site_statuses, start_values
from .batch_fast_pass import DEFAULT_STEPS, first_call
from .core import result_from_covariance, within_tolerances
from .fast_jacobian import residuals_and_columns
from .problem import is_affine, site_data, site_residuals
from .progress import activity, progress_bar
from .residuals import check_convention
from .result import FitResult

__all__ = ["fit_pooled", "PooledFit", "COVARIANCES"]

COVARIANCES = ("full", "diagonal")
"""Forms of the population covariance ``Sigma_g`` :func:`fit_pooled` estimates."""

RANK_RCOND = 1e-10
"""An eigenvalue of a site's ``J^T J`` below this times its largest is taken as 0: the
site's data alone do not fix that direction."""


class PooledFit(eqx.Module):
    """The outcome of :func:`fit_pooled` (``S`` sites, ``M`` own free parameters per
    site, ``G`` groups, ``P`` shared parameters; internal units, radians).

    Attributes:
        sites: per-site :class:`pointax.FitResult` (leading axis = site) at the pooled
            values: ``values``, ``sigmas`` and ``covariance`` from the posterior (the
            prior included), Sky RMS of the site's residuals; each ``model`` holds the
            shared values too.
        independent_values: ``(S, M)`` each site's own least-squares estimate (shared
            parameters at their pooled values); NaN where the site's data alone do not
            fix every parameter.
        independent_sigmas: ``(S, M)`` their standard errors with the group's noise.
        shrinkage: ``(S, M)`` ``|pooled - independent| / independent sigma``: how far,
            in the site's own sigmas, the population moved each value (NaN where not
            fixed alone).
        prior_fraction: ``(S, M)`` the fraction of each parameter's posterior precision
            that comes from the prior, ``1 - posterior variance / independent variance``
            (1 where the data alone do not fix the site; 0 for unpooled parameters).
        mahalanobis: ``(S,)`` the Mahalanobis distance of the site's independent
            estimate from its population (with both covariances).
        dof: ``(S,)`` its degrees of freedom (pooled directions the site's data fix).
        p_value: ``(S,)`` the chi-square tail probability of ``mahalanobis**2``.
        disagrees: ``(S,)`` ``p_value`` below the two-sided normal tail of ``k`` sigma.
        group: ``(S,)`` each site's group index into ``group_names``.
        population_mean: ``(G, M)``; population_covariance: ``(G, M, M)`` (rows and
            columns of unpooled parameters: 0).
        noise: ``(G,)`` the standard deviation of one weighted residual component
            (radians), estimated or as given.
        shared_values, shared_sigmas: ``(P,)``; shared_covariance: ``(P, P)``.
        active: ``(S,)`` sites with data (a site without is its population's prior).
        iterations: EM iterations, all linearisations together.
        em_converged: the last EM met its tolerance within its iteration limit.
        converged: EM converged and the last Gauss-Newton step met ``rtol``/``atol``.
        names, units: the own free parameters; shared_names, shared_units; pooled:
            per own parameter, whether it has a population; group_names; k.
    """

    sites: FitResult
    independent_values: Float[Array, "S M"]
    independent_sigmas: Float[Array, "S M"]
    shrinkage: Float[Array, "S M"]
    prior_fraction: Float[Array, "S M"]
    mahalanobis: Float[Array, " S"]
    dof: Int[Array, " S"]
    p_value: Float[Array, " S"]
    disagrees: Bool[Array, " S"]
    group: Int[Array, " S"]
    population_mean: Float[Array, "G M"]
    population_covariance: Float[Array, "G M M"]
    noise: Float[Array, " G"]
    shared_values: Float[Array, " P"]
    shared_sigmas: Float[Array, " P"]
    shared_covariance: Float[Array, "P P"]
    active: Bool[Array, " S"]
    iterations: Int[Array, ""]
    em_converged: Bool[Array, ""]
    converged: Bool[Array, ""]
    names: tuple[str, ...] = eqx.field(static=True)
    units: tuple[str, ...] = eqx.field(static=True)
    shared_names: tuple[str, ...] = eqx.field(static=True)
    shared_units: tuple[str, ...] = eqx.field(static=True)
    pooled: tuple[bool, ...] = eqx.field(static=True)
    group_names: tuple[str, ...] = eqx.field(static=True)
    k: float = eqx.field(static=True, default=3.0)

    def _param(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no own parameter {name!r}; the pooled parameters are {list(self.names)}") from None

    def _group(self, group) -> int:
        if group is None:
            if len(self.group_names) != 1:
                raise ValueError(f"name the group: one of {list(self.group_names)}")
            return 0
        try:
            return self.group_names.index(str(group))
        except ValueError:
            raise KeyError(f"no group {group!r}; groups: {list(self.group_names)}") from None

    def population_value(self, name: str, group=None, unit: str | None = None) -> float:
        """The population mean of parameter ``name`` in ``group`` (needed with several
        groups), in ``unit`` (default: the parameter's own)."""
        i, g = self._param(name), self._group(group)
        return float(self.population_mean[g, i]) / UNITS[unit or self.units[i]]

    def population_sigma(self, name: str, group=None, unit: str | None = None) -> float:
        """The population's standard deviation of parameter ``name`` (the spread of the
        sites' true values, not the error of the mean)."""
        i, g = self._param(name), self._group(group)
        return float(np.sqrt(self.population_covariance[g, i, i])) / UNITS[unit or self.units[i]]

    def statuses(self) -> list[dict[str, str]]:
        """Per site ``{"status", "reason"}``: "converged", or "failed" when the pooled fit
        did not converge or the site has no data; a site that disagrees with its
        population keeps its status, with the reason saying so."""
        out = site_statuses(self.sites)
        disagrees, active = np.asarray(self.disagrees), np.asarray(self.active)
        distance = np.asarray(self.mahalanobis)
        for s, entry in enumerate(out):
            if not active[s]:
                out[s] = {"status": "failed", "reason": "no data: its values are the population's"}
            elif not bool(self.converged):
                out[s] = {"status": "failed", "reason": "the pooled fit did not converge"}
            elif disagrees[s]:
                extra = f"disagrees with its population (Mahalanobis {distance[s]:.2f}, beyond {self.k:g} sigma)"
                entry["reason"] = "; ".join(r for r in (entry["reason"], extra) if r)
        return out

    def report(self) -> str:
        """The populations, the shared parameters and the sites that disagree."""
        lines = []
        n_active = int(np.sum(np.asarray(self.active)))
        status = "converged" if bool(self.converged) else "NOT CONVERGED"
        lines.append(f"Pooled fit of {n_active} of {len(self.group)} sites in {len(self.group_names)} group(s): "
                     f"{status}, {int(self.iterations)} EM iterations")  # fmt: skip
        arcsec = UNITS["arcsec"]
        for g, gname in enumerate(self.group_names):
            count = int(np.sum(np.asarray(self.group) == g))
            lines.append(f"group {gname}: {count} sites, noise {float(self.noise[g]) / arcsec:.4f} arcsec per axis")
            for i, name in enumerate(self.names):
                u = self.units[i]
                if self.pooled[i]:
                    lines.append(f"  {name:<10s} mean {self.population_value(name, gname):+12.6f}  "
                                 f"spread {self.population_sigma(name, gname):.6f} {u}")  # fmt: skip
                else:
                    lines.append(f"  {name:<10s} per site (unpooled)")
        for q, name in enumerate(self.shared_names):
            scale = UNITS[self.shared_units[q]]
            lines.append(f"  {name:<10s} {float(self.shared_values[q]) / scale:+12.6f} +- "
                         f"{float(self.shared_sigmas[q]) / scale:.6f} {self.shared_units[q]} (shared)")  # fmt: skip
        flagged = np.flatnonzero(np.asarray(self.disagrees))
        lines.append(f"{len(flagged)} site(s) disagree with their population beyond {self.k:g} sigma"
                     + (": " + ", ".join(str(s) for s in flagged[:20]) + (" ..." if len(flagged) > 20 else "") if len(flagged) else ""))  # fmt: skip
        return "\n".join(lines)

    def site_dict(self, s: int) -> dict[str, Any]:
        """Site ``s`` as JSON-ready values: per parameter (own units) the pooled value and
        sigma, the independent value and sigma, shrinkage and prior fraction; the
        Mahalanobis distance, its p-value and the flag."""

        def num(x):
            x = float(x)
            return x if np.isfinite(x) else None

        self = jax.tree.map(np.asarray, self)  # NumPy from here: no JAX arithmetic outside float64
        params = []
        for i, name in enumerate(self.names):
            scale = UNITS[self.units[i]]
            params.append({
                "name": name, "unit": self.units[i], "pooled": self.pooled[i],
                "value": num(self.sites.values[s, i] / scale), "sigma": num(self.sites.sigmas[s, i] / scale),
                "independent_value": num(self.independent_values[s, i] / scale),
                "independent_sigma": num(self.independent_sigmas[s, i] / scale),
                "shrinkage": num(self.shrinkage[s, i]), "prior_fraction": num(self.prior_fraction[s, i]),
            })  # fmt: skip
        return {
            "group": self.group_names[int(self.group[s])],
            "n_obs": int(self.sites.n_obs[s]),
            "sky_rms_arcsec": num(self.sites.sky_rms[s] / UNITS["arcsec"]),
            "mahalanobis": num(self.mahalanobis[s]),
            "dof": int(self.dof[s]),
            "p_value": num(self.p_value[s]),
            "disagrees": bool(self.disagrees[s]),
            "params": params,
        }


# --------------------------------------------------------------------------- the algebra


class _Quadratic(NamedTuple):
    """Every site's residuals linearised at ``(y, p)``: ``|r|^2 ~ c + 2 g.d + d^T H d``
    with ``d = (y' - y, p' - p)``; ``n`` used residual components, ``active`` n > 0."""

    y: Array  # (S, M)
    p: Array  # (P,)
    h: Array  # (S, K, K), K = M + P
    g: Array  # (S, K)
    c: Array  # (S,)
    n: Array  # (S,)
    active: Array  # (S,)


class _Population(NamedTuple):
    mu: Array  # (G, M)
    cov: Array  # (G, M, M)
    s2: Array  # (G,)


class _Posterior(NamedTuple):
    """Every site's MAP step and posterior covariance given a population."""

    dy: Array  # (S, M)
    dp: Array  # (P,)
    pyy: Array  # (S, M, M) marginal posterior covariance of the own parameters
    cyp: Array  # (S, M, P) their cross-covariance with the shared ones
    cpp: Array  # (P, P)
    a_inv: Array  # (S, M, M) posterior covariance with the shared parameters known


def _linearise(model: Model, own, shared, y, p, data) -> _Quadratic:
    """The quadratics of every site at ``(y, p)`` (vmapped over sites): the weighted
    residuals and Jacobian columns (:func:`pointax.fitting.fast_jacobian.residuals_and_columns`)
    reduced to ``J^T J``, ``J^T r`` and ``r^T r``."""
    params = tuple(own) + tuple(shared)
    m = len(own)

    def one(ys, d):
        values = [ys[k] for k in range(m)] + [p[q] for q in range(len(shared))]
        rw, cols = residuals_and_columns(model.replace_parameters(params, values), d, params)
        h = jnp.stack([jnp.stack(row) for row in ne.normal_matrix(cols)]) if cols else jnp.zeros((0, 0))
        g = jnp.stack([ne.inner(col, rw) for col in cols]) if cols else jnp.zeros((0,))
        return h, g, ne.inner(rw, rw), 2.0 * jnp.sum(d.used)

    h, g, c, n = jax.vmap(one)(y, data)
    return _Quadratic(y, p, h, g, c, n, n > 0)


def _shifted(q: _Quadratic, dy, dp) -> _Quadratic:
    """The same quadratics expanded about ``(y + dy, p + dp)`` (exact algebra)."""
    d = jnp.concatenate([dy, jnp.broadcast_to(dp, (dy.shape[0], dp.shape[0]))], axis=-1)
    hd = _matvec(q.h, d)
    return q._replace(y=q.y + dy, p=q.p + dp, g=q.g + hd, c=q.c + jnp.sum(d * (2 * q.g + hd), axis=-1))


def _matvec(a: Array, x: Array) -> Array:
    """``a @ x`` per site: ``(S, m, m) x (S, m) -> (S, m)``."""
    return jnp.einsum("sij,sj->si", a, x)


def _spd_inverse(a: Array) -> Array:
    """Inverses of a stack of symmetric positive definite matrices ``(S, m, m)``: the
    Cholesky factorisation written out entry by entry (it vectorises across sites,
    about 3x the speed of ``jnp.linalg`` on 10,000 5x5 systems), ``jnp.linalg`` above
    :data:`pointax.fitting.normal_equations.MAX_UNROLLED` unknowns."""
    m = a.shape[-1]
    if m == 0:
        return a
    if m > ne.MAX_UNROLLED:
        return jnp.linalg.inv(a)
    low, _ = ne.cholesky([[a[..., i, j] for j in range(m)] for i in range(m)])
    return ne.inverse(low)


def _precisions(cov: Array, pooled: Array) -> Array:
    """``Sigma_g^-1`` on the pooled parameters, 0 on the others (``cov`` holds the
    identity in their rows and columns)."""
    return _spd_inverse(cov) * (pooled[:, None] & pooled[None, :])


def _posterior(q: _Quadratic, pop: _Population, group, pooled) -> _Posterior:
    """The E-step: every site's MAP step from its linearisation point and its posterior
    covariance (sites without data: the prior)."""
    m = q.y.shape[1]
    lam = _precisions(pop.cov, pooled)[group]
    w = jnp.where(q.active, 1.0 / pop.s2[group], 0.0)
    hyy, hyp, hpp = q.h[:, :m, :m], q.h[:, :m, m:], q.h[:, m:, m:]
    gy, gp = q.g[:, :m], q.g[:, m:]
    a_inv = _spd_inverse(hyy * w[:, None, None] + lam)
    b = -gy * w[:, None] + _matvec(lam, pop.mu[group] - q.y)
    dy = _matvec(a_inv, b)
    n_shared = q.p.shape[0]
    if not n_shared:
        return _Posterior(dy, q.p, a_inv, jnp.zeros((*dy.shape, 0)), jnp.zeros((0, 0)), a_inv)
    bmat = hyp * w[:, None, None]  # (S, M, P)
    ainv_b = a_inv @ bmat
    schur = jnp.sum(hpp * w[:, None, None] - jnp.swapaxes(bmat, 1, 2) @ ainv_b, axis=0)
    rhs = jnp.sum(-gp * w[:, None] - jnp.einsum("smp,sm->sp", bmat, dy), axis=0)
    cpp = jnp.linalg.inv(schur)
    dp = cpp @ rhs
    dy = dy - ainv_b @ dp
    cyp = -ainv_b @ cpp
    pyy = a_inv + ainv_b @ cpp @ jnp.swapaxes(ainv_b, 1, 2)
    return _Posterior(dy, dp, pyy, cyp, cpp, a_inv)


def _segment_mean(x, weight, group, n_groups):
    total = jax.ops.segment_sum(x * weight.reshape((-1,) + (1,) * (x.ndim - 1)), group, n_groups)
    count = jax.ops.segment_sum(weight, group, n_groups)
    return total / jnp.maximum(count, 1e-300).reshape((-1,) + (1,) * (x.ndim - 1)), count


def _update(q: _Quadratic, post: _Posterior, pop: _Population, group, n_groups, pooled, diagonal, noise_fixed):
    """The M-step: the population from the sites' posteriors (groups without an active
    site keep theirs)."""
    weight = q.active.astype(q.y.dtype)
    y = q.y + post.dy
    mu, count = _segment_mean(y, weight, group, n_groups)
    d = y - mu[group]
    cov, _ = _segment_mean(d[:, :, None] * d[:, None, :] + post.pyy, weight, group, n_groups)
    eye = jnp.eye(y.shape[1])
    both = pooled[:, None] & pooled[None, :]
    cov = jnp.where(both, cov * (eye if diagonal else 1.0), eye)
    step = jnp.concatenate([post.dy, jnp.broadcast_to(post.dp, (y.shape[0], post.dp.shape[0]))], axis=-1)
    m = y.shape[1]
    expected = (
        q.c
        + jnp.sum(step * (2 * q.g + _matvec(q.h, step)), axis=-1)
        + jnp.sum(q.h[:, :m, :m] * post.pyy, axis=(1, 2))
        + 2 * jnp.sum(q.h[:, :m, m:] * post.cyp, axis=(1, 2))
        + jnp.sum(q.h[:, m:, m:] * post.cpp, axis=(1, 2))
    )
    total = jax.ops.segment_sum(expected * weight, group, n_groups)
    components = jax.ops.segment_sum(q.n * weight, group, n_groups)
    s2 = jnp.where(noise_fixed | (components == 0), pop.s2, total / jnp.maximum(components, 1.0))
    seen = count > 0
    return _Population(jnp.where(seen[:, None], mu, pop.mu), jnp.where(seen[:, None, None], cov, pop.cov), s2)


def _change(old: _Population, new: _Population, ref: _Population) -> Array:
    """EM's convergence measure: the largest change of a population mean, in the
    starting population's sigmas (:func:`_initial_population`: broad), of a population
    variance relative to the starting one, and of the noise variance relative. On the
    start's fixed scale, a variance that EM drives towards 0 (a parameter the sites do
    not tell apart from the mean) converges too: relative to itself it would change by
    the same fraction at every update."""
    var_ref = jnp.diagonal(ref.cov, axis1=1, axis2=2)
    dmu = jnp.max(jnp.abs(new.mu - old.mu) / jnp.sqrt(var_ref), initial=0.0)
    var_old, var_new = jnp.diagonal(old.cov, axis1=1, axis2=2), jnp.diagonal(new.cov, axis1=1, axis2=2)
    dvar = jnp.max(jnp.abs(var_new - var_old) / var_ref, initial=0.0)
    ds2 = jnp.max(jnp.abs(new.s2 - old.s2) / new.s2, initial=0.0)
    return jnp.maximum(jnp.maximum(dmu, dvar), ds2)


def _initial_population(q: _Quadratic, group, n_groups, pooled, diagonal, noise) -> _Population:
    """A start for EM: the noise from the residuals at the start (or as given); each
    site's own ridge-regularised least-squares estimate, their mean and scatter plus
    the typical variance one site's data leave (a broad start: EM narrows it)."""
    m = q.y.shape[1]
    weight = q.active.astype(q.y.dtype)
    total = jax.ops.segment_sum(q.c * weight, group, n_groups)
    components = jax.ops.segment_sum(q.n * weight, group, n_groups)
    s2 = jnp.where(noise > 0, noise**2, jnp.where(components > 0, total / jnp.maximum(components, 1.0), 1.0))
    s2 = jnp.maximum(s2, 1e-300)
    hyy = q.h[:, :m, :m]
    diag = jnp.diagonal(hyy, axis1=1, axis2=2)
    ridge = 1e-8 * jnp.mean(diag, axis=-1, keepdims=True) + 1e-300
    own = q.y - _matvec(_spd_inverse(hyy + ridge[:, :, None] * jnp.eye(m)), q.g[:, :m])
    mu, _ = _segment_mean(own, weight, group, n_groups)
    d = own - mu[group]
    scatter, _ = _segment_mean(d[:, :, None] * d[:, None, :], weight, group, n_groups)
    info, _ = _segment_mean(diag, weight, group, n_groups)
    cov = scatter + jax.vmap(jnp.diag)(s2[:, None] / jnp.maximum(info, 1e-300))
    eye = jnp.eye(m)
    cov = jnp.where(pooled[:, None] & pooled[None, :], cov * (eye if diagonal else 1.0), eye)
    return _Population(mu, cov, s2)


def _em(q: _Quadratic, pop: _Population, ref: _Population, group, n_groups, pooled, diagonal, noise_fixed, max_iterations,
        tol):  # fmt: skip
    """EM on the quadratics from ``pop``, accelerated by SQUAREM (Varadhan and Roland
    2008: two EM updates, a step along their squared extrapolation, one more update to
    stabilise; a step that leaves a covariance not positive definite falls back to the
    second update), until the change of the last update (:func:`_change`) is below
    ``tol`` or ``max_iterations`` EM updates; returns the population, the updates and
    whether it met the tolerance. Plain EM needs thousands of updates where the sites'
    data fix little (the population then explains most of their values); SQUAREM cuts
    that to tens."""

    def update(pop):
        return _update(q, _posterior(q, pop, group, pooled), pop, group, n_groups, pooled, diagonal, noise_fixed)

    def body(state):
        pop, it, _ = state
        p1 = update(pop)
        p2 = update(p1)
        r = jax.tree.map(jnp.subtract, p1, pop)
        v = jax.tree.map(lambda a, b, c: a - 2 * b + c, p2, p1, pop)
        norm_r, norm_v = _scaled_norm(r, pop), _scaled_norm(v, pop)
        alpha = jnp.minimum(-jnp.sqrt(norm_r / jnp.maximum(norm_v, 1e-300)), -1.0)
        jump = jax.tree.map(lambda x, a, b: x - 2 * alpha * a + alpha**2 * b, pop, r, v)
        valid = jnp.all(jnp.isfinite(jnp.linalg.cholesky(jump.cov))) & jnp.all(jump.s2 > 0)
        valid = valid & jnp.isfinite(alpha)
        jump = jax.tree.map(lambda a, b: jnp.where(valid, a, b), jump, p2)
        new = update(jump)
        return new, it + 3, _change(jump, new, ref)

    def more(state):
        _, it, change = state
        return (it < max_iterations) & (change > tol)

    pop, it, change = jax.lax.while_loop(more, body, (pop, jnp.asarray(0), jnp.asarray(jnp.inf)))
    return pop, it, change <= tol


def _scaled_norm(d: _Population, pop: _Population) -> Array:
    """The squared size of a change of the population, each part in the population's
    own scale (means in sigmas, covariances in the product of sigmas, the noise variance
    relative): its parts differ by many orders of magnitude in radians."""
    sd = jnp.sqrt(jnp.diagonal(pop.cov, axis1=1, axis2=2))
    return (
        jnp.sum((d.mu / sd) ** 2)
        + jnp.sum((d.cov / (sd[:, :, None] * sd[:, None, :])) ** 2)
        + jnp.sum((d.s2 / pop.s2) ** 2)
    )


@eqx.filter_jit
def _pooled_fit(model, own, shared, y, p, obs, group, noise, tol, rtol, atol, k, steps, max_iterations, *, n_groups,
                pooled_mask, diagonal, affine):  # fmt: skip
    """The whole pooled fit in one compiled call (see the module). ``steps`` and
    ``max_iterations`` are arrays, so that other counts run the same program."""
    pooled = jnp.asarray(pooled_mask, bool)
    noise_fixed = noise > 0  # (G,): a noise given, not estimated
    data = site_data(model, obs)

    def em(q, pop, ref, limit):
        return _em(q, pop, ref, group, n_groups, pooled, diagonal, noise_fixed, limit, tol)

    if affine:
        q = _linearise(model, own, shared, y, p, data)
        start = _initial_population(q, group, n_groups, pooled, diagonal, noise)
        pop, iterations, em_ok = em(q, start, start, max_iterations)
        post = _posterior(q, pop, group, pooled)
    else:
        # Round i linearises the residuals at the current values (the starting
        # population comes from round 0's), runs EM on those quadratics and steps to the
        # MAP values. Rounds ``steps`` and ``steps + 1`` hold the population (EM's limit
        # 0): a Gauss-Newton step for the MAP values reported, then the step after it,
        # which the convergence test takes (the first finishes what the population's
        # last change left, its size the square of that change times the curvature,
        # above rtol on the example turntables). The linearisation and EM appear once
        # in the program, inside the loop's body: they are most of the program, and so
        # of its compiling.
        def one_round(i, state):
            q, post, pop, ref, iterations, ok = state
            q = _linearise(model, own, shared, q.y + post.dy, q.p + post.dp, data)
            # The starting population (also EM's reference scale), computed in round 0 only.
            pop, ref = jax.lax.cond(
                i == 0, lambda: (_initial_population(q, group, n_groups, pooled, diagonal, noise),) * 2, lambda: (pop, ref)
            )
            held = i >= steps
            pop, it, em_ok = em(q, pop, ref, jnp.where(held, 0, max_iterations))
            post = _posterior(q, pop, group, pooled)
            return q, post, pop, ref, iterations + it, jnp.where(held, ok, em_ok)

        # Round 0 starts from ``(y, p)``: a quadratic at those values and a zero step.
        q, post, pop = _round_placeholders(y, p, n_groups)
        state = (q, post, pop, pop, jnp.asarray(0), jnp.asarray(True))
        q, post, pop, _, iterations, em_ok = jax.lax.fori_loop(0, steps + 2, one_round, state)
    small = jnp.all(within_tolerances(post.dy, q.y + post.dy, rtol, atol) | ~q.active[:, None]) & jnp.all(
        within_tolerances(post.dp, q.p + post.dp, rtol, atol)
    )
    final = _shifted(q, post.dy, post.dp)
    post = _posterior(final, pop, group, pooled)  # covariances at the final point (its step ~ 0)
    return _report(model, own, shared, final, post, pop, data, group, pooled, k, iterations, em_ok, small | affine)


def _round_placeholders(y, p, n_groups: int) -> tuple[_Quadratic, _Posterior, _Population]:
    """Zeros of the shapes a round of the nonlinear fit carries, with the values at
    ``(y, p)`` and a zero step (the state before round 0, which overwrites the rest)."""
    s, m = y.shape
    k = m + p.shape[0]
    zeros = lambda *shape: jnp.zeros(shape, y.dtype)  # noqa: E731
    q = _Quadratic(y, p, zeros(s, k, k), zeros(s, k), zeros(s), zeros(s), jnp.zeros(s, bool))
    post = _Posterior(zeros(s, m), zeros(p.shape[0]), zeros(s, m, m), zeros(s, m, p.shape[0]),
                      zeros(p.shape[0], p.shape[0]), zeros(s, m, m))  # fmt: skip
    return q, post, _Population(zeros(n_groups, m), zeros(n_groups, m, m), zeros(n_groups))


def _report(model, own, shared, q: _Quadratic, post: _Posterior, pop: _Population, data, group, pooled, k,
            iterations, em_ok, small):  # fmt: skip
    """Per-site figures at the pooled values (``q`` expanded about them)."""
    m = q.y.shape[1]
    s2 = pop.s2[group]
    hyy, gy = q.h[:, :m, :m], q.g[:, :m]
    # The site's own least squares (pseudo-inverse: its data may not fix every parameter).
    evals, evecs = jnp.linalg.eigh(hyy)
    keep = evals > RANK_RCOND * jnp.max(evals, axis=-1, keepdims=True)
    pinv = jnp.einsum("sij,sj,skj->sik", evecs, jnp.where(keep, 1.0 / jnp.where(keep, evals, 1.0), 0.0), evecs)
    rank = jnp.sum(keep, axis=-1)
    determined = (rank == m)[:, None] & q.active[:, None]
    independent_var = s2[:, None] * jnp.diagonal(pinv, axis1=1, axis2=2)
    independent = jnp.where(determined, q.y - _matvec(pinv, gy), jnp.nan)
    independent_sigma = jnp.where(determined, jnp.sqrt(independent_var), jnp.nan)
    shrinkage = jnp.abs(q.y - independent) / independent_sigma
    posterior_var = jnp.diagonal(post.a_inv, axis1=1, axis2=2)
    fraction = jnp.where(determined, jnp.clip(1.0 - posterior_var / independent_var, 0.0, 1.0), 1.0)
    fraction = jnp.where(pooled[None, :], fraction, 0.0)
    # The rise of the MAP objective the prior causes: (y_hat - mu)^T (Sigma + C)^-1 (y_hat - mu).
    lam = _precisions(pop.cov, pooled)[group]
    d = q.y - pop.mu[group]
    chi2 = jnp.einsum("si,sij,sj->s", gy, pinv, gy) / s2 + jnp.einsum("si,sij,sj->s", d, lam, d)
    dof = jnp.maximum(rank - jnp.sum(~pooled), 0)
    chi2 = jnp.where(q.active & (dof > 0), jnp.maximum(chi2, 0.0), jnp.nan)
    p_value = jax.scipy.special.gammaincc(jnp.maximum(dof, 1) / 2.0, chi2 / 2.0)
    threshold = jax.scipy.special.erfc(k / jnp.sqrt(2.0))
    disagrees = q.active & (dof > 0) & (p_value < threshold)

    params = tuple(own) + tuple(shared)
    fixed_shared = tuple(x.name for x in shared)
    converged = em_ok & small & jnp.all(jnp.isfinite(q.y)) & jnp.all(jnp.isfinite(q.p))

    def one(ys, pyy, s2_site, d):
        fitted = model.replace_parameters(params, [ys[i] for i in range(m)] + [q.p[j] for j in range(len(shared))])
        fitted = fitted.fix(*fixed_shared)
        r = jnp.stack(site_residuals(fitted, d, weighted=False), axis=-1)
        rw = jnp.stack(site_residuals(fitted, d), axis=-1)
        return result_from_covariance(
            fitted, ys, pyy / s2_site, r, rw, d.used, iterations, converged, "gauss-newton", scale=jnp.sqrt(s2_site)
        )

    sites = jax.vmap(one)(q.y, post.pyy, s2, data)
    shared_sigmas = jnp.sqrt(jnp.diagonal(post.cpp))
    mean = jnp.where(pooled[None, :], pop.mu, jnp.nan)
    cov = jnp.where(pooled[:, None] & pooled[None, :], pop.cov, 0.0)
    return (sites, independent, independent_sigma, shrinkage, fraction, jnp.sqrt(chi2), dof, p_value, disagrees,
            mean, cov, jnp.sqrt(pop.s2), q.p, shared_sigmas, post.cpp, q.active, iterations, em_ok, converged)  # fmt: skip


COMPILING_POOLED = "compiling the pooled fit (first call for this model and size)"
"""What a progress bar says while :func:`fit_pooled` compiles."""


def _group_codes(groups, n_sites: int) -> tuple[np.ndarray, tuple[str, ...]]:
    if groups is None:
        return np.zeros(n_sites, np.int32), ("all",)
    labels = np.asarray(groups)
    if labels.shape != (n_sites,):
        raise ValueError(f"groups must hold one label per site ({n_sites}), got shape {labels.shape}")
    names, codes = np.unique(labels.astype(str), return_inverse=True)
    return codes.astype(np.int32), tuple(str(n) for n in names)


@float64
def fit_pooled(
    model: Model,
    observations: Observations,
    *,
    shared: Sequence[str] = (),
    unpooled: Sequence[str] = (),
    groups: Sequence | None = None,
    values: Float[ArrayLike, "S M"] | None = None,
    noise=None,
    covariance: str = "full",
    k: float = 3.0,
    steps: int | None = None,
    max_iterations: int = 2000,
    tol: float = 1e-6,
    rtol: float = 1e-10,
    atol: float = 1e-13,
    progress: bool | Callable[[int, int], None] | None = None,
) -> PooledFit:
    """Fit every site of a network with partial pooling (see the module).

    Args:
        model: the model (structure, fixed parameters, starting values). Its free
            parameters are each site's own, but for ``shared``.
        observations: ``(S, N, ...)`` from :func:`pointax.stack_observations`.
        shared: free parameters common to every site (flat prior, as
            :func:`pointax.fit_shared`).
        unpooled: own parameters with no population (per site, flat prior), e.g. a
            turntable's azimuth zero ``alpha0``.
        groups: ``(S,)`` a label per site (sites of one design share a label); each
            group has its own population and noise. Default: one group.
        values: ``(S, M)`` starting values of the own free parameters (order of
            ``model.free_parameters`` without the shared ones); default the model's.
        noise: the standard deviation of one residual component (radians or an astropy
            Quantity), known; default: estimated per group with the population.
        covariance: the population covariance, "full" or "diagonal".
        k: a site whose independent estimate lies beyond ``k`` sigma of its population
            (the chi-square tail of its Mahalanobis distance) is flagged.
        steps: linearisations of the residuals (default: 1 for models affine in their
            free parameters, :func:`pointax.fitting.problem.is_affine`, else
            :data:`pointax.fitting.batch_fast_pass.DEFAULT_STEPS`).
        max_iterations, tol: EM's iteration limit per linearisation and its tolerance
            (:func:`_change`: changes of the population means and variances on the
            scale of the broad starting population, of the noise variance relative).
        rtol, atol: the last Gauss-Newton step's convergence test (nonlinear models).
        progress: ``True`` for a progress bar on standard error when it is a terminal
            (it says "compiling the pooled fit" while the first call for a model and
            size compiles), or a callable ``progress(sites_done, sites_total)`` called
            when the fit is done (a :class:`pointax.fitting.progress.Progress` also shows
            the compilation).

    Returns:
        A :class:`PooledFit`.

    One compilation per model structure, number of groups and batch shape: new data,
    starting values, groups of the same count, a new ``noise`` value, other ``steps``
    (beyond 1 for a model affine in its parameters, which then takes its own program)
    or another ``max_iterations`` run the same program.
    """
    check_batch(observations)
    check_convention(model, observations)
    observations = observations.only_readings(model.readings)
    if covariance not in COVARIANCES:
        raise ValueError(f"covariance must be one of {COVARIANCES}, got {covariance!r}")
    shared, unpooled = tuple(shared), tuple(unpooled)
    free = [x.name for x in model.free_parameters]
    for label, names in (("shared", shared), ("unpooled", unpooled)):
        unknown = [n for n in names if n not in free]
        if unknown:
            raise ValueError(f"{label} parameters {unknown} are not free parameters of the model ({free})")
    both = sorted(set(shared) & set(unpooled))
    if both:
        raise ValueError(f"parameters {both} are named both shared and unpooled")
    alone = model.fix(*shared) if shared else model
    own = alone.free_parameters
    if not own:
        raise ValueError("no own parameter left to pool: every free parameter is shared")
    shared_params = tuple(x for x in model.free_parameters if x.name in shared)
    n_sites = observations.encoder.shape[0]
    y0 = start_values(alone, n_sites, values, "own free parameters")
    p0 = np.asarray([float(model.get(x.name)) for x in shared_params], np.float64)
    codes, group_names = _group_codes(groups, n_sites)
    noise_fixed = noise is not None
    sigma = float(angles_in_radians(noise, "noise")) if noise_fixed else 0.0
    if noise_fixed and not sigma > 0:
        raise ValueError(f"noise must be positive, got {noise!r}")
    if steps is None:
        steps = 1 if is_affine(model) else DEFAULT_STEPS
    if int(steps) < 1:
        raise ValueError(f"steps must be >= 1, got {steps!r}")
    # Parameters as float64 arrays: new values never recompile.
    host = model.with_values(model.values())
    host = host.replace_parameters(host.parameters, [np.asarray(getattr(host.terms[x.term], x.field), np.float64) for x in host.parameters])
    obs = host_batch(observations)
    pooled_mask = tuple(x.name not in unpooled for x in own)
    if covariance == "full":
        n_pooled = sum(pooled_mask)
        with_data = np.any(np.asarray(observations.weight) > 0, axis=-1)
        for g, name in enumerate(group_names):
            count = int(np.sum(with_data & (codes == g)))
            if count <= n_pooled:
                raise ValueError(
                    f"group {name!r} has {count} sites with data for {n_pooled} pooled parameters: a full population "
                    "covariance needs more sites than parameters (its estimate is singular); use covariance='diagonal'"
                )
    statics = dict(n_groups=len(group_names), pooled_mask=pooled_mask, diagonal=covariance == "diagonal",
                   affine=bool(is_affine(model)) and int(steps) == 1)  # fmt: skip
    bar = progress_bar(n_sites, "pooling", "site", enabled=True) if progress is True else None
    report = bar if bar is not None else (progress or None)
    first = first_call("pooled_fit", (host, y0, obs, codes, shared_params), tuple(statics.items()))
    try:
        with activity(report, COMPILING_POOLED) if first else contextlib.nullcontext():
            out = _pooled_fit(
                host, own, shared_params, jnp.asarray(y0), jnp.asarray(p0), obs, jnp.asarray(codes),
                jnp.full(len(group_names), sigma), jnp.asarray(float(tol)), jnp.asarray(float(rtol)),
                jnp.asarray(float(atol)), jnp.asarray(float(k)), jnp.asarray(int(steps)),
                jnp.asarray(int(max_iterations)), **statics,
            )  # fmt: skip
            out = jax.block_until_ready(out)  # the notice lasts as long as the wait
        if report is not None:
            report(n_sites, n_sites)
    finally:
        if bar is not None:
            bar.close()
    (sites, independent, independent_sigma, shrinkage, fraction, distance, dof, p_value, disagrees, mean, cov,
     noise_sd, p, shared_sigmas, shared_cov, active, iterations, em_ok, converged) = out  # fmt: skip
    return PooledFit(
        sites=sites,
        independent_values=independent,
        independent_sigmas=independent_sigma,
        shrinkage=shrinkage,
        prior_fraction=fraction,
        mahalanobis=distance,
        dof=dof,
        p_value=p_value,
        disagrees=disagrees,
        group=jnp.asarray(codes),
        population_mean=mean,
        population_covariance=cov,
        noise=noise_sd,
        shared_values=p,
        shared_sigmas=shared_sigmas,
        shared_covariance=shared_cov,
        active=active,
        iterations=iterations,
        em_converged=em_ok,
        converged=converged,
        names=tuple(x.name for x in own),
        units=tuple(x.unit for x in own),
        shared_names=tuple(x.name for x in shared_params),
        shared_units=tuple(x.unit for x in shared_params),
        pooled=pooled_mask,
        group_names=group_names,
        k=float(k),
    )

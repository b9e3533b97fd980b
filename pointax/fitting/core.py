"""The fit itself, pure JAX: least squares or robust, then TPOINT's statistics.

:func:`fit_core` fits the parameters of a model that a boolean mask ``free`` selects;
the others stay at their values. The mask is an array, not part of the program's
structure, so one compiled fit serves every choice of free parameters (and, with
:mod:`pointax.fitting.structure`, every subset of the terms it was compiled for).
Fixed parameters enter the solver as pinned unknowns: their residual columns are zero
and a pseudo-residual ``y - y0`` per fixed parameter keeps the linear systems
well-posed without moving them.

Robust fits (``loss`` 'cauchy', 'huber' or 'soft_l1') minimise ``sum_i rho(|r_i|^2)``
with the scale chosen from the data, flag observations whose residual exceeds
``reject`` robust standard deviations as outliers, and finish with a plain
least-squares fit of the rest, so values, sigmas and statistics keep TPOINT's meaning.
The loss, its scale, ``reject`` and the step limit are arrays (:class:`FitSettings`), so
one compiled fit serves every choice of them.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Iterator, Mapping
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from ..core.model import Model
from ..core.observations import Observations
from .options import SOLVER_NAMES, FitOptions
from .problem import Problem, define_problem
from .result import SUCCESSFUL, FitResult, solver_status
from .statistics import Statistics, normalised_weights, robust_sigma, statistics, svd_unit_covariance

__all__ = [
    "SOLVERS",
    "LOSSES",
    "ROBUST_LOSSES",
    "FitSettings",
    "robust_rho",
    "fit_core",
    "least_squares",
    "gauss_newton_step",
    "linearised_change",
    "LinearisedStep",
    "fit_result",
    "labelled",
    "restrict",
    "free_mask",
    "result_from_covariance",
]


class _Solvers(Mapping):
    """Solver name -> (display name, optimistix class), importing optimistix on first
    look-up: a process that runs a stored fit (:mod:`pointax.fitting.programs`) never
    needs it, and importing it and lineax is a noticeable part of a ``pointax fit``."""

    _CLASSES = {"lm": "LevenbergMarquardt", "gauss-newton": "GaussNewton", "dogleg": "Dogleg"}

    def __getitem__(self, name: str):
        import optimistix as optx

        return SOLVER_NAMES[name], getattr(optx, self._CLASSES[name])

    def __iter__(self) -> Iterator[str]:
        return iter(self._CLASSES)

    def __len__(self) -> int:
        return len(self._CLASSES)


SOLVERS: Mapping[str, tuple] = _Solvers()
"""Solver name -> (display name, optimistix class)."""


def _rho_cauchy(z, c2):
    return c2 * jnp.log1p(z / c2)


def _rho_huber(z, c2):
    c = jnp.sqrt(c2)
    return jnp.where(z <= c2, z, 2 * c * jnp.sqrt(jnp.maximum(z, c2)) - c2)


def _rho_soft_l1(z, c2):
    return 2 * c2 * (jnp.sqrt(1 + z / c2) - 1)


LOSSES = {"linear": None, "huber": _rho_huber, "soft_l1": _rho_soft_l1, "cauchy": _rho_cauchy}
"""Loss name -> ``rho(z, c^2)`` of the squared residual norm ``z`` (as scipy's
``least_squares`` defines them, scaled by ``c^2``); 'linear' is plain least squares."""

ROBUST_LOSSES = ("huber", "soft_l1", "cauchy")
"""The robust losses in the order :attr:`FitSettings.loss` numbers them."""


class FitSettings(NamedTuple):
    """The options of a fit that are data of its compiled program, not part of its
    structure (:meth:`pointax.FitOptions.compiled` is the rest): the step limit and a
    robust fit's loss, soft margin and rejection threshold, as arrays, so that another
    of any of them refits without compiling. A least-squares fit ignores the robust ones."""

    loss: Int[Array, ""]
    """Index of the loss in :data:`ROBUST_LOSSES`."""
    scale: Float[Array, ""]
    """The soft margin, radians; 0: automatic (twice the robust standard deviation of
    the residuals, re-estimated after a first robust pass)."""
    reject: Float[Array, ""]
    """Observations beyond this many robust standard deviations are outliers."""
    max_steps: Int[Array, ""]
    """The step limit of each solve (:class:`pointax.fitting.step_limit.StepLimited`)."""

    @classmethod
    def of(cls, options: FitOptions) -> "FitSettings":
        """``options``' loss, ``loss_scale`` (None: 0, automatic), ``reject`` and
        ``max_steps`` as NumPy scalars (a least-squares fit's loss: index 0, unused)."""
        loss = ROBUST_LOSSES.index(options.loss) if options.robust else 0
        return cls(np.int32(loss), np.float64(options.loss_scale or 0.0), np.float64(options.reject), np.int32(options.max_steps))


def robust_rho(loss: Int[Array, ""], z, c2):
    """``rho(z, c^2)`` of the robust loss numbered ``loss`` in :data:`ROBUST_LOSSES` (an
    array: under ``vmap`` each site may have its own)."""
    return jax.lax.switch(loss, [LOSSES[name] for name in ROBUST_LOSSES], z, c2)


def free_mask(model: Model) -> np.ndarray:
    """``(M,)`` which of the model's parameters a fit adjusts (not in ``model.fixed``)."""
    return np.array([p.name not in model.fixed for p in model.parameters], bool)


def least_squares(
    model: Model,
    free: Bool[Array, " m"],
    obs: Observations | Problem,
    weight,
    options: FitOptions,
    rho=None,
    c2=None,
    robust=True,
    max_steps=None,
):
    """One optimistix solve of the ``free`` parameters, the others held at their values,
    on the observations ``obs`` (or their :class:`Problem`, prepared once), stopped after
    ``max_steps`` steps (an integer, may be a traced array; None: ``options.max_steps``).

    ``rho`` (with the squared scale ``c2``) makes it a robust fit by rescaling each
    observation's residual to ``r sqrt(rho(|r|^2) / |r|^2)``, whose squares sum to
    ``sum rho``; ``robust`` (a boolean, may be traced) False turns the rescaling off, so
    that one compiled solve serves robust and least-squares passes. Returns
    ``(solution, scaled)``: ``solution.value`` holds every parameter (``(M,)``, in model
    order) and ``scaled(y, None)`` the ``(n, 2)`` residuals the loss sees at ``y`` (times
    the square roots of ``weight``, rescaled by ``rho`` if given and ``robust``), the free
    entries of ``y`` only taking effect.
    """
    problem = define_problem(model, obs, free)
    y0 = model.values("all")
    sqrt_w = jnp.sqrt(weight)[:, None]

    def scaled(y, _=None):
        r = problem.residuals(model.with_values(jnp.where(free, y, y0))) * sqrt_w
        if rho is None:
            return r
        z = jnp.sum(r**2, axis=-1)
        positive = (z > 0) & robust
        safe = jnp.where(positive, z, 1.0)
        return r * jnp.where(positive, jnp.sqrt(rho(safe, c2) / safe), 1.0)[:, None]

    def fn(y, _):
        return scaled(y), jnp.where(free, 0.0, y - y0)

    import optimistix as optx

    from .step_limit import StepLimited

    limit = jnp.asarray(options.max_steps if max_steps is None else max_steps)
    optimiser = StepLimited(SOLVERS[options.solver][1](rtol=options.rtol, atol=options.atol), limit)
    sol = optx.least_squares(fn, optimiser, y0, max_steps=None, throw=False)
    return sol, scaled


def fit_core(
    model: Model, free: Bool[Array, " m"], obs: Observations, options: FitOptions, settings: FitSettings | None = None
) -> FitResult:
    """Fit the ``free`` parameters of ``model`` (pure JAX: jit, vmap, lax.map).

    ``settings`` (arrays) gives the step limit and a robust fit's loss, scale and
    threshold in place of ``options``' (whose ``robust`` alone then chooses least squares
    or robust): how :func:`pointax.fit` runs one compiled fit for all of them, with
    :meth:`pointax.FitOptions.compiled` as the structure.

    Returns a :class:`FitResult` over *every* parameter of the model (``names`` all of
    them): fixed ones keep their values, with sigma 0 and no correlation meaning;
    :func:`restrict` turns it into the result for the free ones. Its ``loss`` and
    ``reject`` are ``options``'.
    """
    free = jnp.asarray(free, bool)
    given = obs.weight > 0
    problem = define_problem(model, obs, free)  # what the observations fix, once for every pass
    weight = normalised_weights(obs.weight, given)
    settings = FitSettings.of(options) if settings is None else settings
    if not options.robust:
        used = given
        sol, _ = least_squares(model, free, problem, weight, options, max_steps=settings.max_steps)
        y_solver = jnp.where(free, sol.value, model.values("all"))
        iterations, result = sol.stats["num_steps"], solver_status(sol.result)
        outliers = jnp.zeros(given.shape, bool)
        scale, robust_ok = jnp.asarray(0.0), jnp.asarray(True)
    else:
        y_solver, iterations, result, outliers, scale, robust_ok = _robust_passes(
            model, free, problem, obs.weight, weight, options, settings
        )
        used = given & ~outliers
        weight = normalised_weights(obs.weight, used)
    # One Gauss-Newton step from the solver's answer (exact for residuals affine in the
    # parameters): the solver stops anywhere within its tolerances, and where it stops
    # depends on rounding, so without it the same model fitted inside unions of other
    # sizes (:mod:`pointax.fitting.structure`) differed by up to 1.4e-11 rad.
    step = gauss_newton_step(model, free, problem, weight, used, y_solver)
    # A solver that ends at its step limit while the polishing step passes optimistix's
    # Cauchy test (no parameter and no used weighted residual moves beyond the
    # tolerances) stopped at the optimum (Levenberg-Marquardt there rejects every further
    # step, and optimistix tests convergence only after an accepted one). The residuals'
    # part matters: a Gauss-Newton run diverged to 1e14 rad passes the parameters' part
    # on its relative tolerance alone.
    after = step.residuals * jnp.sqrt(weight)[:, None]
    residuals_settled = within_tolerances(after - step.start_residuals, step.start_residuals, options.rtol, options.atol)
    settled = jnp.all(within_tolerances(step.change, y_solver, options.rtol, options.atol)) & jnp.all(
        residuals_settled | ~used[:, None]
    )
    status = jnp.where(settled & (result == solver_status("nonlinear_max_steps_reached")), SUCCESSFUL, result)
    return fit_result(
        step.model,
        step.values,
        step.statistics,
        step.residuals,
        used,
        step.degenerate,
        iterations=iterations,
        converged=(status == SUCCESSFUL) & step.finite,
        status=status,
        solver=options.solver,
        loss=options.loss,
        reject=options.reject if options.robust else 0.0,
        outliers=outliers,
        robust_scale=scale,
        robust_converged=robust_ok,
        every_parameter=True,
    )


def _robust_passes(model: Model, free, problem: Problem, raw_weight, weight, options: FitOptions, settings: FitSettings):
    """The passes of a robust fit: the robust solves (two when the scale is automatic:
    the first from the scale of the starting model's residuals, which may be large, the
    second from the fit's), then the least-squares solve of the observations not
    flagged as outliers after them. One loop around one solve, so that the solver is
    compiled once, not once per pass (a robust fit's program is then about the size of
    a least-squares one); its length is data, as the loss is (``settings``).

    ``raw_weight`` ``(n,)`` the observations' own weights (0: not used), ``weight``
    those normalised over the observations used. Returns ``(y, iterations, status of
    the last solve, outliers, robust scale, every robust solve succeeded)``; ``y``
    ``(M,)`` every parameter, model order.
    """
    rho = functools.partial(robust_rho, settings.loss)
    given = raw_weight > 0
    auto = settings.scale <= 0
    n_robust = jnp.where(auto, 2, 1)
    # Residuals are judged weighted (sqrt(w) r, the quantity the loss sees), so a
    # down-weighted observation is not rejected for being imprecise.
    sqrt_w = jnp.sqrt(weight)[:, None]

    def one_pass(k, carry):
        y, iterations, _, outliers, scale, robust_ok = carry
        robust = k < n_robust
        # Soft margin c: two robust sigmas unless given.
        c2 = jnp.maximum(jnp.where(auto, 2 * scale, settings.scale) ** 2, 1e-30)
        w = jnp.where(robust, weight, normalised_weights(raw_weight, given & ~outliers))
        sol, _ = least_squares(model.with_values(y), free, problem, w, options, rho, c2, robust, settings.max_steps)
        y = jnp.where(free, sol.value, y)
        status = solver_status(sol.result)
        rw = problem.residuals(model.with_values(y)) * sqrt_w
        new_scale = robust_sigma(rw, given)
        flagged = given & (jnp.sqrt(jnp.sum(rw**2, axis=-1)) > settings.reject * new_scale)
        return (
            y,
            iterations + sol.stats["num_steps"],
            status,
            jnp.where(k == n_robust - 1, flagged, outliers),
            jnp.where(robust, new_scale, scale),
            robust_ok & ((status == SUCCESSFUL) | ~robust),
        )

    y0 = model.values("all")
    scale = robust_sigma(problem.residuals(model) * sqrt_w, given)
    carry = (y0, jnp.asarray(0), solver_status("successful"), jnp.zeros(given.shape, bool), scale, jnp.asarray(True))
    return jax.lax.fori_loop(0, n_robust + 1, one_pass, carry)


def within_tolerances(change, reference, rtol: float, atol: float):
    """optimistix's Cauchy test, element by element: ``|change| <= atol + rtol |reference|``
    (a parameter's step against its value, a residual's change against the residual).
    The solo fit's step-limit check and the batched fit's fast pass share it."""
    return jnp.abs(change) <= atol + rtol * jnp.abs(reference)


class LinearisedStep(NamedTuple):
    """One Gauss-Newton step of a least-squares fit (:func:`gauss_newton_step`)."""

    model: Model
    """The model at the new values."""
    values: Float[Array, " m"]
    """Every parameter's new value, model order."""
    change: Float[Array, " m"]
    """What the step added to each free parameter (0 where it was not finite)."""
    residuals: Float[Array, "n 2"]
    """Residuals at the new values (unweighted, every observation)."""
    statistics: Statistics
    """TPOINT's statistics: residuals at the new values, ``(J^T J)^-1`` at the old; the
    leave-one-out figures from the hat matrix of the same Jacobian."""
    degenerate: Bool[Array, " m"]
    finite: Bool[Array, ""]
    """The new values and their used residuals are finite."""
    step_finite: Bool[Array, ""]
    """The step itself was finite (else the values stayed)."""
    start_residuals: Float[Array, "n 2"]
    """Residuals at the old values times the square roots of the weights."""


def gauss_newton_step(
    model: Model, free: Bool[Array, " m"], obs: Observations | Problem, weight, used, y
) -> LinearisedStep:
    """One linearised least-squares adjustment of the ``free`` parameters from the values
    ``y`` (``(M,)``, every parameter of ``model``): ``y - (J^T J)^-1 J^T r(y)`` with ``r``
    the residuals times the square roots of ``weight`` and ``J`` their Jacobian (the
    fixed parameters' columns are zero and kept out of the inverse,
    :func:`svd_unit_covariance`). The polishing step of :func:`fit_core`, and TPOINT's
    FIT (:mod:`pointax.procedures`)."""
    problem = define_problem(model, obs, free)
    y0 = model.values("all")
    sqrt_w = jnp.sqrt(weight)[:, None]

    def weighted(y):
        flat = (problem.residuals(model.with_values(jnp.where(free, y, y0))) * sqrt_w).reshape(-1)
        return flat, flat

    jac, flat = jax.jacfwd(weighted, has_aux=True)(y)  # the residuals are the Jacobian's primal
    change, unit_cov, degenerate, step_finite = linearised_change(jac, flat, free)
    y = y + change
    fitted = model.with_values(y)
    r = problem.residuals(fitted)  # outliers keep their residuals; statistics skip them
    rw = r * sqrt_w
    # Leave-one-out from the hat matrix of this linearisation (no refit).
    masked_jac = jnp.where(free, jac, 0.0)
    stats = statistics(rw, used, jnp.sum(free), unit_cov, degenerate, jac=masked_jac, residuals=r)
    finite = jnp.all(jnp.isfinite(rw)) & jnp.all(jnp.isfinite(y))
    return LinearisedStep(fitted, y, change, r, stats, degenerate, finite, step_finite, flat.reshape(r.shape))


def linearised_change(
    jac: Float[Array, "k m"], weighted: Float[Array, " k"], free: Bool[Array, " m"]
) -> tuple[Float[Array, " m"], Float[Array, "m m"], Bool[Array, " m"], Bool[Array, ""]]:
    """The least-squares change of the ``free`` parameters for residuals ``weighted``
    (``(k,)``, times the square roots of their weights) with Jacobian ``jac`` (``(k, m)``,
    every parameter; the columns of the others are ignored): ``-(J^T J)^-1 J^T r``, 0 for
    parameters not free, with ``(J^T J)^-1`` and the degenerate parameters from
    :func:`svd_unit_covariance`, and whether the change was finite (if not, it is 0).
    The linear algebra of :func:`gauss_newton_step`."""
    jac = jnp.where(free, jac, 0.0)  # (not jac * free: an unused column may hold inf)
    unit_cov, degenerate = svd_unit_covariance(jac, free)
    change = jnp.where(free, -(unit_cov @ (jac.T @ weighted)), 0.0)
    finite = jnp.all(jnp.isfinite(change))
    return jnp.where(finite, change, 0.0), unit_cov, degenerate, finite


def fit_result(
    fitted: Model, values, stats: Statistics, residuals, used, degenerate, *, iterations, converged, status, solver,
    loss="linear", reject=0.0, outliers=None, robust_scale=0.0, robust_converged=True, every_parameter=False,
) -> FitResult:  # fmt: skip
    """A :class:`FitResult` over the free parameters of ``fitted`` (with
    ``every_parameter``: over all of them, as :func:`fit_core`'s; ``values`` theirs, in
    order) from its pieces: TPOINT's ``stats`` (:func:`pointax.fitting.statistics.statistics`),
    the ``(n, 2)`` ``residuals``, the ``used`` observations, the ``degenerate`` parameters,
    and how the solver ended."""
    params = fitted.parameters if every_parameter else fitted.free_parameters
    return FitResult(
        model=fitted,
        values=values,
        **stats._asdict(),  # n_obs, sky_rms, popn_sd, covariance, sigmas, correlation
        residuals=residuals,
        used=used,
        iterations=jnp.asarray(iterations),
        converged=converged,
        status=jnp.asarray(status, jnp.int32),
        degenerate=degenerate,
        outliers=jnp.zeros(used.shape, bool) if outliers is None else outliers,
        robust_scale=jnp.asarray(robust_scale),
        robust_converged=jnp.asarray(robust_converged),
        names=tuple(p.name for p in params),
        units=tuple(p.unit for p in params),
        solver=solver,
        loss=loss,
        reject=reject,
    )


def labelled(result: FitResult, options: FitOptions) -> FitResult:
    """``result``, of a fit compiled for ``options.compiled()`` with ``options``'
    :class:`FitSettings` as data, labelled with ``options``' own ``loss`` and ``reject``."""
    return dataclasses.replace(result, loss=options.loss, reject=options.reject if options.robust else 0.0)


def result_structure(model: Model, free, obs: Observations, settings: FitSettings, options: FitOptions):
    """The pytree structure of :func:`fit_core`'s result, built without tracing it (for
    :mod:`pointax.fitting.programs`; checked there against the traced one)."""
    return fit_result_structure(model, model.parameters, options)


def fit_result_structure(model: Model, params, options: FitOptions | None = None):
    """The pytree structure of a :class:`FitResult` of ``model`` whose fitted parameters
    are ``params`` (solver, loss and rejection from ``options``; None: the batched fast
    pass's plain Gauss-Newton), built without tracing: what
    :mod:`pointax.fitting.programs` needs to store a traced fit."""
    x = np.zeros(())
    if options is None:
        how = {"solver": "gauss-newton"}
    else:
        reject = options.reject if LOSSES[options.loss] is not None else 0.0
        how = {"solver": options.solver, "loss": options.loss, "reject": reject}
    template = FitResult(
        model=model, values=x, sigmas=x, covariance=x, correlation=x, residuals=x, used=x, n_obs=x, sky_rms=x,
        popn_sd=x, loo_residuals=x, loo_rms=x, iterations=x, converged=x, status=x, degenerate=x, outliers=x,
        robust_scale=x, robust_converged=x, names=tuple(p.name for p in params), units=tuple(p.unit for p in params),
        **how,
    )  # fmt: skip
    return jax.tree.structure(template)


def restrict(full: FitResult, index, model: Model, caption: str = "", numpy=None) -> FitResult:
    """The result of fitting ``model`` from :func:`fit_core`'s result ``full`` over a
    model that holds ``model``'s terms (and maybe more): ``index[k]`` is the position in
    ``full`` of ``model``'s k-th free parameter.

    Works on traced arrays (inside ``jit``, ``vmap``) and on the host: with
    ``numpy=True`` every array is taken to NumPy first and indexed there, so that no
    small computation is compiled for a new shape.
    """
    params = model.free_parameters
    index = np.asarray(index, int)
    if numpy:
        full = jax.tree.map(lambda x: np.asarray(x) if isinstance(x, jax.Array) else x, full)
    pick = lambda x: x[..., index]  # noqa: E731
    pick2 = lambda x: x[..., index[:, None], index[None, :]]  # noqa: E731
    values = pick(full.values)
    fitted = model.replace_parameters(params, [values[..., k] for k in range(len(params))])
    out = FitResult(
        model=fitted,
        values=values,
        sigmas=pick(full.sigmas),
        covariance=pick2(full.covariance),
        correlation=pick2(full.correlation),
        residuals=full.residuals,
        used=full.used,
        n_obs=full.n_obs,
        sky_rms=full.sky_rms,
        popn_sd=full.popn_sd,
        loo_residuals=full.loo_residuals,
        loo_rms=full.loo_rms,
        iterations=full.iterations,
        converged=full.converged,
        status=full.status,
        degenerate=pick(full.degenerate),
        outliers=full.outliers,
        robust_scale=full.robust_scale,
        robust_converged=full.robust_converged,
        names=tuple(p.name for p in params),
        units=tuple(p.unit for p in params),
        solver=full.solver,
        caption=caption,
        loss=full.loss,
        reject=full.reject,
    )
    if numpy:
        out = jax.device_put(out)
    return out


def result_from_covariance(
    fitted: Model,
    values: Float[Array, " m"],
    unit_covariance: Float[Array, "m m"],
    residuals: Float[Array, "n 2"],
    weighted: Float[Array, "n 2"],
    used: Bool[Array, " n"],
    iterations,
    converged: Bool[Array, ""],
    solver: str,
    scale: Float[Array, ""] | None = None,
    jac: Float[Array, "k m"] | None = None,
) -> FitResult:
    """A least-squares :class:`FitResult` with TPOINT's statistics from ``(J^T J)^-1``
    (the batched fast path's Cholesky factor, the shared-parameter fit's Schur
    complement) rather than from :func:`fit_core`'s SVD.

    Args:
        fitted: the model with the fitted values; ``values`` its free parameters.
        unit_covariance: ``(J^T J)^-1`` of the weighted residuals.
        residuals, weighted: ``(n, 2)`` residuals, plain and times the square roots of
            the normalised weights (0 for unused observations).
        scale: the standard deviation the covariance is scaled by (default: this fit's
            Sky RMS, as TPOINT's sigmas).
        jac: ``(2n, m)`` Jacobian of ``weighted`` (row by row), for the leave-one-out
            figures; without it they are NaN.
    """
    m = len(fitted.free_parameters)
    stats = statistics(weighted, used, m, unit_covariance, None, scale, jac=jac, residuals=residuals)
    ok = converged & jnp.all(jnp.isfinite(values)) & jnp.isfinite(stats.sky_rms)
    return fit_result(
        fitted,
        values,
        stats,
        residuals,
        used,
        jnp.zeros((m,), bool),
        iterations=iterations,
        converged=ok,
        status=jnp.where(ok, SUCCESSFUL, solver_status("nonlinear_max_steps_reached")),
        solver=solver,
    )

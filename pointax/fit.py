"""Least-squares fitting of pointing models with optimistix and JAX Jacobians.

The fit minimises the weighted sum of squared on-sky residuals. A residual is
*observed minus model* in the tangent plane of the observed direction: (cross-elevation,
elevation) in radians, so it is ``(dA cos E, dE)`` for small offsets and has no pole at
the zenith. Statistics follow TPOINT's definitions exactly (unit weights)::

    Sky RMS = sqrt( sum_i |r_i|^2 / N )          N observations
    Popn SD = Sky RMS * sqrt( N / (N - M) )       M fitted parameters
    sigma_j = Sky RMS * sqrt( [(J^T J)^-1]_jj )   J: d r / d parameters

With weights ``w`` they are normalised to mean 1 over the used observations and enter
as ``sqrt(w_i) r_i``; with unit weights this is TPOINT. Observations with weight 0 are
ignored (and may hold NaN).

Robust fits (``loss="cauchy"``, ``"huber"`` or ``"soft_l1"``) minimise
``sum_i rho(|r_i|^2)`` with the scale chosen from the data, flag observations whose
residual exceeds ``reject`` robust standard deviations as outliers, and finish with a
plain least-squares fit of the rest, so values, sigmas and statistics keep TPOINT's
meaning (on the observations kept).

The fit knows nothing of any particular term: parameters are whatever the model's
terms declare, and the Jacobian comes from ``jax.jacfwd``.
"""

from __future__ import annotations

import math
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, Bool, Float, Int

from ._x64 import float64
from .model import Model
from .observations import Observations
from .rotations import tangent_offset, wrap_pi
from .units import ARCSEC, UNITS

__all__ = ["fit", "FitResult", "SOLVERS", "LOSSES", "residuals", "CORRELATION_WARNING", "robust_sigma", "check_options", "prepare"]

SOLVERS = {
    "lm": ("Levenberg-Marquardt", optx.LevenbergMarquardt),
    "gauss-newton": ("Gauss-Newton", optx.GaussNewton),
    "dogleg": ("Dogleg", optx.Dogleg),
}
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

RAYLEIGH_MEDIAN = math.sqrt(2 * math.log(2))
"""Median of the norm of a 2-D Gaussian offset with unit standard deviation per axis."""

CORRELATION_WARNING = 0.95
"""Reports warn about parameter pairs whose |correlation| exceeds this."""

DEGENERATE_RCOND = 1e-10
"""Singular values of the Jacobian below this fraction of the largest count as zero:
the parameters that share such a direction cannot be told apart by the data."""


class FitResult(eqx.Module):
    """The outcome of :func:`fit` (a pytree: batched fits stack along a leading axis).

    Values and sigmas are in internal units (radians for angles); :meth:`table`,
    :meth:`report` and :meth:`to_dict` convert to each parameter's display unit.

    Attributes:
        model: the model with fitted values.
        names: names of the fitted (free) parameters, in order.
        units: their display units.
        values: ``(M,)`` fitted values.
        sigmas: ``(M,)`` standard errors (TPOINT's definition); ``inf`` for a parameter
            the data cannot determine (see ``degenerate``).
        covariance: ``(M, M)`` covariance matrix.
        correlation: ``(M, M)`` correlation matrix.
        residuals: ``(N, 2)`` observed minus model, (cross-elevation, elevation) radians,
            zero for ignored observations.
        used: ``(N,)`` which observations were used (weight > 0).
        n_obs: number of observations used.
        sky_rms, popn_sd: TPOINT's Sky RMS and population standard deviation, radians.
        iterations: solver steps taken.
        converged: whether the solver met its tolerances with finite residuals.
        result: optimistix's result code.
        degenerate: ``(M,)`` parameters lying in a (near-)null direction of the
            Jacobian: the data cannot separate them from the others flagged.
        outliers: ``(N,)`` observations a robust fit rejected (never for loss 'linear').
        robust_scale: robust per-axis standard deviation (radians) of the weighted
            residuals ``sqrt(w) r`` (weights normalised to mean 1) that outliers were
            judged by (0 for loss 'linear').
        robust_converged: whether the robust passes that chose the outliers met their
            tolerances (always True for loss 'linear'). ``converged`` is the final
            least-squares stage's; a robust pass that stopped at ``max_steps`` is
            reported by :meth:`warnings`, since the outlier choice may then be off.
        solver: solver name.
        loss: loss name (:data:`LOSSES`).
    """

    model: Model
    values: Float[Array, " m"]
    sigmas: Float[Array, " m"]
    covariance: Float[Array, "m m"]
    correlation: Float[Array, "m m"]
    residuals: Float[Array, "n 2"]
    used: Bool[Array, " n"]
    n_obs: Int[Array, ""]
    sky_rms: Float[Array, ""]
    popn_sd: Float[Array, ""]
    iterations: Int[Array, ""]
    converged: Bool[Array, ""]
    result: optx.RESULTS
    degenerate: Bool[Array, " m"]
    outliers: Bool[Array, " n"]
    robust_scale: Float[Array, ""]
    robust_converged: Bool[Array, ""]
    names: tuple[str, ...] = eqx.field(static=True)
    units: tuple[str, ...] = eqx.field(static=True)
    solver: str = eqx.field(static=True)
    caption: str = eqx.field(static=True, default="")
    loss: str = eqx.field(static=True, default="linear")
    reject: float = eqx.field(static=True, default=0.0)

    # ------------------------------------------------------------ accessors

    def _index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no fitted parameter {name!r}; fitted: {list(self.names)}") from None

    def value(self, name: str, unit: str | None = None) -> float:
        """Fitted value of ``name`` in ``unit`` (default: the parameter's display unit)."""
        i = self._index(name)
        return float(self.values[i]) / UNITS[unit or self.units[i]]

    def sigma(self, name: str, unit: str | None = None) -> float:
        """Standard error of ``name`` in ``unit`` (default: the parameter's display unit)."""
        i = self._index(name)
        return float(self.sigmas[i]) / UNITS[unit or self.units[i]]

    @property
    def message(self) -> str:
        """Why the solver stopped, in words ('' when it converged)."""
        if bool(self.converged):
            return ""
        if not bool(jnp.all(jnp.isfinite(self.residuals))):
            return "residuals are not finite (NaN or inf in the data or the model)"
        if self.result == optx.RESULTS.successful:
            return "the solver stopped with non-finite values"
        return optx.RESULTS[self.result] or "the solver did not converge"

    def table(self) -> list[dict[str, Any]]:
        """One dict per fitted parameter: name, value, sigma, unit (display units)."""
        vals = np.asarray(self.values)
        sigs = np.asarray(self.sigmas)
        return [
            {"name": n, "value": float(v / UNITS[u]), "sigma": float(s / UNITS[u]), "unit": u}
            for n, u, v, s in zip(self.names, self.units, vals, sigs)
        ]

    def outlier_indices(self) -> list[int]:
        """0-based indices of the observations a robust fit flagged as outliers."""
        return [int(i) for i in np.flatnonzero(np.asarray(self.outliers))]

    @property
    def _residual_unit(self) -> str:
        # Heliostat engineers think in mrad, sun-tracker people in degrees (when every
        # parameter is in degrees), telescope people in arcsec.
        if "mrad" in self.units:
            return "mrad"
        return "deg" if self.units and all(u == "deg" for u in self.units) else "arcsec"

    def correlated_pairs(self, threshold: float = CORRELATION_WARNING) -> list[tuple[str, str, float]]:
        """Parameter pairs with |correlation| above ``threshold``."""
        corr = np.asarray(self.correlation)
        out = []
        for i in range(len(self.names)):
            for j in range(i + 1, len(self.names)):
                if np.isfinite(corr[i, j]) and abs(corr[i, j]) > threshold:
                    out.append((self.names[i], self.names[j], float(corr[i, j])))
        return out

    def warnings(self) -> list[str]:
        """Plain-language warnings: non-convergence, degenerate and correlated parameters."""
        out = []
        if not bool(self.converged):
            out.append(f"the fit did not converge after {int(self.iterations)} iterations: {self.message}")
        if not bool(self.robust_converged):
            out.append(
                f"the robust ({self.loss}) passes that chose the outliers did not converge; "
                "the outlier flags may be off (raise max_steps)"
            )
        degenerate = [n for n, d in zip(self.names, np.asarray(self.degenerate)) if d]
        if degenerate:
            out.append(
                "the data cannot tell these parameters apart (Jacobian rank-deficient): "
                + ", ".join(degenerate)
                + "; fix one of them or add observations that separate them"
            )
        for a, b, r in self.correlated_pairs():
            out.append(f"{a} and {b} are strongly correlated (r = {r:+.3f})")
        n, m = int(self.n_obs), len(self.names)
        if n <= m:
            out.append(f"only {n} observations for {m} parameters: Popn SD is undefined")
        return out

    def report(self) -> str:
        """A TPOINT-style report: term, value, sigma; Sky RMS; Popn SD; warnings."""
        solver_name = SOLVERS[self.solver][0]
        lines = []
        if self.caption:
            lines.append(self.caption)
        lines.append(f"{self.model.describe()}")
        status = (
            f"converged in {int(self.iterations)} iterations"
            if bool(self.converged)
            else f"NOT CONVERGED after {int(self.iterations)} iterations"
        )
        form = " (TPOINT's residuals: terms at the observed position)" if self.model.residual_form == "tpoint" else ""
        lines.append(f"{solver_name} fit of {int(self.n_obs)} observations{form}: {status}")
        flagged = self.outlier_indices()
        if self.loss != "linear":
            lines.append(
                f"{self.loss} loss; robust sigma {float(self.robust_scale) / UNITS[self._residual_unit]:.4g} "
                f"{self._residual_unit}; {len(flagged)} outlier(s) beyond {self.reject:g} sigma"
                + (f": observations {', '.join(str(i + 1) for i in flagged)}" if flagged else "")
            )
        lines.append("")
        width = max([9] + [len(p.name) for p in self.model.parameters])
        lines.append(f"       {'coeff':<{width}s}        value       sigma")
        for k, row in enumerate(self.table(), 1):
            unit = "" if row["unit"] == "arcsec" else f"  ({row['unit']})"
            lines.append(f"  {k:3d}  {row['name']:<{width}s} {row['value']:+12.4f} {row['sigma']:11.4f}{unit}")
        fixed = [p for p in self.model.parameters if p.name in self.model.fixed]
        for p in fixed:
            v = float(self.model.get(p.name)) / UNITS[p.unit]
            unit = "" if p.unit == "arcsec" else f"  ({p.unit})"
            lines.append(f"       {p.name:<{width}s} {v:+12.4f}       fixed{unit}")
        lines.append("")
        unit = self._residual_unit
        label = "" if unit == "arcsec" else f" {unit}"  # TPOINT prints arcsec bare
        lines.append(f"Sky RMS = {float(self.sky_rms) / UNITS[unit]:9.4f}{label}")
        popn = float(self.popn_sd) / UNITS[unit]
        lines.append(f"Popn SD = {popn:9.4f}{label}" if math.isfinite(popn) else "Popn SD =   undefined")
        warnings = self.warnings()
        if warnings:
            lines.append("")
            lines.extend(f"WARNING: {w}" for w in warnings)
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary; the keys are stable (see ``pointax fit --json``)."""

        def number(x):
            x = float(x)
            return x if math.isfinite(x) else None

        corr = np.asarray(self.correlation)
        return {
            "n_obs": int(self.n_obs),
            "sky_rms_arcsec": number(float(self.sky_rms) / ARCSEC),
            "popn_sd_arcsec": number(float(self.popn_sd) / ARCSEC),
            "converged": bool(self.converged),
            "iterations": int(self.iterations),
            "message": self.message,
            "solver": self.solver,
            "terms": [
                {
                    "name": row["name"],
                    "value_arcsec": number(row["value"] * UNITS[row["unit"]] / ARCSEC),
                    "sigma_arcsec": number(row["sigma"] * UNITS[row["unit"]] / ARCSEC),
                    "value": number(row["value"]),
                    "sigma": number(row["sigma"]),
                    "unit": row["unit"],
                }
                for row in self.table()
            ],
            "fixed": {
                p.name: number(float(self.model.get(p.name)) / UNITS[p.unit])
                for p in self.model.parameters
                if p.name in self.model.fixed
            },
            "correlation": [[number(c) for c in row] for row in corr],
            "loss": self.loss,
            "outliers": self.outlier_indices(),
            "warnings": self.warnings(),
        }


def check_options(solver: str, loss: str, loss_scale: float | None, reject: float) -> None:
    """Raise ValueError, naming the argument, for a bad solver or robust-loss option."""
    if solver not in SOLVERS:
        raise ValueError(f"unknown solver {solver!r}; expected one of {sorted(SOLVERS)}")
    if loss not in LOSSES:
        raise ValueError(f"unknown loss {loss!r}; expected one of {sorted(LOSSES)}")
    if loss_scale is not None and not (math.isfinite(loss_scale) and loss_scale > 0):
        raise ValueError(f"loss_scale must be a positive number of radians, got {loss_scale!r}")
    if not (math.isfinite(reject) and reject > 0):
        raise ValueError(f"reject must be a positive number of robust sigmas, got {reject!r}")


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


def _check_convention(model: Model, obs: Observations) -> None:
    mine, theirs = model.mount.convention, obs.convention
    if mine is not None and theirs is not None and mine != theirs:
        raise ValueError(
            f"the observations' encoder angles follow the {theirs!r} convention but the model's "
            f"mount expects {mine!r}; build the model with the data's convention "
            f"(e.g. pointax.AltAz(terms, azimuth={theirs!r}))"
        )


def residuals(model: Model, obs: Observations) -> Float[Array, "n 2"]:
    """Observed minus model on the sky, ``(n, 2)`` (cross-elevation, elevation) radians,
    as the model's :attr:`~pointax.Model.residual_form` defines them.

    Pure JAX; observations with weight 0 give 0 (and may hold NaN).
    """
    if model.residual_form == "tpoint":
        return _tpoint_residuals(model, obs)
    used = obs.weight > 0
    encoder = jnp.where(used[:, None], obs.encoder, 0.0)
    # Targets into the mount frame (F is orthogonal, so its inverse is its transpose).
    target = jnp.asarray(obs.target) @ model.mount.frame
    at_rest = model.mount.boresight
    target = jnp.where(used[:, None], target, at_rest)
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

    def one(reading, direction):
        d, angles = model.chain_direction(reading)
        chain = mount.angles_of(d, near=angles)
        observed = mount.angles_of(direction, near=mount.axis_angles(reading))
        offset = model._sky_offset(observed)
        diff = observed - chain if offset is None else observed - chain - offset
        return jnp.stack([wrap_pi(diff[0]) * jnp.cos(observed[1]), diff[1]])

    r = jax.vmap(one)(encoder, target)
    return jnp.where(used[:, None], r, 0.0)


def _covariance(jac: Array, scale: Array) -> tuple[Array, Array]:
    """Covariance ``scale^2 (J^T J)^-1`` via SVD, and a mask of degenerate parameters."""
    if jac.shape[1] == 0:
        return jnp.zeros((0, 0)), jnp.zeros((0,), bool)
    _, s, vt = jnp.linalg.svd(jac, full_matrices=False)
    small = s <= DEGENERATE_RCOND * s[0]
    inv_s2 = jnp.where(small, 0.0, 1.0 / jnp.where(small, 1.0, s) ** 2)
    cov = (vt.T * inv_s2) @ vt * scale**2
    # A parameter is degenerate when it takes part in a null direction of J.
    degenerate = jnp.any(small[:, None] & (jnp.abs(vt) > 0.1), axis=0)
    return cov, degenerate


def robust_sigma(r: Float[Array, "n 2"], used: Bool[Array, " n"]) -> Float[Array, ""]:
    """Robust per-axis standard deviation of 2-D residuals: the median residual norm
    over the ``used`` observations divided by its Gaussian expectation
    (:data:`RAYLEIGH_MEDIAN` sigma); insensitive to up to half the rows being wild."""
    z = jnp.sum(jnp.where(used[:, None], r, 0.0) ** 2, axis=-1)
    norm = jnp.where(used, jnp.sqrt(jnp.where(used, z, 1.0)), jnp.nan)
    return jnp.nanmedian(norm) / RAYLEIGH_MEDIAN


def _normalised(weight: Array, used: Array) -> Array:
    """Weights of the ``used`` rows scaled to mean 1; 0 elsewhere."""
    weight = jnp.where(used, weight, 0.0)
    return weight * jnp.sum(used) / jnp.sum(weight)


def _least_squares(model, obs, weight, solver, max_steps, rtol, atol, rho=None, c2=None):
    """One optimistix least-squares solve of the free parameters; ``rho`` (with the
    squared scale ``c2``) turns it into a robust fit by rescaling each observation's
    residual to ``r sqrt(rho(|r|^2) / |r|^2)``, whose squares sum to ``sum rho``."""
    sqrt_w = jnp.sqrt(weight)[:, None]

    def fn(y, _):
        r = residuals(model.with_values(y, "free"), obs) * sqrt_w
        if rho is None:
            return r
        z = jnp.sum(r**2, axis=-1)
        positive = z > 0
        safe = jnp.where(positive, z, 1.0)
        factor = jnp.where(positive, jnp.sqrt(rho(safe, c2) / safe), 1.0)
        return r * factor[:, None]

    optimiser = SOLVERS[solver][1](rtol=rtol, atol=atol)
    sol = optx.least_squares(fn, optimiser, model.values("free"), max_steps=max_steps, throw=False)
    return sol, fn


def _fit(
    model: Model,
    obs: Observations,
    solver: str,
    max_steps: int,
    rtol: float,
    atol: float,
    caption: str = "",
    loss: str = "linear",
    loss_scale: float | None = None,
    reject: float = 3.0,
) -> FitResult:
    """The whole fit, pure JAX (jit- and vmap-able); see :func:`fit` for the arguments."""
    given = obs.weight > 0
    weight = _normalised(obs.weight, given)
    rho = LOSSES[loss]
    iterations = jnp.asarray(0)
    robust_ok = jnp.asarray(True)
    outliers = jnp.zeros(given.shape, bool)
    scale = jnp.asarray(0.0)
    if rho is not None:
        # Residuals are judged weighted (sqrt(w) r, the quantity the loss sees), so a
        # down-weighted observation is not rejected for being imprecise.
        sqrt_w = jnp.sqrt(weight)[:, None]

        def weighted_sigma(m):
            return robust_sigma(residuals(m, obs) * sqrt_w, given)

        # Two passes when the scale is automatic: the first starts from the scale of
        # the starting model's residuals (may be large), the second from the fit's.
        auto = loss_scale is None
        scale = weighted_sigma(model)
        for _ in range(2 if auto else 1):
            # Soft margin c: two robust sigmas unless given.
            c2 = jnp.maximum((2 * scale) ** 2 if auto else jnp.asarray(loss_scale) ** 2, 1e-30)
            sol, _ = _least_squares(model, obs, weight, solver, max_steps, rtol, atol, rho, c2)
            model = model.with_values(sol.value, "free")
            iterations = iterations + sol.stats["num_steps"]
            robust_ok = robust_ok & (sol.result == optx.RESULTS.successful)
            scale = weighted_sigma(model)
        rw = residuals(model, obs) * sqrt_w
        outliers = given & (jnp.sqrt(jnp.sum(rw**2, axis=-1)) > reject * scale)
    used = given & ~outliers
    n_obs = jnp.sum(used)
    weight = _normalised(obs.weight, used)
    sol, weighted = _least_squares(model, obs, weight, solver, max_steps, rtol, atol)
    y = sol.value
    fitted = model.with_values(y, "free")
    r = residuals(fitted, obs)  # outliers keep their residuals; statistics skip them
    rw = r * jnp.sqrt(weight)[:, None]
    sky_rms = jnp.sqrt(jnp.sum(rw**2) / n_obs)
    m = y.shape[0]
    popn_sd = jnp.where(n_obs > m, sky_rms * jnp.sqrt(n_obs / jnp.maximum(n_obs - m, 1)), jnp.inf)
    jac = jax.jacfwd(lambda y: weighted(y, None).reshape(-1))(y)
    cov, degenerate = _covariance(jac, sky_rms)
    sigmas = jnp.where(degenerate, jnp.inf, jnp.sqrt(jnp.diag(cov)))
    safe = jnp.where(degenerate | (sigmas == 0), 1.0, sigmas)
    corr = cov / (safe[:, None] * safe[None, :])
    corr = jnp.where(degenerate[:, None] | degenerate[None, :], jnp.nan, corr)
    finite = jnp.all(jnp.isfinite(rw)) & jnp.all(jnp.isfinite(y))
    converged = (sol.result == optx.RESULTS.successful) & finite
    params = model.free_parameters
    return FitResult(
        model=fitted,
        values=y,
        sigmas=sigmas,
        covariance=cov,
        correlation=corr,
        residuals=r,
        used=used,
        n_obs=n_obs,
        sky_rms=sky_rms,
        popn_sd=popn_sd,
        iterations=iterations + sol.stats["num_steps"],
        converged=converged,
        result=sol.result,
        degenerate=degenerate,
        outliers=outliers,
        robust_scale=scale,
        robust_converged=robust_ok,
        names=tuple(p.name for p in params),
        units=tuple(p.unit for p in params),
        solver=solver,
        caption=caption,
        loss=loss,
        reject=float(reject) if rho is not None else 0.0,
    )


_fit_jit = eqx.filter_jit(_fit)


def least_squares_result(
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
) -> FitResult:
    """A least-squares :class:`FitResult` with TPOINT's statistics, for fits that are not
    :func:`fit`'s own (the batched fast path, the shared-parameter fit).

    Args:
        fitted: the model with the fitted values; ``values`` its free parameters.
        unit_covariance: ``(J^T J)^-1`` of the weighted residuals.
        residuals, weighted: ``(n, 2)`` residuals, plain and times the square roots of
            the normalised weights (0 for unused observations).
        scale: the standard deviation the covariance is scaled by (default: this fit's
            Sky RMS, as TPOINT's sigmas).
    """
    params = fitted.free_parameters
    m = len(params)
    n_obs = jnp.sum(used)
    sky_rms = jnp.sqrt(jnp.sum(weighted**2) / n_obs)
    popn_sd = jnp.where(n_obs > m, sky_rms * jnp.sqrt(n_obs / jnp.maximum(n_obs - m, 1)), jnp.inf)
    cov = unit_covariance * (sky_rms if scale is None else scale) ** 2
    sigmas = jnp.sqrt(jnp.diag(cov))
    safe = jnp.where(sigmas == 0, 1.0, sigmas)
    ok = converged & jnp.all(jnp.isfinite(values)) & jnp.isfinite(sky_rms)
    return FitResult(
        model=fitted,
        values=values,
        sigmas=sigmas,
        covariance=cov,
        correlation=cov / (safe[:, None] * safe[None, :]),
        residuals=residuals,
        used=used,
        n_obs=n_obs,
        sky_rms=sky_rms,
        popn_sd=popn_sd,
        iterations=jnp.asarray(iterations),
        converged=ok,
        result=optx.RESULTS.where(ok, optx.RESULTS.successful, optx.RESULTS.nonlinear_max_steps_reached),
        degenerate=jnp.zeros((m,), bool),
        outliers=jnp.zeros(used.shape, bool),
        robust_scale=jnp.asarray(0.0),
        robust_converged=jnp.asarray(True),
        names=tuple(p.name for p in params),
        units=tuple(p.unit for p in params),
        solver=solver,
    )


@float64
def fit(
    model: Model,
    data,
    *,
    solver: str = "lm",
    weights: Float[Array, " n"] | None = None,
    fixed: tuple[str, ...] = (),
    max_steps: int = 256,
    rtol: float = 1e-10,
    atol: float = 1e-13,
    caption: str | None = None,
    loss: str = "linear",
    loss_scale: float | None = None,
    reject: float = 3.0,
) -> FitResult:
    """Fit the free parameters of ``model`` to pointing observations.

    Args:
        model: a :class:`pointax.Model` (its current values are the starting point; its
            ``fixed`` parameters stay as they are).
        data: :class:`pointax.Observations`, or a run read by :mod:`pointax.io`.
        solver: 'lm' (Levenberg-Marquardt, default), 'gauss-newton' or 'dogleg'.
        weights: optional ``(n,)`` relative weights replacing the observations' own.
        fixed: more parameter names to hold fixed for this fit.
        max_steps: solver step limit; a fit that reaches it reports ``converged=False``.
        rtol, atol: optimistix tolerances on the parameters (radians) and the cost.
        caption: title line for the report (default: the run's caption, if any).
        loss: 'linear' (least squares, default) or a robust loss from :data:`LOSSES`
            ('cauchy' is the most forgiving of gross outliers).
        loss_scale: soft margin of the robust loss, radians (default: twice the robust
            standard deviation of the residuals, re-estimated after a first pass).
        reject: with a robust loss, observations whose weighted residual norm exceeds
            ``reject`` robust standard deviations are flagged as ``outliers`` and left
            out of the final least-squares fit that gives values and statistics.

    Returns:
        A :class:`FitResult`. A fit that fails to converge does not raise: check
        ``result.converged`` (the report and ``warnings()`` say why).
    """
    check_options(solver, loss, loss_scale, reject)
    model, obs = prepare(model, data, weights, fixed)
    if caption is None:
        caption = getattr(data, "caption", "") or ""
    return _fit_jit(model, obs, solver, max_steps, rtol, atol, caption, loss, loss_scale, reject)


def prepare(model: Model, data, weights=None, fixed: tuple[str, ...] = ()) -> tuple[Model, Observations]:
    """Check and convert :func:`fit`'s inputs: observations (with ``weights``) in the
    model's convention, ``fixed`` names held, float64 arrays ready for ``jit``."""
    obs = as_observations(data)
    _check_convention(model, obs)
    if weights is not None:
        weights = np.asarray(weights, np.float64)
        if weights.shape != (len(obs),):
            raise ValueError(f"weights must have shape ({len(obs)},), got {weights.shape}")
        if np.any(weights < 0) or not np.all(np.isfinite(weights)):
            raise ValueError("weights must be finite and non-negative")
        obs = Observations(obs.encoder, obs.target, weights, obs.convention)
    if fixed:
        model = model.fix(*fixed)
    if not np.any(np.asarray(obs.weight) > 0):
        raise ValueError("no observation has a positive weight: nothing to fit")
    # Parameters as float64 arrays, so that jit traces them instead of baking them in.
    model = model.with_values(model.values())
    obs = jax.tree.map(lambda x: jnp.asarray(x, jnp.float64), obs)
    return model, obs

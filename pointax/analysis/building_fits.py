"""The least-squares fits of :func:`pointax.analysis.build_model` (:class:`Builder`).

Every fit is the fitting core's: Gauss-Newton steps of
:func:`pointax.fitting.core.gauss_newton_step`, with TPOINT's statistics
(:mod:`pointax.fitting.statistics`), in one compiled loop over a superset model (every
candidate's parameters in it, those not in use held at 0). Which terms are in use and
which stars are fitted (the in-sample fit, each fold) are masks given to that compiled
program as data, so trying a term or a fold compiles nothing, and a later build of the
same terms reuses the programs. Candidates are screened by one linearised step from the
current fit (its Jacobian over every candidate), with the same statistics.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Iterable
from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from ..core import xla_options
from ..fitting.core import linearised_change
from ..fitting.problem import define_problem
from ..fitting.statistics import normalised_weights, statistics
from ..core.model import Model
from ..core.observations import Observations
from .folds import Scheme
from ..fitting.statistics import axis_rms

__all__ = ["STEP_TOLERANCE", "Builder", "FitState", "compiled_program"]

STEP_TOLERANCE = 1e-12
"""build_model's Gauss-Newton fits stop when the next step is below this (radians)."""


class _Steps(NamedTuple):
    """One linearised least-squares step per row set (:func:`_steps`), as NumPy arrays
    once fetched."""

    values: Float[Array, "b m"]
    """Every parameter of the superset after the step (model order, internal units)."""
    change: Float[Array, "b m"]
    """What the step added to each parameter (0 where it was not finite)."""
    residuals: Float[Array, "b n 2"]
    """Unweighted residuals after the step as the Jacobian predicts them, every
    observation (fitted or not), radians."""
    sigmas: Float[Array, "b m"]
    """TPOINT sigmas (:func:`pointax.fitting.statistics.statistics`; inf: degenerate);
    meaningless for parameters not fitted."""
    sky_rms: Float[Array, " b"]
    """TPOINT's Sky RMS of the fitted rows' residuals after the step, radians."""
    finite: Bool[Array, " b"]
    """The step, the values and the fitted rows' residuals are finite."""


def _linearise(model: Model, obs: Observations, y: Float[Array, " m"]) -> tuple[Array, Array]:
    """Residuals ``(n, 2)`` of ``model`` with the values ``y`` (every parameter) and their
    Jacobian ``(2n, m)`` over every parameter (rows ``2i, 2i + 1``: observation ``i``),
    from one trace of the model (the residuals are the Jacobian's primal), on the
    fitting core's problem definition (:mod:`pointax.fitting.problem`)."""
    problem = define_problem(model, obs)

    def r(y):
        flat = problem.residuals(model.with_values(y)).reshape(-1)
        return flat, flat

    jac, flat = jax.jacfwd(r, has_aux=True)(y)
    return flat.reshape(-1, 2), jac


_PROGRAMS: dict[tuple, Any] = {}
"""The last few programs of :func:`compiled_program`."""


def compiled_program(fn, static: Model, obs: Observations):
    """``f(arrays, *args) = fn(eqx.combine(arrays, static), obs, *args)``, compiled. The
    model's arrays (its parameters) are an argument, so the program serves every set of
    terms and every build of the same model (``static``: its structure) on the same
    observations; the observations are compiled in as constants: XLA folds what depends
    on them alone, and the program compiles quicker (``benchmarks/fauto_notes.md``)."""
    leaves, treedef = jax.tree.flatten(obs)
    key = (fn, static, treedef, tuple((x.shape, x.dtype.str, np.asarray(x).tobytes()) for x in leaves))
    program = _PROGRAMS.get(key)
    if program is None:
        program = xla_options.jit(lambda arrays, *args: fn(eqx.combine(arrays, static), obs, *args))
        while len(_PROGRAMS) >= 8:
            del _PROGRAMS[next(iter(_PROGRAMS))]
        _PROGRAMS[key] = program
    return program


def _steps(
    jac: Float[Array, "b k m"],
    r: Float[Array, "b n 2"],
    y: Float[Array, "b m"],
    free: Bool[Array, " m"],
    rows: Bool[Array, "b n"],
) -> _Steps:
    """One linearised least-squares step of the ``free`` parameters for each row set of
    ``rows``, from the values ``y`` (every parameter), the ``(n, 2)`` residuals ``r`` of
    every observation there (radians) and their ``(2n, m)`` Jacobian ``jac`` over every
    parameter (:func:`_linearise`), each with a leading row-set axis: the fitting core's
    linear algebra (:func:`pointax.fitting.core.linearised_change`, unit weights on the
    rows) and TPOINT's statistics (:func:`pointax.fitting.statistics.statistics`) of the
    residuals after the step, predicted as ``r + J dy``. The steps of a fit, and the
    screening of a candidate (every row set from the in-sample fit)."""

    def one(jac, r, y, rows):
        sqrt_w = jnp.sqrt(normalised_weights(rows.astype(jac.dtype), rows))  # 1 on rows, 0 elsewhere
        weighted = (r * sqrt_w[:, None]).reshape(-1)
        weighted_jac = jac * jnp.repeat(sqrt_w, 2)[:, None]
        change, unit_cov, degenerate, step_finite = linearised_change(weighted_jac, weighted, free)
        values = y + change
        predicted = r + (jac @ change).reshape(r.shape)
        weighted = predicted * sqrt_w[:, None]
        stats = statistics(weighted, rows, jnp.sum(free), unit_cov, degenerate)
        finite = step_finite & jnp.all(jnp.isfinite(weighted)) & jnp.all(jnp.isfinite(values))
        return _Steps(values, change, predicted, stats.sigmas, stats.sky_rms, finite)

    return jax.vmap(one)(jac, r, y, rows)


@functools.cache
def _steps_program():
    """:func:`_steps`, compiled (one program for every build)."""
    return xla_options.jit(_steps)


def _where(mask: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a`` in the row sets of ``mask`` (``(b,)``), ``b`` elsewhere."""
    return np.where(mask.reshape((-1,) + (1,) * (a.ndim - 1)), a, b)


@dataclasses.dataclass
class FitState:
    """A converged fit of one set of active terms: in-sample and out-of-sample figures."""

    active: frozenset[int]  # term indices of the superset
    y: np.ndarray  # (m,) every parameter of the superset, 0 for inactive ones
    r: np.ndarray  # (n, 2) residuals of the in-sample fit (all rows), radians
    sigmas: np.ndarray  # (m,) TPOINT sigmas (inf: degenerate; nan: inactive or fixed)
    rms_in: float
    rms_out: float
    sky_rms: float
    n_params: int
    converged: bool
    # The in-sample fit's last values accepted, residuals and Jacobian there, once per
    # row set (device arrays): where :func:`_steps` screens candidates from.
    origin: tuple[Array, Array, Array]


class Builder:
    """Least-squares fits of any subset of a superset model's terms on each of a scheme's
    row sets, and candidates screened from the in-sample fit, with two compiled
    programs: the residuals and their Jacobian over every parameter
    (:func:`_linearise`), and the linear algebra and statistics of a step
    (:func:`_steps`). Which terms are active and which rows are fitted are data of
    these (masks), so trying a term compiles nothing; the superset, the observations
    and the number of row sets fix the programs, and a later build of the same
    superset reuses them."""

    def __init__(self, superset: Model, scheme: Scheme, cos2, max_iterations: int = 30):
        # Every parameter value an array: the model's leaves are data, not baked in.
        self.arrays, static = eqx.partition(superset.with_values(superset.values("all")), eqx.is_array)
        self.scheme = scheme
        self.obs = jax.tree.map(lambda x: jnp.asarray(x, jnp.float64), scheme.obs)
        self._linearise = compiled_program(_linearise, static, self.obs)
        # (b, n): the in-sample rows, then each split's fitting rows.
        self.row_sets = np.stack([scheme.fit_rows] + [f for f, _ in scheme.splits])
        self.rows = jax.device_put(self.row_sets)
        self.cos2 = cos2
        self.max_iterations = max_iterations
        params = superset.parameters
        self.m = len(params)
        self.fitted = np.array([p.name not in superset.fixed for p in params], bool)  # (m,)
        self.columns: dict[int, list[int]] = {}  # term -> its free parameters (all-parameter index)
        for j, info in enumerate(params):
            if self.fitted[j]:
                self.columns.setdefault(info.term, []).append(j)
        self.y_start = np.asarray(superset.values("all"), np.float64)

    def linearise(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:func:`_linearise` at the values ``y`` (``(m,)``): ``(n, 2)`` residuals, ``(2n, m)`` Jacobian."""
        r, jac = self._linearise(self.arrays, jax.device_put(np.asarray(y, np.float64)))
        return np.asarray(r), np.asarray(jac)

    def mask(self, active: Iterable[int]) -> np.ndarray:
        """``(m,)`` the free parameters of the ``active`` terms."""
        out = np.zeros(self.m, bool)
        out[[c for t in active for c in self.columns.get(t, [])]] = True
        return out

    def fit(self, free: np.ndarray, y0: np.ndarray) -> tuple[_Steps, np.ndarray, tuple[np.ndarray, ...]]:
        """Least squares of the ``free`` parameters on each row set, the others held at
        their values ``y0`` (``(m,)``), by Gauss-Newton steps from ``y0``: the row sets
        step together, each step one :func:`_steps` for them all, each trial point one
        :func:`_linearise`.

        A step that raises the cost (the sum of the squared residuals of the row set's
        rows) is halved, at most 9 times, until it does not. A fit stops when its next
        step is below :data:`STEP_TOLERANCE` (radians, largest over the parameters:
        converged), when no halving lowers the cost (converged if the step is below
        1e-10 rad), or after ``max_iterations`` steps (not converged).

        Returns:
            The step from each fit's last values accepted (for a converged fit below
            :data:`STEP_TOLERANCE`): the values after it, the residuals predicted there
            and TPOINT's statistics (NumPy :class:`_Steps`); whether each fit converged;
            and those last values accepted, the residuals and the Jacobian there
            (``(b, m)``, ``(b, n, 2)``, ``(b, 2n, m)``).
        """
        rows = self.row_sets
        b = len(rows)
        r0, jac0 = self.linearise(y0)  # the same start for every row set
        y, r, jac = np.repeat(y0[None], b, 0), np.repeat(r0[None], b, 0), np.repeat(jac0[None], b, 0)
        cost = np.sum(np.where(rows[:, :, None], r, 0.0) ** 2, axis=(1, 2))
        free_, steps = jax.device_put(free), _steps_program()
        live, converged = np.ones(b, bool), np.zeros(b, bool)
        out = None
        for k in range(self.max_iterations + 1):
            s = jax.tree.map(np.asarray, steps(jac, r, y, free_, self.rows))
            out = s if out is None else jax.tree.map(lambda new, old: _where(live, new, old), s, out)
            if k == self.max_iterations:
                break  # the fits still live took max_iterations steps: not converged
            largest = np.max(np.abs(s.change), axis=1, initial=0.0)
            small = live & (largest < STEP_TOLERANCE)
            converged |= small & s.finite
            live &= ~small
            trying, scale = live.copy(), 1.0
            for _ in range(10):  # the step, then up to 9 halvings: never accept a raised cost
                for i in np.flatnonzero(trying):
                    point = y[i] + scale * s.change[i]
                    r_i, jac_i = self.linearise(point)
                    cost_i = np.sum(np.where(rows[i][:, None], r_i, 0.0) ** 2)
                    if cost_i <= cost[i]:
                        y[i], r[i], jac[i], cost[i], trying[i] = point, r_i, jac_i, cost_i, False
                if not trying.any():
                    break
                scale *= 0.5
            converged |= trying & (largest < 1e-10) & s.finite  # no halving lowered the cost
            live &= ~trying
            if not live.any():
                break
        return out, converged, (y, r, jac)

    def total(self, r: np.ndarray, rows: np.ndarray) -> float:
        """In-sample total RMS (eqs 21-23) of the residuals ``r`` (``(n, 2)``) on ``rows``."""
        return axis_rms(r[rows], None if self.cos2 is None else self.cos2[rows]).total

    def pooled(self, r: np.ndarray) -> float:
        """Out-of-sample total RMS (eqs 21-23) of the splits' predictions: ``r`` is
        ``(k, n, 2)``, split ``k``'s residuals of every observation; NaN for a scheme
        without splits (:func:`pointax.analysis.fauto` fits in sample only)."""
        if not self.scheme.splits:
            return math.nan
        pieces = [r[k][v_rows] for k, (_, v_rows) in enumerate(self.scheme.splits)]
        cos = None if self.cos2 is None else np.concatenate([self.cos2[v] for _, v in self.scheme.splits])
        return axis_rms(np.concatenate(pieces), cos).total

    def state(self, active: frozenset[int], y0: np.ndarray) -> FitState:
        """Converged in-sample fit and out-of-sample predictions of ``active``, from the
        values ``y0`` (``(m,)``; inactive parameters start, and stay, at 0)."""
        free = self.mask(active)
        fits, converged, (y, r, jac) = self.fit(free, np.where(self.fitted & ~free, 0.0, y0))
        b = len(self.row_sets)
        origin = jax.device_put(tuple(np.repeat(a[:1], b, 0) for a in (jac, r, y)))
        return FitState(
            active,
            fits.values[0],
            fits.residuals[0],
            np.where(free, fits.sigmas[0], np.nan),
            self.total(fits.residuals[0], self.scheme.fit_rows),
            self.pooled(fits.residuals[1:]),
            float(fits.sky_rms[0]),
            int(free.sum()),
            bool(np.all(converged)),
            origin,
        )

    def screen(self, state: FitState, term: int) -> tuple[float, float, bool]:
        """``(|value/sigma|, out-of-sample RMS, degenerate)`` with ``term`` added: one
        Gauss-Newton step from the in-sample fit, with its Jacobian, for the in-sample
        fit and for every fold (:func:`_steps`)."""
        s = _steps_program()(*state.origin, jax.device_put(self.mask(state.active | {term})), self.rows)
        new = self.columns[term]
        sig = np.asarray(s.sigmas)[0, new]
        if np.any(~np.isfinite(sig)):
            return 0.0, math.inf, True
        z = float(np.max(np.abs(np.asarray(s.values)[0, new] / sig)))
        return z, self.pooled(np.asarray(s.residuals)[1:]), False

    def significance(self, state: FitState, term: int) -> float:
        """``term``'s ``|value / sigma|`` in the fit ``state`` (largest over its
        parameters; 0 when a sigma is not finite or not positive)."""
        cols = self.columns[term]
        s = state.sigmas[cols]
        if np.any(~np.isfinite(s)) or np.any(s <= 0):
            return 0.0
        return float(np.max(np.abs(state.y[cols] / s)))

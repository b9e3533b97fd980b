"""Automatic model building in the spirit of TPOINT's ``FAUTO`` (:func:`build_model`):
grow a model term by term from candidates, keeping terms that are significant and
predict unseen stars better, dropping those that are not, and record the path
(:class:`ModelBuild`).

Every fit is the fitting core's: Gauss-Newton steps of
:func:`pointax.fitting.core.gauss_newton_step`, with TPOINT's statistics
(:mod:`pointax.fitting.statistics`), in one compiled loop over a superset model (every
candidate's parameters in it, those not in use held at 0). Which terms are in use and
which stars are fitted (the in-sample fit, each fold) are masks given to that compiled
program as data, so trying a term or a fold compiles nothing, and a later build of the
same terms reuses the programs. Candidates are screened by one linearised step from the
current fit (its Jacobian over every candidate), with the same statistics. The figures
are those of :mod:`pointax.analysis.statistics`; the out-of-sample schemes those of
:mod:`pointax.analysis.folds`.
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

from .._x64 import float64
from ..fitting.core import linearised_change
from ..fitting.problem import define_problem
from ..fitting.residuals import residuals
from ..fitting.statistics import normalised_weights, statistics
from ..fitting.xla_options import fast_compile_options
from ..model import Model
from ..observations import Observations
from ..progress import progress_bar
from ..terms.base import Term
from ..units import ARCSEC, UNITS
from .families import family_model
from .folds import Scheme, evaluation_scheme, integer_at_least
from .statistics import axis_rms, finite_or_none, resolve_per_axis, second_axis_cosines

__all__ = ["STEP_TOLERANCE", "BuildStep", "ModelBuild", "build_model"]

STEP_TOLERANCE = 1e-12
"""build_model's Gauss-Newton fits stop when the next step is below this (radians)."""


@dataclasses.dataclass(frozen=True)
class BuildStep:
    """One step of :func:`build_model`'s path.

    Attributes:
        action: 'start', 'add' or 'drop'.
        term: the term added or dropped (for 'start', a summary of the start model).
        n_params: fitted parameters after the step.
        rms_in: in-sample total RMS after the step (eqs 21-23), radians.
        rms_out: out-of-sample total RMS after the step, radians.
        significance: the term's ``|value / sigma|`` (largest over its parameters): when
            added, in the model it joined; when dropped, in the model it left.
        sky_rms: TPOINT's Sky RMS of the in-sample fit, radians.
        converged: whether the step's in-sample and fold fits converged.
    """

    action: str
    term: str
    n_params: int
    rms_in: float
    rms_out: float
    significance: float
    sky_rms: float
    converged: bool = True

    def to_dict(self) -> dict[str, Any]:
        return {
            "converged": self.converged,
            "action": self.action,
            "term": self.term,
            "n_params": self.n_params,
            "rms_in_arcsec": finite_or_none(self.rms_in / ARCSEC),
            "rms_out_arcsec": finite_or_none(self.rms_out / ARCSEC),
            "significance": finite_or_none(self.significance),
            "sky_rms_arcsec": finite_or_none(self.sky_rms / ARCSEC),
        }


@dataclasses.dataclass(frozen=True)
class ModelBuild:
    """The outcome of :func:`build_model`.

    Attributes:
        model: the final model, its parameters fitted on the in-sample stars.
        path: the :class:`BuildStep` s taken, 'start' first.
        stopped: why the building stopped, in words.
        names: the final model's fitted parameter names.
        values, sigmas: their values and TPOINT sigmas (internal units, radians).
        units: their display units.
        rules: the rules used, in words.
        skipped: candidates left out before the search, with the reason.
    """

    model: Model
    path: tuple[BuildStep, ...]
    stopped: str
    names: tuple[str, ...]
    values: np.ndarray
    sigmas: np.ndarray
    units: tuple[str, ...]
    rules: str
    skipped: tuple[str, ...] = ()

    @property
    def added(self) -> list[str]:
        """Terms added and not dropped again, in the order they were added."""
        final = {t.name for t in self.model.terms}
        return [s.term for s in self.path if s.action == "add" and s.term in final]

    @property
    def dropped(self) -> list[str]:
        """Terms dropped and not added again."""
        final = {t.name for t in self.model.terms}
        return [s.term for s in self.path if s.action == "drop" and s.term not in final]

    def report(self) -> str:
        """The path as a table (arcsec), the stopping reason and the final parameters."""
        width = max(24, *(len(s.term) for s in self.path))
        head = f"{'step':>4s}  {'action':<6s}  {'term':<{width}s} {'params':>6s} {'RMS in':>8s} {'RMS out':>8s} {'|v/sigma|':>9s}"
        lines = [f"Automatic model building ({self.rules})", "", head, "-" * len(head)]
        for k, s in enumerate(self.path):
            sig = "" if s.action == "start" else f"{s.significance:9.1f}"
            lines.append(
                f"{k:4d}  {s.action:<6s}  {s.term:<{width}s} {s.n_params:6d} {s.rms_in / ARCSEC:8.2f} "
                f"{s.rms_out / ARCSEC:8.2f} {sig:>9s}"
            )
        lines.append(f"stopped: {self.stopped}")
        for k, s in enumerate(self.path):
            if not s.converged:
                lines.append(f"WARNING: the fits of step {k} did not converge; its figures may be off")
        if self.skipped:
            lines.append("candidates left out: " + "; ".join(self.skipped))
        lines += ["", f"final model: {self.model.describe()}"]
        for n, v, s, u in zip(self.names, self.values, self.sigmas, self.units):
            scale = UNITS[u]
            unit = "" if u == "arcsec" else f"  ({u})"
            lines.append(f"  {n:<{width}s} {v / scale:+12.4f} {s / scale:11.4f}{unit}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        return {
            "rules": self.rules,
            "stopped": self.stopped,
            "skipped": list(self.skipped),
            "path": [s.to_dict() for s in self.path],
            "terms": [
                {"name": n, "value": finite_or_none(v / UNITS[u]), "sigma": finite_or_none(s / UNITS[u]), "unit": u}
                for n, v, s, u in zip(self.names, self.values, self.sigmas, self.units)
            ],
        }


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
"""The last few programs of :func:`_program`."""


def _program(fn, static: Model, obs: Observations):
    """``f(arrays, *args) = fn(eqx.combine(arrays, static), obs, *args)``, compiled. The
    model's arrays (its parameters) are an argument, so the program serves every set of
    terms and every build of the same model (``static``: its structure) on the same
    observations; the observations are compiled in as constants (XLA folds what depends
    on them alone: :func:`_linearise` of the 48-star test case's superset compiled in
    0.6 s against 0.9 s with them an argument)."""
    leaves, treedef = jax.tree.flatten(obs)
    key = (fn, static, treedef, tuple((x.shape, x.dtype.str, np.asarray(x).tobytes()) for x in leaves))
    program = _PROGRAMS.get(key)
    if program is None:
        program = jax.jit(
            lambda arrays, *args: fn(eqx.combine(arrays, static), obs, *args), compiler_options=fast_compile_options()
        )
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
        change, unit_cov, degenerate = linearised_change(jac * jnp.repeat(sqrt_w, 2)[:, None], weighted, free)
        step_finite = jnp.all(jnp.isfinite(change))
        change = jnp.where(step_finite, change, 0.0)
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
    return jax.jit(_steps, compiler_options=fast_compile_options())


def _where(mask: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a`` in the row sets of ``mask`` (``(b,)``), ``b`` elsewhere."""
    return np.where(mask.reshape((-1,) + (1,) * (a.ndim - 1)), a, b)


@dataclasses.dataclass
class _State:
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


class _Builder:
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
        self._linearise = _program(_linearise, static, self.obs)
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
        return axis_rms(r[rows], None if self.cos2 is None else self.cos2[rows]).total

    def pooled(self, r: np.ndarray) -> float:
        """Out-of-sample total RMS (eqs 21-23) of the splits' predictions: ``r`` is
        ``(k, n, 2)``, split ``k``'s residuals of every observation."""
        pieces = [r[k][v_rows] for k, (_, v_rows) in enumerate(self.scheme.splits)]
        cos = None if self.cos2 is None else np.concatenate([self.cos2[v] for _, v in self.scheme.splits])
        return axis_rms(np.concatenate(pieces), cos).total

    def state(self, active: frozenset[int], y0: np.ndarray) -> _State:
        """Converged in-sample fit and out-of-sample predictions of ``active``, from the
        values ``y0`` (``(m,)``; inactive parameters start, and stay, at 0)."""
        free = self.mask(active)
        fits, converged, (y, r, jac) = self.fit(free, np.where(self.fitted & ~free, 0.0, y0))
        b = len(self.row_sets)
        origin = jax.device_put(tuple(np.repeat(a[:1], b, 0) for a in (jac, r, y)))
        return _State(
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

    def screen(self, state: _State, term: int) -> tuple[float, float, bool]:
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

    def significance(self, state: _State, term: int) -> float:
        cols = self.columns[term]
        s = state.sigmas[cols]
        if np.any(~np.isfinite(s)) or np.any(s <= 0):
            return 0.0
        return float(np.max(np.abs(state.y[cols] / s)))


def _candidate_terms(candidates, obs: Observations, naming: str, form: str) -> tuple[Term, ...]:
    if isinstance(candidates, Model):
        return candidates.terms
    if isinstance(candidates, str):
        return family_model(candidates, obs, naming=naming, form=form).terms
    candidates = tuple(candidates)
    if all(isinstance(t, str) for t in candidates):
        return family_model(candidates, obs, naming=naming, form=form).terms
    for t in candidates:
        if not isinstance(t, Term):
            raise TypeError(f"candidates must be pointax.Term objects, a model or names, got {type(t).__name__}")
    return candidates


@float64
def build_model(
    candidates,
    observations,
    *,
    start: Model | str,
    folds: int | None = 5,
    holdout=None,
    seed: int = 0,
    add_threshold: float = 3.0,
    drop_threshold: float = 2.0,
    keep: Iterable[str] = (),
    max_steps: int = 40,
    per_axis: str | None = None,
    naming: str = "tpoint",
    form: str = "linear",
    progress: bool = False,
) -> ModelBuild:
    """Build a model automatically, in the spirit of TPOINT's FAUTO: add candidate terms
    that are significant and predict unseen stars better, drop terms that are not
    significant, and record the path.

    The rules, applied in turn until neither changes the model (or after ``max_steps``
    add and drop steps):

    1. **Add.** Each candidate not in the model is tried. Eligible are those whose
       ``|value / sigma|`` in the enlarged model is at least ``add_threshold`` (largest
       over the term's parameters), that the data can tell apart from the model's
       terms (no rank deficiency), that lower the out-of-sample RMS, and whose addition
       leads to a set of terms not visited before. The eligible one with the lowest
       out-of-sample RMS is added.
    2. **Drop.** While a term of the model (other than those in ``keep``) has
       ``|value / sigma| < drop_threshold`` (0 when the data cannot determine it), the
       least significant one is dropped and the model refitted. Adding comes first, so
       a term is not judged while the model still misses a large error (the residual
       then inflates every sigma).

    Out-of-sample RMS is the total of eqs 21-23 (:func:`pointax.analysis.axis_rms`) over k-fold
    predictions (``folds``, default 5) or a holdout (``holdout``, as in :func:`pointax.compare`;
    then ``folds`` is ignored). Candidates are screened with the Jacobian at the current
    fit (one Gauss-Newton step from it: the neglected change is of second order in the
    coefficients' change, about ``dc^2 / 1 rad``, 0.002" for a 20" term); every step's
    reported figures come from converged Gauss-Newton fits, which agree with
    :func:`pointax.fit` to its tolerance. Candidates must leave the pointing unchanged
    when their parameters are 0 (every library term does; checked).

    Args:
        candidates: terms that may be added: :class:`pointax.Term` objects, a model
            (its terms) or names (:func:`family_model`, e.g. ``"harmonic linearised"``).
            Candidates named like a term of ``start`` are left out (and listed).
        observations: as for :func:`pointax.compare` (equal weights).
        start: the starting model, or a family name for the observations' mount. Its
            fixed parameters stay fixed.
        folds, holdout, seed: the out-of-sample scheme.
        add_threshold, drop_threshold: significance thresholds (defaults 3 and 2).
        keep: names of terms of ``start`` that are never dropped.
        max_steps: most add and drop steps.
        per_axis: as for :func:`pointax.compare` (what the RMS measures on the first axis).
        naming, form: how names resolve (:func:`family_model`).
        progress: show a progress bar (candidates screened, terms in the model) on
            standard error when it is a terminal (:func:`pointax.progress.progress_bar`).

    Returns:
        :class:`ModelBuild`: the final model (fitted on the in-sample stars), the path
        and why it stopped; ``print(build.report())``.
    """
    if holdout is not None:
        folds = None
    elif folds is None:
        raise ValueError("build_model needs an out-of-sample scheme: folds=k (default 5) or holdout")
    if not (
        math.isfinite(add_threshold) and math.isfinite(drop_threshold) and add_threshold > 0 and drop_threshold >= 0
    ):
        raise ValueError(f"thresholds must be finite and positive, got add {add_threshold!r}, drop {drop_threshold!r}")
    max_steps = integer_at_least("max_steps", max_steps, 0)
    scheme = evaluation_scheme(observations, holdout, folds, seed)
    start_label = start if isinstance(start, str) else "start model"
    if isinstance(start, str):
        start = family_model(start, scheme.obs, naming=naming, form=form)
    if not isinstance(start, Model):
        raise TypeError(f"start must be a pointax.Model or a family name, got {type(start).__name__}")
    conv = start.mount.convention
    if conv is not None and scheme.obs.convention is not None and conv != scheme.obs.convention:
        raise ValueError(
            f"start's mount expects the {conv!r} convention, the observations are {scheme.obs.convention!r}"
        )
    keep = set(keep)
    unknown = keep - {t.name for t in start.terms}
    if unknown:
        raise ValueError(f"keep names terms not in the start model: {sorted(unknown)}")
    pool = _candidate_terms(candidates, scheme.obs, naming, form)
    names = {t.name for t in start.terms}
    chosen, skipped = [], []
    for t in pool:
        if t.name in names:
            skipped.append(f"{t.name} (already in the model)")
            continue
        names.add(t.name)
        chosen.append(t)
    superset = start.with_terms(*chosen)
    superset = superset.set(**{p.name: 0.0 for p in superset.parameters[len(start.parameters) :]})
    cos2 = second_axis_cosines(start.mount, scheme.obs, resolve_per_axis(start.mount, per_axis))
    builder = _Builder(superset, scheme, cos2)
    n_start = len(start.terms)
    candidate_ids = [i for i in range(n_start, len(superset.terms)) if builder.columns.get(i)]
    for i in range(n_start, len(superset.terms)):
        if not builder.columns.get(i):
            skipped.append(f"{superset.terms[i].name} (no free parameters)")

    # Candidates at 0 must leave the pointing as it is.
    start_arrays, start_static = eqx.partition(start, eqx.is_array)
    r_start = np.asarray(_program(residuals, start_static, builder.obs)(start_arrays))
    r_super, _ = builder.linearise(builder.y_start)
    if not np.allclose(r_start, r_super, rtol=0, atol=1e-12):
        raise ValueError(
            "some candidate terms change the pointing when their parameters are 0; build_model needs terms that do not"
        )

    term_name = [t.name for t in superset.terms]
    active = frozenset(i for i in range(n_start) if builder.columns.get(i))
    state = builder.state(active, builder.y_start)
    label = f"{start_label} ({len(start.terms)} terms)"
    path = [
        BuildStep("start", label, state.n_params, state.rms_in, state.rms_out, math.nan, state.sky_rms, state.converged)
    ]
    visited = {active}
    stopped = f"max_steps={max_steps} reached"
    steps = 0
    bar = progress_bar(None, "build_model", "candidate", enabled=progress)
    while steps < max_steps:
        # 1. Add the candidate that predicts best among the significant ones.
        best = None
        bar.set_description(f"build_model: step {steps + 1}, {len(state.active)} terms")
        for t in candidate_ids:
            if t in state.active or (state.active | {t}) in visited:
                continue
            zt, out, degenerate = builder.screen(state, t)
            bar.update()
            if degenerate or zt < add_threshold or not out < state.rms_out:
                continue
            if best is None or out < best[1]:
                best = (t, out)
        if best is not None:
            t = best[0]
            state = builder.state(state.active | {t}, state.y)
            visited.add(state.active)
            z_t = builder.significance(state, t)
            path.append(
                BuildStep(
                    "add",
                    term_name[t],
                    state.n_params,
                    state.rms_in,
                    state.rms_out,
                    z_t,
                    state.sky_rms,
                    state.converged,
                )
            )
            steps += 1
        # 2. Drop the least significant term below the threshold, one at a time.
        dropped = False
        while steps < max_steps:
            z = {t: builder.significance(state, t) for t in sorted(state.active) if term_name[t] not in keep}
            weak = [t for t in z if z[t] < drop_threshold]
            if not weak:
                break
            t = min(weak, key=lambda k: z[k])
            state = builder.state(state.active - {t}, state.y)
            visited.add(state.active)
            path.append(
                BuildStep(
                    "drop",
                    term_name[t],
                    state.n_params,
                    state.rms_in,
                    state.rms_out,
                    z[t],
                    state.sky_rms,
                    state.converged,
                )
            )
            steps += 1
            dropped = True
        if best is None and not dropped:
            stopped = (
                f"no candidate has |value/sigma| >= {add_threshold:g} and lowers the out-of-sample RMS, "
                f"and every term has |value/sigma| >= {drop_threshold:g}"
            )
            break

    bar.close()
    # The active terms, and the start's terms without free parameters (all fixed).
    final_terms = [
        i for i in range(len(superset.terms)) if i in state.active or (i < n_start and not builder.columns.get(i))
    ]
    fitted = superset.with_values(jax.device_put(state.y))
    model = start.restructured(terms=[fitted.terms[i] for i in final_terms])
    cols = np.flatnonzero(builder.mask(state.active))
    params = superset.parameters
    rules = (
        f"add: |value/sigma| >= {add_threshold:g} and lower out-of-sample RMS; drop: |value/sigma| < {drop_threshold:g}; "
        f"{scheme.description}"
    )
    return ModelBuild(
        model=model,
        path=tuple(path),
        stopped=stopped,
        names=tuple(params[c].name for c in cols),
        values=state.y[cols],
        sigmas=state.sigmas[cols],
        units=tuple(params[c].unit for c in cols),
        rules=rules,
        skipped=tuple(skipped),
    )

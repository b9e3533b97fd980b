"""Automatic model building in the spirit of TPOINT's ``FAUTO`` (:func:`build_model`):
grow a model term by term from candidates, keeping terms that are significant and
predict unseen stars better, dropping those that are not, and record the path
(:class:`ModelBuild`).

The fits are Gauss-Newton in NumPy on one compiled residual-and-Jacobian function of a
superset model (every candidate's parameters in it, those not in use held at 0), so
trying a term costs no compilation. The figures are those of :mod:`pointax.analysis.statistics`;
the out-of-sample schemes those of :mod:`pointax.analysis.folds`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._x64 import float64
from ..fitting.residuals import residuals
from ..fitting.statistics import DEGENERATE_RCOND
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


def _linearise(model: Model, obs: Observations, y: Float[Array, " p"]) -> tuple[Array, Array]:
    """Residuals ``(2n,)`` of ``model`` with free values ``y`` and their Jacobian ``(2n, p)``."""

    def r(y):
        return residuals(model.with_values(y, "free"), obs).reshape(-1)

    return r(y), jax.jacfwd(r)(y)


@dataclasses.dataclass
class _State:
    """A converged fit of one set of active terms: in-sample and out-of-sample figures."""

    active: frozenset[int]  # term indices of the superset
    y: np.ndarray  # (p,) free values, 0 for inactive parameters
    r: np.ndarray  # (n, 2) residuals of the in-sample fit (all rows)
    jac: np.ndarray  # (2n, p) Jacobian there
    sigmas: np.ndarray  # (p,) TPOINT sigmas (inf: degenerate; nan: inactive)
    rms_in: float
    rms_out: float
    sky_rms: float
    n_params: int
    converged: bool


class _Builder:
    """Least-squares fits of any subset of a superset model's terms, with one compiled
    residual-and-Jacobian function (:func:`_linearise`); Gauss-Newton in NumPy."""

    def __init__(self, superset: Model, scheme: Scheme, cos2, max_iterations: int = 30):
        self.model = superset
        self.scheme = scheme
        obs = jax.tree.map(lambda x: jnp.asarray(x, jnp.float64), scheme.obs)
        # One compilation per build, model and observations closed over: a call then
        # costs the evaluation only (equinox's filter_jit re-partitions a model of many
        # terms on every call, which cost more than the evaluation here).
        self._lin = jax.jit(lambda y: _linearise(superset, obs, y))
        self.cos2 = cos2
        self.max_iterations = max_iterations
        free = superset.free_parameters
        self.p = len(free)
        self.columns: dict[int, list[int]] = {}
        for j, info in enumerate(free):
            self.columns.setdefault(info.term, []).append(j)
        self.y_start = np.asarray(superset.values("free"), np.float64)

    def lin(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r, jac = self._lin(jnp.asarray(y, jnp.float64))
        return np.asarray(r), np.asarray(jac)

    def cols(self, active: Iterable[int]) -> np.ndarray:
        return np.array(sorted(c for t in active for c in self.columns.get(t, [])), dtype=int)

    def solve(self, active, rows: np.ndarray, y0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        """Gauss-Newton (step-halving) on the rows ``rows`` (bool (n,)) for the columns
        of the ``active`` terms; inactive parameters are 0. Returns y, r, J at the end
        and whether it converged (the next step below :data:`STEP_TOLERANCE`, or below
        1e-10 rad where no step lowers the cost any more)."""
        cols = self.cols(active)
        rr = np.repeat(rows, 2)
        y = np.where(np.isin(np.arange(self.p), cols), y0, 0.0)
        r, jac = self.lin(y)
        cost = float(np.sum(r[rr] ** 2))
        if cols.size == 0:
            return y, r, jac, True
        converged = False
        for _ in range(self.max_iterations):
            step, *_ = np.linalg.lstsq(jac[np.ix_(rr, cols)], -r[rr], rcond=DEGENERATE_RCOND)
            if np.max(np.abs(step)) < STEP_TOLERANCE:
                converged = True  # the next step is below 2e-7 arcsec
                break
            scale, accepted = 1.0, False
            for _ in range(10):  # step halving: never accept a step that raises the cost
                trial = y.copy()
                trial[cols] += scale * step
                r_t, jac_t = self.lin(trial)
                cost_t = float(np.sum(r_t[rr] ** 2))
                if cost_t <= cost:
                    accepted = True
                    break
                scale *= 0.5
            if not accepted:
                converged = bool(np.max(np.abs(step)) < 1e-10)
                break
            y, r, jac, cost = trial, r_t, jac_t, cost_t
        return y, r, jac, converged

    def sigmas(self, jac_rows: np.ndarray, cols: np.ndarray, sky_rms: float) -> np.ndarray:
        """TPOINT sigmas of ``cols`` (inf where degenerate, as :func:`pointax.fit`)."""
        out = np.full(self.p, np.nan)
        if cols.size == 0:
            return out
        _, s, vt = np.linalg.svd(jac_rows[:, cols], full_matrices=False)
        small = s <= DEGENERATE_RCOND * s[0]
        inv = np.where(small, 0.0, 1.0 / np.where(small, 1.0, s) ** 2)
        var = np.einsum("ki,k,ki->i", vt, inv, vt) * sky_rms**2
        degenerate = np.any(small[:, None] & (np.abs(vt) > 0.1), axis=0)
        out[cols] = np.where(degenerate, np.inf, np.sqrt(var))
        return out

    def total(self, r: np.ndarray, rows: np.ndarray) -> float:
        return axis_rms(r[rows], None if self.cos2 is None else self.cos2[rows]).total

    def state(self, active: frozenset[int], y0: np.ndarray) -> _State:
        """Converged in-sample fit and out-of-sample predictions of ``active``."""
        fit_rows = self.scheme.fit_rows
        y, r_flat, jac, converged = self.solve(active, fit_rows, y0)
        r = r_flat.reshape(-1, 2)
        cols = self.cols(active)
        n = int(fit_rows.sum())
        sky = math.sqrt(float(np.sum(r[fit_rows] ** 2)) / n)
        sig = self.sigmas(jac[np.repeat(fit_rows, 2)], cols, sky)
        pieces, cos = [], []
        for f_rows, v_rows in self.scheme.splits:
            if np.array_equal(f_rows, fit_rows):
                r_fold = r
            else:
                _, r_fold_flat, _, ok = self.solve(active, f_rows, y)
                r_fold = r_fold_flat.reshape(-1, 2)
                converged = converged and ok
            pieces.append(r_fold[v_rows])
            if self.cos2 is not None:
                cos.append(self.cos2[v_rows])
        rms_out = axis_rms(np.concatenate(pieces), np.concatenate(cos) if cos else None).total
        return _State(active, y, r, jac, sig, self.total(r, fit_rows), rms_out, sky, int(cols.size), converged)

    def screen(self, state: _State, term: int) -> tuple[float, float, bool]:
        """``(|value/sigma|, out-of-sample RMS, degenerate)`` with ``term`` added: one
        Gauss-Newton step from the current fit, with its Jacobian, for the in-sample fit
        and for every fold."""
        fit_rows = self.scheme.fit_rows
        active = state.active | {term}
        cols = self.cols(active)
        new = self.columns[term]
        r0 = state.r.reshape(-1)
        jac = state.jac
        rr = np.repeat(fit_rows, 2)
        delta, *_ = np.linalg.lstsq(jac[np.ix_(rr, cols)], -r0[rr], rcond=DEGENERATE_RCOND)
        r_new = (r0 + jac[:, cols] @ delta).reshape(-1, 2)
        n = int(fit_rows.sum())
        sky = math.sqrt(float(np.sum(r_new[fit_rows] ** 2)) / n)
        sig = self.sigmas(jac[rr], cols, sky)
        y_new = state.y.copy()
        y_new[cols] += delta
        if np.any(~np.isfinite(sig[new])):
            return 0.0, math.inf, True
        z = float(np.max(np.abs(y_new[new] / sig[new])))
        pieces, cos = [], []
        for f_rows, v_rows in self.scheme.splits:
            if np.array_equal(f_rows, fit_rows):
                r_fold = r_new
            else:
                fr = np.repeat(f_rows, 2)
                d_fold, *_ = np.linalg.lstsq(jac[np.ix_(fr, cols)], -r0[fr], rcond=DEGENERATE_RCOND)
                r_fold = (r0 + jac[:, cols] @ d_fold).reshape(-1, 2)
            pieces.append(r_fold[v_rows])
            if self.cos2 is not None:
                cos.append(self.cos2[v_rows])
        rms_out = axis_rms(np.concatenate(pieces), np.concatenate(cos) if cos else None).total
        return z, rms_out, False

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
    obs64 = jax.tree.map(lambda x: jnp.asarray(x, jnp.float64), scheme.obs)
    r_start = np.asarray(eqx.filter_jit(residuals)(start, obs64)).reshape(-1)
    r_super, _ = builder.lin(builder.y_start)
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
    fitted = superset.with_values(jnp.asarray(state.y), "free")
    model = start.restructured(terms=[fitted.terms[i] for i in final_terms])
    cols = builder.cols(state.active)
    free = superset.free_parameters
    rules = (
        f"add: |value/sigma| >= {add_threshold:g} and lower out-of-sample RMS; drop: |value/sigma| < {drop_threshold:g}; "
        f"{scheme.description}"
    )
    return ModelBuild(
        model=model,
        path=tuple(path),
        stopped=stopped,
        names=tuple(free[c].name for c in cols),
        values=state.y[cols],
        sigmas=state.sigmas[cols],
        units=tuple(free[c].unit for c in cols),
        rules=rules,
        skipped=tuple(skipped),
    )

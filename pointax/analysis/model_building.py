"""Automatic model building in the spirit of TPOINT's ``FAUTO`` (:func:`build_model`):
grow a model term by term from candidates, keeping terms that are significant and
predict unseen stars better, dropping those that are not, and record the path
(:class:`ModelBuild`).

Its fits, and the screening of the candidates, are
:mod:`pointax.analysis.building_fits`'s. The figures are those of
:mod:`pointax.fitting.statistics`; the out-of-sample schemes those of
:mod:`pointax.analysis.folds`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from typing import Any

import equinox as eqx
import jax
import numpy as np

from ..core.precision import float64
from ..fitting.residuals import residuals
from ..core.model import Model
from ..core.observations import Observations
from ..fitting.progress import progress_bar
from ..core.term import Term
from ..core.units import ARCSEC, UNITS
from .building_fits import Builder, compiled_program
from .families import family_model
from .folds import evaluation_scheme, integer_at_least
from ..fitting.result import finite_or_none
from .per_axis import resolve_per_axis, second_axis_cosines

__all__ = ["BuildStep", "ModelBuild", "build_model"]


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
    form: str = "rigorous",
    progress: bool = False,
) -> ModelBuild:
    """Build a model automatically by cross-validation: add candidate terms that are
    significant and predict unseen stars better, drop terms that are not significant,
    and record the path.

    How it differs from :func:`pointax.analysis.fauto` (TPOINT-style FAUTO, what the
    ``FAUTO`` command runs): ``fauto`` starts from the mount's basic physical terms and
    keeps them, tries the further physical terms before any harmonic, judges a term in
    sample (``|value / sigma| >= 2`` and a lower Popn SD) and never tries a candidate
    nearly collinear with a term in the model; ``build_model`` starts from the model
    given, treats every candidate alike, requires a lower out-of-sample RMS (k-fold or
    holdout) and a higher significance to add (3 by default), and has no collinearity
    screen beyond rank deficiency (``FAUTO CV`` in a session, ``pointax.build_model``).

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
            standard error when it is a terminal (:func:`pointax.fitting.progress.progress_bar`).

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
    builder = Builder(superset, scheme, cos2)
    n_start = len(start.terms)
    candidate_ids = [i for i in range(n_start, len(superset.terms)) if builder.columns.get(i)]
    for i in range(n_start, len(superset.terms)):
        if not builder.columns.get(i):
            skipped.append(f"{superset.terms[i].name} (no free parameters)")

    # Candidates at 0 must leave the pointing as it is.
    start_arrays, start_static = eqx.partition(start, eqx.is_array)
    r_start = np.asarray(compiled_program(residuals, start_static, builder.obs)(start_arrays))
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

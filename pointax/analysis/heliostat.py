"""Heliostat calibration from PAINT samples: robust fit, outlier flags, leave-one-out
(optional; skipped, with a note, where the samples are too few for it).

    run = px.io.read_paint("../shared/data/paint/AA39")
    cal = px.calibrate_heliostat(run)
    print(cal.report())

The angular errors reported are between the measured mirror normal (the unit bisector
of the sun and focal-spot directions) and the model's normal, in mrad; the reflected
ray errs twice as much.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Iterable
from typing import Any

import numpy as np

from ..core.precision import float64
from ..fitting.residuals import residuals
from ..fitting.result import FitResult
from ..fitting.solo import fit
from ..io.paint import PaintRun, read_paint
from ..core.model import Model
from ..core.mounts import HeliostatMount
from ..core.observations import Observations
from ..core.rotations import offset_angle
from ..terms.heliostat_terms import HELIOSTAT_DEFAULT, heliostat
from ..fitting.cross_validation import leave_one_out

__all__ = ["HeliostatCalibration", "calibrate_heliostat", "heliostat_model", "loo_shortfall"]

MRAD = 1e-3


def heliostat_model(run: PaintRun, terms: str | Iterable[str] = HELIOSTAT_DEFAULT) -> Model:
    """The nominal model of a PAINT heliostat: its actuator geometry and the ``terms``
    (names from :data:`pointax.terms.heliostat_terms.HELIOSTAT_TERMS`, all starting at 0)."""
    return Model(HeliostatMount.from_paint(run.heliostat), heliostat(terms))


@dataclasses.dataclass(frozen=True)
class HeliostatCalibration:
    """Errors of every sample before calibration, after it, and left out of it.

    Attributes:
        sample_ids: the samples, in file order.
        result: the (robust) fit of all samples.
        before: ``(n,)`` angle between measured and nominal normal, radians.
        after: ``(n,)`` the same for the fitted model.
        loo: ``(n,)`` the same for fits that left the sample out (NaN where no
            leave-one-out ran: see ``loo_note``).
        outliers: ``(n,)`` samples the robust fit flagged (not used for its values).
        loo_converged: ``(n,)`` whether each leave-one-out fit converged (True where
            none ran).
        loo_note: why leave-one-out did not run (``None`` when it ran).
    """

    sample_ids: tuple[str, ...]
    result: FitResult
    before: np.ndarray
    after: np.ndarray
    loo: np.ndarray
    outliers: np.ndarray
    loo_converged: np.ndarray
    loo_note: str | None = None

    @property
    def loo_ran(self) -> bool:
        """Whether leave-one-out fits were made."""
        return self.loo_note is None

    def rms(self, which: str, include_outliers: bool = False) -> float:
        """RMS of ``which`` ('before', 'after' or 'loo'), radians, over the unflagged
        samples (or all of them). "Unflagged" means kept by the fit of *all* samples;
        each leave-one-out fit re-detects outliers without its own sample, so a
        sample's leave-one-out error never depends on itself, but the choice of which
        samples enter this RMS does."""
        errors = np.asarray(getattr(self, which))
        keep = np.ones(errors.shape, bool) if include_outliers else ~self.outliers
        return float(np.sqrt(np.mean(errors[keep] ** 2))) if keep.any() else math.nan

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (the keys of ``pointax fit DIR --format paint --json``)."""

        def number(x):
            x = float(x)
            return x if math.isfinite(x) else None

        fit_dict = self.result.to_dict()
        kinds = ("before", "after", "loo")
        return {
            "n_obs": len(self.sample_ids),
            "n_used": int(self.result.n_obs),
            "samples": list(self.sample_ids),
            "params": [
                {"name": row["name"], "value": number(row["value"]), "sigma": number(row["sigma"]), "unit": row["unit"]}
                for row in self.result.table()
            ],
            "error_mrad": {
                **{k: [number(e / MRAD) for e in getattr(self, k)] for k in kinds},
                "rms": {k: number(self.rms(k) / MRAD) for k in kinds},
                "rms_all": {k: number(self.rms(k, include_outliers=True) / MRAD) for k in kinds},
            },
            "outliers": [self.sample_ids[i] for i in np.flatnonzero(self.outliers)],
            "converged": fit_dict["converged"],
            "loo_converged": bool(np.all(self.loo_converged)),
            "loo_skipped": self.loo_note,
            "iterations": fit_dict["iterations"],
            "message": fit_dict["message"],
            "loss": fit_dict["loss"],
            "correlation": fit_dict["correlation"],
            "warnings": self.warnings(),
        }

    def warnings(self) -> list[str]:
        """The fit's warnings plus leave-one-out fits that did not converge, or why
        leave-one-out was skipped."""
        out = list(self.result.warnings())
        if self.loo_note is not None:
            out.append(self.loo_note)
        failed = [self.sample_ids[i] for i in np.flatnonzero(~self.loo_converged)]
        if failed:
            out.append(f"leave-one-out fits without sample(s) {', '.join(failed)} did not converge")
        return out

    def report(self) -> str:
        """The fit report and a per-sample table of errors in mrad (``-`` in the loo
        column, and a note below, where no leave-one-out ran)."""

        def mrad(x: float) -> str:
            return f"{x / MRAD:7.2f}" if math.isfinite(x) else f"{'-':>7s}"

        width = max(8, *(len(s) for s in self.sample_ids))
        lines = [self.result.report(), "", f"  {'sample':<{width}s}  before    after      loo   (mrad, normal)"]
        for k, sid in enumerate(self.sample_ids):
            flag = "  outlier" if self.outliers[k] else ""
            lines.append(f"  {sid:<{width}s} {mrad(self.before[k])}  {mrad(self.after[k])}  {mrad(self.loo[k])}{flag}")
        n_kept = int(np.sum(~self.outliers))
        lines.append(
            f"  {'RMS':<{width}s} {mrad(self.rms('before'))}  {mrad(self.rms('after'))}  "
            f"{mrad(self.rms('loo'))}   ({n_kept} unflagged samples)"
        )
        lines.append(
            f"  {'RMS all':<{width}s} {mrad(self.rms('before', True))}  {mrad(self.rms('after', True))}  "
            f"{mrad(self.rms('loo', True))}"
        )
        if self.loo_note is not None:
            lines.append(f"  Note: {self.loo_note}.")
        return "\n".join(lines)


def _errors(model: Model, obs: Observations) -> np.ndarray:
    """Angle between observed and modelled direction of every observation, radians."""
    every = obs.with_weight(None)  # weights aside
    return np.asarray(offset_angle(residuals(model, every)))


@float64
def calibrate_heliostat(
    run: PaintRun | str | os.PathLike,
    terms: str | Iterable[str] = HELIOSTAT_DEFAULT,
    *,
    loss: str = "cauchy",
    reject: float = 3.0,
    solver: str = "lm",
    max_steps: int = 256,
    fixed: Iterable[str] = (),
    focal_spot: str = "HeliOS",
    progress: bool = False,
    loo: bool | None = None,
) -> HeliostatCalibration:
    """Calibrate one heliostat on its PAINT samples and cross-check it.

    Args:
        run: a :class:`pointax.io.PaintRun` or the heliostat's folder.
        terms: parameters to fit (default: the four axis tilts t1n t1u t2e t2n; adding
            d1 beside t2e makes the fit report them as indistinguishable).
        loss: robust loss (:data:`pointax.fitting.LOSSES`); 'linear' for plain least squares.
        reject: outlier threshold in robust standard deviations.
        solver: least-squares solver name.
        max_steps: solver step limit of each fit.
        fixed: parameters held at 0 (their nominal value).
        focal_spot: focal-spot method when ``run`` is a folder.
        progress: a progress bar of the leave-one-out folds on standard error when it
            is a terminal.
        loo: leave-one-out fits: ``None`` (default) makes them where the samples
            allow (:func:`loo_shortfall`) and otherwise skips them with a note
            (``HeliostatCalibration.loo_note``, in the report and the warnings);
            ``True`` requires them (ValueError where too few samples); ``False``
            skips them.

    Returns:
        :class:`HeliostatCalibration`: before, after and leave-one-out errors of every
        sample, and the fit.

    Raises:
        ValueError: ``loo=True`` with too few samples (saying how many are needed).
    """
    if not isinstance(run, PaintRun):
        run = read_paint(run, focal_spot=focal_spot)
    model = heliostat_model(run, terms).fix(*fixed)
    obs = run.observations
    options = {"loss": loss, "reject": reject, "solver": solver, "max_steps": max_steps}
    if loo not in (None, True, False):
        raise ValueError(f"calibrate_heliostat: loo is {loo!r}, expected None (where possible), True or False")
    shortfall = loo_shortfall(model, obs)
    if loo is True and shortfall is not None:
        raise ValueError(f"{run.directory}: {shortfall}")
    result = fit(model, obs, **options)
    n = len(run.sample_ids)
    if loo is False or shortfall is not None:
        note = "leave-one-out not asked for" if loo is False else f"leave-one-out skipped: {shortfall}"
        loo_errors, loo_converged = np.full(n, np.nan), np.ones(n, bool)
    else:
        note = None
        folds = leave_one_out(model, obs, **options, progress=progress)
        loo_errors, loo_converged = np.asarray(folds.errors), np.asarray(folds.converged)
    return HeliostatCalibration(
        sample_ids=tuple(run.sample_ids),
        result=result,
        before=_errors(model, obs),
        after=_errors(result.model, obs),
        loo=loo_errors,
        outliers=np.asarray(result.outliers),
        loo_converged=loo_converged,
        loo_note=note,
    )


def loo_shortfall(model: Model, obs: Observations) -> str | None:
    """Why a leave-one-out of ``model`` on ``obs`` cannot be made, or None when it can:
    each fold keeps all samples with positive weight but one, and needs more residuals
    (two per sample) than free parameters, so that its fit leaves a sigma to estimate
    (the condition :func:`pointax.fitting.cross_validation.leave_one_out` enforces)."""
    n_used = int(np.sum(np.asarray(obs.weight) > 0)) if obs.weight is not None else len(obs.encoder)
    n_free = len(model.free_parameters)
    need = n_free // 2 + 2  # smallest n with 2 (n - 1) > n_free
    if n_used >= max(2, need):
        return None
    return (
        f"{n_used} sample(s) with positive weight, each fold would keep {max(n_used - 1, 0)} "
        f"({2 * max(n_used - 1, 0)} residuals) for {n_free} free parameter(s); it needs at least {max(2, need)} samples"
    )

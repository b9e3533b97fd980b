"""Fair comparison of pointing-model families (:func:`compare`), laid out like the
level-mount paper's Table 3 (:class:`Comparison`).

:func:`compare` fits several model families to the same observations and reports, per
family, what a pointing engineer needs to choose between them: in-sample and
out-of-sample per-axis RMS (eqs 21-23), TPOINT's Sky RMS, AIC and BIC and the
significance of each parameter (:mod:`pointax.fitting.statistics` defines them all), with
a holdout or k-fold scheme (:mod:`pointax.analysis.folds`). Families are
:class:`pointax.Model` objects or names (:mod:`pointax.analysis.families`).

Every fit is :func:`pointax.fit` (held-back stars get weight 0, so a family compiles
once for all its fits) and every prediction is :func:`pointax.residuals` of the fitted
model on the held-back observations.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from ..core.model import Model
from ..core.observations import Observations
from ..core.precision import float64
from ..core.units import ARCSEC
from ..fitting.progress import progress_bar
from ..fitting.residuals import residuals
from ..fitting.result import FitResult, finite_or_none
from ..fitting.solo import fit
from ..fitting.statistics import AxisRMS, axis_rms, information_criteria, significance, sky_rms
from .families import family_model
from .folds import evaluation_scheme
from .per_axis import resolve_per_axis, second_axis_cosines

__all__ = ["BEFORE", "FamilyStats", "Comparison", "compare"]

BEFORE = "before correction"
"""Label of the row with no terms fitted."""


def _families(families, obs: Observations, naming: str, form: str, mount=None) -> dict[str, Model]:
    """``compare``'s families as ``{label: model}``, names resolved on the observations'
    mount (:func:`family_model`), each checked to fit these observations."""
    if isinstance(families, Mapping):
        items = list(families.items())
    elif isinstance(families, str):
        items = [(families, families)]
    else:
        items = [(f, f) if isinstance(f, str) else (None, f) for f in families]
        if any(label is None for label, _ in items):
            raise TypeError("families must map labels to models (a dict), or be a sequence of family names")
    if not items:
        raise ValueError("no model families to compare")
    out: dict[str, Model] = {}
    for label, family in items:
        if not isinstance(label, str) or not label or label == BEFORE:
            raise ValueError(f"bad family label {label!r}: use a non-empty string other than {BEFORE!r}")
        if isinstance(family, str) or (isinstance(family, Sequence) and all(isinstance(t, str) for t in family)):
            model = family_model(family, obs if mount is None else mount, naming=naming, form=form)
        elif isinstance(family, Model):
            model = family
        else:
            raise TypeError(f"family {label!r}: expected a pointax.Model or a family name, got {type(family).__name__}")
        convention = model.mount.convention
        if convention is not None and obs.convention is not None and convention != obs.convention:
            raise ValueError(
                f"family {label!r}: its mount expects readings in the {convention!r} convention, "
                f"the observations are {obs.convention!r}"
            )
        if not model.free_parameters:
            raise ValueError(f"family {label!r} has no free parameters to fit")
        out[label] = model
    mounts = {type(m.mount) for m in out.values()}
    if len(mounts) > 1:
        raise ValueError(f"all families must share one mount kind, got {sorted(t.__name__ for t in mounts)}")
    return out


@dataclasses.dataclass(frozen=True)
class FamilyStats:
    """One row of a :class:`Comparison` (radians inside; :meth:`to_dict` in arcsec).

    Attributes:
        label: the family's label.
        model: the model fitted on the in-sample stars (for the before-correction row,
            the mount with no terms).
        result: its :class:`pointax.FitResult` (``None`` for the before-correction row).
        n_params: number of fitted parameters.
        in_sample: :class:`AxisRMS` of the in-sample residuals (eqs 21-23).
        sky_rms: TPOINT's Sky RMS of the in-sample fit, radians.
        out_of_sample: :class:`AxisRMS` of the out-of-sample predictions, or ``None``.
        log_likelihood, aic, bic: of the in-sample fit
            (:func:`pointax.fitting.statistics.information_criteria`).
        significance: ``value / sigma`` of each fitted parameter, by name.
        warnings: the fit's warnings (:meth:`pointax.FitResult.warnings`: parameters the
            data cannot tell apart, strong correlations, non-convergence), and the
            out-of-sample fits' non-convergence.
        converged: whether the in-sample fit and every out-of-sample fit converged.
    """

    label: str
    model: Model
    result: FitResult | None
    n_params: int
    in_sample: AxisRMS
    sky_rms: float
    out_of_sample: AxisRMS | None
    log_likelihood: float
    aic: float
    bic: float
    significance: dict[str, float]
    warnings: tuple[str, ...]
    converged: bool

    def weak(self, threshold: float = 2.0) -> list[str]:
        """Parameters with ``|value / sigma|`` below ``threshold``."""
        return [n for n, z in self.significance.items() if abs(z) < threshold]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (arcsec; ``null`` for what is not finite or not computed)."""
        terms = []
        if self.result is not None:
            for row in self.result.table():
                terms.append(
                    {
                        "name": row["name"],
                        "value": finite_or_none(row["value"]),
                        "sigma": finite_or_none(row["sigma"]),
                        "unit": row["unit"],
                        "significance": finite_or_none(self.significance[row["name"]]),
                    }
                )
        return {
            "label": self.label,
            "n_params": self.n_params,
            "in_sample": _rms_dict(self.in_sample),
            "sky_rms": finite_or_none(self.sky_rms / ARCSEC),
            "out_of_sample": None if self.out_of_sample is None else _rms_dict(self.out_of_sample),
            "log_likelihood": finite_or_none(self.log_likelihood),
            "aic": finite_or_none(self.aic),
            "bic": finite_or_none(self.bic),
            "converged": self.converged,
            "terms": terms,
            "warnings": list(self.warnings),
        }


def _rms_dict(r: AxisRMS) -> dict[str, Any]:
    return {k: (finite_or_none(v) if k != "n" else v) for k, v in r.arcsec().items()}


@dataclasses.dataclass(frozen=True)
class Comparison:
    """The outcome of :func:`compare`: one :class:`FamilyStats` per family, the first
    row the observations before correction (no terms).

    Attributes:
        rows: the rows, before correction first, then the families in the order given.
        scheme: 'none', 'validation set', 'split', 'holdout' or 'k-fold'.
        description: the scheme in words (stars fitted, validated, seed).
        n_fit: stars in the in-sample fit.
        n_validation: out-of-sample predictions (0 without a scheme).
        per_axis: 'angle' or 'sky' (:data:`pointax.analysis.PER_AXIS`).
        axis_names: the mount's names of its axes, e.g. ('L', 'B').
        n_dropped: observations left out because their weight was 0.
    """

    rows: tuple[FamilyStats, ...]
    scheme: str
    description: str
    n_fit: int
    n_validation: int
    per_axis: str
    axis_names: tuple[str, str]
    n_dropped: int = 0

    def __getitem__(self, label: str) -> FamilyStats:
        for row in self.rows:
            if row.label == label:
                return row
        raise KeyError(f"no family {label!r}; the comparison has {[r.label for r in self.rows]}")

    @property
    def labels(self) -> list[str]:
        return [r.label for r in self.rows]

    def _axis_headers(self) -> tuple[str, str]:
        a1, a2 = (a[:1].upper() + a[1:] for a in self.axis_names)  # L, B; Az, El; Ha, Dec
        if self.per_axis == "sky":
            return f"d{a1} cos {a2}", f"d{a2}"
        return f"d{a1}", f"d{a2}"

    def table(self, *, notes: bool = True) -> str:
        """The comparison laid out like the level-mount paper's Table 3, one row per
        family (arcsec): in-sample per-axis and total RMS (eqs 21-23), the same out of
        sample, TPOINT's Sky RMS, number of parameters, AIC and BIC; then each family's
        warnings and its parameters with ``|value/sigma| < 2``."""
        h1, h2 = self._axis_headers()
        width = max(18, *(len(r.label) for r in self.rows))
        lines = [
            f"Model comparison: {self.description}.",
            "RMS in arcsec as the level-mount paper's eqs 21-23 (n - 1); per axis: "
            + ("axis-angle residuals" if self.per_axis == "angle" else "offsets on the sky")
            + "; Sky RMS as TPOINT's.",
        ]
        if self.n_dropped:
            lines.append(f"{self.n_dropped} observation(s) with weight 0 left out.")
        col = max(9, len(h1) + 1, len(h2) + 1)
        top = (
            f"{'':<{width}s} | {'in-sample':^{3 * col + 2}s} | {'out-of-sample':^{3 * col + 2}s} |"
            f" {'Sky RMS':>8s} {'params':>6s} {'AIC':>9s} {'BIC':>9s}"
        )
        head = (
            f"{'family':<{width}s} | {h1:>{col}s} {h2:>{col}s} {'total':>{col}s} | "
            f"{h1:>{col}s} {h2:>{col}s} {'total':>{col}s} | {'':>8s} {'':>6s} {'':>9s} {'':>9s}"
        )
        lines += ["", top, head, "-" * len(head)]

        def cells(r: AxisRMS | None) -> str:
            if r is None:
                return " ".join(f"{'-':>{col}s}" for _ in range(3))
            return " ".join(
                f"{v / ARCSEC:{col}.2f}" if math.isfinite(v) else f"{'nan':>{col}s}"
                for v in (r.axis1, r.axis2, r.total)
            )

        for row in self.rows:
            lines.append(
                f"{row.label:<{width}s} | {cells(row.in_sample)} | {cells(row.out_of_sample)} | "
                f"{row.sky_rms / ARCSEC:8.2f} {row.n_params:6d} {row.aic:9.1f} {row.bic:9.1f}"
            )
        if notes:
            extra = []
            for row in self.rows[1:]:
                extra.extend(f"  {row.label}: WARNING: {w}" for w in row.warnings)
                weak = row.weak()
                if weak:
                    extra.append(f"  {row.label}: |value/sigma| < 2: {', '.join(weak)}")
            if extra:
                lines += ["", "Notes:", *extra]
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: the scheme and one entry per row (arcsec; see :meth:`FamilyStats.to_dict`)."""
        return {
            "scheme": self.scheme,
            "description": self.description,
            "n_fit": self.n_fit,
            "n_validation": self.n_validation,
            "per_axis": self.per_axis,
            "axes": list(self._axis_headers()),
            "unit": "arcsec",
            "rms_definition": "sqrt(sum d^2 / (n - 1)) per axis, total = hypot (level-mount paper eqs 21-23)",
            "likelihood": "iid Gaussian on the 2n sky residual components (arcsec), ML variance RSS/(2n); k = params + 1",
            "n_dropped": self.n_dropped,
            "families": [r.to_dict() for r in self.rows],
        }


def _row(label, model, result, n_params, r_in, r_out, cos_in, cos_out, warnings_, converged) -> FamilyStats:
    ins = axis_rms(r_in, cos_in)
    out = None if r_out is None else axis_rms(r_out, cos_out)
    log_l, aic, bic = information_criteria(r_in, n_params)
    if result is not None:
        sky = float(result.sky_rms)
        z = dict(zip(result.names, significance(result.values, result.sigmas).tolist()))
    else:
        sky = float(sky_rms(jnp.asarray(r_in), jnp.ones(len(r_in), bool)))
        z = {}
    return FamilyStats(label, model, result, n_params, ins, sky, out, log_l, aic, bic, z, tuple(warnings_), converged)


@float64
def compare(
    families: Mapping[str, Model | str] | Sequence[str] | str,
    observations,
    *,
    holdout=None,
    folds: int | None = None,
    seed: int = 0,
    per_axis: str | None = None,
    naming: str = "tpoint",
    form: str = "rigorous",
    solver: str = "lm",
    max_steps: int = 256,
    progress: bool = False,
    mount=None,
) -> Comparison:
    """Fit several model families to the same stars and compare them fairly.

    Args:
        families: ``{label: model}`` with :class:`pointax.Model` values or family names
            (:func:`family_model`), or a sequence of family names (labels = names).
        observations: :class:`pointax.Observations` or a run with ``.observations``
            (``None`` with ``holdout=(fit_obs, validation_obs)``). Rows with weight 0
            are left out (and counted); the others must have equal weights.
        holdout: out-of-sample scheme: validation observations, a fraction to hold back,
            ``(fit_rows, validation_rows)`` or ``(fit_obs, validation_obs)``
            (:mod:`pointax.analysis.folds`).
        folds: k-fold cross-validation instead (k >= 2).
        seed: seed of the random holdout or fold assignment.
        per_axis: 'angle' (the paper's ``DL``) or 'sky' (``dL cos B``, TPOINT's ``dA cos
            E``); default 'angle' on an X-Y mount (the paper's eqs 21-23), 'sky' on
            others (the first-axis angle residual grows as ``sec E`` towards the zenith).
        naming, form: how family names resolve (:func:`family_model`).
        mount: the mount family names resolve on (default: the observations'; an
            equatorial run read by :func:`pointax.io.read_tpoint` gives its latitude).
        solver, max_steps: passed to :func:`pointax.fit`.
        progress: show a progress bar of the fits (families and folds) on standard
            error when it is a terminal (:func:`pointax.fitting.progress.progress_bar`).

    Returns:
        A :class:`Comparison`: ``.table()`` prints it like the paper's Table 3,
        ``.to_dict()`` gives JSON.

    Raises:
        ValueError, TypeError: bad families, observations or scheme (the message says which).
    """
    if mount is None and getattr(observations, "mount", None) == "equatorial":
        mount = observations  # family names resolve on its latitude
    scheme = evaluation_scheme(observations, holdout, folds, seed)
    models = _families(families, scheme.obs, naming, form, mount)
    mount = next(iter(models.values())).mount
    per_axis = resolve_per_axis(mount, per_axis)
    cos2 = second_axis_cosines(mount, scheme.obs, per_axis)
    obs = scheme.obs
    fit_rows = scheme.fit_rows
    obs64 = jax.tree.map(lambda x: jnp.asarray(x, jnp.float64), obs)

    def cos(mask):
        return None if cos2 is None else cos2[mask]

    def predict(model: Model, rows: np.ndarray) -> np.ndarray:
        """``px.residuals(model, the observations of rows)``: the rows are picked by
        weight, so every set of rows shares one compiled evaluation per model."""
        chosen = obs64.with_weight(jnp.asarray(rows, jnp.float64))
        return np.asarray(residuals(model, chosen))[rows]

    out_rows = np.zeros(len(obs), bool)
    for _, v_rows in scheme.splits:
        out_rows |= v_rows
    rows: list[FamilyStats] = []
    # Before correction: the mount alone, nothing fitted.
    bare = Model(mount, ())
    r_bare = predict(bare, np.ones(len(obs), bool))
    if scheme.splits:
        r_out, cos_out = r_bare[np.flatnonzero(out_rows)], cos(out_rows)
    else:
        r_out, cos_out = None, None
    rows.append(_row(BEFORE, bare, None, 0, r_bare[fit_rows], r_out, cos(fit_rows), cos_out, (), True))

    extra_fits = sum(1 for f_rows, _ in scheme.splits if not np.array_equal(f_rows, fit_rows))
    bar = progress_bar(len(models) * (1 + extra_fits), "compare", "fit", enabled=progress)
    for label, model in models.items():
        bar.set_description(f"compare {label}")
        result = fit(model, obs, weights=fit_rows.astype(np.float64), solver=solver, max_steps=max_steps)
        bar.update()
        warnings_ = list(result.warnings())
        converged = bool(result.converged)
        r_in = np.asarray(result.residuals)[fit_rows]
        r_out, cos_out = None, None
        if scheme.splits:
            # Each held-back star is predicted by the model fitted without it; the
            # splits' validation rows are disjoint, so the predictions fill r_all.
            r_all = np.zeros((len(obs), 2))
            for k, (f_rows, v_rows) in enumerate(scheme.splits):
                if np.array_equal(f_rows, fit_rows):
                    fitted = result.model
                else:
                    fold = fit(model, obs, weights=f_rows.astype(np.float64), solver=solver, max_steps=max_steps)
                    bar.update()
                    fitted = fold.model
                    if not bool(fold.converged):
                        converged = False
                        warnings_.append(f"the fit of fold {k + 1} did not converge: {fold.message}")
                r_all[v_rows] = predict(fitted, v_rows)
            r_out, cos_out = r_all[out_rows], cos(out_rows)
        n_params = len(result.names)
        rows.append(
            _row(label, result.model, result, n_params, r_in, r_out, cos(fit_rows), cos_out, warnings_, converged)
        )

    bar.close()
    return Comparison(
        rows=tuple(rows),
        scheme=scheme.kind,
        description=scheme.description,
        n_fit=scheme.n_fit,
        n_validation=scheme.n_validation,
        per_axis=per_axis,
        axis_names=tuple(type(mount).axis_names),
        n_dropped=scheme.n_dropped,
    )

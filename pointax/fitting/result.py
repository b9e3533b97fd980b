"""The outcome of a fit: values, sigmas, TPOINT's statistics, report and JSON summary."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from ..core.model import Model
from ..core.units import ARCSEC, UNITS
from .options import SOLVER_NAMES

__all__ = [
    "FitResult",
    "SUCCESSFUL",
    "solver_status",
    "STATUS_NAMES",
    "CORRELATION_WARNING",
    "ABSURD_SKY_RMS_DEG",
    "too_few_residuals",
    "too_little_data",
    "residual_unit",
    "finite_or_none",
]

CORRELATION_WARNING = 0.95
"""Reports warn about parameter pairs whose |correlation| exceeds this."""

ABSURD_SKY_RMS_DEG = 1.0
"""Reports warn when the Sky RMS after a fit exceeds this many degrees (3600"): real
telescopes fit to arcseconds, sun trackers and heliostats to a few mrad (0.1 deg)."""


STANDOUT_SIGMAS = 5.0
""":meth:`FitResult.standout_rows`: a residual beyond this many robust standard
deviations stands out of the rest."""


SUCCESSFUL = 0
""":attr:`FitResult.status` of a solver that met its tolerances (optimistix's
``RESULTS.successful``)."""


STATUS_NAMES = (
    "successful",
    "max_steps_reached",
    "singular",
    "breakdown",
    "stagnation",
    "conlim",
    "nonfinite_input",
    "nonlinear_max_steps_reached",
    "nonlinear_divergence",
    "nonfinite",
)
"""The ``optx.RESULTS`` items :attr:`FitResult.status` codes: the code is the index here
(another result: ``len(STATUS_NAMES)``)."""


def solver_status(result) -> Int[Array, ""]:
    """optimistix's result (an ``optx.RESULTS`` item, or the name of one) as the integer
    :attr:`FitResult.status` holds (:data:`STATUS_NAMES`): an array, so that a stored
    fit's result rebuilds without importing optimistix (:mod:`pointax.fitting.programs`).
    Compared through the items' public ``==``, so it works under jit and vmap."""
    if isinstance(result, str):
        return jnp.asarray(STATUS_NAMES.index(result), jnp.int32)
    import optimistix as optx

    code = jnp.asarray(len(STATUS_NAMES), jnp.int32)
    for index in reversed(range(len(STATUS_NAMES))):
        code = jnp.where(result == getattr(optx.RESULTS, STATUS_NAMES[index]), index, code)
    return code


def residual_unit(units) -> str:
    """The unit a fit's residuals, Sky RMS and Popn SD are shown in, from its parameters'
    display ``units``: 'mrad' when one is in mrad (heliostat engineers think in mrad),
    'deg' when every one is in degrees (sun trackers, turntables), else 'arcsec'
    (telescopes)."""
    units = tuple(units)
    if "mrad" in units:
        return "mrad"
    return "deg" if units and all(u == "deg" for u in units) else "arcsec"


def finite_or_none(x) -> float | None:
    """``float(x)``, or None where it is not finite (JSON has no inf or NaN)."""
    x = float(x)
    return x if math.isfinite(x) else None


def too_few_residuals(n_used, n_free: int):
    """Whether ``n_used`` observations (an int or an array of them, one per site) give no
    more residuals, two per observation, than ``n_free`` free parameters (never with none)."""
    return (2 * np.asarray(n_used) <= n_free) & (n_free > 0)


def too_little_data(n_used: int, params) -> str:
    """Why ``n_used`` observations cannot fit the free parameters ``params``
    (:func:`too_few_residuals`), or '' when they can."""
    n_free, n_residuals = len(params), 2 * n_used
    if not too_few_residuals(n_used, n_free):
        return ""
    return (
        f"{n_used} observation(s) give {n_residuals} residuals for {n_free} free parameters "
        f"({', '.join(p.name for p in params)}): the fit would pass through every point and "
        f"no sigma could be estimated (each would be 0); give more than {n_free // 2} observations or fix "
        "parameters"
    )


PER_ROW_FIELDS = ("residuals", "used", "loo_residuals", "outliers")
"""The fields of a :class:`pointax.FitResult` with one entry per observation row."""


def first_rows(result: "FitResult", n: int) -> "FitResult":
    """``result`` with its per-row fields (:data:`PER_ROW_FIELDS`) cut to the first ``n``
    rows: a fit of padded rows, or one site of a batch, without the padding."""
    return dataclasses.replace(result, **{name: getattr(result, name)[:n] for name in PER_ROW_FIELDS})


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
        loo_residuals: ``(N, 2)`` leave-one-out residuals, radians: for a used star the
            residual it has in the fit without it, both components left out together,
            from the hat matrix of the weighted linearised problem at the solution
            (``e_i = (I - H_ii)^-1 r_i``, no refit: exact for the linear problem,
            :func:`pointax.fitting.statistics.leave_one_out`); for a star not used its
            residual. NaN where the fit gives no Jacobian (batched fast path).
        loo_rms: leave-one-out RMS over the used stars, radians (weighted as the Sky
            RMS): the out-of-sample figure beside Sky RMS and Popn SD.
        iterations: solver steps taken.
        converged: whether the solver met its tolerances with finite residuals.
        status: optimistix's result code, an integer (:data:`SUCCESSFUL`: met its
            tolerances); :attr:`result` is the ``optx.RESULTS`` item, :attr:`message`
            the reason in words.
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
    loo_residuals: Float[Array, "n 2"]
    loo_rms: Float[Array, ""]
    iterations: Int[Array, ""]
    converged: Bool[Array, ""]
    status: Int[Array, ""]
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

    def __getattribute__(self, name: str):
        # Methods as plain bound methods: equinox wraps every method it hands out in a
        # BoundMethod module (a pytree, for jit), which costs more than the method itself
        # when a network's report calls them for thousands of sites; a result's methods
        # are reports on the host, never passed to jit.
        return object.__getattribute__(self, name)

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
        if np.ndim(self.n_obs) == 0:
            too_little = too_little_data(int(self.n_obs), self.model.free_parameters)
            if too_little:
                return too_little
        if not bool(jnp.all(jnp.isfinite(self.residuals))):
            return "residuals are not finite (NaN or inf in the data or the model)"
        if bool(np.all(np.asarray(self.status) == SUCCESSFUL)):
            return "the solver stopped with non-finite values"
        import optimistix as optx

        return optx.RESULTS[self.result] or "the solver did not converge"

    @property
    def result(self):
        """optimistix's result of a single fit, as an ``optx.RESULTS`` item (imports
        optimistix); a batched result has one per site: :attr:`status`."""
        import optimistix as optx

        code = int(np.asarray(self.status).reshape(-1)[0]) if np.size(self.status) == 1 else None
        if code is None:
            raise ValueError("a batched result has one solver result per site: see .status")
        name = STATUS_NAMES[code] if code < len(STATUS_NAMES) else "nonlinear_divergence"
        return getattr(optx.RESULTS, name)

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
        return residual_unit(self.units)

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
        """Plain-language warnings: non-convergence, degenerate and correlated parameters, an
        absurd Sky RMS (:meth:`absurd_fit`), values outside their declared ranges
        (:mod:`pointax.fitting.ranges`)."""
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
        if not self.names:
            out.append(
                "no free parameters (an empty term list, or every parameter fixed): nothing was fitted, and "
                "the Sky RMS is that of the model as given"
            )
        absurd = self.absurd_fit()
        if absurd:
            out.append(absurd)
        from .ranges import range_warning  # ranges builds on this module

        outside = range_warning(np.asarray(self.values), self.model.free_parameters)
        if outside:
            out.append(outside)

        n, m = int(self.n_obs), len(self.names)
        if n <= m:
            out.append(f"only {n} observations for {m} parameters: Popn SD is undefined")
        return out

    def standout_rows(self, sigmas: float = STANDOUT_SIGMAS) -> list[int]:
        """0-based indices of the used observations whose residual stands out of the rest
        by a robust (median-based) look: an on-sky residual above ``sigmas`` robust
        standard deviations (the median residual norm over its Gaussian expectation,
        :func:`pointax.fitting.statistics.robust_sigma`), and above the Sky RMS.
        Empty when more than a fifth of the rows would stand out, or when the median
        residual itself exceeds :data:`ABSURD_SKY_RMS_DEG` (then the data as a whole
        are off, not a few rows)."""
        r = np.asarray(self.residuals, np.float64)
        used = np.asarray(self.used, bool)
        if r.ndim != 2 or not used.any():
            return []
        norm = np.hypot(r[:, 0], r[:, 1])
        finite = used & np.isfinite(norm)
        if not finite.any():
            return []
        from .statistics import RAYLEIGH_MEDIAN

        median = float(np.median(norm[finite]))
        if median > ABSURD_SKY_RMS_DEG * UNITS["deg"]:
            return []  # the typical residual is absurd: the data as a whole are off
        sigma = median / RAYLEIGH_MEDIAN
        out = np.flatnonzero(finite & (norm > sigmas * sigma) & (norm > float(self.sky_rms)))
        if len(out) > max(1, int(finite.sum()) // 5):
            return []
        return [int(i) for i in out[np.argsort(-norm[out])]]

    def absurd_fit(self) -> str:
        """A warning when the Sky RMS after the fit, or the residual of a row that stands
        out, exceeds :data:`ABSURD_SKY_RMS_DEG` (no pointing model leaves residuals
        that large), else ''. It names the rows
        that stand out in a robust look (:meth:`standout_rows`: a corrupt or mistyped
        record drags a least-squares fit), and otherwise the likely cause of the data
        as a whole being off (unit, convention, columns)."""
        rms = float(self.sky_rms)
        if not math.isfinite(rms):
            return ""
        limit = ABSURD_SKY_RMS_DEG * UNITS["deg"]
        r = np.asarray(self.residuals, np.float64)
        norm = np.hypot(r[:, 0], r[:, 1]) if r.ndim == 2 else np.zeros(0)
        if rms <= limit:
            # A sane Sky RMS may still hide a record whose residual alone is absurd.
            rows = [i for i in self.standout_rows() if norm[i] > limit]
            if not rows:
                return ""
            head = f"Sky RMS {rms / ARCSEC:.6g}\" after the fit, but some residuals are absurd (more than {ABSURD_SKY_RMS_DEG:g} deg)"
        else:
            head = (
                f"Sky RMS {rms / ARCSEC:.6g}\" ({rms / UNITS['deg']:.4g} deg) after the fit is absurd for a pointing "
                f"model (more than {ABSURD_SKY_RMS_DEG:g} deg)"
            )
            rows = self.standout_rows()
        if rows:
            used = np.asarray(self.used, bool)
            rest = float(np.median(norm[used & ~np.isin(np.arange(len(norm)), rows)])) if used.sum() > len(rows) else 0.0
            shown = ", ".join(f"{i + 1} ({norm[i] / UNITS['deg']:.3g} deg)" for i in rows[:10])
            more = f" and {len(rows) - 10} more" if len(rows) > 10 else ""
            listed = ",".join(str(i + 1) for i in rows)
            return (
                f"{head}: observation{'s' if len(rows) > 1 else ''} {shown}{more} (rows counted from 1) stand"
                f"{'' if len(rows) > 1 else 's'} out of the rest (median residual {rest / ARCSEC:.3g}\"), probably "
                f"bad records (a corrupt or mistyped line) that drag the fit: check them, leave them out "
                f"(pointax fit --mask {listed}; weights 0) or fit robustly (loss='cauchy', --loss cauchy)"
            )
        return (
            f"{head}: no few rows stand out, so the likely cause is angles in the wrong unit (radians "
            "read as degrees, or degrees given where radians are expected), a wrong azimuth convention, or "
            "columns in the wrong order"
        )

    def report(self) -> str:
        """A TPOINT-style report: term, value, sigma; Sky RMS; Popn SD; warnings."""
        solver_name = SOLVER_NAMES[self.solver]
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
        loo = float(self.loo_rms) / UNITS[unit]
        if not math.isnan(loo):
            # Leave-one-out from the hat matrix of the linearised fit: no refits.
            value = f"{loo:9.4f}{label}" if math.isfinite(loo) else "  undefined (a star alone fixes a parameter)"
            lines.append(f"LOO RMS = {value}  (leave-one-out, each star out of the fit in turn)")
        warnings = self.warnings()
        from .ranges import twin_note  # ranges builds on this module

        twin = twin_note(self.model, np.asarray(self.values), self.model.free_parameters)
        if warnings or twin:
            lines.append("")
        lines.extend(f"WARNING: {w}" for w in warnings)
        if twin:
            lines.append(f"NOTE: {twin}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary; the keys are stable (see ``pointax fit --json``).

        Observations are named two ways: ``outliers`` holds 0-based indices (into
        ``residuals``, Python's), ``outlier_rows`` the same observations as 1-based row
        numbers in file order, as the report, the listing and TPOINT count them."""
        number = finite_or_none
        corr = np.asarray(self.correlation)
        return {
            "n_obs": int(self.n_obs),
            "sky_rms_arcsec": number(float(self.sky_rms) / ARCSEC),
            "popn_sd_arcsec": number(float(self.popn_sd) / ARCSEC),
            "loo_rms_arcsec": number(float(self.loo_rms) / ARCSEC),
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
            "outliers": self.outlier_indices(),  # 0-based indices (Python's)
            "outlier_rows": [i + 1 for i in self.outlier_indices()],  # 1-based rows, as the report and TPOINT count
            "warnings": self.warnings(),
        }

"""Per-site records of a batched fit, built column-wise: the statuses of
:func:`pointax.site_statuses` and the dicts of ``site_result(result, k).to_dict()``
for every site at once.

    statuses = site_statuses(result)        # [{"status", "reason"}, ...], one per site
    dicts = site_dicts(result)              # [FitResult.to_dict() of each site, ...]

A network of 10,000 sites built them one :class:`pointax.FitResult` at a time (a slice
of every leaf, a method call per field): about 3.5 s of Python. Here each field is one
NumPy operation over the site axis and one ``tolist``; only the sites whose text is not
the common one (not converged, degenerate, a warning to give, values outside their
ranges, fixed parameters) go through the per-site methods, so every string and number
is that of :meth:`pointax.FitResult.to_dict` to the bit (checked by
``tests/test_batch_records.py``).
"""

from __future__ import annotations

from typing import Any

import jax
import numpy as np

from ..core.units import ARCSEC, UNITS
from .ranges import range_warning
from .result import ABSURD_SKY_RMS_DEG, CORRELATION_WARNING, FitResult

__all__ = ["site_result", "site_statuses", "site_dicts"]


def site_result(result: FitResult, site: int) -> FitResult:
    """One site's :class:`pointax.FitResult` out of a batched one (report, table, ...)."""
    # x[site, ...] keeps 0-d arrays (x[site] of a NumPy leaf would be a NumPy scalar).
    return jax.tree.map(lambda x: x[site, ...], result)


def _n_sites(result: FitResult) -> int:
    return int(np.shape(result.converged)[0])


def _out_of_range(values: np.ndarray, params) -> np.ndarray:
    """``(S,)`` whether a site has a finite value outside its parameter's expected range
    (:func:`pointax.fitting.ranges.out_of_range`, for every site at once)."""
    bad = np.zeros(values.shape[0], bool)
    for k, p in enumerate(params):
        if p.expected is not None:
            v = values[:, k]
            bad |= np.isfinite(v) & ~((p.expected[0] <= v) & (v <= p.expected[1]))
    return bad


def site_statuses(result: FitResult) -> list[dict[str, str]]:
    """Per site of a batched result: ``{"status": ..., "reason": ...}`` with status
    ``"converged"``, ``"degenerate"`` (converged, but some parameters cannot be told
    apart: the reason names them) or ``"failed"`` (the reason says why: too few
    observations for the free parameters, as :func:`pointax.fit` refuses them, or why
    the solver stopped). A converged site whose values lie outside their declared ranges
    (:mod:`pointax.fitting.ranges`: an equivalent solution in another branch) keeps its
    status, with the reason saying so. Column-wise: one NumPy pass per field, not a
    FitResult per site."""
    n = _n_sites(result)
    converged = np.asarray(result.converged, bool).reshape(n)
    degenerate = np.asarray(result.degenerate, bool).reshape(n, len(result.names))
    values = np.asarray(result.values, np.float64).reshape(n, len(result.names))
    params = result.model.free_parameters
    outside = _out_of_range(values, params)
    out: list[dict[str, str]] = []
    for k, (ok, flags, far) in enumerate(zip(converged.tolist(), degenerate.any(axis=1).tolist(), outside.tolist())):
        if not ok:
            out.append({"status": "failed", "reason": site_result(result, k).message})
        elif flags:
            names = [name for name, d in zip(result.names, degenerate[k]) if d]
            out.append({"status": "degenerate", "reason": "cannot be told apart: " + ", ".join(names)})
        else:
            out.append({"status": "converged", "reason": range_warning(values[k], params) if far else ""})
    return out


def _plain(result: FitResult, n: int) -> np.ndarray:
    """``(S,)`` the sites whose ``to_dict`` has no warning and an empty message: converged
    (robust passes too), nothing degenerate or strongly correlated, more observations
    than parameters, values in range, and a Sky RMS and residuals that
    :meth:`pointax.FitResult.absurd_fit` cannot call absurd."""
    m = len(result.names)
    if m == 0:
        return np.zeros(n, bool)
    ok = np.asarray(result.converged, bool).reshape(n) & np.asarray(result.robust_converged, bool).reshape(n)
    ok &= ~np.asarray(result.degenerate, bool).reshape(n, m).any(axis=1)
    corr = np.asarray(result.correlation, np.float64).reshape(n, m, m)
    upper = np.triu(np.ones((m, m), bool), 1)
    ok &= ~(np.isfinite(corr) & (np.abs(corr) > CORRELATION_WARNING) & upper).any(axis=(1, 2))
    ok &= np.asarray(result.n_obs).reshape(n) > m
    ok &= ~_out_of_range(np.asarray(result.values, np.float64).reshape(n, m), result.model.free_parameters)
    # absurd_fit is '' when the Sky RMS is not finite, or when it and every used row's
    # residual lie within the limit (no row can then be named); otherwise ask it.
    limit = ABSURD_SKY_RMS_DEG * UNITS["deg"]
    rms = np.asarray(result.sky_rms, np.float64).reshape(n)
    r = np.asarray(result.residuals, np.float64)
    norm = np.hypot(r[..., 0], r[..., 1]).reshape(n, -1)
    used = np.asarray(result.used, bool).reshape(n, -1)
    rows_within = ~(used & ~(norm <= limit)).any(axis=1)  # a NaN norm is not within
    ok &= ~np.isfinite(rms) | ((rms <= limit) & rows_within)
    return ok


def _numbers(x: np.ndarray) -> list:
    """:func:`~pointax.fitting.result.finite_or_none` of every element, as nested lists."""
    if np.isfinite(x).all():
        return x.tolist()
    return np.where(np.isfinite(x), x, None).tolist()


def site_dicts(result: FitResult) -> list[dict[str, Any]]:
    """``[site_result(result, k).to_dict() for k in range(S)]`` of a batched ``result``,
    column-wise: the same dicts, key order, numbers and strings."""
    n = _n_sites(result)
    names, units = result.names, result.units
    m = len(names)
    plain = _plain(result, n)
    model = result.model
    fixed = [p for p in model.parameters if p.name in model.fixed]
    scale = np.array([UNITS[u] for u in units], np.float64)
    values = np.asarray(result.values, np.float64).reshape(n, m)
    sigmas = np.asarray(result.sigmas, np.float64).reshape(n, m)
    # As FitResult.table then to_dict: value / unit, then (value * unit) / arcsec.
    shown_v, shown_s = values / scale, sigmas / scale
    columns = {
        "value_arcsec": _numbers(shown_v * scale / ARCSEC),
        "sigma_arcsec": _numbers(shown_s * scale / ARCSEC),
        "value": _numbers(shown_v),
        "sigma": _numbers(shown_s),
    }
    fixed_values = {
        p.name: _numbers(np.broadcast_to(np.asarray(model.get(p.name), np.float64), (n,)) / UNITS[p.unit])
        for p in fixed
    }
    stats = {
        key: _numbers(np.asarray(getattr(result, field), np.float64).reshape(n) / ARCSEC)
        for key, field in (("sky_rms_arcsec", "sky_rms"), ("popn_sd_arcsec", "popn_sd"), ("loo_rms_arcsec", "loo_rms"))
    }
    n_obs = np.asarray(result.n_obs).reshape(n).astype(np.int64).tolist()
    iterations = np.asarray(result.iterations).reshape(n).astype(np.int64).tolist()
    converged = np.asarray(result.converged, bool).reshape(n).tolist()
    correlation = _numbers(np.asarray(result.correlation, np.float64).reshape(n, m, m))
    outliers = np.asarray(result.outliers, bool).reshape(n, -1)
    any_outlier = outliers.any(axis=1).tolist()
    out = []
    for k, simple in enumerate(plain.tolist()):
        if not simple:
            out.append(site_result(result, k).to_dict())
            continue
        flagged = [int(i) for i in np.flatnonzero(outliers[k])] if any_outlier[k] else []
        out.append(
            {
                "n_obs": n_obs[k],
                "sky_rms_arcsec": stats["sky_rms_arcsec"][k],
                "popn_sd_arcsec": stats["popn_sd_arcsec"][k],
                "loo_rms_arcsec": stats["loo_rms_arcsec"][k],
                "converged": converged[k],
                "iterations": iterations[k],
                "message": "",
                "solver": result.solver,
                "terms": [
                    {
                        "name": names[i],
                        "value_arcsec": columns["value_arcsec"][k][i],
                        "sigma_arcsec": columns["sigma_arcsec"][k][i],
                        "value": columns["value"][k][i],
                        "sigma": columns["sigma"][k][i],
                        "unit": units[i],
                    }
                    for i in range(m)
                ],
                "fixed": {name: column[k] for name, column in fixed_values.items()},
                "correlation": correlation[k],
                "loss": result.loss,
                "outliers": flagged,
                "outlier_rows": [i + 1 for i in flagged],
                "warnings": [],
            }
        )
    return out

"""What parameter declarations say about fitted values (:func:`pointax.terms.param`).

* A parameter with a ``period`` (an encoder zero) gives the same model at every multiple
  of it: a fit that ends at 600.5 deg reports 240.5 deg, the value in
  ``[0, period)`` (where an encoder reading lies).
* A parameter with an ``expected`` range (a small mechanical error) that ends outside
  it is flagged: the fit found an equivalent solution in another branch (a turntable
  whose encoder zeros came out 180 deg off has ``omega0`` near 180 deg) or stopped at a
  bad start.

Both act on a :class:`pointax.FitResult`, solo or batched (a leading site axis).
"""

from __future__ import annotations

import equinox as eqx
import jax
import numpy as np

from ..core.model import ParameterInfo
from ..core.units import UNITS

__all__ = ["wrap_periodic", "out_of_range", "range_warning", "TWINS", "twin_note"]

TWINS: dict[str, tuple[tuple[tuple[str, str, float], ...], ...]] = {
    "TurntableMount": (
        (("beta0", "+", np.pi),),
        (("alpha0", "+", np.pi), ("beta0", "-", np.pi), ("omega0", "pi-", 0.0)),
    ),
}
"""Mount class name -> its exact twins: other parameter values that give the same
residuals, each a tuple of ``(name, how, amount)`` with ``how`` '+' (add ``amount``),
'-' (subtract) or 'pi-' (``pi - value``). The sun-vector turntable's normal is fitted
as a line (the pitch zero ``beta0`` and ``beta0 + 180 deg`` give the same residuals),
and ``alpha0 + 180 deg, beta0 - 180 deg, omega0 -> 180 deg - omega0`` is the same
turntable turned over (:data:`pointax.terms.sun_vector.SMALL_ANGLE`). Checked by
``tests/test_fit_outputs.py`` on the paper's Table 1."""

def wrap_periodic(result):
    """``result`` (a :class:`pointax.FitResult`) with each periodic parameter brought into ``[0, period)``
    (the model too); the same object when no parameter declares a period or every value
    is already there. The residuals and statistics do not change (same model)."""
    params = result.model.free_parameters
    periodic = [(k, p.period) for k, p in enumerate(params) if p.period is not None]
    if not periodic:
        return result
    values = np.array(result.values, np.float64)
    for k, period in periodic:
        values[..., k] = values[..., k] - period * np.floor(values[..., k] / period)
    if np.array_equal(values, np.asarray(result.values), equal_nan=True):
        return result
    values = jax.device_put(values)
    model = result.model.replace_parameters(params, [values[..., k] for k in range(len(params))])
    return eqx.tree_at(lambda r: (r.values, r.model), result, (values, model))


def twin_note(model, values, params: tuple[ParameterInfo, ...]) -> str:
    """One sentence naming the equivalent solutions of a fit whose mount declares twins
    (:data:`TWINS`) and holds all their parameters free ('' otherwise): the values
    reported are one of several that fit the data exactly as well."""
    twins = TWINS.get(type(getattr(model, "mount", None)).__name__)
    if not twins:
        return ""
    values = np.asarray(values, np.float64)
    if values.ndim != 1:
        return ""
    index = {p.name: k for k, p in enumerate(params)}
    parts = []
    for twin in twins:
        if not all(name in index for name, _, _ in twin):
            continue
        shown = []
        for name, how, amount in twin:
            p = params[index[name]]
            v = values[index[name]]
            v = v + amount if how == "+" else (v - amount if how == "-" else np.pi - v)
            if p.period is not None:
                v = v - p.period * np.floor(v / p.period)
            scale = UNITS.get(p.unit, 1.0)
            shown.append(f"{name} = {v / scale:.4f} {p.unit}")
        parts.append(", ".join(shown))
    if not parts:
        return ""
    return (
        "an equivalent solution exists (the same residuals, another branch of the model): "
        + "; or ".join(parts)
        + " (the values above are one of them; start near the one you want, e.g. pointax.Turntable(start=observations))"
    )


def out_of_range(values, params: tuple[ParameterInfo, ...]) -> list[int]:
    """Indices of the ``(M,)`` ``values`` outside their parameters' expected ranges."""
    values = np.asarray(values, np.float64)
    out = []
    for k, p in enumerate(params):
        if p.expected is not None and np.isfinite(values[k]) and not p.expected[0] <= values[k] <= p.expected[1]:
            out.append(k)
    return out


def range_warning(values, params: tuple[ParameterInfo, ...]) -> str:
    """One sentence on the ``(M,)`` ``values`` outside their expected ranges ('' when none)."""
    bad = out_of_range(values, params)
    if not bad:
        return ""
    parts = []
    for k in bad:
        p = params[k]
        scale = UNITS.get(p.unit, 1.0)
        low, high = (x / scale for x in p.expected)
        parts.append(f"{p.name} = {float(values[k]) / scale:.4g} {p.unit} (expected {low:.4g} to {high:.4g})")
    return (
        "outside the expected range: " + "; ".join(parts) + ". The fit probably found an equivalent solution in "
        "another branch (for a turntable: encoder zeros 180 deg off) or stopped far from the truth: start it "
        "nearer (e.g. pointax.Turntable(start=observations))"
    )

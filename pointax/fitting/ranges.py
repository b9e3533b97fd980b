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

from ..model import ParameterInfo
from ..units import UNITS

__all__ = ["wrap_periodic", "out_of_range", "range_warning"]

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

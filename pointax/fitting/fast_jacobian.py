"""The derivatives of a site's residuals (:func:`pointax.fitting.problem.site_residuals`)
with respect to the model's parameters, for the batched and shared-parameter fits: the
one custom derivative of the residual family (the solo fit differentiates the residuals
with JAX's own forward mode).

* **Jacobian columns one parameter at a time** (:func:`residual_columns`): a forward
  derivative with respect to one parameter skips every stage of the chain before
  that parameter enters (JAX's symbolic zeros), about 3x cheaper than ``jax.jacfwd``
  over all parameters at once.
* **The sky form's fixed point differentiated once for all parameters**
  (:func:`residuals_and_columns`): the iterations of :func:`pointax.fitting.fast_evaluation.site_pointing`
  with their derivatives carried along, rather than the whole loop per parameter.
* **The residuals as optimistix sees them** (:func:`residual_function`): a
  ``jax.custom_jvp`` whose derivative with respect to the fitted parameters is made of
  those columns.
"""

from __future__ import annotations

from collections.abc import Sequence

import jax
import jax.numpy as jnp
from jax.custom_derivatives import SymbolicZero
from jaxtyping import Array

from ..core.model import Model, ParameterInfo
from .fast_evaluation import (
    chain_angles,
    chain_pointing,
    direction_at,
    has_sky_offsets,
    sky_offsets_at,
    tangent_offsets,
)
from .problem import SiteData, site_residuals

__all__ = ["residual_columns", "residuals_and_columns", "residual_function"]


def _values(y, n: int) -> list:
    """The first ``n`` entries of the vector ``y``, one per fitted parameter."""
    return [y[k] for k in range(n)]


def residual_columns(model: Model, data: SiteData, params: Sequence[ParameterInfo]) -> list[tuple[Array, Array]]:
    """Columns of the Jacobian of :func:`pointax.fitting.problem.site_residuals` (weighted) with
    respect to ``params``: ``[(d rx/d p, d ry/d p), ...]``, one forward derivative per
    parameter (:func:`_sky_form_columns` for the sky form's fixed point)."""
    return residuals_and_columns(model, data, params)[1]


def residuals_and_columns(
    model: Model, data: SiteData, params: Sequence[ParameterInfo]
) -> tuple[tuple[Array, Array], list[tuple[Array, Array]]]:
    """:func:`pointax.fitting.problem.site_residuals` (weighted) and :func:`residual_columns`
    together (the sky form's fixed point gives both from one loop)."""
    # A model that reads auxiliary readings is evaluated row by row (problem.reading_site_residuals):
    # its columns are forward derivatives of that evaluation.
    if params and not model.readings and model.residual_form != "tpoint" and has_sky_offsets(model, data.nominal):
        return _sky_form_columns(model, data, params)
    return site_residuals(model, data), [_column(lambda m: site_residuals(m, data), model, p) for p in params]


def _column(fn, model: Model, p: ParameterInfo):
    """The forward derivative of ``fn(model)`` with respect to the parameter ``p``."""
    value = getattr(model.terms[p.term], p.field)
    return jax.jvp(lambda x: fn(model.replace_parameters([p], [x])), (value,), (jnp.ones_like(value),))[1]


def _sky_form_columns(model: Model, data: SiteData, params: Sequence[ParameterInfo]):
    """:func:`residuals_and_columns` for the sky form of a model with sky offsets: the
    forward derivative of the same fixed-point iterations
    (:func:`pointax.fitting.fast_evaluation.site_pointing`'s), for all parameters in one loop.

    Iteration ``i`` maps the sky angles ``s`` to ``chain + g(s)``; its derivative maps
    ``ds/dp`` to ``dchain/dp + G ds/dp + dg/dp``, where ``G`` (2 x 2 per observation) is
    shared by all parameters and ``dg/dp`` touches only the terms holding ``p``. The
    residuals' derivative with respect to the final ``s`` (2 x 2 per observation) then
    gives the columns. Differentiating the loop parameter by parameter instead repeats
    the whole loop, and ``G``, for every parameter."""

    def chain_of(m):
        v, angles = chain_pointing(m, data)
        angles = chain_angles(m, v, angles)
        return angles[:, 0], angles[:, 1]

    def offsets(m, a1, a2):
        return sky_offsets_at(m, a1, a2, data)

    def partials(fn, a1, a2):
        """``fn(a1, a2)`` and its derivatives with respect to ``a1`` and ``a2``."""
        ones = jnp.ones_like(a1)
        out, d1 = jax.jvp(lambda x: fn(x, a2), (a1,), (ones,))
        return out, d1, jax.jvp(lambda x: fn(a1, x), (a2,), (ones,))[1]

    def per_parameter(fn):
        """``fn(model)``'s derivatives with respect to each parameter: two ``(m, n)`` arrays."""
        cols = [_column(fn, model, p) for p in params]
        return jnp.stack([c[0] for c in cols]), jnp.stack([c[1] for c in cols])

    # Structure of arrays: the sky angles as two (n,) arrays, their derivatives as two
    # (m, n) arrays (one row per parameter).
    c1, c2 = chain_of(model)
    tc1, tc2 = per_parameter(chain_of)

    def step(_, carry):
        a1, a2, t1, t2 = carry
        (g1, g2), d1, d2 = partials(lambda x1, x2: offsets(model, x1, x2), a1, a2)
        dg1, dg2 = per_parameter(lambda m: offsets(m, a1, a2))
        return c1 + g1, c2 + g2, tc1 + d1[0] * t1 + d2[0] * t2 + dg1, tc2 + d1[1] * t1 + d2[1] * t2 + dg2

    a1, a2, t1, t2 = jax.lax.fori_loop(0, model.sky_iterations, step, (c1, c2, tc1, tc2))
    r, r1, r2 = partials(lambda x1, x2: tangent_offsets(direction_at(model, x1, x2, data), data.target_trig), a1, a2)
    weighted = lambda x: jnp.where(data.used, x * data.sqrt_weight, 0.0)  # noqa: E731
    cols = [tuple(weighted(r1[i] * t1[k] + r2[i] * t2[k]) for i in range(2)) for k in range(len(params))]
    return (weighted(r[0]), weighted(r[1])), cols


def residual_function(params: Sequence[ParameterInfo]):
    """``f(y, (model, data)) -> (rx, ry)``: the weighted residuals with the parameters
    ``params`` set to the vector ``y``, for optimistix. Its derivative with respect to
    ``y`` comes from :func:`residual_columns` (a ``jax.custom_jvp``), so linearising it
    keeps only the Jacobian's columns; derivatives with respect to the model's other
    leaves and the data are ordinary forward derivatives."""
    params = tuple(params)
    n = len(params)

    @jax.custom_jvp
    def fn(y, model, data):
        return site_residuals(model.replace_parameters(params, _values(y, n)), data)

    def fn_jvp(primals, tangents):
        y, model, data = primals
        ty, t_model, t_data = tangents
        ys = _values(y, n)
        fitted = model.replace_parameters(params, ys)
        if isinstance(ty, SymbolicZero):
            out, columns = site_residuals(fitted, data), None
        else:
            out, columns = residuals_and_columns(fitted, data, params)
        # Sums started from their first term, not from zeros: a linearisation stores every
        # constant it meets as an array (see _scaled).
        parts = []
        if columns is not None:
            parts += [(_scaled(ty[k], cx), _scaled(ty[k], cy)) for k, (cx, cy) in enumerate(columns)]
        extra = _other_tangents(model, data, t_model, t_data, lambda m, d: site_residuals(m.replace_parameters(params, ys), d))
        if extra is not None:
            parts.append(extra)
        if not parts:
            return out, (jnp.zeros_like(out[0]), jnp.zeros_like(out[1]))
        return out, tuple(sum((p[i] for p in parts[1:]), parts[0][i]) for i in range(2))

    fn.defjvp(fn_jvp, symbolic_zeros=True)

    def residuals_of(y, args):
        model, data = args
        return fn(y, model, data)

    return residuals_of


def _scaled(t, column):
    """``t * column``, exactly 0 where ``t`` is: the solver takes the Jacobian's columns
    as the tangent map of unit vectors, and XLA cannot drop ``0 * column`` itself (NaN,
    inf), so each column would be computed from every column's arrays. Written with no constant (the zero is ``t``'s own,
    the test ``t``'s conversion to bool): ``jax.linearize`` stores each constant it meets
    as an array, which the batched fit carried from step to step and XLA could no longer
    fold away (``benchmarks/batch_fit_notes.md``)."""
    return jnp.where(t.astype(bool), t * column, t)


def _other_tangents(model, data, t_model, t_data, f):
    """Forward derivative of ``f(model, data)`` along the tangents of the model's and the
    data's floating-point leaves (None when they are all symbolic zeros)."""
    is_zero = lambda t: isinstance(t, SymbolicZero)  # noqa: E731
    flat_p, treedef = jax.tree.flatten((model, data))
    flat_t = jax.tree.leaves((t_model, t_data), is_leaf=is_zero)
    index = [i for i, p in enumerate(flat_p) if jnp.issubdtype(jnp.result_type(p), jnp.inexact)]
    if all(is_zero(flat_t[i]) for i in index):
        return None

    def g(*xs):
        leaves = list(flat_p)
        for i, x in zip(index, xs):
            leaves[i] = x
        return f(*jax.tree.unflatten(treedef, leaves))

    primal = [flat_p[i] for i in index]
    tangent = [jnp.zeros_like(flat_p[i]) if is_zero(flat_t[i]) else flat_t[i] for i in index]
    return jax.jvp(g, primal, tangent)[1]

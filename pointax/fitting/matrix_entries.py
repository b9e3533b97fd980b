"""3x3 algebra on entries, for the structured evaluation of a site (:mod:`pointax.fitting.fast_evaluation`).

A matrix is a 3x3 nested list of entries; an entry is a Python float (a constant known
when tracing: zeros and ones are skipped), a scalar array (the same for every
observation of a site), an ``(n,)`` array, or the negative of an array (:class:`Neg`:
its sign ends in a subtraction, see :func:`mul`). A vector is a list of three such
entries; :func:`value` turns an entry into an array or float. :func:`axis_form` writes a
mount's axis rotation as ``alpha + beta sin t + gamma cos t`` with constant matrices.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

__all__ = [
    "Neg",
    "value",
    "neg",
    "is_const",
    "mul",
    "add",
    "dot",
    "turn",
    "matmul",
    "entries",
    "axis_form",
    "axis_form_uncached",
    "nominal_entries",
    "constant_entries",
]

class Neg:
    """``-x`` for an array ``x``, not yet computed."""

    __slots__ = ("x",)

    def __init__(self, x):
        self.x = x


def value(a):
    return -a.x if isinstance(a, Neg) else a


def neg(a):
    if isinstance(a, Neg):
        return a.x
    return -a if isinstance(a, float) else Neg(a)


def is_const(x, value: float) -> bool:
    return isinstance(x, float) and x == value


def mul(a, b):
    """``a * b`` with constant zeros, ones and minus ones skipped. A sign stays symbolic
    (``Neg``) until an addition takes it: a rotation's ``-sin`` computed on its own is a
    product of the data alone, which XLA moved out of the fit's loop once per Jacobian
    column, so that the columns no longer shared their common terms (the fit's module
    was a third larger)."""
    if is_const(a, 0.0) or is_const(b, 0.0):
        return 0.0
    if isinstance(a, Neg) or is_const(a, -1.0):
        return neg(mul(neg(a), b))
    if isinstance(b, Neg) or is_const(b, -1.0):
        return neg(mul(a, neg(b)))
    if is_const(a, 1.0):
        return b
    if is_const(b, 1.0):
        return a
    return a * b


def add(a, b):
    if is_const(a, 0.0):
        return b
    if is_const(b, 0.0):
        return a
    if isinstance(b, Neg):
        return neg(a.x + b.x) if isinstance(a, Neg) else a - b.x
    if isinstance(a, Neg):
        return b - a.x
    return a + b


def dot(row, v):
    out = 0.0
    for a, b in zip(row, v):
        out = add(out, mul(a, b))
    return out


def turn(matrix, v):
    return [dot(row, v) for row in matrix]


def matmul(a, b):
    return [[dot(a[i], [b[k][j] for k in range(3)]) for j in range(3)] for i in range(3)]


def entries(matrix: Array) -> list:
    """A traced ``(..., 3, 3)`` matrix as entries ``matrix[..., i, j]``."""
    return [[matrix[..., i, j] for j in range(3)] for i in range(3)]


def axis_form(mount, axis: str) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Constant matrices ``(alpha, beta, gamma)`` with ``mount.<axis>(t) = alpha + beta sin t
    + gamma cos t`` for every angle ``t`` (true of any rotation about a fixed axis, with any
    fixed rotation before or after it), or None if the axis is not of that form or cannot
    be evaluated while tracing (e.g. it depends on traced mount fields).

    Cached per mount class and configuration when the mount has no array fields (its
    axes can then depend on nothing else): evaluating it costs tenths of a second."""
    if jax.tree.leaves(mount):
        return axis_form_uncached(getattr(mount, axis))
    return _axis_form_cached(jax.tree.structure(mount), type(mount), axis, mount)


_FORMS: dict = {}


def _axis_form_cached(treedef, cls, axis, mount):
    key = (cls, treedef, axis)
    if key not in _FORMS:
        _FORMS[key] = axis_form_uncached(getattr(mount, axis))
    return _FORMS[key]


_FORM_ANGLES = (0.0, math.pi / 2, math.pi, 0.7, 2.3, -1.9)


def axis_form_uncached(axis_fn):
    # All six angles in one compiled call, run at once even while a fit is traced: op by
    # op (or under jax.ensure_compile_time_eval) each operation compiles a kernel of its own.
    try:
        traced = jax.jit(jax.vmap(axis_fn)).trace(jax.ShapeDtypeStruct((len(_FORM_ANGLES),), jnp.float64))
        if len(traced.jaxpr.in_avals) != 1:  # it reads traced values (the mount's fields)
            return None
        at = np.asarray(traced.lower().compile()(np.asarray(_FORM_ANGLES, np.float64)), np.float64)
    except (jax.errors.TracerArrayConversionError, jax.errors.ConcretizationTypeError, TypeError):
        return None
    r0, r90, r180 = at[0], at[1], at[2]
    checks = list(zip(_FORM_ANGLES[3:], at[3:]))
    alpha, gamma = (r0 + r180) / 2, (r0 - r180) / 2
    beta = r90 - alpha
    # Entries within rounding of an integer are that integer (sin pi is 1.2e-16, not 0:
    # beta's 1 came out as 1 - 1.1e-16), so that the fit skips its zeros and ones.
    alpha, beta, gamma = (np.where(np.abs(m - np.round(m)) < 1e-14, np.round(m), m) for m in (alpha, beta, gamma))
    for t, r in checks:
        if not np.allclose(alpha + beta * np.sin(t) + gamma * np.cos(t), r, rtol=0, atol=1e-13):
            return None
    return alpha, beta, gamma


def nominal_entries(form, cos_n, sin_n):
    """Entries of ``axis(n)`` from the nominal angle's cos and sin (data only)."""
    alpha, beta, gamma = form
    return [
        [add(float(alpha[i, j]), add(mul(sin_n, float(beta[i, j])), mul(cos_n, float(gamma[i, j])))) for j in range(3)]
        for i in range(3)
    ]


def constant_entries(get: Callable[[], Array]) -> list:
    """The entries of the vector or matrix ``get()`` as Python floats when it is a
    constant (so that its zeros and ones are skipped), else as traced scalars. ``get``
    runs under ``jax.ensure_compile_time_eval`` (a property evaluated outside it would
    already be traced)."""
    try:
        with jax.ensure_compile_time_eval():
            return np.asarray(get(), np.float64).tolist()
    except (jax.errors.TracerArrayConversionError, jax.errors.ConcretizationTypeError, TypeError):
        x = jnp.asarray(get())
        return [x[i] if x.ndim == 1 else [x[i, j] for j in range(x.shape[1])] for i in range(x.shape[0])]

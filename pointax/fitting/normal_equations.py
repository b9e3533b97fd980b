"""Small least-squares systems through the normal equations, written out entry by entry.

A pointing fit's linear systems are tall and thin: ``2 n`` residuals, a handful of
parameters. Under ``jax.vmap`` over thousands of sites, LAPACK's QR or Cholesky is one
library call per site; written out as elementwise arithmetic on ``(sites,)`` arrays the
same factorisation runs vectorised across sites (the cost is measured in
``benchmarks/batch_fit_notes.md``). :class:`NormalCholesky` is that solver for
optimistix / lineax, :class:`CholeskyGaussNewton` optimistix's Gauss-Newton with it that
keeps the last factor for the statistics; :func:`cholesky` and :func:`inverse` serve the
statistics.

The normal equations square the condition number: fine in float64 for pointing models
(their worst correlations, ~0.997, cost about 3 of 16 digits), not for near-degenerate
ones, which the callers detect from the pivots (:func:`cholesky` returns them) and hand
to an SVD.
"""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx
from jaxtyping import Array, Float

__all__ = [
    "NormalCholesky",
    "CholeskyGaussNewton",
    "CholeskyNewtonDescent",
    "factor_entries",
    "columns",
    "inner",
    "normal_matrix",
    "cholesky",
    "solve",
    "inverse",
    "MAX_UNROLLED",
]

MAX_UNROLLED = 16
"""Systems with more unknowns than this use ``jnp.linalg`` (the unrolled code grows as
the cube of the size, and with it the compilation time)."""


def inner(a, b) -> Array:
    """Sum of the products of two pytrees of arrays of equal structure."""
    return sum(jnp.sum(x * y) for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b)))


def normal_matrix(columns: list) -> list[list[Array]]:
    """``A = J^T J`` as nested lists of scalars, from J's columns (each a pytree of arrays)."""
    m = len(columns)
    a = [[None] * m for _ in range(m)]
    for i in range(m):
        for j in range(i + 1):
            a[i][j] = a[j][i] = inner(columns[i], columns[j])
    return a


def cholesky(a: list[list[Array]]) -> tuple[list[list[Array]], Float[Array, " m"]]:
    """Lower Cholesky factor ``L`` (nested lists) of a symmetric positive definite ``a``,
    and the relative pivots ``L_jj^2 / a_jj`` (near 0 or NaN: ``a`` is near-singular)."""
    m = len(a)
    low = [[0.0] * m for _ in range(m)]
    pivots = []
    for j in range(m):
        s = a[j][j]
        for k in range(j):
            s = s - low[j][k] ** 2
        pivots.append(s / a[j][j])
        d = jnp.sqrt(s)
        low[j][j] = d
        for i in range(j + 1, m):
            t = a[i][j]
            for k in range(j):
                t = t - low[i][k] * low[j][k]
            low[i][j] = t / d
    return low, jnp.stack(pivots) if pivots else jnp.zeros((0,))


def solve(low: list[list[Array]], b: list[Array]) -> Float[Array, " m"]:
    """Solve ``L L^T x = b`` by forward and back substitution."""
    m = len(low)
    z = [None] * m
    for i in range(m):
        t = b[i]
        for k in range(i):
            t = t - low[i][k] * z[k]
        z[i] = t / low[i][i]
    x = [None] * m
    for i in reversed(range(m)):
        t = z[i]
        for k in range(i + 1, m):
            t = t - low[k][i] * x[k]
        x[i] = t / low[i][i]
    return jnp.stack(x) if x else jnp.zeros((0,))


def inverse(low: list[list[Array]]) -> Float[Array, "m m"]:
    """``(L L^T)^-1 = L^-T L^-1`` from the Cholesky factor (``L^-1`` by forward
    substitution, then its inner products: about half the operations of solving for
    each column of the identity)."""
    m = len(low)
    if not m:
        return jnp.zeros((0, 0))
    inv = [[None] * m for _ in range(m)]  # L^-1, lower triangular
    for j in range(m):
        inv[j][j] = 1.0 / low[j][j]
        for i in range(j + 1, m):
            t = low[i][j] * inv[j][j]
            for k in range(j + 1, i):
                t = t + low[i][k] * inv[k][j]
            inv[i][j] = -t / low[i][i]
    out = [[None] * m for _ in range(m)]
    for i in range(m):
        for j in range(i + 1):
            out[i][j] = out[j][i] = sum(inv[k][i] * inv[k][j] for k in range(i, m))
    return jnp.stack([jnp.stack(row, axis=-1) for row in out], axis=-2)


def columns(operator: lx.AbstractLinearOperator) -> list:
    """The operator's columns, each a pytree like its output (one product per unknown).

    The unit vectors are NumPy constants: built with ``.at[k].set(1.0)`` inside a loop
    (the batched fit's steps), XLA moved them out of it before folding them, and inside
    the loop they were no longer known to be 0 and 1 (each column cost an extra pass
    over its arrays, and the fit's module 270 more HLO lines and 0.2-0.3 s of
    compilation)."""
    structure = operator.in_structure()
    eye = np.eye(structure.shape[0], dtype=structure.dtype)
    return [operator.mv(eye[k]) for k in range(structure.shape[0])]


def _flat(tree) -> Array:
    return jnp.concatenate([jnp.ravel(leaf) for leaf in jax.tree.leaves(tree)])


class NormalCholesky(lx.AbstractLinearSolver):
    """Least-squares solution of a tall full-rank ``J x = r`` from ``J^T J x = J^T r``, with
    the Cholesky factorisation written out (vectorises under ``vmap``; see the module
    docstring). Unknowns: a flat array; residuals: any pytree of arrays. A rank-deficient
    ``J`` gives NaN or inf, never an error: the caller checks."""

    def init(self, operator: lx.AbstractLinearOperator, options: dict[str, Any]):
        del options
        if jax.tree.structure(operator.in_structure()).num_leaves != 1 or len(operator.in_structure().shape) != 1:
            raise ValueError("NormalCholesky needs a flat vector of unknowns")
        cols = columns(operator)
        if len(cols) > MAX_UNROLLED:
            j = jnp.stack([_flat(c) for c in cols], axis=-1)
            a = j.T @ j
            low = jnp.linalg.cholesky(a)
            return cols, low, jnp.diagonal(low) ** 2 / jnp.diagonal(a)
        low, pivots = cholesky(normal_matrix(cols))
        return cols, low, pivots

    def compute(self, state, vector, options: dict[str, Any]):
        del options
        cols, low, _ = state
        if isinstance(low, list):
            x = solve(low, [inner(c, vector) for c in cols])
        else:
            b = jnp.stack([inner(c, vector) for c in cols])
            x = jax.scipy.linalg.cho_solve((low, True), b)
        return x, lx.RESULTS.successful, {}

    def transpose(self, state, options: dict[str, Any]):
        raise NotImplementedError("NormalCholesky solves least-squares systems only (no transpose)")

    def conj(self, state, options: dict[str, Any]):
        return state, options

    def assume_full_rank(self):
        return True


def factor_entries(low) -> list[list[Array]]:
    """A Cholesky factor as nested lists of entries (:func:`cholesky`'s form), from
    either that form or an ``(m, m)`` array (:class:`NormalCholesky` above
    :data:`MAX_UNROLLED` unknowns)."""
    if isinstance(low, list):
        return low
    m = low.shape[-1]
    return [[low[..., i, j] if j <= i else 0.0 for j in range(m)] for i in range(m)]


class _CholeskyNewtonState(eqx.Module):
    newton: Array
    low: Any  # the factor of J^T J at the last linearisation (NormalCholesky's form)
    pivots: Array
    result: optx.RESULTS


class CholeskyNewtonDescent(optx.AbstractDescent):
    """optimistix's Newton descent for least squares (``J^T J x = J^T r``) through
    :class:`NormalCholesky`, keeping the Cholesky factor and its relative pivots in its
    state (``state.descent_state.low``, ``.pivots``): after the last step they are the
    factor at the solver's ``f_info.jac``, and the statistics need not factorise again."""

    def init(self, y: Array, f_info_struct) -> _CholeskyNewtonState:
        del f_info_struct
        m = y.shape[0]
        zero = jnp.zeros((), y.dtype)
        if m > MAX_UNROLLED:
            low = jnp.zeros((m, m), y.dtype)
        else:  # the structure cholesky() returns: Python zeros above the diagonal
            low = [[zero if j <= i else 0.0 for j in range(m)] for i in range(m)]
        return _CholeskyNewtonState(y, low, jnp.zeros((m,), y.dtype), optx.RESULTS.successful)

    def query(self, y: Array, f_info, state: _CholeskyNewtonState) -> _CholeskyNewtonState:
        del y, state
        solver = NormalCholesky()
        solver_state = solver.init(f_info.jac, {})
        newton, _, _ = solver.compute(solver_state, f_info.residual, {})
        _, low, pivots = solver_state
        return _CholeskyNewtonState(newton, low, pivots, optx.RESULTS.successful)

    def step(self, step_size, state: _CholeskyNewtonState):
        return -step_size * state.newton, state.result


def _quiet(**kwargs) -> None:
    del kwargs


class CholeskyGaussNewton(optx.AbstractGaussNewton):
    """optimistix's Gauss-Newton (full steps, its Cauchy termination) with
    :class:`CholeskyNewtonDescent`: the same iterates as ``optx.GaussNewton(rtol, atol,
    linear_solver=NormalCholesky())``, and the last factor in ``state.descent_state``."""

    rtol: float
    atol: float
    norm: Any
    descent: CholeskyNewtonDescent
    search: optx.LearningRate
    verbose: Any

    def __init__(self, rtol: float, atol: float, norm=optx.max_norm):
        self.rtol = rtol
        self.atol = atol
        self.norm = norm
        self.descent = CholeskyNewtonDescent()
        self.search = optx.LearningRate(1.0)
        self.verbose = _quiet

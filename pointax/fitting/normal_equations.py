"""Small least-squares systems through the normal equations, written out entry by entry.

A pointing fit's linear systems are tall and thin: ``2 n`` residuals, a handful of
parameters. Under ``jax.vmap`` over thousands of sites, LAPACK's QR or Cholesky is one
library call per site; written out as elementwise arithmetic on ``(sites,)`` arrays the
same factorisation runs vectorised across sites (the cost is measured in
``benchmarks/batch_fit_notes.md``). The batched fit's fast pass
(:mod:`pointax.fitting.batch_fast_pass`) and the shared-parameter fit's Schur complement
(:mod:`pointax.fitting.shared`) solve through :func:`cholesky` and :func:`solve`;
:func:`inverse` gives their covariances.

The normal equations square the condition number: fine in float64 for pointing models
(their worst correlations, ~0.997, cost about 3 of 16 digits), not for near-degenerate
ones, which the callers detect from the pivots (:func:`cholesky` returns them) and hand
to an SVD.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

__all__ = [
    "factor_entries",
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


def factor_entries(low) -> list[list[Array]]:
    """A Cholesky factor as nested lists of entries (:func:`cholesky`'s form), from
    either that form or an ``(m, m)`` array (``jnp.linalg.cholesky``'s, above
    :data:`MAX_UNROLLED` unknowns)."""
    if isinstance(low, list):
        return low
    m = low.shape[-1]
    return [[low[..., i, j] if j <= i else 0.0 for j in range(m)] for i in range(m)]

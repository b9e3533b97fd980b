"""Sine and cosine of float64 arrays as vectorised polynomials.

XLA on the CPU computes ``sin`` and ``cos`` in float64 by calling the C library once per
element: 6-7 ns each on this project's machine, against 0.5 ns for a multiply-add pass
over the same array. :func:`sincos` computes both from one argument reduction and two
short polynomials in plain array arithmetic, which XLA vectorises: about 1.5 ns for
the pair (``benchmarks/batch_fit_notes.md``, change 9).

The method is fdlibm's (Sun's C library, the basis of most others): ``x`` is reduced
to ``r = x - q pi/2``, ``|r| <= pi/4``, with ``pi/2`` in Cody and Waite's parts of 33
bits (each part's product with ``q`` is exact for ``|q| < 2^20``) and the rest; ``sin
r`` and ``cos r`` come from fdlibm's minimax polynomials (errors below ``2^-58`` on
``|r| <= pi/4``); the quadrant ``q mod 4`` picks and signs them. Accuracy
(``tests/test_trig.py``, against NumPy): within two units in the last place for ``|x|
< 1e5`` rad, also where the sine or cosine is near 0. Beyond about ``1.6e6`` rad
(``2^20 pi/2``) the reduction loses accuracy gradually: such arguments are not for this
function. Infinite or NaN arguments give NaN, and ``sin(-0) = -0``, as in the C
library. Derivatives are exact (a ``jax.custom_jvp``: ``d sin = cos dx``, ``d cos =
-sin dx``). Arguments other than float64 go to ``jnp.sin`` and ``jnp.cos``.

Where pointax uses it: the observations' encoder angles in a batched fit's site data
(:mod:`pointax.site`), computed once per observation in their own compiled call. Not
inside the compiled fit: there XLA copies a cheap producer into each of its consumers,
and the polynomials of the per-site rotation angles, copied into 28 fusions, made the
module a third larger and its compilation slower (change 9).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

__all__ = ["sincos"]

# pi/2 in three parts of 33 significant bits and what is left (fdlibm's pio2_1, pio2_2,
# pio2_3, pio2_3t), and 2/pi.
_PIO2_1 = 1.57079632673412561417e00
_PIO2_2 = 6.07710050630396597660e-11
_PIO2_3 = 2.02226624871116645580e-21
_PIO2_3T = 8.47842766036889956997e-32
_TWO_OVER_PI = 6.36619772367581382433e-01
# fdlibm's __kernel_sin (S1..S6) and __kernel_cos (C1..C6) coefficients.
_SIN = (
    -1.66666666666666324348e-01,
    8.33333333332248946124e-03,
    -1.98412698298579493134e-04,
    2.75573137070700676789e-06,
    -2.50507602534068634195e-08,
    1.58969099521155010221e-10,
)
_COS = (
    4.16666666666666019037e-02,
    -1.38888888888741095749e-03,
    2.48015872894767294178e-05,
    -2.75573143513906633035e-07,
    2.08757232129817482790e-09,
    -1.13596475577881948265e-11,
)


def _horner(z: Array, coefficients: tuple[float, ...]) -> Array:
    out = coefficients[-1]
    for c in reversed(coefficients[:-1]):
        out = c + z * out
    return out


@jax.custom_jvp
def _sincos64(x: Array) -> tuple[Array, Array]:
    q = jnp.round(x * _TWO_OVER_PI)
    r = (((x - q * _PIO2_1) - q * _PIO2_2) - q * _PIO2_3) - q * _PIO2_3T
    z = r * r
    s = r + r * z * _horner(z, _SIN)
    c = 1.0 - 0.5 * z + z * z * _horner(z, _COS)
    k = q - 4.0 * jnp.floor(0.25 * q)  # q mod 4, exact, in {0, 1, 2, 3}
    odd = (k == 1.0) | (k == 3.0)
    sin = jnp.where(odd, c, s)
    cos = jnp.where(odd, s, c)
    # x = q pi/2 + r: sin is (s, c, -s, -c) and cos (c, -s, -c, s) for k = 0, 1, 2, 3.
    sin = jnp.where(x == 0.0, x, jnp.where(k >= 2.0, -sin, sin))  # sin(-0) = -0
    return sin, jnp.where((k == 1.0) | (k == 2.0), -cos, cos)


@_sincos64.defjvp
def _sincos64_jvp(primals, tangents):
    (x,), (dx,) = primals, tangents
    sin, cos = _sincos64(x)
    return (sin, cos), (cos * dx, -sin * dx)


def sincos(x: Float[ArrayLike, "*shape"]) -> tuple[Float[Array, "*shape"], Float[Array, "*shape"]]:
    """``(sin x, cos x)`` elementwise (radians); see the module docstring for the method
    and its accuracy. Works under ``jit``, ``vmap`` and ``grad``."""
    x = jnp.asarray(x)
    if x.dtype != jnp.float64:
        return jnp.sin(x), jnp.cos(x)
    return _sincos64(x)

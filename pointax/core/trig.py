"""Sine, cosine and arctangent of float64 arrays as vectorised polynomials.

XLA on the CPU computes ``sin``, ``cos`` and ``atan2`` in float64 by calling the C
library once per element, an order of magnitude slower than a multiply-add pass over the
same array. :func:`sincos` computes both from one argument reduction and two short
polynomials in plain array arithmetic, which XLA vectorises, and so does :func:`atan2`
(the figures: ``benchmarks/batch_fit_notes.md``).

Both follow fdlibm (Sun's C library, the basis of most others). :func:`sincos` reduces
``x`` to ``r = x - q pi/2``, ``|r| <= pi/4``, with ``pi/2`` in Cody and Waite's parts
of 33 bits (each part's product with ``q`` is exact for ``|q| < 2^20``) and the rest,
takes ``sin r`` and ``cos r`` from fdlibm's minimax polynomials (errors below ``2^-58``
on ``|r| <= pi/4``), and lets the quadrant ``q mod 4`` pick and sign them. Accuracy
(``tests/test_trig.py``, against NumPy): within two units in the last place for ``|x|
< 1e5`` rad, also where the sine or cosine is near 0. Beyond about ``1.6e6`` rad
(``2^20 pi/2``) the reduction loses accuracy gradually: such arguments are not for this
function. Infinite or NaN arguments give NaN, and ``sin(-0) = -0``, as in the C
library. :func:`atan2` is described in its docstring. Derivatives are exact (each
function has a ``jax.custom_jvp``); arguments other than float64 go to ``jnp``'s own
functions.

Where pointax uses them: in a batched fit's site data, computed once per observation
before the step loop (which takes them as arrays) or, for one-step fits, in a compiled
call of their own: the encoder angles' sines and cosines (:mod:`pointax.fitting.fast_evaluation`)
and the observed angles of the TPOINT residual form
(:meth:`pointax.SphericalMount.sky_point_of`). Not inside the compiled fit: there XLA
copies a cheap producer into each of its consumers, so the polynomials of the per-site
rotation angles would be copied into every fusion that uses an angle, making the module
larger and its compilation slower.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

__all__ = ["sincos", "atan2"]

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


# fdlibm's __ieee754_atan coefficients (aT[0..10]): atan(t) = t - t (s1 + s2) for |t| < 7/16.
_ATAN = (
    3.33333333333329318027e-01,
    -1.99999999998764832476e-01,
    1.42857142725034663711e-01,
    -1.11111104054623557880e-01,
    9.09088713343650656196e-02,
    -7.69187620504482999495e-02,
    6.66107313738753120669e-02,
    -5.83357013379057348645e-02,
    4.97687799461593236017e-02,
    -3.65315727442169155270e-02,
    1.62858201153657823623e-02,
)
_TAN_PI_8 = 4.14213562373095034520e-01  # sqrt(2) - 1
_PIO4_HI, _PIO4_LO = 7.85398163397448278999e-01, 3.06161699786838301793e-17  # atan(1) = hi + lo
_PIO2_HI, _PIO2_LO = 1.57079632679489655800e00, 6.12323399573676603587e-17
_PI_HI, _PI_LO = 3.14159265358979311600e00, 1.22464679914735317720e-16


@jax.custom_jvp
def _atan2_64(y: Array, x: Array) -> Array:
    ax, ay = jnp.abs(x), jnp.abs(y)
    swap = ay > ax  # atan2 = pi/2 - atan(|x| / |y|)
    num, den = jnp.where(swap, ax, ay), jnp.where(swap, ay, ax)  # 0 <= num <= den
    big = num > _TAN_PI_8 * den  # atan(t) = pi/4 + atan((t - 1) / (t + 1))
    t = jnp.where(big, (num - den) / (num + den), num / jnp.where(den == 0.0, 1.0, den))  # |t| <= tan(pi/8)
    z = t * t
    w = z * z
    # fdlibm's split into even and odd coefficients, each a polynomial in t^4.
    a = t - t * (z * _horner(w, _ATAN[0::2]) + w * _horner(w, _ATAN[1::2]))  # atan(t)
    a = jnp.where(big, _PIO4_HI + (a + _PIO4_LO), a)  # atan(num / den) in [0, pi/4]
    a = jnp.where(swap, _PIO2_HI - (a - _PIO2_LO), a)  # atan(|y| / |x|) in [0, pi/2]
    a = jnp.where(jnp.signbit(x), _PI_HI - (a - _PI_LO), a)  # x < 0 (or -0): pi - that
    return jnp.where(jnp.signbit(y), -a, a)


@_atan2_64.defjvp
def _atan2_64_jvp(primals, tangents):
    (y, x), (dy, dx) = primals, tangents
    r2 = x * x + y * y
    return _atan2_64(y, x), (x * dy - y * dx) / r2  # NaN at (0, 0), as jnp.arctan2's


def atan2(y: Float[ArrayLike, "*shape"], x: Float[ArrayLike, "*shape"]) -> Float[Array, "*shape"]:
    """``atan2(y, x)`` elementwise, in ``[-pi, pi]``, as ``jnp.arctan2`` but a vectorised
    polynomial in float64 (fdlibm's ``atan`` after reducing ``min(|x|, |y|) /
    max(|x|, |y|)`` below ``tan(pi/8)``): within two units in the last place of NumPy's.
    ``atan2(+-0, +0) = +-0`` and ``atan2(+-0, -0) = +-pi`` as in the C library; NaN in,
    NaN out; both arguments infinite gives NaN (the C library: a multiple of ``pi/4``).
    Derivatives are exact (``(x dy - y dx) / (x^2 + y^2)``). Arguments other than
    float64 go to ``jnp.arctan2``."""
    y, x = jnp.asarray(y), jnp.asarray(x)
    if jnp.result_type(y, x) != jnp.float64:
        return jnp.arctan2(y, x)
    y, x = jnp.broadcast_arrays(y.astype(jnp.float64), x.astype(jnp.float64))
    return _atan2_64(y, x)

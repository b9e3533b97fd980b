"""Tests for pointax.core.trig: the vectorised sine, cosine and arctangent against NumPy's
(the C library's, within half a unit in the last place for these arguments), their
derivatives, and their behaviour on special values and other dtypes."""

from __future__ import annotations

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pointax.core.rotations import enu_to_azel  # noqa: E402
from pointax.core.trig import atan2, sincos  # noqa: E402


def _ulps(got, expected):
    """Error in units in the last place of the expected value."""
    return np.abs(np.asarray(got) - expected) / np.spacing(np.abs(expected)).clip(np.finfo(float).smallest_subnormal)


ARGUMENTS = {
    "encoder angles": np.random.default_rng(0).uniform(-7.0, 7.0, 200_000),
    "up to 1e5 rad": np.random.default_rng(1).uniform(-1e5, 1e5, 200_000),
    # sin or cos near 0: the reduction must keep the tiny remainder's relative accuracy.
    "near multiples of pi/2": (np.arange(-3000, 3000)[:, None] * (np.pi / 2) + np.array([0.0, 1e-12, -1e-9, 1e-6])).ravel(),
    "tiny": np.concatenate([10.0 ** -np.arange(1, 308), -(10.0 ** -np.arange(1, 308)), [0.0, -0.0, 5e-324]]),
}


@pytest.mark.parametrize("name", ARGUMENTS)
def test_sincos_is_within_two_ulps_of_numpy(name):
    x = ARGUMENTS[name]
    sin, cos = jax.jit(sincos)(x)
    assert np.asarray(sin).dtype == np.float64
    assert _ulps(sin, np.sin(x)).max() <= 2.0
    assert _ulps(cos, np.cos(x)).max() <= 2.0


def test_sincos_keeps_the_sign_of_zero_and_gives_nan_for_non_finite():
    sin, cos = sincos(jnp.array([0.0, -0.0]))
    assert np.array_equal(np.signbit(sin), [False, True]) and np.all(np.asarray(cos) == 1.0)
    sin, cos = sincos(jnp.array([np.inf, -np.inf, np.nan]))
    assert np.all(np.isnan(sin)) and np.all(np.isnan(cos))


def test_sincos_derivatives_are_cos_and_minus_sin():
    x = np.linspace(-10.0, 10.0, 101)
    dsin = jax.vmap(jax.grad(lambda t: sincos(t)[0]))(x)
    dcos = jax.vmap(jax.grad(lambda t: sincos(t)[1]))(x)
    np.testing.assert_allclose(dsin, np.cos(x), rtol=0, atol=2.3e-16)
    np.testing.assert_allclose(dcos, -np.sin(x), rtol=0, atol=2.3e-16)
    # Second derivative through the rule (the rule calls sincos again).
    d2 = jax.grad(jax.grad(lambda t: sincos(t)[0]))(0.7)
    np.testing.assert_allclose(d2, -np.sin(0.7), rtol=0, atol=2.3e-16)


def test_sincos_of_other_dtypes_is_jax_own():
    x = jnp.linspace(-3.0, 3.0, 7, dtype=jnp.float32)
    sin, cos = sincos(x)
    assert sin.dtype == jnp.float32
    np.testing.assert_array_equal(sin, jnp.sin(x))
    np.testing.assert_array_equal(cos, jnp.cos(x))


_RNG = np.random.default_rng(2)
_N = 200_000
ATAN2_ARGUMENTS = {
    "unit square": (_RNG.uniform(-1, 1, _N), _RNG.uniform(-1, 1, _N)),
    # Results below the smallest normal number are flushed to 0 by XLA on the CPU: the
    # ratios stay within 1e280 here.
    "wide range": (
        _RNG.choice([-1.0, 1.0], _N) * 10.0 ** _RNG.uniform(-140, 140, _N),
        _RNG.choice([-1.0, 1.0], _N) * 10.0 ** _RNG.uniform(-140, 140, _N),
    ),
    "near the diagonals": ((t := _RNG.uniform(-1, 1, _N)), np.sign(_RNG.uniform(-1, 1, _N)) * t * (1 + _RNG.normal(0, 1e-3, _N))),
    "near tan(pi/8)": (np.tan(np.pi / 8) * (1 + _RNG.normal(0, 1e-9, _N)), np.ones(_N)),
    "near the axes": (_RNG.normal(0, 1e-8, _N), _RNG.choice([-1.0, 1.0], _N)),
}


@pytest.mark.parametrize("name", ATAN2_ARGUMENTS)
def test_atan2_is_within_two_ulps_of_numpy(name):
    y, x = ATAN2_ARGUMENTS[name]
    got = jax.jit(atan2)(y, x)
    assert _ulps(got, np.arctan2(y, x)).max() <= 2.0
    got = jax.jit(atan2)(x, y)  # the other octants
    assert _ulps(got, np.arctan2(x, y)).max() <= 2.0


def test_atan2_special_values_are_the_c_library_s():
    values = np.array([0.0, -0.0, 1.0, -1.0, np.inf, -np.inf, np.nan])
    y, x = (a.ravel() for a in np.meshgrid(values, values))
    finite_pair = ~(np.isinf(y) & np.isinf(x))
    got, expected = np.asarray(atan2(y, x)), np.arctan2(y, x)
    same = (got == expected) & (np.signbit(got) == np.signbit(expected)) | (np.isnan(got) & np.isnan(expected))
    close = _ulps(got, expected) <= 1.0  # +-pi/2 from x = -0 or y = +-inf: one unit off
    assert np.all((same | close)[finite_pair])
    assert np.all(np.isnan(got[~finite_pair]))  # both infinite: NaN (documented)


def test_atan2_gradient_and_other_dtypes():
    y, x = np.linspace(-2, 2, 40), np.linspace(1.5, -1.5, 40)  # not through (0, 0)
    gy, gx = jax.vmap(jax.grad(atan2, argnums=(0, 1)))(y, x)
    r2 = x * x + y * y
    np.testing.assert_allclose(gy, x / r2, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(gx, -y / r2, rtol=1e-14, atol=1e-15)
    y32, x32 = jnp.float32(0.3), jnp.float32(-0.7)
    assert atan2(y32, x32).dtype == jnp.float32 and atan2(y32, x32) == jnp.arctan2(y32, x32)


def test_enu_to_azel_with_the_polynomial_arctangent():
    v = np.random.default_rng(3).normal(size=(1000, 3))
    v = np.concatenate([v, [[0.0, 0.0, 1.0], [0.0, 0.0, -2.0], [1e-200, 0.0, 1.0]]])
    az, el = enu_to_azel(v)
    az_fast, el_fast = jax.jit(lambda v: enu_to_azel(v, atan2))(v)
    np.testing.assert_allclose(az_fast, az, rtol=0, atol=8.9e-16)
    np.testing.assert_allclose(el_fast, el, rtol=0, atol=4.5e-16)
    assert az_fast[-3] == 0.0 and az_fast[-2] == 0.0  # the zenith and nadir: azimuth 0

"""Tests for pointax.trig: the vectorised sine and cosine against NumPy's (the C
library's, within half a unit in the last place for these arguments), their exact
derivatives, and their behaviour on special values and other dtypes."""

from __future__ import annotations

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pointax.trig import sincos  # noqa: E402


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

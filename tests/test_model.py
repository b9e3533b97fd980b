"""Model: parameter naming and editing, and jit/vmap/grad through the pointing chain.

References: closed-form directions (azel_to_enu written out here) and central finite
differences.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import pointax as px

ARCSEC = np.pi / 648000


class TwoParams(px.Term):
    a: float = px.param(0.0)
    b: float = px.param(0.0, unit="deg")

    def encoder_offset(self, encoder):
        return jnp.stack([self.a, self.b])


# Plain numbers as values on purpose (the editing, not the units, is tested here).
@pytest.mark.filterwarnings("ignore:.*most likely in degrees:pointax.core.errors.InputWarning")
def test_parameter_names_units_and_editing():
    model = px.AltAz([px.terms.IA(coef=1.0), TwoParams(a=2.0, b=3.0)])
    assert model.parameter_names == ["IA", "TwoParams.a", "TwoParams.b"]
    assert [p.unit for p in model.parameters] == ["arcsec", "arcsec", "deg"]
    np.testing.assert_array_equal(np.asarray(model.values()), [1.0, 2.0, 3.0])
    edited = model.set(IA=5.0, **{"TwoParams.b": 7.0})
    assert float(edited.get("IA")) == 5.0 and float(edited.get("TwoParams.b")) == 7.0
    assert float(model.get("IA")) == 1.0  # models are immutable
    fixed = model.fix("TwoParams.a")
    assert [p.name for p in fixed.free_parameters] == ["IA", "TwoParams.b"]
    np.testing.assert_array_equal(np.asarray(fixed.values("free")), [1.0, 3.0])
    refreed = fixed.with_values(jnp.array([8.0, 9.0]), "free")
    np.testing.assert_array_equal(np.asarray(refreed.values()), [8.0, 2.0, 9.0])
    assert fixed.free().fixed == frozenset()
    assert model.without_terms("IA").parameter_names == ["TwoParams.a", "TwoParams.b"]
    assert model.with_terms(px.terms.IE()).parameter_names[-1] == "IE"
    with pytest.raises(KeyError, match="no parameter 'XX'"):
        model.set(XX=1.0)
    with pytest.raises(KeyError, match="no parameter"):
        model.get("XX")
    with pytest.raises(ValueError, match="more than once: IA"):
        px.AltAz([px.terms.IA(), px.terms.rigorous.IA()])
    with pytest.raises(ValueError, match="expected 3 values"):
        model.with_values(jnp.zeros(2))
    with pytest.raises(ValueError, match="which must be 'all' or 'free'"):
        model.values("fixed")
    with pytest.raises(TypeError, match="not a pointax.Term"):
        px.AltAz(["IA"])
    with pytest.raises(ValueError, match="unknown azimuth convention"):
        px.AltAz([], azimuth="E-N")


def test_nominal_model_points_where_the_encoders_say():
    enc = np.array([[0.0, 0.0], [np.pi / 2, 0.3], [-2.0, 1.2], [1.0, np.pi / 2]])
    az, el = enc.T
    expected = np.stack([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)], -1)
    np.testing.assert_allclose(np.asarray(px.AltAz([])(enc)), expected, atol=1e-15)
    # S-E counts azimuth from South through East: A = 180 deg - A_north.
    mirrored = np.asarray(px.AltAz([], azimuth="S-E")(np.stack([np.pi - az, el], -1)))
    np.testing.assert_allclose(mirrored, expected, atol=1e-15)


def test_jit_vmap_grad_through_the_model():
    model = px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX", values={"IA": 30 * ARCSEC, "TF": 10 * ARCSEC}))
    enc = jnp.array([0.4, 0.9])
    jitted = jax.jit(model.direction)(enc)
    np.testing.assert_allclose(np.asarray(jitted), np.asarray(model.direction(enc)), atol=1e-16)
    batch = jnp.array([[0.4, 0.9], [2.0, 0.3]])
    np.testing.assert_allclose(np.asarray(jax.vmap(model.direction)(batch)), np.asarray(model(batch)), atol=1e-16)

    def height(y):
        return model.with_values(y).direction(enc)[2]

    y0 = model.values()
    grad = np.asarray(jax.grad(height)(y0))
    h = 1e-7
    fd = np.array([(height(y0.at[k].add(h)) - height(y0.at[k].add(-h))) / (2 * h) for k in range(len(y0))])
    np.testing.assert_allclose(grad, fd, atol=1e-8)
    # Elevation terms move the height, pure azimuth terms do not.
    assert abs(grad[1]) > 0.1 and abs(grad[0]) < 1e-6


def test_gradient_is_finite_at_the_zenith():
    model = px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW", form="rigorous"))
    enc = jnp.array([0.3, np.pi / 2])
    jac = jax.jacfwd(lambda y: model.with_values(y).direction(enc))(model.values())
    assert np.all(np.isfinite(np.asarray(jac)))


def test_calls_outside_a_trace_compile_once_per_model_structure():
    """px.residuals, the per-observation model, the model's call on a batch and
    px.simulate, called outside any jit, are one compiled program per model structure
    (pointax.core.compiled): a second call, new values of the same terms (Python
    numbers, as a term's defaults are, or arrays) and new encoder angles compile
    nothing. (Op by op, the sky offsets' fixed-point loop compiled again at every
    call.) The answers are those of the same functions traced inside jit."""
    from compile_counter import COUNTER

    def model(ia, an):  # sky offsets (linear form): the fixed-point loop runs
        return px.AltAz([px.terms.IA(coef=ia), px.terms.AN(coef=an), px.terms.CA(coef=0.0)])

    obs = px.simulate(model(30 * ARCSEC, -12 * ARCSEC), np.array([[0.3, 0.5], [2.0, 1.1], [-1.0, 0.8]]))
    first, second = model(10 * ARCSEC, 5 * ARCSEC), model(-4 * ARCSEC, 20 * ARCSEC)
    px.residuals(first, obs)
    first.mount_direction(np.array([0.1, 0.4]))
    grid = np.array([[0.2, 0.4], [0.3, 0.4]])
    first(grid + 0.1)
    px.simulate(first, grid)
    as_arrays = second.with_values(second.values())  # the same values, as JAX arrays
    with COUNTER as counted:
        r_first, r_second = px.residuals(first, obs), px.residuals(second, obs)
        d = [second.mount_direction(np.array([a, 0.4])) for a in (0.2, 0.3)]
        called = second(grid)
        simulated = px.simulate(as_arrays, grid)
    assert counted.count == 0
    np.testing.assert_array_equal(simulated.target, px.simulate(second, grid).target)
    assert not np.allclose(r_first, r_second)
    traced = jax.jit(lambda m: px.residuals(m, obs))(second)
    np.testing.assert_allclose(r_second, traced, rtol=0, atol=1e-15)
    traced_d = jax.jit(jax.vmap(second.mount_direction))(grid)
    np.testing.assert_allclose(np.stack(d), traced_d, rtol=0, atol=1e-15)
    np.testing.assert_allclose(called, jax.jit(jax.vmap(second.direction))(grid), rtol=0, atol=1e-15)

"""The fitting problem of a site (pointax.fitting.problem on pointax.fitting.fast_evaluation), its derivatives
(pointax.fitting.fast_jacobian) and the small normal-equation solver: references are the
plain per-observation model (pointax.residuals), jax.jacfwd of it, finite differences,
and numpy's least squares."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import pointax as px
from pointax.fitting import matrix_entries as entries
from pointax.fitting import normal_equations as ne
from pointax.fitting import fast_evaluation as site
from pointax.core.rotations import rot_z
from pointax.core.simulate import encoder_grid
from pointax.fitting.problem import site_data, site_residuals
from pointax.fitting.fast_jacobian import residual_columns, residual_function

RNG = np.random.default_rng(7)
TPOINT8 = "IA IE NPAE CA AN AW TF TX"


def _weights(n):
    w = RNG.uniform(0.5, 2.0, n)
    w[3] = 0.0  # an unused row
    return w


def values_gem():
    return {n: px.arcsec(v) for n, v in zip("IH ID CH NP MA ME".split(), RNG.normal(0, 60, 6))}


def _cases():
    values = {n: px.arcsec(v) for n, v in zip(TPOINT8.split(), RNG.normal(0, 40, 8))}
    tt = px.Turntable("full").set(mu0=px.deg(0.07), nu0=px.deg(0.01), omega0=px.deg(-0.09), alpha0=px.deg(60.5), beta0=px.deg(165.9))
    enc = np.stack([RNG.uniform(0, 2 * np.pi, 40), px.deg(165.9) + RNG.uniform(0.2, 1.2, 40)], axis=1)
    linear = px.AltAz(px.terms.tpoint(TPOINT8, form="linear", values=values), azimuth="S-E")
    rigorous = px.AltAz(px.terms.tpoint(TPOINT8, form="rigorous", values=values))
    harmonic = px.AltAz(px.terms.tpoint("IA IE HACA2 HESE1", values={"HACA2": px.arcsec(20), "IA": px.arcsec(5)}))
    xy = px.XY("basic")
    xy = xy.with_values(np.asarray(RNG.normal(0, px.arcsec(30), len(xy.parameters))))
    xy_enc = np.stack([RNG.uniform(-1.0, 1.0, 40), RNG.uniform(-0.9, 0.9, 40)], axis=1)
    # A German equatorial mount, half the readings across the pier (declination axis past
    # the pole, written as TheSkyX writes it: -180 to -90 deg), TPOINT's residual form.
    gem = px.Equatorial(
        px.terms.tpoint("IH ID CH NP MA ME", mount="equatorial", latitude=0.6, values=values_gem()), latitude=0.6,
        residual_form="tpoint",
    )
    ha, dec = RNG.uniform(-1.2, 1.2, 40), RNG.uniform(-0.4, 1.2, 40)
    flip = np.arange(40) % 2 == 1
    gem_enc = np.stack([np.where(flip, ha + np.pi, ha), np.where(flip, -np.pi - dec, dec)], axis=1)
    return {
        "equatorial (GEM, across the pier)": (gem, gem_enc),
        "turntable": (tt, enc),
        "altaz linear (sky offsets)": (linear, encoder_grid()),
        "altaz rigorous": (rigorous, encoder_grid()),
        "altaz harmonic": (harmonic, encoder_grid()),
        "xy basic": (xy, xy_enc),
    }


CASES = _cases()
# Jacobians are compared where the chain differs in kind (encoder offsets and rotations;
# sky offsets); the other cases check the residuals (compiling jacfwd of the plain model
# costs ~15 s each).
JACOBIAN_CASES = ("turntable", "altaz linear (sky offsets)")


@pytest.mark.parametrize("name", sorted(CASES))
def test_site_residuals_and_columns_equal_the_plain_model(name):
    truth, enc = CASES[name]
    obs = px.simulate(truth, enc, noise=px.arcsec(2), seed=1)
    obs = px.Observations(obs.encoder, obs.target, _weights(len(obs)), obs.convention)
    start = truth.with_values(np.asarray(truth.values()) * 0.9)
    model = start.with_values(start.values())
    with jax.enable_x64(True):
        w = np.asarray(obs.weight)
        sqrt_w = np.sqrt(w * np.sum(w > 0) / np.sum(w))[:, None]
        data = site_data(model, obs)
        rx, ry = jax.jit(site_residuals)(model, data)
        reference = np.asarray(px.residuals(model, obs)) * sqrt_w
        assert np.max(np.abs(np.stack([rx, ry], -1) - reference)) < 1e-14
        if name not in JACOBIAN_CASES:
            return
        params = model.free_parameters
        cols = jax.jit(lambda m, d: residual_columns(m, d, params))(model, data)
        jac = jax.jacfwd(lambda y: px.residuals(model.with_values(y, "free"), obs) * sqrt_w)(model.values("free"))
        got = np.stack([np.stack(c, -1) for c in cols], -1)
        assert np.max(np.abs(got - np.asarray(jac))) < 1e-13 * max(1.0, np.max(np.abs(jac)))


@pytest.mark.parametrize("name", sorted(CASES))
def test_the_fitting_problem_equals_the_plain_model(name):
    """The solo fit's problem definition (pointax.fitting.problem: the site data with
    XLA's library sines and cosines in the sky form's fixed point) gives the plain
    per-observation model's residuals, unweighted, 0 for the unused row."""
    from pointax.fitting.problem import define_problem

    truth, enc = CASES[name]
    obs = px.simulate(truth, enc, noise=px.arcsec(2), seed=2)
    obs = px.Observations(obs.encoder, obs.target, _weights(len(obs)), obs.convention)
    model = truth.with_values(np.asarray(truth.values()) * 1.1)
    with jax.enable_x64(True):
        problem = jax.jit(define_problem)(model, obs)
        assert problem.data.library_trig
        ours = np.asarray(jax.jit(lambda m, p: p.residuals(m))(model, problem))
        reference = np.asarray(px.residuals(model, obs))
    assert ours[3].tolist() == [0.0, 0.0]
    assert np.max(np.abs(ours - reference)) < 1e-14


def test_a_pinned_zero_adds_nothing_where_its_unit_offset_is_infinite():
    """TPOINT's NPAE (dA = -tan E) has an infinite unit offset at a star exactly at the
    zenith (the observed point's cos E is 0 there). Held at 0 and not fitted, as a fit
    carries the terms a model lacks (pointax.fitting.structure), it must add exactly
    nothing there, in the residuals and the fitted parameters' derivatives (0 * inf
    would be NaN); fitted, it stays honest (not finite)."""
    from pointax.fitting.problem import define_problem

    model = px.AltAz(px.terms.tpoint("IA IE NPAE", form="linear", values={"IA": px.arcsec(20)}), residual_form="tpoint")
    obs = px.simulate(model, encoder_grid(), noise=px.arcsec(1), seed=3)
    target = np.array(obs.target)
    target[5] = [0.0, 0.0, 1.0]
    obs = px.Observations(obs.encoder, target, convention=obs.convention)
    reference = px.AltAz(px.terms.tpoint("IA IE", form="linear", values={"IA": px.arcsec(20)}), residual_form="tpoint")
    with jax.enable_x64(True):
        assert not np.all(np.isfinite(np.asarray(site_data(model, obs).sky_basis[2][0])))  # NPAE's, there
        pinned = define_problem(model, obs, np.array([True, True, False]))
        ours = pinned.residuals(model)
        theirs = define_problem(reference, obs, np.array([True, True])).residuals(reference)
        np.testing.assert_array_equal(np.asarray(ours), np.asarray(theirs))
        jac = jax.jacfwd(lambda y: pinned.residuals(model.with_values(jnp.append(y, 0.0))))(jnp.asarray(model.values()[:2]))
        jac_ref = jax.jacfwd(lambda y: define_problem(reference, obs).residuals(reference.with_values(y)))(
            jnp.asarray(reference.values())
        )
        np.testing.assert_array_equal(np.asarray(jac), np.asarray(jac_ref))
        fitted = define_problem(model, obs, np.array([True, True, True])).residuals(model)
        assert not np.all(np.isfinite(np.asarray(fitted)[5]))


def test_residual_function_derivative_with_respect_to_the_data():
    """The custom derivative also carries derivatives with respect to the data (targets):
    checked against central finite differences."""
    truth, enc = CASES["turntable"]
    obs = px.simulate(truth, enc, noise=px.arcsec(5), seed=2)
    model = truth.with_values(truth.values())
    params = model.free_parameters
    fn = residual_function(params)
    with jax.enable_x64(True):
        y = model.values("free")

        def f(t):
            o = px.Observations(obs.encoder, t, obs.weight, obs.convention)
            return jnp.sum(fn(y, (model, site_data(model, o)))[0] ** 2)

        target = jnp.asarray(obs.target)
        direction = jnp.asarray(RNG.normal(size=target.shape)) * 1e-3
        ad = jax.jvp(f, (target,), (direction,))[1]
        h = 1e-5
        fd = (f(target + h * direction) - f(target - h * direction)) / (2 * h)
        assert abs(float(ad) - float(fd)) < 1e-8 * max(1.0, abs(float(fd)))
        g = jax.grad(f)(target)  # reverse mode through the custom derivative
        assert float(jnp.sum(g * direction)) == pytest.approx(float(ad), rel=1e-9, abs=1e-15)


def test_normal_equations_match_numpy_least_squares():
    rng = np.random.default_rng(11)
    a = rng.normal(size=(30, 6))
    a[:, 5] = a[:, 4] + 0.01 * a[:, 5]  # correlated columns, still full rank (cond(A^T A) ~ 1e5)
    b = rng.normal(size=30)
    with jax.enable_x64(True):
        cols = [jnp.asarray(a[:, k]) for k in range(6)]
        low, pivots = ne.cholesky(ne.normal_matrix(cols))
        x = ne.solve(low, [ne.inner(c, jnp.asarray(b)) for c in cols])
        inv = ne.inverse(low)
    ref = np.linalg.lstsq(a, b, rcond=None)[0]
    # Normal equations: errors grow with cond(A^T A) (~1e5 here) times the machine epsilon.
    assert np.max(np.abs(np.asarray(x) - ref)) < 1e-14 * np.linalg.cond(a.T @ a) * max(1.0, np.max(np.abs(ref)))
    assert np.max(np.abs(np.asarray(inv) - np.linalg.inv(a.T @ a))) < 1e-9 * np.linalg.cond(a.T @ a) * np.max(np.abs(np.linalg.inv(a.T @ a)))
    assert np.all(np.asarray(pivots) > 0) and np.min(np.asarray(pivots)) < 1e-3  # the correlated column shows



def test_entry_algebra_with_symbolic_signs():
    # mul and add keep constant zeros, ones and minus ones out of the arithmetic and a
    # sign symbolic until an addition takes it; references: NumPy on the same values.
    x, y = RNG.normal(size=4), RNG.normal(size=4)
    cases = [0.0, 1.0, -1.0, 2.5, x, y, entries.Neg(x), entries.Neg(y)]

    def plain(e):
        return -e.x if isinstance(e, entries.Neg) else e

    for a in cases:
        for b in cases:
            np.testing.assert_array_equal(entries.value(entries.mul(a, b)), plain(a) * plain(b))
            np.testing.assert_array_equal(entries.value(entries.add(a, b)), plain(a) + plain(b))
    assert entries.mul(-1.0, x).x is x and entries.mul(entries.Neg(x), -1.0) is x  # no arithmetic


def test_axis_forms_of_the_mounts_are_exact():
    # Rotations about coordinate axes: every entry of alpha, beta, gamma is exactly 0 or
    # +-1 (sin pi is not exactly 0 in floating point), so the fit skips them.
    for mount in (px.Turntable("full").mount, px.AltAz(px.terms.tpoint(("IA",))).mount, px.XY("basic").mount):
        for axis in ("axis1", "axis2"):
            form = entries.axis_form(mount, axis)
            assert form is not None
            for m in form:
                assert set(np.unique(m)) <= {-1.0, 0.0, 1.0}, (type(mount).__name__, axis, m)


def test_constant_mount_geometry_is_constant_while_tracing():
    # The structured evaluation skips the zeros and ones of a constant boresight and
    # frame: that needs them as Python floats inside jit, not as traced values.
    seen = {}

    def f(model):
        seen["boresight"] = site._boresight(model.mount)
        seen["frame"] = entries.constant_entries(lambda: model.mount.frame)
        return 0.0

    for model in (px.Turntable("full"), px.AltAz(px.terms.tpoint(("IA",)), azimuth="S-E")):
        with jax.enable_x64(True):
            jax.jit(f)(model)
        assert all(type(x) is float for x in seen["boresight"])
        assert all(type(x) is float for row in seen["frame"] for x in row)
        np.testing.assert_array_equal(seen["frame"], np.asarray(model.mount.frame))


def test_axis_form_while_tracing():
    # Inside jit the fixed-axis form alpha + beta sin t + gamma cos t is still found for a
    # constant axis, and equals the axis rotation (NumPy's cos and sin of Rz); an axis
    # that reads a traced value has no constant form (None), not an error.
    seen = {}

    def f(tilt):
        seen["constant"] = entries.axis_form_uncached(rot_z)
        seen["traced"] = entries.axis_form_uncached(lambda t: rot_z(t + tilt))
        return tilt

    with jax.enable_x64(True):
        jax.jit(f)(0.1)
    assert seen["traced"] is None
    alpha, beta, gamma = seen["constant"]
    for t in RNG.uniform(-7, 7, 5):
        c, s = np.cos(t), np.sin(t)
        rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        np.testing.assert_allclose(alpha + beta * s + gamma * c, rz, rtol=0, atol=1e-15)

"""Terms whose coefficients vary with a reading (pointax.terms.thermal, in_time).

References: the wrapped term evaluated at the coefficient the closed form gives (no
readings), SciPy's B-spline design matrix and NumPy's interp for the time bases,
central finite differences for the Jacobian, and the true values of simulations
(recovered within 2 sigma).
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy_rotations import angle_between
from scipy.interpolate import BSpline

import pointax as px
from pointax.core.simulate import encoder_grid
from pointax.fitting.problem import define_problem
from pointax.terms.varying import bspline_basis, hat_basis

ARCSEC = np.pi / 180 / 3600


def _grid(copies):
    return np.concatenate([encoder_grid(az_offset_deg=5.0 * k) for k in range(copies)])


def test_thermal_names_and_closed_form():
    th = px.terms.thermal("TF", reference=10.0)
    assert th.name == "TF@temperature" and th.readings == ("temperature",)
    model = px.AltAz(list(px.terms.tpoint("IA IE")) + [th])
    assert model.parameter_names == ["IA", "IE", "TF@temperature.value", "TF@temperature.slope"]
    model = model.set(**{"TF@temperature.value": 12 * ARCSEC, "TF@temperature.slope": -0.5 * ARCSEC}, IA=3 * ARCSEC)
    assert model.get("TF@temperature.slope", "arcsec") == pytest.approx(-0.5)
    enc = _grid(1)
    for temp in (0.0, 10.0, 31.0):
        plain = px.AltAz(px.terms.tpoint("IA IE TF")).set(IA=3 * ARCSEC, TF=(12 - 0.5 * (temp - 10.0)) * ARCSEC)
        got = np.asarray(model(enc, readings={"temperature": temp}))
        assert np.max(angle_between(got, np.asarray(plain(enc)))) < 1e-14
    # another reading, a generated term
    wrapped = px.terms.thermal("HECA2", reading="pressure", reference=1000.0)
    assert wrapped.name == "HECA2@pressure" and wrapped.readings == ("pressure",)
    # the wrapped term's value is the start; the slope starts at 0
    start = px.terms.thermal(px.terms.CA(coef=7 * ARCSEC))
    assert float(start.value) == pytest.approx(7 * ARCSEC) and float(start.slope) == 0.0


def test_multi_parameter_term_names():
    class Wobble(px.Term):
        amp: float = px.param(0.0)
        phase: float = px.param(0.0, unit="rad")

        def sky_offset(self, angles):
            import jax.numpy as jnp

            return jnp.stack([self.amp * jnp.sin(angles[0] + self.phase), 0.0 * self.amp])

    model = px.AltAz([px.terms.thermal(Wobble(amp=2 * ARCSEC, phase=0.3))])
    assert model.parameter_names == [
        "Wobble@temperature.amp", "Wobble@temperature.amp_slope",
        "Wobble@temperature.phase", "Wobble@temperature.phase_slope",
    ]  # fmt: skip
    units = {p.name: p.unit for p in model.parameters}
    assert units["Wobble@temperature.phase_slope"] == "rad" and units["Wobble@temperature.amp_slope"] == "arcsec"


def test_in_time_polynomial_and_knots():
    mjd0 = 60000.0
    poly = px.terms.in_time("IA", degree=2, reference=mjd0)
    lin = px.terms.in_time("IE", knots=[mjd0, mjd0 + 100, mjd0 + 300], spline="linear")
    cub = px.terms.in_time("CA", knots=[mjd0, mjd0 + 100, mjd0 + 300])
    model = px.AltAz([poly, lin, cub])
    assert model.readings == ("time",)
    names = model.parameter_names
    assert names[:3] == ["IA@time.value", "IA@time.t1", "IA@time.t2"]
    assert names[3:6] == ["IE@time-linear.k0", "IE@time-linear.k1", "IE@time-linear.k2"]
    assert names[6:] == [f"CA@time-spline.k{k}" for k in range(5)]
    c = np.array([5.0, 0.02, -1e-4, 3.0, -2.0, 4.0, 1.0, 2.0, -1.0, 0.5, 3.0]) * ARCSEC
    model = model.with_values(c)
    enc = _grid(1)
    knots = np.array([mjd0, mjd0 + 100, mjd0 + 300])
    spline = BSpline(np.r_[[knots[0]] * 3, knots, [knots[-1]] * 3], c[6:], 3)
    for day in (mjd0 - 10, mjd0 + 40.0, mjd0 + 250.0):
        x = day - mjd0
        ia = c[0] + c[1] * x + c[2] * x**2
        ie = np.interp(day, knots, c[3:6])
        ca = float(spline(np.clip(day, knots[0], knots[-1])))
        plain = px.AltAz(px.terms.tpoint("IA IE CA")).set(IA=ia, IE=ie, CA=ca)
        got = np.asarray(model(enc, readings={"time": day}))
        assert np.max(angle_between(got, np.asarray(plain(enc)))) < 1e-14
    with pytest.raises(ValueError, match="reference"):
        px.terms.in_time("IA")
    with pytest.raises(ValueError, match="increasing"):
        px.terms.in_time("IA", knots=[2.0, 1.0])


def test_time_bases_against_scipy_and_numpy():
    knots = np.array([0.0, 1.0, 2.5, 4.0, 7.0])
    xs = np.linspace(-1.0, 8.0, 37)
    t = np.r_[[knots[0]] * 3, knots, [knots[-1]] * 3]
    for x in xs:
        b = np.asarray(bspline_basis(x, knots))
        xc = np.clip(x, knots[0], knots[-1])
        want = BSpline.design_matrix([xc], t, 3).toarray()[0]
        np.testing.assert_allclose(b, want, atol=1e-14)
        h = np.asarray(hat_basis(x, knots))
        want = [np.interp(x, knots, np.eye(len(knots))[k]) for k in range(len(knots))]
        np.testing.assert_allclose(h, want, atol=1e-15)


@pytest.mark.parametrize("form", ["sky", "tpoint"])
def test_jacobian_matches_finite_differences(form):
    import jax

    model = px.AltAz(list(px.terms.tpoint("IA IE CA")) + [px.terms.thermal("TF", reference=5.0)], residual_form=form)
    truth = model.with_values(np.array([10.0, -4.0, 3.0, 20.0, 1.2]) * ARCSEC)
    enc = _grid(3)
    temps = np.repeat([-2.0, 8.0, 18.0], len(enc) // 3)
    obs = px.simulate(truth, enc, noise=ARCSEC, readings={"temperature": temps})
    v0 = np.asarray(truth.values()) * 0.6
    problem = define_problem(truth, obs)  # what the fit differentiates

    @jax.jit
    def residuals(v):
        return problem.residuals(truth.with_values(v)).ravel()

    jac = np.asarray(jax.jit(jax.jacfwd(residuals))(jax.numpy.asarray(v0)))
    h = 1e-7
    fd = np.stack(
        [(np.asarray(residuals(v0 + h * e)) - np.asarray(residuals(v0 - h * e))) / (2 * h) for e in np.eye(len(v0))],
        axis=-1,
    )
    np.testing.assert_allclose(jac, fd, atol=1e-7)
    # the slope's column is the value's times (T - reference): the closed form
    np.testing.assert_allclose(jac[:, 4], jac[:, 3] * np.repeat(temps - 5.0, 2), atol=1e-9)


def test_thermal_coefficient_recovered_within_two_sigma():
    """Simulated runs at several temperatures; the thermal coefficient and the physical
    terms fitted jointly from zero: each within 2 sigma of the truth."""
    model = px.AltAz(list(px.terms.tpoint("IA IE CA NPAE AN AW")) + [px.terms.thermal("TF", reference=10.0)])
    true = np.array([25.0, -12.0, 6.0, 4.0, -3.0, 2.5, 18.0, 0.9]) * ARCSEC
    truth = model.with_values(true)
    enc = _grid(4)
    temps = np.repeat([-4.0, 4.0, 12.0, 22.0], len(enc) // 4)
    for seed in range(3):
        obs = px.simulate(truth, enc, noise=1.5 * ARCSEC, seed=seed, readings={"temperature": temps})
        result = px.fit(model.with_values(np.zeros_like(true)), obs)
        assert bool(result.converged)
        values, sigmas = np.asarray(result.values), np.asarray(result.sigmas)
        slope = result.model.parameter_names.index("TF@temperature.slope")
        assert abs(values[slope] - true[slope]) < 2 * sigmas[slope]
        assert np.all(np.abs(values - true) < 3 * sigmas)  # the physical terms too (3 sigma over 8 of them)


@pytest.mark.slow
def test_thermal_flexure_example():
    import importlib.util

    from conftest import EXAMPLES

    spec = importlib.util.spec_from_file_location("thermal_flexure_example", EXAMPLES / "thermal_flexure.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    out = module.main(seed=0, verbose=False)
    assert out["converged"] and abs(out["slope_deviation"]) <= 2
    assert out["library_difference"] < 1e-6 and out["round_trip_rad"] < 1e-9

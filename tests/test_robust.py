"""Robust fits (loss, loss_scale, reject, outlier flags), robust_sigma and leave-one-out.

Independent references written here: the truth of simulated data and the rows where
gross outliers were injected; numpy medians for the robust sigma; scipy's loss
definitions (scipy.optimize.least_squares docs) and scipy.optimize.minimize for the
robust cost; a Python loop of plain fits for leave-one-out.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.optimize

import pointax as px
from compile_counter import COUNTER
from pointax.fitting import LOSSES, FitOptions, fit_model, free_mask, least_squares, robust_sigma
from pointax.core.simulate import encoder_grid

ARCSEC = math.pi / 648000
NAMES = "IA IE NPAE CA AN AW TF TX"
TRUE = {"IA": 35.0, "IE": -14.0, "NPAE": 6.0, "CA": -9.0, "AN": 4.0, "AW": -7.0, "TF": 11.0, "TX": 3.0}
OUTLIERS = {5: 60.0, 23: 110.0, 41: 200.0, 52: 300.0}  # row -> size, arcsec


def _model(values=None):
    values = {k: v * ARCSEC for k, v in (values or {}).items()}
    return px.AltAz(px.terms.tpoint(NAMES, form="rigorous", values=values))


def _tangent_basis(t):
    az = np.arctan2(t[:, 0], t[:, 1])
    el = np.arctan2(t[:, 2], np.hypot(t[:, 0], t[:, 1]))
    e_az = np.stack([np.cos(az), -np.sin(az), np.zeros_like(az)], -1)
    e_el = np.stack([-np.sin(el) * np.sin(az), -np.sin(el) * np.cos(az), np.cos(el)], -1)
    return e_az, e_el


def _inject(obs, outliers, seed=0):
    """Move the targets of ``outliers`` (row -> arcsec) in random directions (numpy)."""
    target = np.array(obs.target)
    rng = np.random.default_rng(seed)
    rows = np.array(list(outliers))
    e_az, e_el = _tangent_basis(target[rows])
    angle = rng.uniform(0, 2 * np.pi, len(rows))
    size = np.array(list(outliers.values())) * ARCSEC
    moved = target[rows] + np.tan(size)[:, None] * (np.cos(angle)[:, None] * e_az + np.sin(angle)[:, None] * e_el)
    target[rows] = moved / np.linalg.norm(moved, axis=-1, keepdims=True)
    return px.Observations(obs.encoder, target, obs.weight, obs.convention)


@pytest.fixture(scope="module")
def clean():
    return px.simulate(_model(TRUE), encoder_grid(12, (20, 35, 50, 65, 80)), noise=1.0 * ARCSEC, seed=39)


@pytest.fixture(scope="module")
def dirty(clean):
    return _inject(clean, OUTLIERS)


@pytest.fixture(scope="module")
def reference(dirty):
    """Plain least squares without the injected rows (weight 0)."""
    w = np.ones(len(dirty))
    w[list(OUTLIERS)] = 0.0
    return px.fit(_model(), dirty, weights=w)


@pytest.fixture(scope="module")
def linear_clean(clean):
    return px.fit(_model(), clean)


# --------------------------------------------------------------------------- 1. outliers


@pytest.mark.parametrize("loss", ["cauchy", "huber", "soft_l1"])
def test_robust_fit_flags_exactly_the_injected_outliers(dirty, reference, loss):
    r = px.fit(_model(), dirty, loss=loss)
    assert bool(r.converged), r.message
    assert r.outlier_indices() == sorted(OUTLIERS)
    assert int(r.n_obs) == len(dirty) - len(OUTLIERS)
    truth = np.array([TRUE[n] for n in r.names]) * ARCSEC
    assert np.all(np.abs(np.asarray(r.values) - truth) < 4 * np.asarray(r.sigmas))
    # The documented final stage: a plain fit of the kept rows.
    np.testing.assert_allclose(np.asarray(r.values), np.asarray(reference.values), rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.asarray(r.sigmas), np.asarray(reference.sigmas), rtol=1e-6)
    assert math.isclose(float(r.sky_rms), float(reference.sky_rms), rel_tol=1e-6)
    # Outliers keep their residuals (about their injected size), the others are ~1".
    sizes = np.linalg.norm(np.asarray(r.residuals), axis=-1) / ARCSEC
    for row, size in OUTLIERS.items():
        assert abs(sizes[row] - size) < 10
    assert 0.7 * ARCSEC < float(r.robust_scale) < 1.4 * ARCSEC
    # A plain fit is dragged by them.
    plain = px.fit(_model(), dirty)
    assert float(plain.sky_rms) > 10 * float(r.sky_rms)
    assert r.to_dict()["outliers"] == sorted(OUTLIERS) and r.to_dict()["loss"] == loss
    assert "outlier(s) beyond 3 sigma: observations 6, 24, 42, 53" in r.report()


# --------------------------------------------------------------------------- 2. no outliers


def test_robust_fit_of_clean_data_matches_the_linear_fit(clean, linear_clean):
    r = px.fit(_model(), clean, loss="cauchy")
    assert bool(r.converged)
    # What 3-sigma tails of these data give: the rows whose least-squares residual
    # exceeds 3 robust sigmas (numpy median of the norms); for seed 39, none.
    norms = np.linalg.norm(np.asarray(linear_clean.residuals), axis=-1)
    sigma = np.median(norms) / math.sqrt(2 * math.log(2))
    tails = np.flatnonzero(norms > 3 * sigma)
    assert len(tails) == 0 and np.max(norms) < 2.8 * sigma  # not borderline
    assert r.outlier_indices() == []
    # Two least-squares runs from different starts (the robust passes move it) agree to
    # the solver's tolerance, ~1e-12 rad; 1e-10 rad (2e-5") leaves room for rounding.
    np.testing.assert_allclose(np.asarray(r.values), np.asarray(linear_clean.values), rtol=0, atol=1e-10)
    np.testing.assert_allclose(np.asarray(r.sigmas), np.asarray(linear_clean.sigmas), rtol=1e-6)
    assert linear_clean.outlier_indices() == [] and float(linear_clean.robust_scale) == 0.0


# --------------------------------------------------------------------------- 3. robust_sigma


def test_robust_sigma_is_the_scaled_median_norm():
    rng = np.random.default_rng(3)
    r = rng.normal(size=(41, 2)) * 2.0
    r[:5] *= 100.0
    used = np.ones(41, bool)
    used[[0, 7, 12]] = False
    r[0] = np.nan  # unused rows may hold anything
    want = np.median(np.linalg.norm(r[used], axis=-1)) / math.sqrt(2 * math.log(2))
    got = float(robust_sigma(jnp.asarray(r), jnp.asarray(used)))
    assert math.isclose(got, want, rel_tol=1e-12)
    # Even count: numpy's median averages the middle two.
    used[1] = False
    want = np.median(np.linalg.norm(r[used], axis=-1)) / math.sqrt(2 * math.log(2))
    assert math.isclose(float(robust_sigma(jnp.asarray(r), jnp.asarray(used))), want, rel_tol=1e-12)


def test_robust_sigma_estimates_gaussian_sigma():
    rng = np.random.default_rng(4)
    for sigma in (1e-6, 0.3):
        r = rng.normal(scale=sigma, size=(20000, 2))
        got = float(robust_sigma(jnp.asarray(r), jnp.ones(20000, bool)))
        assert abs(got / sigma - 1) < 0.03
        # and 10 % of wild rows barely move it
        r[:2000] *= 1000
        got = float(robust_sigma(jnp.asarray(r), jnp.ones(20000, bool)))
        assert abs(got / sigma - 1) < 0.2


# --------------------------------------------------------------------------- 4. robust cost


def _scipy_rho(loss, z):
    """rho(z) of scipy.optimize.least_squares (its documentation), unit scale."""
    if loss == "cauchy":
        return np.log1p(z)
    if loss == "huber":
        return np.where(z <= 1, z, 2 * np.sqrt(z) - 1)
    if loss == "soft_l1":
        return 2 * (np.sqrt(1 + z) - 1)
    raise ValueError(loss)


@pytest.mark.parametrize("loss", ["cauchy", "huber", "soft_l1"])
def test_losses_are_scipys(loss):
    rng = np.random.default_rng(9)
    c = 3e-5
    r = rng.normal(scale=c, size=(200, 2)) * rng.choice([0.1, 1.0, 30.0], size=(200, 1))
    z = np.sum(r**2, axis=-1)
    got = np.asarray(LOSSES[loss](jnp.asarray(z), c**2))
    np.testing.assert_allclose(got, c**2 * _scipy_rho(loss, z / c**2), rtol=1e-12)
    # The scaled-residual trick: r * sqrt(rho(|r|^2) / |r|^2) has squares summing to sum rho.
    scaled = r * np.sqrt(got / z)[:, None]
    assert math.isclose(np.sum(scaled**2), np.sum(c**2 * _scipy_rho(loss, z / c**2)), rel_tol=1e-12)
    # rho(z) ~ z for small z: least squares near the centre.
    small = np.asarray(LOSSES[loss](jnp.asarray(1e-8 * c**2), c**2))
    assert math.isclose(float(small), 1e-8 * c**2, rel_tol=1e-8)


def test_robust_stage_minimises_sum_rho(dirty, reference):
    """The robust solve (pointax.fitting.least_squares with a loss and a given scale c)
    returns residuals whose squares sum to sum c^2 rho(|r|^2 / c^2), and its solution
    minimises that cost: scipy's LM on the per-observation residuals
    sqrt(c^2 rho(|r_i|^2 / c^2)) (a different but equivalent formulation) finds the
    same point, to a small fraction of the parameters' sigmas (IA, CA and NPAE share a
    flat valley of the cost, where the two stop a few mas apart; pointax's cost is the
    lower)."""
    model = _model().with_values(_model().values())
    obs = dirty
    c = 3.0  # arcsec
    rho = LOSSES["cauchy"]
    options = FitOptions("lm", 256, 1e-10, 1e-13)
    sol, fn = least_squares(model, free_mask(model), obs, jnp.ones(len(obs)), options, rho, (c * ARCSEC) ** 2)
    y = np.asarray(sol.value) / ARCSEC
    residual = jax.jit(lambda y: px.residuals(model.with_values(y * ARCSEC), obs) / ARCSEC)

    def per_obs(y):
        z = np.sum(np.asarray(residual(jnp.asarray(y))) ** 2, axis=-1)
        return np.sqrt(c**2 * _scipy_rho("cauchy", z / c**2))

    def cost(y):
        return float(np.sum(per_obs(y) ** 2))

    # The rescaled residuals' squares are the robust cost (at the solution and elsewhere).
    for yy in (y, y + np.linspace(-20, 20, len(y))):
        scaled = np.asarray(fn(jnp.asarray(yy * ARCSEC), None)) / ARCSEC
        assert math.isclose(np.sum(scaled**2), cost(yy), rel_tol=1e-10)
    ref = scipy.optimize.least_squares(per_obs, np.zeros(len(y)), method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    assert cost(y) <= cost(ref.x) * (1 + 1e-9)
    sigmas = np.asarray(reference.sigmas) / ARCSEC
    assert np.all(np.abs(y - ref.x) < 0.02 * sigmas)
    # Far from the linear fit of the kept rows only in the unweighted outlier pull.
    assert np.all(np.abs(y - np.asarray(reference.values) / ARCSEC) < 2 * sigmas)


# --------------------------------------------------------------------------- 5. leave-one-out


@pytest.fixture(scope="module")
def small():
    """16 observations (rows 0-15): one gross outlier (row 3) and one row with weight 0
    holding NaN (row 9). Padded with 44 weight-0 NaN rows to the 60 rows of the other
    tests' data, so the fits reuse their compiled code (and padding is exercised)."""
    obs = px.simulate(_model(TRUE), encoder_grid(4, (25, 45, 65, 85), az_offset_deg=20), noise=ARCSEC, seed=8)
    obs = _inject(obs, {3: 150.0}, seed=1)
    encoder = np.full((60, 2), np.nan)
    target = np.full((60, 3), np.nan)
    weight = np.zeros(60)
    encoder[:16], target[:16], weight[:16] = obs.encoder, obs.target, 1.0
    target[9] = np.nan
    weight[9] = 0.0
    return px.Observations(encoder, target, weight, obs.convention)


SMALL_USED = [i for i in range(16) if i != 9]
UNUSED = [9] + list(range(16, 60))


@pytest.fixture(scope="module")
def loo_runs(small):
    """Per loss: the batched leave-one-out, and a Python loop of fits with weight 0 on
    the left-out row, each predicting it through px.residuals on that row alone."""
    out = {}
    for loss in ("linear", "cauchy"):
        loo = px.leave_one_out(_model(), small, loss=loss)
        loop = {}
        for i in SMALL_USED:
            w = np.asarray(small.weight).copy()
            w[i] = 0.0
            r = px.fit(_model(), small, weights=w, loss=loss)
            row = slice(i, i + 1)
            one = px.Observations(np.asarray(small.encoder)[row], np.asarray(small.target)[row], None, small.convention)
            loop[i] = (r, np.asarray(px.residuals(r.model, one))[0])
        out[loss] = (loo, loop)
    return out


@pytest.mark.parametrize("loss", ["linear", "cauchy"])
def test_leave_one_out_matches_a_loop_of_fits(small, loo_runs, loss):
    loo, loop = loo_runs[loss]
    n = len(small)
    assert loo.errors.shape == (n,)
    errors, offsets = np.asarray(loo.errors), np.asarray(loo.offsets)
    # The weight-0 row is NaN; its NaN target poisons no other fold.
    assert np.all(np.isnan(errors[UNUSED])) and np.all(np.isnan(offsets[UNUSED]))
    assert np.all(np.isfinite(errors[SMALL_USED]))
    for i in SMALL_USED:
        r, offset = loop[i]
        np.testing.assert_allclose(offsets[i], offset, rtol=0, atol=1e-9)
        assert abs(errors[i] - np.linalg.norm(offset)) < 1e-9
        np.testing.assert_allclose(np.asarray(loo.folds.values)[i], np.asarray(r.values), rtol=0, atol=1e-9)
        np.testing.assert_array_equal(np.asarray(loo.folds.outliers)[i], np.asarray(r.outliers))
        assert int(loo.folds.n_obs[i]) == int(r.n_obs) <= 14
    assert math.isclose(loo.rms(), math.sqrt(np.mean(errors[SMALL_USED] ** 2)), rel_tol=1e-12)
    if loss == "linear":
        assert np.all(np.asarray(loo.converged)[SMALL_USED])
    else:
        # The left-out outlier cannot help predict itself, and no other fold uses it.
        assert errors[3] > 100 * ARCSEC
        outliers = np.asarray(loo.folds.outliers)
        assert all(outliers[i, 3] for i in SMALL_USED if i != 3)
        assert np.max(errors[[i for i in SMALL_USED if i != 3]]) < 10 * ARCSEC


# --------------------------------------------------------------------------- 6. arguments


@pytest.mark.parametrize(
    "kwargs, word",
    [
        ({"loss": "tukey"}, "loss"),
        ({"loss": "cauchy", "loss_scale": -1e-5}, "loss_scale"),
        ({"loss": "cauchy", "loss_scale": 0.0}, "loss_scale"),
        ({"loss": "cauchy", "loss_scale": math.nan}, "loss_scale"),
        ({"loss": "cauchy", "reject": 0.0}, "reject"),
        ({"loss": "cauchy", "reject": -2.0}, "reject"),
    ],
)
def test_bad_arguments(clean, kwargs, word):
    with pytest.raises(ValueError, match=word):
        px.fit(_model(), clean, **kwargs)


def test_leave_one_out_rejects_unknown_loss(clean):
    with pytest.raises(ValueError, match="loss"):
        px.leave_one_out(_model(), clean, loss="tukey")


def test_down_weighted_observations_are_not_rejected_for_being_imprecise():
    """Gaussian noise with two precisions and correct 1/sigma^2 weights: the robust fit
    judges sqrt(w) r, so neither group is flagged (3-sigma tails aside)."""
    grid = encoder_grid(12, (20, 35, 50, 65, 80))
    truth = _model(TRUE)
    noisy = np.arange(len(grid)) % 2 == 0  # every other observation is 5x noisier
    precise = px.simulate(truth, grid, noise=1.0 * ARCSEC, seed=3)
    rough = px.simulate(truth, grid, noise=5.0 * ARCSEC, seed=4)
    target = np.where(noisy[:, None], np.asarray(rough.target), np.asarray(precise.target))
    weight = np.where(noisy, 1 / 25.0, 1.0)
    obs = px.Observations(grid, target, weight, precise.convention)
    result = px.fit(_model(), obs, loss="cauchy")
    assert bool(result.converged)
    flagged = np.asarray(result.outliers)
    assert flagged[noisy].sum() <= 1 and flagged[~noisy].sum() <= 1, result.outlier_indices()


def test_leave_one_out_checks_the_convention_and_honours_fixed(clean):
    wrong = px.Observations(clean.encoder[:12], clean.target[:12], convention="S-E")
    with pytest.raises(ValueError, match="convention"):
        px.leave_one_out(_model(), wrong)
    loo = px.leave_one_out(_model(TRUE), clean[:12], fixed=("TX", "TF", "AW", "AN"))
    assert loo.folds.values.shape == (12, 4)


# --------------------------------------------------------------------------- 7. program size


def _loops(jaxpr) -> tuple[int, int]:
    """``(every while loop, innermost ones)`` anywhere in ``jaxpr``: each optimistix
    solve is an innermost loop; a robust fit's passes are a loop around one."""
    from jax.extend.core import ClosedJaxpr

    every = innermost = 0
    for eqn in jaxpr.eqns:
        inside = (0, 0)
        for value in eqn.params.values():
            for sub in value if isinstance(value, (tuple, list)) else (value,):
                if isinstance(sub, ClosedJaxpr):
                    found = _loops(sub.jaxpr)
                    inside = (inside[0] + found[0], inside[1] + found[1])
        every += inside[0] + (eqn.primitive.name == "while")
        innermost += inside[1] + (eqn.primitive.name == "while" and inside[0] == 0)
    return every, innermost


@pytest.mark.parametrize("loss, scale", [("linear", None), ("cauchy", None), ("cauchy", 1e-5), ("huber", None)])
def test_robust_passes_are_one_compiled_solve(loss, scale):
    """A robust fit's passes (robust solves, then least squares without the outliers)
    run in a loop around one solve, so its program holds one solver, as a least-squares
    fit's does, not one per pass (a cold robust `px.fit` of the MMT run: 12.6 s -> 6 s).
    Traced as px.fit runs it: the robust settings as arguments."""
    from pointax.fitting.core import FitSettings, fit_core

    model = _model()
    obs = px.simulate(model, encoder_grid(4, (25, 45, 65, 85)), noise=ARCSEC, seed=3)
    options = FitOptions(loss=loss, loss_scale=scale)
    run = lambda o, robust: fit_core(model, free_mask(model), o, options.compiled(), robust)  # noqa: E731
    every, solves = _loops(jax.make_jaxpr(run)(obs, FitSettings.of(options)).jaxpr)
    assert solves == 1 and every == (1 if loss == "linear" else 2)


def test_another_loss_scale_or_reject_refits_without_compiling(dirty, reference):
    """A robust fit's loss, scale and rejection threshold are data of its compiled
    program: after one robust fit, each of them changed compiles nothing, and each
    takes effect (the injected outliers for another loss, none beyond a lenient
    threshold: then the plain least-squares fit of every row; a given scale as the
    same settings compiled as constants give)."""
    px.fit(_model(), dirty, loss="cauchy")
    with COUNTER:
        huber = px.fit(_model(), dirty, loss="huber")
        scaled = px.fit(_model(), dirty, loss="soft_l1", loss_scale=2 * ARCSEC, reject=2.5)
        lenient = px.fit(_model(), dirty, loss="cauchy", reject=1000.0)
    assert COUNTER.count == 0
    assert (huber.loss, huber.reject, scaled.loss, scaled.reject, lenient.reject) == ("huber", 3.0, "soft_l1", 2.5, 1000.0)
    assert huber.outlier_indices() == sorted(OUTLIERS)
    np.testing.assert_allclose(np.asarray(huber.values), np.asarray(reference.values), rtol=0, atol=1e-9)
    assert lenient.outlier_indices() == [] and "0 outlier(s) beyond 1000 sigma" in lenient.report()
    plain = px.fit(_model(), dirty)
    np.testing.assert_allclose(np.asarray(lenient.values), np.asarray(plain.values), rtol=0, atol=1e-10)
    options = FitOptions(loss="soft_l1", loss_scale=2 * ARCSEC, reject=2.5)
    constants = jax.jit(lambda o: fit_model(_model(), o, options))(dirty)
    np.testing.assert_array_equal(scaled.outliers, np.asarray(constants.outliers))
    np.testing.assert_allclose(np.asarray(scaled.values), np.asarray(constants.values), rtol=0, atol=1e-11)
    assert "beyond 2.5 sigma" in scaled.report()

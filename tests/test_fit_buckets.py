"""A fit compiles once per bucket of run lengths (:func:`pointax.fitting.solo.fit_bucket`):
runs of different lengths in one bucket share the compiled fit (counted with JAX's
compilation events), and the padded fit equals the fit of exactly the run's rows
(the core called directly, no padding) and NumPy's least squares."""

from __future__ import annotations

import jax
import numpy as np
import pytest

import pointax as px
from compile_counter import COUNTER
from pointax.core.simulate import encoder_grid
from pointax.fitting.options import FitOptions
from pointax.fitting.solo import fit_bucket, fit_model, pad_observations

ARCSEC = np.pi / 648000
TRUE = {"IA": 40.0, "IE": -12.0, "CA": -8.0, "AN": 3.0, "AW": -6.0, "TF": 9.0}


def _model(values=None):
    return px.AltAz(px.terms.tpoint(list(TRUE), form="rigorous", values=values))


@pytest.fixture(scope="module")
def run():
    truth = _model({k: v * ARCSEC for k, v in TRUE.items()})
    return px.simulate(truth, encoder_grid(12, (15, 30, 45, 60, 75)), noise=1.0 * ARCSEC, seed=11)


def test_buckets_are_powers_of_two_from_16():
    assert [fit_bucket(n) for n in (1, 7, 16, 17, 33, 60, 64, 65, 80, 83, 128, 129)] == [
        16, 16, 16, 32, 64, 64, 64, 128, 128, 128, 128, 256]


def test_runs_of_one_bucket_compile_once(run):
    """Runs of 34 to 60 stars (bucket 64) and later masks of them: one compilation, for
    the first."""
    px.fit(_model(), run[:34])
    with COUNTER as counted:
        results = [px.fit(_model(), run[:n]) for n in (35, 41, 50, 60)]
        _ = [float(r.sky_rms) for r in results]
    assert counted.count == 0
    assert [int(r.n_obs) for r in results] == [35, 41, 50, 60]
    assert [np.asarray(r.residuals).shape for r in results] == [(35, 2), (41, 2), (50, 2), (60, 2)]


@pytest.mark.parametrize("loss", ["linear", "cauchy"])
def test_padded_fit_equals_the_fit_of_the_rows_alone(run, loss):
    """45 stars padded to 64 against the core on exactly the 45 rows; every per-row
    field, the statistics and the outlier choice of a robust fit agree."""
    obs = run[:45]
    target = np.array(obs.target)
    target[7] = px.rotations.azel_to_enu(*np.asarray(px.rotations.enu_to_azel(target[7])) + 60 * ARCSEC)
    obs = px.Observations(obs.encoder, target, convention=obs.convention)
    padded = px.fit(_model(), obs, loss=loss)
    options = FitOptions(loss=loss)
    alone = jax.jit(lambda m, o: fit_model(m, o, options))(_model(), obs)
    for field in ("values", "sigmas", "residuals", "loo_residuals"):
        np.testing.assert_allclose(np.asarray(getattr(padded, field)), np.asarray(getattr(alone, field)),
                                   rtol=1e-9, atol=1e-13, err_msg=field)
    for field in ("used", "outliers"):
        np.testing.assert_array_equal(np.asarray(getattr(padded, field)), np.asarray(getattr(alone, field)))
    for field in ("sky_rms", "popn_sd", "loo_rms", "n_obs"):
        assert float(getattr(padded, field)) == pytest.approx(float(getattr(alone, field)), rel=1e-10), field
    if loss == "cauchy":
        assert np.flatnonzero(np.asarray(padded.outliers)).tolist() == [7]


def test_padded_fit_equals_numpy_least_squares(run):
    """The linear fit of 37 stars (padded to 64) against NumPy's least squares of the
    linearised TPOINT problem around the fit (one Gauss-Newton step from the solution
    moves nothing)."""
    obs = run[:37]
    result = px.fit(px.AltAz(px.terms.tpoint(list(TRUE), form="linear")), obs)
    jac = np.asarray(jax.jit(jax.jacfwd(lambda v: px.residuals(result.model.with_values(v), obs).reshape(-1, order="F")))(
        result.model.values()))
    r = np.asarray(px.residuals(result.model, obs)).reshape(-1, order="F")
    step = np.linalg.lstsq(jac, -r, rcond=None)[0]
    assert np.max(np.abs(step)) < 1e-9 * ARCSEC
    assert int(result.n_obs) == 37 and np.asarray(result.residuals).shape == (37, 2)


def test_padding_rows_have_weight_zero_and_copy_the_first(run):
    obs = run[:5]
    padded = pad_observations(obs, 16)
    assert len(padded) == 16
    np.testing.assert_array_equal(np.asarray(padded.weight), [1.0] * 5 + [0.0] * 11)
    np.testing.assert_array_equal(np.asarray(padded.encoder)[5:], np.repeat(np.asarray(obs.encoder)[:1], 11, 0))
    assert pad_observations(obs, 5) is obs

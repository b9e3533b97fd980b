"""Leave-one-out figures of every fit (pointax.fitting.statistics.leave_one_out) against
explicit refits with each star left out, on the real MMT run.

The hat-matrix figure is exact for the linear problem (TPOINT's residual form with
TPOINT-form terms), so it must equal the refits to rounding; for the exact sky form it
is the linearised figure and equals the refits to the linearisation error.
"""

from pathlib import Path

import numpy as np
import pytest

import pointax as px
from pointax.fitting.masking import all_residuals

DATA = Path(__file__).resolve().parents[1] / "examples" / "data" / "mmt_20210821.dat"
TERMS = "IA IE NPAE CA AN AW TF TX"


def _refits(model, run, weights):
    """Each used star's residual in the fit without it (explicit refits)."""
    out = np.zeros((len(run), 2))
    for i in np.flatnonzero(weights > 0):
        w = weights.copy()
        w[i] = 0.0
        refit = px.fit(model, run, weights=w)
        out[i] = all_residuals(refit.model, run.observations)[i]
    return out


@pytest.fixture(scope="module")
def run():
    return px.io.read_tpoint(DATA, azimuth="S-E")


@pytest.mark.slow
@pytest.mark.parametrize(("form", "residual_form", "rtol"), [("linear", "tpoint", 1e-6), ("rigorous", "sky", 1e-4)])
def test_loo_matches_refits(run, form, residual_form, rtol):
    model = run.model(px.terms.tpoint(TERMS, form=form), residual_form=residual_form)
    weights = np.ones(len(run))
    weights[[5, 40]] = 0.0  # two masked stars: already out of the fit
    result = px.fit(model, run, weights=weights)
    expected = _refits(model, run, weights)
    used = weights > 0
    loo = np.asarray(result.loo_residuals)
    scale = np.max(np.abs(expected[used]))
    assert np.max(np.abs(loo[used] - expected[used])) <= rtol * scale
    rms = np.sqrt(np.sum(expected[used] ** 2) / used.sum())
    assert float(result.loo_rms) == pytest.approx(rms, rel=rtol)
    # Out of sample is worse than in sample, and not by much on a good run.
    assert float(result.sky_rms) < float(result.loo_rms) < 1.2 * float(result.sky_rms)
    assert np.all(loo[~used] == 0.0)  # not computed in the fit (pointax.fitting.masking.fit_residuals has them)


def test_loo_in_report_and_json(run):
    result = px.fit(run.model(px.terms.tpoint(TERMS)), run)
    loo = float(result.loo_rms) / px.units.ARCSEC
    assert f"LOO RMS = {loo:9.4f}" in result.report()
    assert result.to_dict()["loo_rms_arcsec"] == pytest.approx(loo)


def test_loo_of_robust_outlier_is_its_residual(run):
    """A star a robust fit rejected is out of the final fit: its leave-one-out residual is
    its residual, and it does not count in the RMS."""
    obs = run.observations
    target = np.array(obs.target)
    bad = 17
    # Move one star by about 60" in elevation (a gross outlier).
    target[bad] = target[bad] + 3e-4 * np.array([0.0, 0.0, 1.0])
    target[bad] /= np.linalg.norm(target[bad])
    data = px.Observations(obs.encoder, target, obs.weight, obs.convention)
    model = px.AltAz(px.terms.tpoint(TERMS), azimuth=run.azimuth)
    result = px.fit(model, data, loss="cauchy")
    flagged = result.outlier_indices()
    assert bad in flagged
    np.testing.assert_array_equal(np.asarray(result.loo_residuals)[flagged], np.asarray(result.residuals)[flagged])
    used = np.asarray(result.used)
    assert float(result.loo_rms) < 1.5 * float(result.sky_rms)
    assert np.isfinite(np.asarray(result.loo_residuals)[used]).all()


def test_loo_is_traceable():
    """The figure is part of the pure-JAX fit: jit and vmap carry it."""
    import jax

    from pointax.fitting import leave_one_out

    rng = np.random.default_rng(1)
    jac = rng.normal(size=(20, 3))
    r = rng.normal(size=(10, 2))
    used = np.ones(10, bool)
    cov = np.linalg.inv(jac.T @ jac)
    # Residuals at the least-squares solution of r ~ J beta; reference: the same fit
    # without each star's two rows, its residuals there.
    fitted = r.reshape(-1) - jac @ np.linalg.lstsq(jac, r.reshape(-1), rcond=None)[0]
    loo, rms = jax.jit(leave_one_out)(fitted.reshape(10, 2), used, jac, cov)
    for i in range(10):
        keep = np.ones(20, bool)
        keep[2 * i : 2 * i + 2] = False
        beta = np.linalg.lstsq(jac[keep], r.reshape(-1)[keep], rcond=None)[0]
        np.testing.assert_allclose(np.asarray(loo)[i], (r.reshape(-1) - jac @ beta)[2 * i : 2 * i + 2], rtol=1e-10)
    batched = jax.vmap(leave_one_out, in_axes=(0, None, None, None))(np.stack([fitted.reshape(10, 2)] * 2), used, jac, cov)
    np.testing.assert_allclose(np.asarray(batched[1][0]), float(rms))

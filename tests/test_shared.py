"""Parameters shared by all sites (pointax.fit_shared): the joint least-squares solution
against scipy's Levenberg-Marquardt on an independent numpy version of the whole
problem; a site that cannot be fitted alone is left out and spoils nothing."""

from __future__ import annotations

import numpy as np
import pytest
from numpy_rotations import Rx, Ry, Rz
from scipy.optimize import least_squares

import pointax as px
from pointax.terms.sun_vector import estimate_zeros

OMEGA0 = px.deg(-0.0947)


def _site(seed, n=30):
    rng = np.random.default_rng(seed)
    truth = px.Turntable("full").set(
        mu0=px.deg(rng.normal(0.07, 0.02)),
        nu0=px.deg(rng.normal(0.01, 0.02)),
        omega0=OMEGA0,  # the shared design value
        alpha0=px.deg(rng.uniform(0, 360)),
        beta0=px.deg(165 + rng.normal(0, 2)),
    )
    enc = np.stack([rng.uniform(0, 2 * np.pi, n), float(truth.get("beta0")) + np.radians(rng.uniform(15, 70, n))], axis=1)
    return px.simulate(truth, enc, noise=px.deg(0.01), seed=seed)


def _own_start(obs):
    return [0.0, 0.0, *estimate_zeros(np.asarray(obs.encoder), np.asarray(obs.target))]


def _scipy_joint(sites, starts):
    """The paper's formula S = Rx(mu0) Ry(nu0) Rz(alpha - alpha0) Ry(omega0) Rx(beta - beta0) y,
    all sites and the shared omega0 in one scipy least-squares problem (chord residuals)."""

    def resid(x):
        out = []
        for k, obs in enumerate(sites):
            mu, nu, a0, b0 = x[4 * k : 4 * k + 4]
            for (al, be), t in zip(np.asarray(obs.encoder), np.asarray(obs.target)):
                d = Rx(mu) @ Ry(nu) @ Rz(al - a0) @ Ry(x[-1]) @ Rx(be - b0) @ np.array([0.0, 1.0, 0.0])
                out.append(d - t)
        return np.concatenate(out)

    x0 = np.concatenate([np.ravel(starts), [0.0]])
    return least_squares(resid, x0, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15).x


@pytest.fixture(scope="module")
def network():
    return [_site(k) for k in range(4)]


def test_joint_fit_matches_scipy(network):
    starts = np.array([_own_start(s) for s in network])
    fit = px.fit_shared(px.Turntable("full"), px.stack_observations(network), shared=("omega0",), values=starts)
    assert bool(fit.converged) and all(s["status"] == "converged" for s in fit.statuses())
    ref = _scipy_joint(network, starts)
    # Tangent-plane (pointax) and chord (scipy here) residuals give the same minimum to
    # first order in the residuals (~2e-4 rad): ~1e-10 rad apart.
    assert abs(float(fit.shared_values[0]) - ref[-1]) < 1e-9
    np.testing.assert_allclose(np.asarray(fit.sites.values), ref[:-1].reshape(4, 4), rtol=0, atol=1e-9)
    assert abs(fit.shared_value("omega0", "deg") - (-0.0947)) < 5 * fit.shared_sigma("omega0", "deg")
    assert "omega0" in fit.report() and fit.sites.names == ("mu0", "nu0", "alpha0", "beta0")


def test_a_bad_site_is_left_out_and_spoils_nothing(network):
    starts = np.array([_own_start(s) for s in network])
    bad = network[1]
    encoder = np.array(bad.encoder)
    encoder[[2, 5]] = np.nan
    poisoned = [network[0], px.Observations(encoder, bad.target, convention="turntable"), network[2], network[3]]
    with_bad = px.fit_shared(px.Turntable("full"), px.stack_observations(poisoned), shared=("omega0",), values=starts)
    # The same batch without the bad site's data (all its rows at weight 0, so the shapes
    # and compilations are shared): the site fails alone either way.
    silent = px.Observations(bad.encoder, bad.target, np.zeros(len(bad)), convention="turntable")
    clean = [network[0], silent, network[2], network[3]]
    without = px.fit_shared(px.Turntable("full"), px.stack_observations(clean), shared=("omega0",), values=starts)
    statuses = with_bad.statuses()
    assert statuses[1]["status"] == "failed" and "left out of the joint fit" in statuses[1]["reason"]
    assert [bool(x) for x in np.asarray(with_bad.included)] == [True, False, True, True]
    assert abs(float(with_bad.shared_values[0]) - float(without.shared_values[0])) < 1e-12
    np.testing.assert_allclose(np.asarray(with_bad.sites.values)[[0, 2, 3]], np.asarray(without.sites.values)[[0, 2, 3]], rtol=0, atol=1e-12)


def test_argument_errors(network):
    batch = px.stack_observations(network)
    with pytest.raises(ValueError, match="not free parameters"):
        px.fit_shared(px.Turntable("full"), batch, shared=("nope",))
    with pytest.raises(ValueError, match="no shared parameter"):
        px.fit_shared(px.Turntable("full"), batch, shared=())


def _numpy_joint(model, sites, shared, starts, p0):
    """The joint least-squares problem assembled densely in NumPy: every site's weighted
    residuals (pointax.residuals, the plain forward model, times the square roots of the
    weights normalised to mean 1 over the site's used rows) stacked, the block-arrow
    Jacobian from jax.jacfwd of those per site, Gauss-Newton with np.linalg.lstsq to
    convergence; then Sky RMS over every used row, Popn SD and (J^T J)^-1 Sky RMS^2."""
    import jax

    names = [p.name for p in model.free_parameters]
    own = [n for n in names if n not in shared]
    m, p, s = len(own), len(shared), len(sites)

    def site_fn(obs):
        w = np.asarray(obs.weight, np.float64)
        used = w > 0
        sqrt_w = np.sqrt(np.where(used, w, 0.0) * used.sum() / w[used].sum())

        def f(v):
            values = dict(zip(own, v[:m])) | dict(zip(shared, v[m:]))
            fitted = model.with_values(jax.numpy.stack([values[n] for n in names]), "free")
            r = px.residuals(fitted, obs)
            return (jax.numpy.where(used[:, None], r, 0.0) * sqrt_w[:, None]).reshape(-1)

        return jax.jit(f), int(used.sum())

    fns = [site_fn(obs) for obs in sites]

    def linearise(x):
        rows, blocks = [], []
        for k, (f, _) in enumerate(fns):
            v = np.concatenate([x[k * m : (k + 1) * m], x[s * m :]])
            rows.append(np.asarray(f(v)))
            jac = np.asarray(jax.jacfwd(f)(v))
            block = np.zeros((jac.shape[0], s * m + p))
            block[:, k * m : (k + 1) * m] = jac[:, :m]
            block[:, s * m :] = jac[:, m:]
            blocks.append(block)
        return np.concatenate(rows), np.concatenate(blocks)

    x = np.concatenate([np.ravel(starts), p0])
    for _ in range(50):
        r, jac = linearise(x)
        dx = np.linalg.lstsq(jac, -r, rcond=None)[0]
        x = x + dx
        if np.max(np.abs(dx)) < 1e-15:
            break
    r, jac = linearise(x)
    n_used = sum(n for _, n in fns)
    sky = np.sqrt(np.sum(r**2) / n_used)
    cov = np.linalg.inv(jac.T @ jac) * sky**2
    popn = sky * np.sqrt(n_used / (n_used - (s * m + p)))
    return x, cov, sky, popn


def test_joint_solution_covariance_and_sky_rms_match_numpy(network):
    """fit_shared's solution, covariances (shared block, per-site blocks) and Sky RMS
    against the dense NumPy solution of the same joint problem, with unequal weights and
    a row at weight 0, to 1e-9 relative."""
    sites = []
    for k, obs in enumerate(network):
        w = 1.0 + 0.5 * np.cos(np.arange(len(obs)) + k)
        w[3 + k] = 0.0
        sites.append(px.Observations(obs.encoder, obs.target, w, convention="turntable"))
    model = px.Turntable("full")
    starts = np.array([_own_start(s) for s in network])
    fit = px.fit_shared(model, px.stack_observations(sites), shared=("omega0",), values=starts)
    assert bool(fit.converged) and bool(np.all(fit.included))
    x, cov, sky, popn = _numpy_joint(model, sites, ("omega0",), starts, np.zeros(1))
    s, m = len(sites), 4
    np.testing.assert_allclose(np.asarray(fit.sites.values), x[: s * m].reshape(s, m), rtol=0, atol=1e-13)
    assert abs(float(fit.shared_values[0]) - x[-1]) < 1e-13
    assert float(fit.sky_rms) == pytest.approx(sky, rel=1e-9)
    assert float(fit.popn_sd) == pytest.approx(popn, rel=1e-9)
    np.testing.assert_allclose(np.asarray(fit.shared_covariance), cov[s * m :, s * m :], rtol=1e-9)
    np.testing.assert_allclose(float(fit.shared_sigmas[0]), np.sqrt(cov[-1, -1]), rtol=1e-9)
    for k in range(s):
        block = cov[k * m : (k + 1) * m, k * m : (k + 1) * m]
        np.testing.assert_allclose(np.asarray(fit.sites.covariance[k]), block, rtol=1e-9)
        np.testing.assert_allclose(np.asarray(fit.sites.sigmas[k]), np.sqrt(np.diag(block)), rtol=1e-9)

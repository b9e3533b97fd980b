"""Partial pooling of a network (pointax.fit_pooled) against independent references:

* the MAP values and posterior sigmas, for the population the EM ended at, against the
  dense joint least-squares solution of the same problem (every site's TPOINT design
  matrix from tests/tpoint_numpy.py and the prior's rows stacked into one NumPy
  ``lstsq``), with groups, a shared and an unpooled parameter; for a nonlinear
  (sky-form turntable) model against scipy's least squares on the plain residuals;
* the EM's population is a fixed point of its M-step computed from that dense solution;
* the Mahalanobis distance against its closed form ``(y - mu)^T (Sigma + C)^-1 (y - mu)``;
* a site with many observations is moved by less than its sigma, one with few by much
  more; the population of a simulated network is recovered within its sampling error;
* new data values run the same compiled program; a nonlinear fit's program holds one
  EM and one linearisation of the residuals, whatever its number of steps.
"""

from __future__ import annotations

import jax
import numpy as np
import pytest
from scipy.optimize import least_squares

import pointax as px
import tpoint_numpy as ref
from compile_counter import COUNTER, traces

NAMES = ["IA", "IE", "AN", "AW", "TF"]
MU = np.array([30.0, -20.0, 10.0, 5.0, 8.0]) * ref.ARCSEC
SD = np.array([10.0, 8.0, 4.0, 4.0, 3.0]) * ref.ARCSEC
NOISE = 1.0 * ref.ARCSEC


def _site(n, seed, mu=MU, sd=SD, noise=NOISE):
    """A simulated alt-az site: TPOINT's linear terms drawn from the population, ``n``
    stars, noise on the raw encoders; ``(observations, truth, observed (A, E), raw)``."""
    r = np.random.default_rng(seed)
    coefs = mu + sd * r.normal(size=len(mu))
    A, E = r.uniform(0, 2 * np.pi, n), r.uniform(np.radians(15), np.radians(80), n)
    dA, dE = ref.offsets(NAMES, coefs, A, E)
    raw = np.stack([A - dA + noise * r.normal(size=n) / np.cos(E), E - dE + noise * r.normal(size=n)], -1)
    target = np.stack([np.sin(A) * np.cos(E), np.cos(A) * np.cos(E), np.sin(E)], -1)
    return px.Observations(raw, target, convention="N-E"), coefs, np.stack([A, E], -1), raw


def _model():
    return px.AltAz(px.terms.tpoint(" ".join(NAMES), form="linear"), residual_form="tpoint")


def _design(observed, raw):
    """TPOINT's residuals ``d - F c`` of one site (tests/tpoint_numpy.py's basis)."""
    A, E = observed[:, 0], observed[:, 1]
    cols = [np.concatenate([fA * np.cos(E), fE]) for fA, fE in (ref.basis(n, A, E) for n in NAMES)]
    d = np.concatenate([ref.wrap(A - raw[:, 0]) * np.cos(E), E - raw[:, 1]])
    return np.stack(cols, axis=-1), d


def _upper(precision):
    """``R`` with ``R^T R = precision`` (symmetric positive semi-definite)."""
    w, v = np.linalg.eigh(precision)
    return (v * np.sqrt(np.clip(w, 0, None))).T


def _dense_map(sites, groups, fit, shared=(), unpooled=()):
    """The MAP problem for the fit's population as one dense least squares: unknowns
    every site's own coefficients, then the shared ones; rows every site's residuals
    over the group's noise, then every site's prior rows. Returns (own (S, M), shared
    (P,), covariance of all unknowns)."""
    own = [n for n in NAMES if n not in shared]
    k_own, k_sh, n_sites = len(own), len(shared), len(sites)
    pooled = np.array([n not in unpooled for n in own])
    width = n_sites * k_own + k_sh
    rows, rhs = [], []
    for s, (obs, _, observed, raw) in enumerate(sites):
        g = groups[s]
        sigma = float(fit.noise[g])
        F, d = _design(observed, raw)
        block = np.zeros((len(d), width))
        block[:, s * k_own : (s + 1) * k_own] = F[:, [NAMES.index(n) for n in own]]
        if k_sh:
            block[:, n_sites * k_own :] = F[:, [NAMES.index(n) for n in shared]]
        rows.append(block / sigma)
        rhs.append(d / sigma)
        cov = np.asarray(fit.population_covariance[g])[np.ix_(pooled, pooled)]
        R = _upper(np.linalg.inv(cov))
        prior = np.zeros((len(R), width))
        prior[:, s * k_own : (s + 1) * k_own][:, pooled] = R
        rows.append(prior)
        rhs.append(R @ np.asarray(fit.population_mean[g])[pooled])
    X, y = np.concatenate(rows), np.concatenate(rhs)
    z = np.linalg.lstsq(X, y, rcond=None)[0]
    return z[: n_sites * k_own].reshape(n_sites, k_own), z[n_sites * k_own :], np.linalg.inv(X.T @ X)


def test_reference_residuals_are_pointax_residuals():
    """The reference's design matrix gives pointax's TPOINT-form residuals."""
    obs, coefs, observed, raw = _site(7, 3)
    F, d = _design(observed, raw)
    model = _model().set(**dict(zip(NAMES, coefs)))
    ours = np.asarray(px.residuals(model, obs))
    np.testing.assert_allclose(np.concatenate([ours[:, 0], ours[:, 1]]), d - F @ coefs, atol=1e-14)


@pytest.fixture(scope="module")
def small_network():
    return [_site(n, seed) for seed, n in enumerate([3, 4, 8, 60])]


@pytest.fixture(scope="module")
def small_fit(small_network):
    batch = px.stack_observations([s[0] for s in small_network])
    return px.fit_pooled(_model(), batch, covariance="diagonal", tol=1e-12)


def test_map_equals_dense_joint_least_squares(small_network, small_fit):
    fit = small_fit
    assert bool(fit.converged)
    assert int(fit.iterations) < 300  # SQUAREM: tens of EM updates to 1e-12 here (plain EM: over 2000)
    own, _, cov = _dense_map(small_network, [0] * 4, fit)
    np.testing.assert_allclose(np.asarray(fit.sites.values), own, rtol=1e-8, atol=1e-8 * np.abs(own).max())
    sigmas = np.sqrt(np.diag(cov)).reshape(4, 5)
    np.testing.assert_allclose(np.asarray(fit.sites.sigmas), sigmas, rtol=1e-8)


def test_progress_names_the_compilation_and_counts_the_sites(small_network, small_fit, monkeypatch):
    """fit_pooled(progress=...) says "compiling" around the first call of a model and
    size (a fresh process's first call: the record of calls is emptied here, so the
    compiled program is reused and only the notice is checked), then all sites done;
    the same call again says nothing of compiling. The answer is the fit's."""
    import contextlib

    from pointax.fitting import batch_fast_pass
    from pointax.fitting.pooled import COMPILING_POOLED

    class Recorder:
        def __init__(self):
            self.calls, self.texts = [], []

        def __call__(self, done, total):
            self.calls.append((done, total))

        @contextlib.contextmanager
        def activity(self, text):
            self.texts.append(text)
            yield

    monkeypatch.setattr(batch_fast_pass, "_SEEN", set())
    batch = px.stack_observations([s[0] for s in small_network])
    for first in (True, False):
        seen = Recorder()
        fit = px.fit_pooled(_model(), batch, covariance="diagonal", tol=1e-12, progress=seen)
        assert seen.texts == ([COMPILING_POOLED] if first else [])
        assert seen.calls == [(4, 4)]
        np.testing.assert_array_equal(np.asarray(fit.sites.values), np.asarray(small_fit.sites.values))


def test_population_is_a_fixed_point_of_the_m_step(small_network, small_fit):
    """mu = mean MAP value, Sigma = their scatter + mean posterior covariance (its
    diagonal: the fit's form), s2 = the expected squared residual, all from the dense
    solution."""
    fit = small_fit
    own, _, cov = _dense_map(small_network, [0] * 4, fit)
    blocks = [cov[5 * s : 5 * s + 5, 5 * s : 5 * s + 5] for s in range(4)]
    mu = own.mean(axis=0)
    sigma = np.diag(np.diag(np.mean([np.outer(y - mu, y - mu) + P for y, P in zip(own, blocks)], axis=0)))  # diagonal
    expected, count = 0.0, 0
    for (obs, _, observed, raw), y, P in zip(small_network, own, blocks):
        F, d = _design(observed, raw)
        expected += np.sum((d - F @ y) ** 2) + np.trace(F.T @ F @ P)
        count += len(d)
    scale = np.sqrt(np.diag(sigma))
    np.testing.assert_allclose(np.asarray(fit.population_mean[0]) / scale, mu / scale, atol=1e-6)
    np.testing.assert_allclose(np.asarray(fit.population_covariance[0]) / np.outer(scale, scale),
                               sigma / np.outer(scale, scale), atol=1e-6)  # fmt: skip
    np.testing.assert_allclose(float(fit.noise[0]) ** 2, expected / count, rtol=1e-6)


def test_mahalanobis_shrinkage_and_prior_fraction_closed_form(small_network, small_fit):
    fit = small_fit
    mu, Sigma, s2 = np.asarray(fit.population_mean[0]), np.asarray(fit.population_covariance[0]), float(fit.noise[0]) ** 2
    own, _, cov = _dense_map(small_network, [0] * 4, fit)
    for s, (obs, _, observed, raw) in enumerate(small_network):
        F, d = _design(observed, raw)
        y_hat = np.linalg.lstsq(F, d, rcond=None)[0]
        C = s2 * np.linalg.inv(F.T @ F)
        dist = np.sqrt((y_hat - mu) @ np.linalg.solve(Sigma + C, y_hat - mu))
        np.testing.assert_allclose(float(fit.mahalanobis[s]), dist, rtol=1e-7)
        np.testing.assert_allclose(np.asarray(fit.independent_values[s]), y_hat, rtol=1e-8, atol=1e-14)
        np.testing.assert_allclose(np.asarray(fit.independent_sigmas[s]), np.sqrt(np.diag(C)), rtol=1e-8)
        np.testing.assert_allclose(np.asarray(fit.shrinkage[s]), np.abs(own[s] - y_hat) / np.sqrt(np.diag(C)), rtol=1e-6)
        posterior = np.linalg.inv(F.T @ F / s2 + np.linalg.inv(Sigma))
        np.testing.assert_allclose(np.asarray(fit.prior_fraction[s]), 1 - np.diag(posterior) / np.diag(C), rtol=1e-7)
    assert not np.asarray(fit.disagrees).any()


def test_groups_shared_and_unpooled_against_dense_joint_least_squares():
    """Two groups of one design each, TF shared by every site, IA per site with no
    population: the joint MAP (own and shared values, sigmas) equals the dense solution."""
    mu_b = MU + np.array([0, 0, 30, -20, 0]) * ref.ARCSEC
    sites = [_site(n, 10 + s) for s, n in enumerate([3, 5, 12, 40])]
    sites += [_site(n, 20 + s, mu=mu_b) for s, n in enumerate([4, 6, 30])]
    groups = ["a"] * 4 + ["b"] * 3
    batch = px.stack_observations([s[0] for s in sites])
    fit = px.fit_pooled(_model(), batch, shared=("TF",), unpooled=("IA",), groups=groups, covariance="diagonal", tol=1e-12)
    assert bool(fit.converged) and fit.group_names == ("a", "b") and fit.names == ("IA", "IE", "AN", "AW")
    own, shared, cov = _dense_map(sites, [0] * 4 + [1] * 3, fit, shared=("TF",), unpooled=("IA",))
    np.testing.assert_allclose(np.asarray(fit.sites.values), own, rtol=1e-8, atol=1e-8 * np.abs(own).max())
    np.testing.assert_allclose(np.asarray(fit.shared_values), shared, rtol=1e-8)
    np.testing.assert_allclose(np.asarray(fit.sites.sigmas), np.sqrt(np.diag(cov))[:-1].reshape(7, 4), rtol=1e-8)
    np.testing.assert_allclose(np.asarray(fit.shared_sigmas), np.sqrt(np.diag(cov))[-1:], rtol=1e-8)
    assert np.all(np.asarray(fit.prior_fraction)[:, 0] == 0.0)  # IA: no population
    assert abs(fit.population_value("AN", "b", "arcsec") - fit.population_value("AN", "a", "arcsec")) > 10


def test_many_observations_move_less_than_their_sigma(small_fit):
    """The 60-star site is moved by less than its own sigma; the 3-star site is moved
    ten times as far (radians) and takes most of its precision from the population."""
    shrink, fraction = np.asarray(small_fit.shrinkage), np.asarray(small_fit.prior_fraction)
    assert np.all(shrink[3] < 1.0)
    assert np.max(fraction[3]) < 0.1 < np.min(fraction[0])
    moved = np.abs(np.asarray(small_fit.sites.values) - np.asarray(small_fit.independent_values))
    assert np.mean(moved[0]) > 10 * np.mean(moved[3])


def test_em_recovers_a_known_population():
    """400 sites of 3 to 60 stars: the population mean within 4 standard errors (the
    scatter of the true values and the posterior variances over the sites), the spread
    within 20 %, the noise within 5 %."""
    sizes = [3, 5, 10, 60] * 100
    sites = [_site(n, 1000 + k) for k, n in enumerate(sizes)]
    fit = px.fit_pooled(_model(), px.stack_observations([s[0] for s in sites]))
    assert bool(fit.converged)
    truth = np.array([s[1] for s in sites])
    posterior_var = np.asarray(fit.sites.sigmas) ** 2
    se = np.sqrt((SD**2 + posterior_var.mean(axis=0)) / len(sites))
    assert np.all(np.abs(np.asarray(fit.population_mean[0]) - MU) < 4 * se)
    spread = np.sqrt(np.diag(np.asarray(fit.population_covariance[0])))
    np.testing.assert_allclose(spread, SD, rtol=0.2)
    assert abs(float(fit.noise[0]) / NOISE - 1) < 0.05
    # Pooling beats the site's own fit where the data are few.
    few = np.array(sizes) == 3
    pooled_err = np.sqrt(np.mean((np.asarray(fit.sites.values) - truth)[few] ** 2))
    own_err = np.sqrt(np.mean((np.asarray(fit.independent_values) - truth)[few] ** 2))
    assert pooled_err < 0.5 * own_err


def test_outlying_site_is_flagged():
    sites = [_site(n, 40 + k) for k, n in enumerate([10, 20, 30] * 10)]
    obs, coefs, observed, raw = _site(30, 99, mu=MU + 40 * SD)  # far outside the population
    fit = px.fit_pooled(_model(), px.stack_observations([s[0] for s in sites] + [obs]))
    flags = np.asarray(fit.disagrees)
    assert flags[-1] and flags[:-1].sum() <= 1
    assert "disagrees with its population" in fit.statuses()[-1]["reason"]
    assert "1 site(s) disagree" in fit.report() or flags.sum() > 1


def test_posterior_inverse_is_written_out():
    """The E-step's 5x5 inverses are the written-out Cholesky factorisation (vectorised
    across sites), not a LAPACK call per site; and they are inverses."""
    import jax

    from pointax.fitting import pooled

    x = np.random.default_rng(0).normal(size=(3, 12, 5))
    a = np.einsum("sni,snj->sij", x, x)
    with jax.enable_x64(True):
        assert "cholesky" not in str(jax.make_jaxpr(pooled._spd_inverse)(a))
        inverse = np.asarray(pooled._spd_inverse(a))
    np.testing.assert_allclose(inverse @ a, np.broadcast_to(np.eye(5), a.shape), atol=1e-10)


def test_full_covariance_needs_more_sites_than_parameters(small_network):
    with pytest.raises(ValueError, match="4 sites with data for 5 pooled parameters.*diagonal"):
        px.fit_pooled(_model(), px.stack_observations([s[0] for s in small_network]))


def test_no_recompilation_when_data_change(small_network):
    batch = px.stack_observations([s[0] for s in small_network])
    px.fit_pooled(_model(), batch, covariance="diagonal")
    other = px.stack_observations([_site(n, 500 + k)[0] for k, n in enumerate([3, 4, 8, 60])])
    start = np.full((4, 5), 1e-5)
    with traces() as seen:
        px.fit_pooled(_model(), other, values=start, noise=2 * ref.ARCSEC, k=2.0, covariance="diagonal")
        px.fit_pooled(_model().set(IA=1e-5), other, groups=["one design"] * 4, covariance="diagonal")
    assert "_pooled_fit" not in seen, seen


# --------------------------------------------------------------------------- nonlinear


def _turntable_site(n, seed):
    rng = np.random.default_rng(seed)
    truth = px.Turntable("full").set(
        mu0=px.deg(rng.normal(0.07, 0.02)),
        nu0=px.deg(rng.normal(0.01, 0.02)),
        omega0=px.deg(rng.normal(-0.09, 0.02)),
        alpha0=px.deg(rng.uniform(0, 360)),
        beta0=px.deg(165 + rng.normal(0, 0.05)),
    )
    enc = np.stack([rng.uniform(0, 2 * np.pi, n), float(truth.get("beta0")) + np.radians(rng.uniform(15, 70, n))], axis=1)
    return px.simulate(truth, enc, noise=px.deg(0.01), seed=seed), truth


def _turntable_starts(obs) -> np.ndarray:
    """Start values of the turntable sites ``obs``: mu0 nu0 omega0 at 0, the encoder
    zeros from the data (``(S, 5)``, radians)."""
    from pointax.terms.sun_vector import estimate_zeros

    return np.array([[0.0, 0.0, 0.0, *estimate_zeros(np.asarray(o.encoder), np.asarray(o.target))] for o in obs])


# Five sites padded to 60 rows, encoder zeros per site, a full covariance: the shapes and
# structure of the example network's pooled fit (examples/data/network, the command-line
# test below), so that this module compiles one nonlinear pooled program.
TURNTABLE_SIZES = (6, 8, 12, 20, 60)
TURNTABLE_UNPOOLED = ("alpha0", "beta0")


def _pooled_turntables(obs, starts, **options):
    return px.fit_pooled(
        px.Turntable("full"), px.stack_observations(obs), values=starts, unpooled=TURNTABLE_UNPOOLED,
        covariance="full", **options,
    )  # fmt: skip


@pytest.fixture(scope="module")
def turntables():
    """The simulated turntable network: ``(observations per site, start values)``."""
    obs = [_turntable_site(n, 70 + k)[0] for k, n in enumerate(TURNTABLE_SIZES)]
    return obs, _turntable_starts(obs)


@pytest.fixture(scope="module")
def first_nonlinear_fit(turntables):
    """The module's first nonlinear pooled fit (two steps), traced with the fit's
    linearisations and EMs counted: ``(names traced, calls counted, result)``. Every
    test that fits the turntables asks for it, so it traces the program whatever the
    order the tests run in."""
    from pointax.fitting import pooled

    called = {"_linearise": 0, "_em": 0}
    with pytest.MonkeyPatch.context() as patch:
        for name in called:
            original = getattr(pooled, name)

            def counted(*args, _original=original, _name=name, **kwargs):
                called[_name] += 1  # inside the compiled fit: runs when it is traced
                return _original(*args, **kwargs)

            patch.setattr(pooled, name, counted)
        with traces() as seen:
            two = _pooled_turntables(*turntables, steps=2)
    return set(seen), dict(called), two


def test_a_nonlinear_fit_compiles_one_em_and_one_linearisation(turntables, first_nonlinear_fit):
    """The rounds of a nonlinear pooled fit, the start's linearisation and the last
    Gauss-Newton steps included, are one loop: its program holds one linearisation of
    the residuals and one EM, at any number of steps (copies of them before and after
    the loop doubled its compiling). The number of steps and EM's iteration limit are
    data: other counts run the same program (nothing traced, nothing compiled) and take
    the steps and the limit asked for (counted in EM updates)."""
    seen, called, two = first_nonlinear_fit
    assert "_pooled_fit" in seen  # traced there, so the counts are of this program
    assert called == {"_linearise": 1, "_em": 1}, called
    with traces() as seen, COUNTER as compiled:
        five = _pooled_turntables(*turntables, steps=5)
        capped = _pooled_turntables(*turntables, steps=5, max_iterations=3)
    assert "_pooled_fit" not in seen and compiled.count == 0, (seen, compiled.count)
    for out in (two, five, capped):
        assert np.all(np.isfinite(np.asarray(out.sites.values)))
    # Each round but the last two runs EM, whose every pass makes 3 updates: capped at 3,
    # five rounds make exactly 15; uncapped, at least that many.
    iterations = [int(np.max(np.asarray(out.sites.iterations))) for out in (two, five, capped)]
    assert iterations[2] == 15 and iterations[1] >= 15 and iterations[0] >= 6, iterations


def test_nonlinear_map_equals_scipy_least_squares(turntables, first_nonlinear_fit):
    """A sky-form turntable (encoder zeros per site): the pooled values are the MAP of
    the population the fit ended at, as scipy finds it on the plain residuals
    (px.residuals) plus the prior's rows."""
    obs, starts = turntables
    fit = _pooled_turntables(obs, starts)  # the MAP of the population it ends at, whatever EM's tolerance
    assert bool(fit.converged)
    model = px.Turntable("full")
    names = [p.name for p in model.free_parameters]
    pooled = np.array([n not in TURNTABLE_UNPOOLED for n in names])
    mu = np.asarray(fit.population_mean[0])[pooled]
    R = _upper(np.linalg.inv(np.asarray(fit.population_covariance[0])[np.ix_(pooled, pooled)]))
    sigma = float(fit.noise[0])

    # px.residuals is pure JAX: compiled once per site size (eagerly, scipy's hundreds of
    # calls each traced it again: half a minute).
    site_residuals = jax.jit(lambda y, o: px.residuals(model.with_values(y), o))

    def resid(x):
        out = []
        for k, o in enumerate(obs):
            y = x[5 * k : 5 * k + 5]
            out.append(np.ravel(np.asarray(site_residuals(y, o))) / sigma)
            out.append(R @ (y[pooled] - mu))
        return np.concatenate(out)

    x = least_squares(resid, starts.ravel(), method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15).x
    got = np.asarray(fit.sites.values).ravel()
    np.testing.assert_allclose(got, x, rtol=1e-8, atol=1e-8 * np.abs(x).max())


# --------------------------------------------------------------------------- command line


def test_fit_network_pooled_on_the_example_manifest(monkeypatch):
    """``pointax fit-network --pooled``: the four clean turntables and ts-05 (whose data
    alone cannot separate its tilts from its pitch zero) pooled as one design, the
    unreadable ts-06 failed, the lone MMT run fitted alone (and said so); the sites
    whose own data fix them moved by less than 3 of their own sigmas."""
    import argparse
    import io
    import json
    from pathlib import Path

    from pointax.cli.fit_network import add_fit_network_parser, run_fit_network

    monkeypatch.setenv("POINTAX_JAX_CACHE", "")
    network = Path(__file__).resolve().parent.parent / "examples" / "data" / "network"
    parser = argparse.ArgumentParser(prog="pointax")
    add_fit_network_parser(parser.add_subparsers(dest="command"))
    out, err = io.StringIO(), io.StringIO()
    args = parser.parse_args(["fit-network", str(network / "manifest.csv"), "--pooled", "--json", "--quiet"])
    code = run_fit_network(args, stdout=out, stderr=err)
    assert code == 1  # ts-06 cannot be read
    sites = {d["site"]: d for d in json.loads(out.getvalue())}
    assert sites["ts-06"]["status"] == "failed" and not sites["ts-06"]["pooled"]
    assert not sites["mmt"]["pooled"] and "not pooled" in sites["mmt"]["reason"]
    assert sites["mmt"]["status"] == "converged"
    for name in ["ts-01", "ts-02", "ts-03", "ts-04", "ts-05"]:
        d = sites[name]
        assert d["pooled"] and d["status"] == "converged", (name, d["reason"])
        assert all(p["sigma"] > 0 for p in d["params"])
        if name != "ts-05":  # fixed by its own data: moved by a few of its own sigmas at most
            assert all(p["shrinkage"] < 3 for p in d["params"]), (name, d["params"])
    # The library call counts the sites of both designs on one progress (5 pooled, the MMT
    # run alone; ts-06 unread), rising to all of them.
    from pointax.analysis.pooled_report import pooled_network

    seen = []
    again = pooled_network(network / "manifest.csv", progress=lambda done, total: seen.append((done, total)))
    assert seen[-1] == (6, 6) and all(t == 6 for _, t in seen)
    assert [d for d, _ in seen] == sorted(d for d, _ in seen)
    assert [d["site"] for d in again.sites] == list(sites)
    assert sites["ts-05"]["params"][0]["independent_value"] is None  # not fixed by its data alone


@pytest.mark.slow  # its own pooled program: about 20 s of compilation
def test_readings_reach_the_pooled_fit():
    """A term that reads the temperature (``thermal("TF")``: TF + slope (T - 10 C)) pools
    with the readings of each site: every site's independent estimate equals NumPy's
    least squares on its TPOINT design matrix with the slope's column ``TF basis x (T - 10)``
    (a fit that lost the readings would refuse them, or fit without the slope)."""
    r = np.random.default_rng(7)
    sites = [_site(n, 30 + s) for s, n in enumerate([12, 15, 20, 40])]
    temps = [r.uniform(-5.0, 25.0, len(s[2])) for s in sites]
    batch = px.stack_observations(
        [px.Observations(s[0].encoder, s[0].target, convention="N-E", readings={"temperature": t})
         for s, t in zip(sites, temps)]  # fmt: skip
    )
    thermal_tf = px.terms.thermal(px.terms.tpoint("TF", form="linear")[0], reference=10.0)
    terms = [*px.terms.tpoint("IA IE AN AW", form="linear"), thermal_tf]
    model = px.AltAz(terms, residual_form="tpoint")
    fit = px.fit_pooled(model, batch, covariance="diagonal")
    assert fit.names == ("IA", "IE", "AN", "AW", "TF@temperature.value", "TF@temperature.slope")
    for s, ((_, _, observed, raw), t) in enumerate(zip(sites, temps)):
        F, d = _design(observed, raw)
        slope = F[:, -1] * (np.concatenate([t, t]) - 10.0)
        y_hat = np.linalg.lstsq(np.column_stack([F, slope]), d, rcond=None)[0]
        np.testing.assert_allclose(np.asarray(fit.independent_values[s]), y_hat, rtol=1e-8)

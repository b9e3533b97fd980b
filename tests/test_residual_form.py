"""TPOINT's own residual form (``residual_form="tpoint"``): terms at the observed
position, residuals (dA cos E, dE).

References: an ordinary least-squares fit of TPOINT's basis functions written out with
numpy (``test_conformance._ols_reference``, DESIGN.md's definitions) and TPOINT's own
model file for the MMT run; finite differences for derivatives; solo fits for batches.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import MMT_DAT, MMT_MOD
from test_batch import _padded
from test_conformance import _ols_reference

import pointax as px
from pointax.fitting.problem import is_affine, site_data, site_residuals
from pointax.fitting.fast_jacobian import residual_function
from pointax.core.term import angle_pair


def _linear(*args, **kwargs):
    """TPOINT's terms in the linear form: the form whose TPOINT residuals are the linear
    least-squares problem of DESIGN.md's definitions (the default form is rigorous)."""
    return px.terms.tpoint(*args, form="linear", **kwargs)

ARCSEC = np.pi / 648000
TERMS = "IA IE NPAE CA AN AW TF TX"


@pytest.fixture(scope="module")
def mmt():
    return px.io.read_tpoint(MMT_DAT, azimuth="S-E")


@pytest.fixture(scope="module")
def tpoint_fit(mmt):
    return px.fit(px.AltAz(_linear(TERMS), azimuth=mmt.azimuth, residual_form="tpoint"), mmt)


def test_tpoint_form_is_the_linear_least_squares_fit(mmt, tpoint_fit):
    x, sigma, rms, cov = _ols_reference(mmt)
    assert tpoint_fit.converged
    np.testing.assert_allclose(np.asarray(tpoint_fit.values), x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(tpoint_fit.sigmas), sigma, rtol=1e-8)
    assert float(tpoint_fit.sky_rms) == pytest.approx(rms, rel=1e-10)
    np.testing.assert_allclose(np.asarray(tpoint_fit.covariance), cov, rtol=1e-7, atol=1e-30)


def test_tpoint_form_reproduces_tpoint(tpoint_fit):
    tpoint = px.io.read_model(MMT_MOD)
    for term in tpoint.terms:
        assert tpoint_fit.value(term.name) == pytest.approx(term.value, abs=0.005), term.name
        assert tpoint_fit.sigma(term.name) == pytest.approx(term.sigma, abs=0.005), term.name
    assert float(tpoint_fit.sky_rms) / ARCSEC == pytest.approx(tpoint.sky_rms, abs=0.001)


def test_the_two_forms_differ_at_second_order(mmt, tpoint_fit):
    """Same model, two objectives: on a real run (offsets of tens of arcseconds) the
    fitted values differ by a few 1e-9 rad (0.001")."""
    sky = px.fit(px.AltAz(_linear(TERMS), azimuth=mmt.azimuth), mmt)
    diff = np.max(np.abs(np.asarray(sky.values) - np.asarray(tpoint_fit.values)))
    assert 1e-11 < diff < 1e-8


class SkyWobble(px.Term):
    """A user's sky offset that is not linear in its parameters (and says so)."""

    amp: float = px.terms.param(0.0)
    phase: float = px.terms.param(0.3, unit="rad")

    def sky_offset(self, angles):
        return angle_pair(self.amp * jnp.sin(angles[0] + self.phase), self.amp**2 * 1e3 * jnp.cos(angles[1]))


def _mixed_models():
    """Models mixing rotations, encoder offsets, linear and nonlinear sky offsets."""
    tp = _linear("IA IE AN AW TF TX HESE2", values={"IA": 20 * ARCSEC, "AN": 8 * ARCSEC, "TF": 5 * ARCSEC})
    rigorous = px.terms.tpoint("NPAE CA", form="rigorous", values={"NPAE": 12 * ARCSEC, "CA": -30 * ARCSEC})
    wobble = SkyWobble(amp=6 * ARCSEC)
    altaz = px.AltAz((*tp, *rigorous, wobble), azimuth="S-E", residual_form="tpoint")
    xy = px.XY("basic", residual_form="tpoint")
    xy = xy.with_values(np.asarray(xy.values()) + 20 * ARCSEC)
    return {"alt-az": altaz, "xy": xy}


@pytest.mark.parametrize("name", ["alt-az", "xy"])
def test_site_evaluation_equals_the_generic_residuals(name):
    model = _mixed_models()[name]
    rng = np.random.default_rng(4)
    n = 40
    encoder = np.stack([rng.uniform(-3, 3, n), rng.uniform(0.3, 1.3, n)], axis=1)
    obs = px.simulate(model, encoder, noise=5 * ARCSEC, seed=1)
    weight = rng.uniform(0.5, 2, n)
    weight[[5, 9]] = 0.0
    enc = np.array(obs.encoder)
    enc[5] = np.nan  # unused rows may hold NaN
    obs = px.Observations(enc, obs.target, weight, obs.convention)
    data = site_data(model, obs)
    ours = np.stack([np.asarray(x) for x in site_residuals(model, data, weighted=False)], axis=-1)
    generic = np.asarray(px.residuals(model, obs))
    assert np.all(np.isfinite(ours)) and np.all(ours[[5, 9]] == 0)
    np.testing.assert_allclose(ours, generic, rtol=0, atol=1e-15)


def test_tpoint_residuals_by_hand():
    """The generic residuals against a numpy transcription of TPOINT's definition."""
    values = {"IA": 40 * ARCSEC, "IE": -15 * ARCSEC, "AN": 9 * ARCSEC, "TX": 2 * ARCSEC}
    model = px.AltAz(_linear("IA IE AN TX", values=values), residual_form="tpoint")
    rng = np.random.default_rng(0)
    raw = np.stack([rng.uniform(0, 2 * np.pi, 20), rng.uniform(0.3, 1.4, 20)], axis=1)
    observed = raw + rng.normal(0, 50 * ARCSEC, raw.shape)
    obs = px.Observations(raw, px.rotations.azel_to_enu_numpy(observed[:, 0], observed[:, 1]))
    A, E = observed.T
    dA = (A - raw[:, 0] - (-values["IA"] - values["AN"] * np.sin(A) * np.tan(E)) + np.pi) % (2 * np.pi) - np.pi
    dE = E - raw[:, 1] - (values["IE"] - values["AN"] * np.cos(A) - values["TX"] / np.tan(E))
    np.testing.assert_allclose(np.asarray(px.residuals(model, obs)), np.stack([dA * np.cos(E), dE], -1), rtol=0, atol=1e-15)


def test_derivatives_match_finite_differences():
    model = _mixed_models()["alt-az"]
    rng = np.random.default_rng(2)
    encoder = np.stack([rng.uniform(-3, 3, 30), rng.uniform(0.3, 1.3, 30)], axis=1)
    obs = px.simulate(model, encoder, noise=5 * ARCSEC, seed=2)
    data = site_data(model, obs)
    params = model.free_parameters
    fn = residual_function(params)
    y = model.values("free")

    def flat(v):
        return jnp.concatenate(fn(v, (model, data)))

    jac = np.asarray(jax.jacfwd(flat)(y))
    h = 1e-7
    for k in range(len(params)):
        e = np.zeros(len(params))
        e[k] = h
        fd = (np.asarray(flat(y + e)) - np.asarray(flat(y - e))) / (2 * h)
        np.testing.assert_allclose(jac[:, k], fd, rtol=0, atol=1e-7 * max(1.0, np.max(np.abs(fd))), err_msg=params[k].name)


def _tpoint_site(seed: int, n: int):
    rng = np.random.default_rng(seed)
    values = dict(zip(TERMS.split(), rng.normal(0, [100, 30, 20, 20, 10, 10, 10, 3]) * ARCSEC))
    truth = px.AltAz(_linear(TERMS, values=values))
    raw = np.stack([rng.uniform(0, 2 * np.pi, n), np.radians(rng.uniform(15, 85, n))], axis=1)
    return px.simulate(truth, raw, noise=ARCSEC, seed=seed)


def test_batch_takes_one_step_and_equals_solo_fits():
    model = px.AltAz(_linear(TERMS), residual_form="tpoint")
    assert is_affine(model)
    sites = [_tpoint_site(k, n) for k, n in enumerate((60, 41, 55, 60))]
    nan_site = _tpoint_site(10, 60)
    encoder = np.array(nan_site.encoder)
    encoder[7] = np.nan
    sites.insert(2, px.Observations(encoder, nan_site.target, convention=nan_site.convention))
    flat = _tpoint_site(11, 60)
    encoder = np.array(flat.encoder)
    encoder[:, 1] = encoder[0, 1]  # one elevation: NPAE, CA, TF and TX cannot be told apart
    sites.insert(4, px.simulate(px.AltAz(), encoder, seed=3))
    result = px.fit_batch(model, px.stack_observations(sites))
    statuses = px.site_statuses(result)
    for k, site in enumerate(sites):
        if k in (2, 4):
            continue
        solo = px.fit(model, _padded(site, 60))  # weight-0 rows: one compilation for all
        assert bool(result.converged[k]) and int(result.iterations[k]) == 1
        np.testing.assert_allclose(np.asarray(result.values[k]), np.asarray(solo.values), rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.asarray(result.sigmas[k]), np.asarray(solo.sigmas), rtol=1e-8)
    assert statuses[2]["status"] == "failed"
    assert statuses[4]["status"] in ("failed", "degenerate")


def test_affine_only_when_every_free_parameter_is_linear():
    linear = _linear(TERMS)
    assert not is_affine(px.AltAz(linear))  # the exact form: a fixed point, not affine
    rigorous = px.terms.tpoint("CA", form="rigorous")
    mixed = px.AltAz((*linear[:2], *rigorous), residual_form="tpoint")
    assert not is_affine(mixed)
    assert is_affine(mixed.fix("CA"))


def test_residual_form_is_kept_and_checked():
    model = px.AltAz(_linear("IA IE CA"), residual_form="tpoint")
    for copy in (model.fix("IA"), model.free(), model.with_terms(*_linear("TF")), model.without_terms("CA"),
                 model.with_values(model.values())):
        assert copy.residual_form == "tpoint"
    assert model.with_residual_form("sky").residual_form == "sky"
    with pytest.raises(ValueError, match="residual_form must be one of"):
        px.AltAz(residual_form="angles")
    with pytest.raises(ValueError, match="TurntableMount has none"):
        px.Model(px.TurntableMount(), residual_form="tpoint")


def test_claimed_linearity_must_come_with_a_sky_offset():
    class Liar(px.Term):
        coef: float = px.terms.param(0.0)
        linear_sky_offset = True

    model = px.AltAz((Liar(),), residual_form="tpoint")
    obs = px.simulate(px.AltAz(), np.array([[0.1, 0.5], [1.0, 0.7]]))
    with pytest.raises(TypeError, match="Liar says linear_sky_offset but has no sky_offset"):
        site_data(model, obs)


def test_jit_and_vmap_of_tpoint_residuals(mmt):
    model = px.AltAz(_linear(TERMS), azimuth=mmt.azimuth, residual_form="tpoint")
    obs = mmt.observations
    direct = np.asarray(px.residuals(model, obs))
    jitted = np.asarray(eqx.filter_jit(px.residuals)(model, obs))
    np.testing.assert_allclose(jitted, direct, rtol=0, atol=1e-15)
    values = jnp.stack([model.values(), model.values() + 1e-5])
    batched = jax.vmap(lambda v: px.residuals(model.with_values(v), obs))(values)
    np.testing.assert_allclose(np.asarray(batched[0]), direct, rtol=0, atol=1e-16)


def test_command_line_fits_tpoint_residuals(mmt, capsys):
    import json

    from pointax.cli import main

    assert main(["fit", str(MMT_DAT), "--azimuth", "S-E", "--residuals", "tpoint", "--form", "linear", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["residuals"] == "tpoint"
    x, *_ = _ols_reference(mmt)
    values = np.array([p["value_arcsec"] for p in out["terms"]]) * ARCSEC
    np.testing.assert_allclose(values, x, rtol=0, atol=1e-11)
    assert main(["fit", str(MMT_DAT), "--azimuth", "S-E", "--residuals", "tpoint"]) == 0
    assert "TPOINT's residuals" in capsys.readouterr().out


class TwiceAzimuth(px.Term):
    """A user's linear sky term that only defines sky_offset (no SkyPoint version)."""

    coef: float = px.terms.param(0.0)
    linear_sky_offset = True

    def sky_offset(self, angles):
        return angle_pair(self.coef * jnp.sin(2 * angles[0]), 0.5 * self.coef * jnp.cos(angles[1]))


def test_user_linear_term_without_skypoint_takes_the_fast_path():
    terms = (*_linear("IA IE"), TwiceAzimuth())
    truth = px.AltAz(terms, residual_form="tpoint").set(IA=30 * ARCSEC, IE=-10 * ARCSEC, TwiceAzimuth=15 * ARCSEC)
    model = px.AltAz(terms, residual_form="tpoint")
    assert is_affine(model)
    sites = [_tpoint_site(k, 50) for k in range(3)]
    sites = [px.simulate(truth, np.asarray(s.encoder), noise=ARCSEC, seed=k) for k, s in enumerate(sites)]
    data = site_data(model.set(TwiceAzimuth=7 * ARCSEC), sites[0])
    ours = np.stack([np.asarray(x) for x in site_residuals(model.set(TwiceAzimuth=7 * ARCSEC), data, weighted=False)], -1)
    np.testing.assert_allclose(ours, np.asarray(px.residuals(model.set(TwiceAzimuth=7 * ARCSEC), sites[0])), rtol=0, atol=1e-15)
    result = px.fit_batch(model, px.stack_observations(sites))
    for k, site in enumerate(sites):
        solo = px.fit(model, site)
        assert bool(result.converged[k]) and int(result.iterations[k]) == 1
        np.testing.assert_allclose(np.asarray(result.values[k]), np.asarray(solo.values), rtol=0, atol=1e-12)
    recovered = float(result.values[0][2]) / ARCSEC
    assert abs(recovered - 15) < 5 * float(result.sigmas[0][2]) / ARCSEC


class _AzimuthFromMinusY(px.SphericalMount):
    """A spherical mount whose own angles_of counts axis 1 differently (for the fallback)."""

    def angles_of(self, direction, near):
        return super().angles_of(direction, near) + jnp.array([0.5, 0.0])


@pytest.mark.parametrize("mount", [px.AltAzMount(azimuth="S-E"), px.XYMount(), px.EquatorialMount(0.6), _AzimuthFromMinusY()])
def test_sky_point_from_components_is_the_angles_with_their_sines(mount):
    """sky_point_of (sines and cosines from the components) against angles_of and
    jnp.sin / jnp.cos of its angles: both solutions, the poles, non-unit directions."""
    rng = np.random.default_rng(8)
    n = 3000
    direction = rng.normal(size=(n, 3)) * rng.uniform(0.5, 2.0, (n, 1))
    direction[:4] = [[0, 0, 1], [0, 0, -2], [0, 0, 0.5], [1e-200, 0, 1]]  # the poles, and next to one
    near = np.stack([rng.uniform(-12, 12, n), rng.uniform(-3, 3, n)], -1)  # both solutions, many turns
    angles = np.asarray(jax.vmap(mount.angles_of)(jnp.asarray(direction), jnp.asarray(near)))
    first = np.abs(angles[:, 1]) <= np.pi / 2
    assert first.any() and (~first).any()
    expected = [angles[:, 0], angles[:, 1], np.sin(angles[:, 0]), np.cos(angles[:, 0]), np.sin(angles[:, 1]), np.cos(angles[:, 1])]
    for how, point in [
        ("eager", mount.sky_point_of(jnp.asarray(direction), jnp.asarray(near))),
        ("jit", jax.jit(lambda d, n: mount.sky_point_of(d, n))(direction, near)),
        ("vmap", jax.vmap(mount.sky_point_of)(jnp.asarray(direction), jnp.asarray(near))),
    ]:
        assert isinstance(point, px.terms.SkyPoint)
        for name, ours, ref in zip(point._fields, point, expected):
            np.testing.assert_allclose(np.asarray(ours), ref, rtol=0, atol=4e-15, err_msg=f"{how}: {name}")


class CosAzimuthInElevation(px.Term):
    """A linear sky term finite at the zenith whose offset there depends on the azimuth."""

    coef: float = px.terms.param(0.0)
    linear_sky_offset = True

    def sky_offset_at(self, point):
        return angle_pair(0.0, self.coef * point.cos_az)

    def sky_offset(self, angles):
        return self.sky_offset_at(px.terms.SkyPoint.at(angles))


def test_batch_with_an_observation_at_the_zenith_equals_solo_fits():
    """At the pole the observed azimuth is the encoder's; the batch takes its sine and
    cosine (a branch that runs only then) and agrees with solo fits."""
    terms = (*_linear("IA IE"), CosAzimuthInElevation())
    model = px.AltAz(terms, residual_form="tpoint")
    truth = model.set(IA=30 * ARCSEC, IE=-10 * ARCSEC, CosAzimuthInElevation=15 * ARCSEC)
    sites = []
    for k in range(3):
        raw = np.array(_tpoint_site(k, 40).encoder)
        raw[3, 1] = np.pi / 2 + 10 * ARCSEC  # the encoders near the zenith (IE = -10")
        obs = px.simulate(truth, raw, noise=ARCSEC, seed=k)
        target = np.array(obs.target)
        if k != 1:
            target[3] = [0.0, 0.0, 1.0]  # the star exactly there
        sites.append(px.Observations(raw, target, convention=obs.convention))
    result = px.fit_batch(model, px.stack_observations(sites))
    for k, site in enumerate(sites):
        solo = px.fit(model, site)
        assert bool(result.converged[k]) and bool(solo.converged)
        np.testing.assert_allclose(np.asarray(result.values[k]), np.asarray(solo.values), rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.asarray(result.residuals[k]), np.asarray(solo.residuals), rtol=0, atol=1e-13)

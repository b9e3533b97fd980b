"""Auxiliary readings in the core (issue 31): Observations carry them, terms read them by
name, fits and the inverse take them, a change of their values never recompiles, and a
missing one is named.

References: closed forms (a user term reading the temperature equals the library's TF
at the coefficient the temperature gives, evaluated without readings), the true values
of noise-free simulations, NumPy's angle between vectors, and JAX's compilation events
(counted, as tests/test_fitting_core.py does).
"""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp
import numpy as np
import pytest
from compile_counter import COUNTER
from numpy_rotations import angle_between

import pointax as px
from pointax.core.readings import READINGS, check_readings
from pointax.core.simulate import encoder_grid
from pointax.fitting import structure
from pointax.fitting.problem import define_problem

ARCSEC = np.pi / 180 / 3600


class TubeFlexureT(px.Term):
    """A user's tube flexure whose coefficient follows the temperature."""

    readings: ClassVar[tuple[str, ...]] = ("temperature",)
    TF: float = px.param(0.0)
    TF_T: float = px.param(0.0)

    def sky_offset(self, angles):
        tf = self.TF + self.TF_T * self.reading("temperature")
        return jnp.stack([0.0 * tf, -tf * jnp.cos(angles[1])])


def _grid(copies=3):
    return np.concatenate([encoder_grid(az_offset_deg=7.0 * k) for k in range(copies)])


def _temperatures(n, copies=3):
    return np.repeat(np.linspace(-5.0, 20.0, copies), n // copies)


def _model(form="sky"):
    terms = list(px.terms.tpoint("IA IE CA NPAE")) + [TubeFlexureT()]
    return px.AltAz(terms, residual_form=form)


def _truth(form="sky"):
    return _model(form).set(IA=20 * ARCSEC, IE=-8 * ARCSEC, CA=5 * ARCSEC, NPAE=3 * ARCSEC, **{"TubeFlexureT.TF": 15 * ARCSEC, "TubeFlexureT.TF_T": 0.8 * ARCSEC})


@pytest.fixture(scope="module", autouse=True)
def fresh_unions():
    structure.clear()


def test_observations_carry_readings():
    enc = _grid(1)
    n = len(enc)
    target = np.asarray(px.AltAz([])(enc))
    t = np.arange(n, dtype=float)
    obs = px.Observations(enc, target, readings={"temperature": t, "time": 60000 + t})
    assert sorted(obs.readings) == ["temperature", "time"]
    assert px.Observations(enc, target).readings == {}
    sub = obs[np.arange(n) % 2 == 0]
    np.testing.assert_array_equal(sub.readings["temperature"], t[::2])
    np.testing.assert_array_equal(obs[3:5].readings["time"], 60000 + t[3:5])
    used = jnp.asarray(np.arange(n) > 4)
    filled = obs.filled_readings(used)
    np.testing.assert_array_equal(np.asarray(filled["temperature"]), np.where(np.arange(n) > 4, t, t[5]))
    with pytest.raises(ValueError, match="reading 'temperature' must have shape"):
        px.Observations(enc, target, readings={"temperature": t[:-1]})
    # a batch: a reading one site lacks and the padding are NaN (not recorded)
    batch = px.stack_observations([obs, px.Observations(enc[:10], target[:10])], n_obs=n + 2)
    assert batch.readings["temperature"].shape == (2, n + 2)
    np.testing.assert_array_equal(batch.readings["temperature"][0, :n], t)
    assert np.isnan(batch.readings["temperature"][0, n:]).all() and np.isnan(batch.readings["temperature"][1]).all()
    assert set(READINGS) >= {"temperature", "pressure", "humidity", "time", "rotator", "tilt_1", "tilt_2"}


def test_model_readings_and_closed_form():
    """A term reading the temperature equals TF at the coefficient it gives (no readings)."""
    model = _truth()
    assert model.readings == ("temperature",)
    assert px.AltAz(px.terms.tpoint("IA IE")).readings == ()
    assert "TubeFlexureT.TF_T" in model.parameter_names and len(model.values()) == 6  # readings are no parameter
    enc = _grid(1)
    for temp in (-3.0, 12.5):
        plain = px.AltAz(px.terms.tpoint("IA IE CA NPAE TF")).set(
            IA=20 * ARCSEC, IE=-8 * ARCSEC, CA=5 * ARCSEC, NPAE=3 * ARCSEC, TF=(15 + 0.8 * temp) * ARCSEC
        )
        got = np.asarray(model(enc, readings={"temperature": np.full(len(enc), temp)}))
        np.testing.assert_allclose(angle_between(got, np.asarray(plain(enc))), 0.0, atol=1e-13)
        one = np.asarray(model.direction(enc[3], readings={"temperature": temp}))
        np.testing.assert_allclose(one, np.asarray(plain.direction(enc[3])), atol=1e-14)
    # with_values / values ignore the readings
    assert np.array_equal(np.asarray(model.with_values(model.values()).values()), np.asarray(model.values()))


def test_missing_reading_is_named():
    model = _truth()
    enc = _grid(1)
    with pytest.raises(ValueError, match="'temperature'"):
        model(enc)
    with pytest.raises(KeyError, match="temperature"):
        model(enc, readings={"pressure": 1000.0})
    target = np.asarray(model(enc, readings={"temperature": 5.0}))
    with pytest.raises(ValueError, match="reading 'temperature' is not among"):
        px.fit(model, px.Observations(enc, target))
    t = np.full(len(enc), 5.0)
    t[[2, 6]] = np.nan
    with pytest.raises(ValueError, match=r"reading 'temperature' is not recorded \(NaN\) at row 3, row 7"):
        px.fit(model, px.Observations(enc, target, readings={"temperature": t}))
    # rows without it, weighted 0, are fine
    w = np.isfinite(t).astype(float)
    check_readings(model, px.Observations(enc, target, w, readings={"temperature": t}))
    with pytest.raises(ValueError, match="give their values at the time of the command"):
        px.command(model, target[:2])


@pytest.mark.parametrize("form", ["sky", "tpoint"])
def test_fit_residuals_equal_the_plain_model(form):
    """The fit's residual function (define_problem) equals pointax.residuals, which is
    the per-observation forward model bound to each row's readings."""
    model = _truth(form)
    enc = _grid()
    t = _temperatures(len(enc))
    obs = px.simulate(model, enc, noise=2 * ARCSEC, readings={"temperature": t})
    other = model.with_values(model.values() * 0.7)
    got = np.asarray(define_problem(other, obs).residuals(other))
    want = np.asarray(px.residuals(other, obs))
    np.testing.assert_allclose(got, want, atol=1e-13)
    # the reference: each temperature's rows against the plain TF model at its coefficient
    for temp in np.unique(t):
        rows = t == temp
        values = dict(zip(other.parameter_names, np.asarray(other.values())))
        plain = px.AltAz(px.terms.tpoint("IA IE CA NPAE TF"), residual_form=form).set(
            IA=values["IA"], IE=values["IE"], CA=values["CA"], NPAE=values["NPAE"],
            TF=values["TubeFlexureT.TF"] + values["TubeFlexureT.TF_T"] * temp,
        )
        np.testing.assert_allclose(want[rows], np.asarray(px.residuals(plain, obs[rows])), atol=1e-13)


def test_fit_recovers_noise_free_truth_and_batch():
    truth = _truth()
    enc = _grid()
    t = _temperatures(len(enc))
    start = truth.with_values(np.zeros(len(truth.parameter_names)))
    sites = []
    for k in range(3):
        tk = t + 4.0 * k
        sites.append(px.simulate(truth.set(IA=(20 + 5 * k) * ARCSEC), enc, readings={"temperature": tk}))
    solo = px.fit(start, sites[0])
    np.testing.assert_allclose(np.asarray(solo.values), np.asarray(truth.values()), atol=1e-10)
    batch = px.fit_batch(start, px.stack_observations(sites))
    for k in range(3):
        want = np.asarray(truth.set(IA=(20 + 5 * k) * ARCSEC).values())
        np.testing.assert_allclose(np.asarray(batch.values[k]), want, atol=1e-10)


def test_new_readings_and_fixed_sets_do_not_recompile():
    truth = _truth()
    enc = _grid()
    t = _temperatures(len(enc))
    start = truth.with_values(np.zeros(len(truth.parameter_names)))
    first = px.fit(start, px.simulate(truth, enc, noise=ARCSEC, readings={"temperature": t}))
    assert first.converged
    variants = [
        (start, t + 3.0),
        (start, t[::-1] * 1.5),
        (start.fix("CA"), t),
        (truth.fix("TubeFlexureT.TF_T"), t + 1.0),
    ]
    results = []
    with COUNTER as counted:
        for model, temps in variants:
            obs = px.simulate(truth, enc, noise=ARCSEC, seed=3, readings={"temperature": temps})
            results.append(px.fit(model, obs))
    assert counted.count == 0
    assert all(bool(r.converged) for r in results)
    # the fixed slope stayed at its value
    assert np.isclose(float(results[3].model.get("TubeFlexureT.TF_T")), 0.8 * ARCSEC, rtol=0, atol=1e-15)


def test_inverse_with_readings_round_trips():
    """px.command with the readings at the time of the command, then the model with the
    same readings: back to the wanted direction within 1e-9 rad."""
    model = _truth()
    rng = np.random.default_rng(1)
    n = 40
    az = rng.uniform(0, 2 * np.pi, n)
    el = rng.uniform(np.radians(15), np.radians(80), n)
    wanted = np.stack([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)], axis=-1)
    temps = rng.uniform(-10, 25, n)
    cmd = px.command(model, wanted, readings={"temperature": temps})
    assert np.all(np.asarray(cmd.ok))
    back = np.asarray(model(np.asarray(cmd.reading), readings={"temperature": temps}))
    assert np.max(angle_between(back, wanted)) < 1e-9
    # the readings matter: another temperature gives another reading (by TF_T x 20 C)
    warmer = px.command(model, wanted, readings={"temperature": temps + 20.0})
    shift = np.asarray(warmer.reading)[:, 1] - np.asarray(cmd.reading)[:, 1]
    np.testing.assert_allclose(shift, 20 * 0.8 * ARCSEC * np.cos(el), rtol=2e-3)
    # one scalar reading for a batch
    one = px.command(model, wanted[:3], readings={"temperature": 4.0})
    back = np.asarray(model(np.asarray(one.reading), readings={"temperature": 4.0}))
    assert np.max(angle_between(back, wanted[:3])) < 1e-9


def test_models_without_readings_carry_nothing_more():
    """A model that reads no readings keeps the fast evaluation: its site data carry no
    encoder copy and no readings, even when the observations have readings."""
    model = px.AltAz(px.terms.tpoint("IA IE CA TF"))
    enc = _grid(1)
    obs = px.simulate(model, enc, readings={"temperature": np.zeros(len(enc))})
    data = define_problem(model, obs).data
    assert data.encoder is None and data.readings is None
    reading = define_problem(_truth(), obs).data
    assert reading.encoder is not None and len(reading.readings) == 1


def test_with_weight_keeps_readings():
    enc = _grid(1)
    obs = px.Observations(enc, np.asarray(px.AltAz([])(enc)), readings={"temperature": np.arange(len(enc), dtype=float)})
    w = np.zeros(len(enc))
    other = obs.with_weight(w)
    np.testing.assert_array_equal(other.weight, w)
    np.testing.assert_array_equal(other.readings["temperature"], obs.readings["temperature"])

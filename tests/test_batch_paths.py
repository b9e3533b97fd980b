"""Structural guards of the batched fit's paths (counted, never timed): clean sites of the
library's models stay on the fast fixed-step pass; sites left to the full loop are fitted
one by one and equal their solo fits; the compile options per model."""

from __future__ import annotations

import jax
import numpy as np
import pytest

import pointax as px
from pointax.fitting import batch as batch
from pointax.fitting import batch_fast_pass as fast_pass
from pointax.fitting.problem import is_affine
from pointax.core.simulate import encoder_grid

TPOINT = "IA IE CA AN AW TF"  # a small model: the guard is structural, the compilation short


def _sites(truth, n_sites, noise, encoder):
    return [px.simulate(truth, encoder, noise=noise, seed=k) for k in range(n_sites)]


def _tpoint_truth(form, terms_form="linear"):
    return px.AltAz(px.terms.tpoint(TPOINT, form=terms_form), residual_form=form).set(
        IA=px.arcsec(120), IE=px.arcsec(-30), CA=px.arcsec(20), AN=px.arcsec(8), AW=px.arcsec(-12), TF=px.arcsec(15)
    )


CASES = {
    "tpoint terms, sky form": (lambda: _tpoint_truth("sky"), lambda: encoder_grid(6, (20, 40, 60, 80))),
    "tpoint terms, tpoint form": (lambda: _tpoint_truth("tpoint"), lambda: encoder_grid(6, (20, 40, 60, 80))),
    "rigorous tpoint terms (the default form)": (
        lambda: _tpoint_truth("sky", px.terms.DEFAULT_FORM),
        lambda: encoder_grid(6, (20, 40, 60, 80)),
    ),
    "turntable": (
        lambda: px.Turntable("full").set(mu0=px.deg(0.07), nu0=px.deg(0.01), omega0=px.deg(-0.09), alpha0=px.deg(0.3), beta0=px.deg(-0.2)),
        lambda: np.stack(np.meshgrid(np.radians(np.arange(0, 360, 30)), np.radians([15, 35, 55, 75])), -1).reshape(-1, 2),
    ),
}


@pytest.mark.parametrize("name", list(CASES))
def test_clean_sites_of_library_models_stay_on_the_fast_path(name, monkeypatch):
    truth_fn, enc_fn = CASES[name]
    truth, encoder = truth_fn(), enc_fn()
    sites = _sites(truth, 6, px.arcsec(1.0), encoder)
    start = truth.with_values(np.zeros(len(truth.parameters)))
    calls = []
    real = batch._fit_sites
    monkeypatch.setattr(batch, "_fit_sites", lambda *a, **k: calls.append(1) or real(*a, **k))
    result = px.fit_batch(start, px.stack_observations(sites))
    assert np.all(np.asarray(result.converged))
    assert calls == []  # no site went to the full loop
    if is_affine(start):
        steps = 1
    elif fast_pass.starts_in_tpoint_form(start):  # one TPOINT-form step, exact steps, chord steps
        steps = 1 + fast_pass.TPOINT_START_STEPS + fast_pass.TPOINT_START_CHORDS
    else:
        steps = fast_pass.DEFAULT_STEPS
    assert np.all(np.asarray(result.iterations) == steps)
    assert fast_pass.starts_in_tpoint_form(start) == (name == "tpoint terms, sky form")


def test_sites_left_to_the_full_loop_equal_their_solo_fits():
    """A rigorous model with a wobble-like nonlinearity: with steps=1 no site converges
    on the fast pass, so all go one by one through the full loop (lax.map), which is the
    solo fit's code: equal values (to rounding)."""
    truth = px.AltAz(px.terms.tpoint("IA IE", form="rigorous")).set(IA=px.arcsec(900), IE=px.arcsec(-400))
    sites = _sites(truth, 3, px.arcsec(1.0), encoder_grid(6, (20, 40, 60, 80)))
    start = truth.with_values(np.zeros(2))
    result = px.fit_batch(start, px.stack_observations(sites), steps=1)
    assert np.all(np.asarray(result.iterations) > 1)
    for k, obs in enumerate(sites):
        solo = px.fit(start, obs)
        np.testing.assert_allclose(np.asarray(result.values[k]), np.asarray(solo.values), rtol=0, atol=1e-14)


def test_fast_compile_options_per_model():
    assert fast_pass.uses_fast_compile_options(px.Turntable("full"))
    assert fast_pass.uses_fast_compile_options(px.AltAz(px.terms.tpoint("IA IE"), residual_form="tpoint"))
    assert fast_pass.uses_fast_compile_options(px.AltAz(px.terms.tpoint("IA IE", form="rigorous")))
    assert not fast_pass.uses_fast_compile_options(px.AltAz(px.terms.tpoint("IA IE", form="linear")))


class _Wobble(px.Term):
    """A user rotation term (the wobble of examples/new_error_term.py): nonlinear in its phase."""

    amp: float = px.terms.param(0.0)
    phase: float = px.terms.param(0.0, unit="deg")

    def base_rotation(self, angles):
        import jax.numpy as jnp

        turn = 2.0 * angles[0] + self.phase
        return px.rotations.small_tilt(self.amp * jnp.cos(turn), self.amp * jnp.sin(turn))


def test_the_tpoint_start_is_only_for_linear_sky_terms(monkeypatch):
    """TPOINT's linear terms with a free user rotation term in the sky form: one step of
    the TPOINT form does not solve it, so the fit takes the five exact steps, and sites
    started near the truth stay on the fast path (with the TPOINT start and one exact
    step, every site went to the full loop). Fixed, the wobble leaves only linear sky
    terms free: then the TPOINT start applies."""
    linear = px.terms.tpoint("IA IE CA", form="linear")
    truth = px.AltAz(linear + (_Wobble(amp=px.arcsec(6), phase=px.deg(35)),)).set(IA=px.arcsec(30), IE=px.arcsec(-12), CA=px.arcsec(-9))
    start = px.AltAz(linear + (_Wobble(amp=px.arcsec(5), phase=px.deg(30)),))
    assert not fast_pass.starts_in_tpoint_form(start)
    assert fast_pass.starts_in_tpoint_form(start.fix("_Wobble.amp", "_Wobble.phase"))
    sites = _sites(truth, 4, px.arcsec(1.0), encoder_grid(8, (20, 35, 50, 65, 80)))
    calls = []
    real = batch._fit_sites
    monkeypatch.setattr(batch, "_fit_sites", lambda *a, **k: calls.append(1) or real(*a, **k))
    result = px.fit_batch(start, px.stack_observations(sites))
    assert np.all(np.asarray(result.converged)) and calls == []
    assert np.all(np.asarray(result.iterations) == fast_pass.DEFAULT_STEPS)


def test_quick_compile_options_leave_the_level_to_jax_when_it_asks_for_least_optimisation():
    """pointax's options raise XLA's optimisation level to 2, except where the user set
    JAX's ``jax_disable_most_optimizations`` (the test suite does): then JAX's 0 holds."""
    from pointax.core import xla_options

    before = jax.config.read("jax_disable_most_optimizations")
    try:
        for flag, level in ((False, True), (True, False)):
            jax.config.update("jax_disable_most_optimizations", flag)
            xla_options.fast_compile_options.cache_clear()
            options = xla_options.fast_compile_options()
            assert options["xla_cpu_use_fusion_emitters"] is False
            assert ("xla_backend_optimization_level" in options) == level
    finally:
        jax.config.update("jax_disable_most_optimizations", before)
        xla_options.fast_compile_options.cache_clear()

"""float64 without touching the user's JAX settings (run in a fresh interpreter)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

from conftest import MMT_DAT


def test_fit_residuals_and_the_forward_model_are_float64_while_user_jax_stays_float32():
    """With JAX's x64 mode off (and left off), a fit computes in float64 (TPOINT's IA
    for the MMT run), and so do px.residuals and the model's per-observation methods
    called outside a fit (in float32 the residuals of this run were 0.065" off): they
    equal the fit's own residuals. One fresh interpreter for both: each import of the
    numerical libraries and first fit costs seconds."""
    code = textwrap.dedent(
        f"""
        import warnings
        warnings.filterwarnings("error", message=".*float64.*")  # JAX's truncation warning
        import jax, jax.numpy as jnp, numpy as np
        import pointax as px
        assert not jax.config.jax_enable_x64
        run = px.io.read_tpoint({str(MMT_DAT)!r}, azimuth="S-E")
        r = px.fit(px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"), azimuth="S-E"), run)
        assert r.values.dtype == jnp.float64, r.values.dtype
        assert abs(r.value("IA") - 1209.2612) < 0.01, r.value("IA")
        assert not jax.config.jax_enable_x64
        assert jnp.ones(2).dtype == jnp.float32
        res = px.residuals(r.model, run.observations)
        assert res.dtype == jnp.float64, res.dtype
        gap = float(np.max(np.abs(np.asarray(res) - np.asarray(r.residuals)))) / px.units.ARCSEC
        assert gap < 1e-6, gap
        assert np.array_equal(np.asarray(px.residuals(r.model, run)), np.asarray(res))  # the run, as px.fit takes it
        e = run.observations.encoder[0]
        for method in (r.model.mount_direction, r.model.direction, r.model.sky_angles):
            assert method(e).dtype == jnp.float64, method
        assert not jax.config.jax_enable_x64
        assert jnp.ones(2).dtype == jnp.float32
        print("ok")
        """
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().endswith("ok")


def test_model_building_blocks_and_heliostat_geometry_are_float64_outside_x64_mode():
    """With JAX's x64 mode off, the model's other per-observation methods
    (corrected_encoder, chain_direction, sky_offset, sky_position) compute in float64
    (corrected_encoder ran in float32 with JAX's truncation warning), and a
    HeliostatMount keeps its actuator geometry as float64 (it was stored in float32,
    moving a heliostat's directions by about 0.04"): each equals the same call made
    with x64 on."""
    code = textwrap.dedent(
        """
        import warnings
        warnings.filterwarnings("error", message=".*float64.*")  # JAX's truncation warning
        import jax, jax.numpy as jnp, numpy as np
        import pointax as px
        assert not jax.config.jax_enable_x64
        model = px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"), azimuth="S-E").set(
            IA=px.arcsec(1209.26), IE=px.arcsec(-31.7), TF=px.arcsec(12.3), NPAE=px.arcsec(4.1))
        e = np.radians(np.array([[123.456789, 41.234567], [301.2, 72.5], [15.0, 22.0]]))
        calls = {
            "corrected_encoder": lambda: model.corrected_encoder(e[0]),
            "chain_direction": lambda: model.chain_direction(e[0]),
            "sky_offset": lambda: model.sky_offset(e[0]),
            "sky_position": lambda: model.sky_position(e),
        }
        for name, call in calls.items():
            got = call()
            with jax.enable_x64(True):
                want = call()
            for g, w in zip(jax.tree.leaves(got), jax.tree.leaves(want)):
                assert g.dtype == jnp.float64, (name, g.dtype)
                assert np.array_equal(np.asarray(g), np.asarray(w)), name
        geometry = dict(increment=[154166.666, 154166.666], initial_stroke=[0.075417, 0.078234],
                        offset=[0.34095, 0.3479], pivot_radius=[0.3204, 0.309], initial_angle=[-1.570796, 0.959931],
                        clockwise=[0.0, 1.0])
        mount = px.HeliostatMount(**geometry)
        for field in ("increment", "initial_stroke", "offset", "pivot_radius", "initial_angle"):
            value = getattr(mount, field)
            assert value.dtype == jnp.float64, (field, value.dtype)
            assert np.array_equal(np.asarray(value), np.asarray(geometry[field], np.float64)), field
        steps = np.array([[25000.0, 42000.0], [61000.0, 13000.0]])
        heliostat = px.Model(mount, px.terms.heliostat("t1n t1u t2e t2n"))
        got = heliostat(steps)
        with jax.enable_x64(True):
            want = px.Model(px.HeliostatMount(**geometry), px.terms.heliostat("t1n t1u t2e t2n"))(steps)
        assert got.dtype == jnp.float64, got.dtype
        gap = float(np.max(np.abs(np.asarray(got) - np.asarray(want)))) / px.units.ARCSEC
        assert gap < 1e-9, gap
        assert not jax.config.jax_enable_x64
        print("ok")
        """
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().endswith("ok")

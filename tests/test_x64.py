"""float64 without touching the user's JAX settings (run in a fresh interpreter)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

from conftest import MMT_DAT


def test_fit_is_float64_while_user_jax_stays_float32():
    code = textwrap.dedent(
        f"""
        import jax, jax.numpy as jnp, numpy as np
        import pointax as px
        assert not jax.config.jax_enable_x64
        run = px.io.read_tpoint({str(MMT_DAT)!r}, azimuth="S-E")
        r = px.fit(px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"), azimuth="S-E"), run)
        assert r.values.dtype == jnp.float64, r.values.dtype
        assert abs(r.value("IA") - 1209.2612) < 0.01, r.value("IA")
        assert not jax.config.jax_enable_x64
        assert jnp.ones(2).dtype == jnp.float32
        print("ok")
        """
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().endswith("ok")


def test_residuals_and_the_forward_model_are_float64_outside_x64_mode():
    """Called outside a fit with JAX's x64 mode off, px.residuals and the model's
    per-observation methods compute in float64 (in float32 the residuals of this run
    were 0.065" off), and equal the fit's own residuals."""
    code = textwrap.dedent(
        f"""
        import warnings
        warnings.filterwarnings("error", message=".*float64.*")  # JAX's truncation warning
        import jax, jax.numpy as jnp, numpy as np
        import pointax as px
        run = px.io.read_tpoint({str(MMT_DAT)!r}, azimuth="S-E")
        r = px.fit(px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"), azimuth="S-E"), run)
        assert not jax.config.jax_enable_x64
        res = px.residuals(r.model, run.observations)
        assert res.dtype == jnp.float64, res.dtype
        gap = float(np.max(np.abs(np.asarray(res) - np.asarray(r.residuals)))) / px.units.ARCSEC
        assert gap < 1e-6, gap
        e = run.observations.encoder[0]
        for method in (r.model.mount_direction, r.model.direction, r.model.sky_angles):
            assert method(e).dtype == jnp.float64, method
        assert not jax.config.jax_enable_x64
        print("ok")
        """
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().endswith("ok")

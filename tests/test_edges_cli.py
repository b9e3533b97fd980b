"""Edges of ``pointax plan`` and ``pointax centroid``: contradicting options refused
before any numerical library is imported, a magnitude limit brighter than every star,
a sun plan's map titled with the figures of its table, ``design_bound`` in float64
outside x64, and ``pointax centroid`` without torch."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest

import pointax as px
from pointax import planning as pl
from pointax.core.units import ARCSEC, DEG

STARS = ["plan", "--site", "31.96,-111.60,2100", "--time", "2026-03-01T05:00"]
SUN = ["plan", "--sun", "--site", "40,116.3,50", "--time", "2026-03-01"]

# Pairs (and single values) of plan options that contradict: each is refused with exit
# status 2, the message naming the options, and nothing numerical imported.
CONTRADICTIONS = [
    (STARS + ["--min-elevation", "60", "--max-elevation", "30"], r"minimum elevation \(60 deg\) must be below the maximum \(30"),
    (STARS + ["--min-elevation", "86"], r"minimum elevation \(86 deg\) must be below the maximum \(85"),
    (SUN + ["--max-elevation", "10"], r"minimum elevation \(15 deg\) must be below the maximum \(10"),
    (STARS + ["--min-elevation", "95"], r"--min-elevation must be between -90 and 90"),
    (STARS + ["--az-limits=270,-270"], r"--az-limits: the minimum \(270\) must be below the maximum \(-270\)"),
    (STARS + ["--el-limits=80,10"], r"--el-limits: the minimum \(80\) must be below the maximum \(10\)"),
    (STARS + ["--target-rms", "-1"], r"--target-rms must be a positive number"),
    (STARS + ["--max-magnitude", "nan"], r"--max-magnitude must be a finite number"),
    (SUN + ["--max-magnitude", "3"], r"--max-magnitude selects stars"),
    (SUN + ["--days", "0"], r"--days must be a positive number"),
    (SUN + ["--step", "-10"], r"--step must be a positive number"),
    (SUN + ["--days", "1", "--step", "2000"], r"--step 2000 minutes is longer than --days 1"),
    (STARS + ["--pressure", "-5"], r"--pressure must be between 0 and 1100"),
    (["plan", "--site", "95,0,0", "--time", "2026-03-01T05:00"], r"--site: latitude must be between -90 and 90"),
]


def _fresh(code: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                          env={**os.environ, **(env or {})})  # fmt: skip


def test_contradicting_plan_options_are_refused_before_importing_jax():
    code = (
        "import json, sys\n"
        "from pointax.cli import main\n"
        f"cases = {[argv for argv, _ in CONTRADICTIONS]!r}\n"
        "out = [main(argv) for argv in cases]\n"
        "print(json.dumps({'status': out, 'loaded': [m for m in ('jax', 'numpy', 'astropy') if m in sys.modules]}))\n"
    )
    proc = _fresh(code)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["loaded"] == [], out
    errors = [line for line in proc.stderr.splitlines() if line.startswith("pointax plan: error:")]
    assert len(errors) == len(CONTRADICTIONS), proc.stderr
    for (argv, pattern), status, line in zip(CONTRADICTIONS, out["status"], errors):
        assert status == 2, (argv, line)
        assert re.search(pattern, line), (argv, line)


def test_a_magnitude_limit_brighter_than_every_star_names_the_brightest(capsys):
    from pointax.cli import main

    assert main(STARS + ["--max-magnitude", "-5"]) == 2
    err = capsys.readouterr().err
    brightest = float(np.min(px.stars.bright_stars().select(None, True).magnitude))
    assert "SkyCoord" not in err
    assert "no star of the catalogue is as bright as magnitude -5" in err
    assert f"the brightest is magnitude {brightest:.2f}" in err, err
    with pytest.raises(ValueError, match="the brightest is magnitude"):
        pl.star_candidates(px.sky.site(31.96, -111.60, 2100), "2026-03-01T05:00", max_magnitude=brightest - 0.01)
    assert len(pl.star_candidates(px.sky.site(31.96, -111.60, 2100), "2026-03-01T05:00", max_magnitude=brightest,
                                  min_elevation_deg=-90, max_elevation_deg=90, sun_avoid_deg=None, moon_avoid_deg=None)) >= 1  # fmt: skip


def _title_figures(fig) -> tuple[float, float]:
    title = fig.axes[0].get_title()
    rms, top = re.search(r'RMS over the [^0-9]*([0-9.]+)", max ([0-9.]+)"', title).groups()
    return float(rms), float(top)


@pytest.mark.slow
def test_a_sun_plan_map_is_titled_with_the_figures_of_its_table():
    """The table's predicted RMS and maximum (over the sun's path) are those of the sky
    map's title, both named 'over the sun's path'; a star plan's map gives the sky's."""
    pytest.importorskip("matplotlib")
    where = px.sky.site(40.0, 116.3, 50.0)
    cand = pl.sun_candidates(where, "2026-03-01", 10, step_minutes=30)
    model = px.Turntable("full").set(alpha0=60.5 * DEG, beta0=165.9 * DEG)
    plan = px.plan_run(model, cand, 12, noise=36 * ARCSEC)
    table = plan.table()
    assert "over the sun's path" in table
    fig = plan.accuracy.skymap(resolution_deg=10)
    assert "RMS over the sun's path" in fig.axes[0].get_title()
    rms, top = _title_figures(fig)
    assert rms == pytest.approx(round(plan.summary["rms_arcsec"], 3), abs=1e-9)
    assert top == pytest.approx(round(plan.summary["max_arcsec"], 3), abs=1e-9)
    assert f'{plan.summary["rms_arcsec"]:.3f}"' in table
    grid = px.plan_run(px.AltAz(px.terms.tpoint("IA IE CA NPAE AN AW")), pl.grid_candidates(n_az=12, elevations_deg=(20, 40, 60, 80)), 10)
    fig = grid.accuracy.skymap(resolution_deg=10)
    assert "RMS over the sky" in fig.axes[0].get_title()
    assert _title_figures(fig)[0] == pytest.approx(round(grid.summary["rms_arcsec"], 3), abs=1e-9)


def test_design_bound_and_the_greedy_design_run_in_float64_outside_x64():
    """Outside JAX's x64 mode (no JAX_ENABLE_X64, as a user's process), design_bound,
    greedy_design and exchange_design compute in float64: no truncation warning, and
    the same bound as in x64 mode to 1e-12."""
    code = (
        "import warnings, json\n"
        "warnings.simplefilter('error')\n"
        "import numpy as np, jax\n"
        "from pointax.planning import design_bound, greedy_design\n"
        "from pointax.planning.design import exchange_design\n"
        "rng = np.random.default_rng(0)\n"
        "a = rng.normal(size=(40, 2, 4)) * (1 + 1e-9 * rng.normal(size=(40, 2, 4))); g = np.diag([1.0, 2.0, 3.0, 4.0])\n"
        "b = design_bound(a, g, 10, iterations=200)\n"
        "order, _ = greedy_design(a, g, 6)\n"
        "idx, _ = exchange_design(a, g, order)\n"
        "print(json.dumps({'x64': bool(jax.config.jax_enable_x64), 'bound': b, 'order': order.tolist()}))\n"
    )
    proc = _fresh(code, {"JAX_ENABLE_X64": "0"})
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["x64"] is False
    rng = np.random.default_rng(0)
    a = rng.normal(size=(40, 2, 4)) * (1 + 1e-9 * rng.normal(size=(40, 2, 4)))
    want = pl.design_bound(a, np.diag([1.0, 2.0, 3.0, 4.0]), 10, iterations=200)
    assert out["bound"] == pytest.approx(list(want), rel=1e-12)


def test_centroid_without_torch_gives_the_install_line(tmp_path):
    """torch made unimportable: ``pointax centroid`` exits 2 with the extra's install
    line, no traceback (as ``plot`` and ``report`` do for matplotlib)."""
    frame = tmp_path / "frame.npy"
    np.save(frame, np.zeros((8, 8), np.uint16))
    code = (
        "import sys\n"
        "sys.modules['torch'] = None  # import torch raises ImportError\n"
        "from pointax.cli import main\n"
        f"sys.exit(main(['centroid', {str(frame)!r}]))\n"
    )
    proc = _fresh(code)
    assert proc.returncode == 2, (proc.returncode, proc.stderr[-2000:])
    assert "Traceback" not in proc.stderr
    assert "pip install 'pointax[vision]'" in proc.stderr
    assert proc.stderr.startswith("pointax centroid: error:"), proc.stderr

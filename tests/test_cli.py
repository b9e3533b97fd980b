"""The pointax command: report, stable JSON keys, exit codes, error messages.

Reference: TPOINT's own model file for the bundled run.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import MMT_DAT, MMT_MOD

import pointax as px
from pointax.cli import main
from pointax.io import read_model


@pytest.fixture(autouse=True)
def no_compilation_cache(monkeypatch):
    """Keep the tests from writing JAX's compilation cache into the home folder."""
    monkeypatch.setenv("POINTAX_JAX_CACHE", "")


@pytest.fixture(scope="module")
def json_fit():
    # In this process (the entry point itself, `python -m pointax`, runs in
    # test_compilation_cache_is_used_when_set): a subprocess would import and compile again.
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["fit", str(MMT_DAT), "--azimuth", "S-E", "--json"]) == 0
    return json.loads(out.getvalue())


def test_compilation_cache_is_used_when_set(tmp_path):
    cache = tmp_path / "cache"
    env = {**os.environ, "POINTAX_JAX_CACHE": str(cache)}
    cmd = [sys.executable, "-m", "pointax", "fit", str(MMT_DAT), "--terms", "IA,IE", "--json"]
    first = json.loads(subprocess.run(cmd, capture_output=True, text=True, check=True, env=env).stdout)
    assert any(cache.iterdir())
    second = json.loads(subprocess.run(cmd, capture_output=True, text=True, check=True, env=env).stdout)
    assert first["terms"] == second["terms"]


def test_json_has_the_stable_keys_and_tpoint_numbers(json_fit):
    out = json_fit
    for key in ("n_obs", "sky_rms_arcsec", "popn_sd_arcsec", "converged", "terms", "correlation"):
        assert key in out
    tpoint = read_model(MMT_MOD)
    assert out["n_obs"] == 80 and out["converged"] is True
    assert [t["name"] for t in out["terms"]] == tpoint.names
    for got, want in zip(out["terms"], tpoint.terms):
        assert set(got) >= {"name", "value_arcsec", "sigma_arcsec"}
        assert got["value_arcsec"] == pytest.approx(want.value, abs=0.01)
        assert got["sigma_arcsec"] == pytest.approx(want.sigma, abs=0.01)
    assert out["sky_rms_arcsec"] == pytest.approx(tpoint.sky_rms, abs=0.01)
    corr = np.array(out["correlation"])
    assert corr.shape == (8, 8)
    np.testing.assert_allclose(np.diag(corr), 1.0)


def test_report_text(capsys, tmp_path):
    written = tmp_path / "fit.mod"
    code = main(["fit", str(MMT_DAT), "--terms", "IA IE NPAE CA AN AW TF TX", "--write-model", str(written)])
    out = capsys.readouterr().out
    assert code == 0
    assert "Sky RMS =" in out and "Popn SD =" in out and "IA" in out and "+1209.26" in out
    assert read_model(written).n_obs == 80


def test_rigorous_form_and_fixed_terms(capsys):
    code = main(["fit", str(MMT_DAT), "--terms", "IA,IE,AN,AW", "--form", "rigorous", "--fix", "AN", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["form"] == "rigorous"
    assert [t["name"] for t in out["terms"]] == ["IA", "IE", "AW"] and out["fixed"] == {"AN": 0.0}


def test_bad_input_exit_code_and_message(capsys, tmp_path):
    bad = tmp_path / "bad.dat"
    bad.write_text("caption\n: ALTAZ\n+31 41 19.6\n10 20 30 4x\n")
    assert main(["fit", str(bad)]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:4:" in err and "field 4 (raw elevation)" in err
    assert main(["fit", str(tmp_path / "missing.dat")]) == 2
    assert "No such file" in capsys.readouterr().err
    assert main(["fit", str(MMT_DAT), "--terms", "IA,NOPE"]) == 2
    assert "unknown TPOINT term 'NOPE'" in capsys.readouterr().err


def test_non_convergence_exit_code(capsys):
    assert main(["fit", str(MMT_DAT), "--terms", "IA,IE", "--max-steps", "1"]) == 1
    assert "NOT CONVERGED" in capsys.readouterr().out


# ------------------------------------------------------------------ pointax command

TURNTABLE_PARAMS = "mu0=0.0751,nu0=0.0145,omega0=-0.0947,alpha0=60.5425,beta0=165.8931"


def _enu(az_deg, el_deg):
    az, el = np.radians(az_deg), np.radians(el_deg)
    return np.array([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)])


def test_command_turntable_json_points_where_asked(tmp_path, capsys):
    import pointax as px

    wanted = [(141.022, 50.469), (359.9, 30.0), (0.1, 70.0), (222.0, 15.0)]
    path = tmp_path / "dirs.txt"
    path.write_text("# az el\n" + "\n".join(f"{a} {e}  # a comment" for a, e in wanted) + "\n")
    assert main(["command", str(path), "--params", TURNTABLE_PARAMS, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert len(out) == len(wanted)
    values = dict(kv.split("=") for kv in TURNTABLE_PARAMS.split(","))
    model = px.Turntable("full").set(**{k: px.deg(float(v)) for k, v in values.items()})
    for row, (az, el) in zip(out, wanted):
        assert row["ok"] and row["reason"] == ""
        # Independent check: the model evaluated at the printed readings.
        reading = np.radians([row["alpha_deg"], row["beta_deg"]])
        assert 0.0 <= reading[0] < 2 * np.pi  # default turntable limits 0..360 deg
        np.testing.assert_allclose(np.asarray(model(reading)), _enu(az, el), atol=1e-9)


def test_command_reflect_flags_opposite_pairs(tmp_path, capsys):
    path = tmp_path / "pairs.txt"
    path.write_text("141.022 50.469 200 60\n90 30 270 -30\n")
    assert main(["command", str(path), "--reflect", "--params", TURNTABLE_PARAMS]) == 1
    out = capsys.readouterr().out
    assert "sun and target are opposite" in out
    assert out.count(" yes ") == 1


def test_command_altaz_with_tpoint_model(tmp_path, capsys):
    import pointax as px

    path = tmp_path / "dirs.txt"
    path.write_text("141.022 50.469\n10 45\n")
    args = ["command", str(path), "--mount", "altaz", "--model", str(MMT_MOD), "--azimuth", "S-E", "--json"]
    assert main(args) == 0
    out = json.loads(capsys.readouterr().out)
    mod = read_model(MMT_MOD)
    model = px.AltAz(px.terms.tpoint(" ".join(t.name for t in mod.terms)), azimuth="S-E")
    model = model.set(**{t.name: px.arcsec(t.value) for t in mod.terms})
    for row in out:
        reading = np.radians([row["az_deg"], row["el_deg"]])
        np.testing.assert_allclose(np.asarray(model(reading)), _enu(*row["input_deg"]), atol=1e-9)


@pytest.mark.parametrize(
    "text, message",
    [
        ("141 50 7\n", "dirs.txt:1: expected 2 numbers"),
        ("\n141 fifty\n", "dirs.txt:2: not a number"),
        ("# nothing\n", "no directions"),
    ],
)
def test_command_bad_directions_file(tmp_path, capsys, text, message):
    path = tmp_path / "dirs.txt"
    path.write_text(text)
    assert main(["command", str(path), "--params", TURNTABLE_PARAMS]) == 2
    assert message in capsys.readouterr().err


def test_command_bad_params(tmp_path, capsys):
    path = tmp_path / "dirs.txt"
    path.write_text("141 50\n")
    assert main(["command", str(path), "--params", "zeta0=1"]) == 2
    assert "no parameter 'zeta0'" in capsys.readouterr().err
    assert main(["command", str(tmp_path / "missing.txt")]) == 2
    assert "missing.txt" in capsys.readouterr().err


def test_command_json_writes_null_for_undefined_readings(tmp_path, capsys):
    path = tmp_path / "pairs.txt"
    path.write_text("90 30 270 -30\n")
    assert main(["command", str(path), "--reflect", "--params", TURNTABLE_PARAMS, "--json"]) == 1
    text = capsys.readouterr().out
    assert "NaN" not in text
    row = json.loads(text)[0]
    assert row["alpha_deg"] is None and not row["ok"]


def test_command_limits_and_elevation_errors(tmp_path, capsys):
    path = tmp_path / "dirs.txt"
    path.write_text("141 50\n")
    assert main(["command", str(path), "--limits", "0,360,x,5"]) == 2
    assert "--limits: not a number" in capsys.readouterr().err
    # An open axis: only axis 1 limited.
    assert main(["command", str(path), "--params", TURNTABLE_PARAMS, "--limits", "0,360,,", "--json"]) == 0
    capsys.readouterr()
    path.write_text("141 100\n")
    assert main(["command", str(path)]) == 2
    assert "dirs.txt:1: elevation outside -90..90" in capsys.readouterr().err


def test_paint_rejects_tpoint_only_options(tmp_path, capsys):
    assert main(["fit", str(tmp_path), "--format", "paint", "--write-model", "x.mod"]) == 2
    assert "--write-model applies to TPOINT runs" in capsys.readouterr().err


GPOINT_SAMPLE = Path(__file__).parent / "data" / "gpoint" / "altaz_manual.txt"


def test_fit_gpoint_file_with_gpoint_and_tpoint_names(capsys):
    """gpoint's own terms (lower case), an extra term and a TPOINT harmonic, mixed."""
    code = main(["fit", str(GPOINT_SAMPLE), "--format", "gpoint", "--terms", "ia,ie,tn,te,npae,npoa,tf", "--fix", "tf", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["converged"]
    assert [t["name"] for t in out["terms"]] == ["ia", "ie", "tn", "te", "npae", "npoa"]
    assert "tf" in out["fixed"]
    # The same fit through the Python API gives the same numbers.
    run = px.io.read_gpoint(GPOINT_SAMPLE)
    model = px.AltAz(px.terms.gpoint_terms("ia,ie,tn,te,npae,npoa,tf"), azimuth=run.azimuth, fixed=["tf"])
    api = px.fit(model, run)
    for row in out["terms"]:
        assert row["value_arcsec"] == pytest.approx(api.value(row["name"], "arcsec"), abs=1e-9)


def test_fit_gpoint_rejects_tpoint_only_options(capsys):
    assert main(["fit", str(GPOINT_SAMPLE), "--format", "gpoint", "--azimuth", "S-E"]) == 2
    assert "South through West" in capsys.readouterr().err
    assert main(["fit", str(GPOINT_SAMPLE), "--format", "gpoint", "--write-model", "x.mod"]) == 2
    assert "lower-case" in capsys.readouterr().err


def test_cache_directory_follows_the_environment(monkeypatch, tmp_path):
    from pointax.fitting.compilation_cache import default_cache_dir, enable_compilation_cache

    monkeypatch.setenv("POINTAX_JAX_CACHE", "")
    assert default_cache_dir() is None and enable_compilation_cache() is None
    monkeypatch.setenv("POINTAX_JAX_CACHE", str(tmp_path / "c"))
    assert default_cache_dir() == tmp_path / "c"
    monkeypatch.delenv("POINTAX_JAX_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "x"))
    assert default_cache_dir() == tmp_path / "x" / "pointax" / "jax"


def test_tpoint_help_and_missing_script_import_no_numerical_library(tmp_path):
    code = (
        "import sys\n"
        "from pointax.cli import main\n"
        f"assert main(['tpoint', {str(tmp_path / 'missing.ptp')!r}]) == 2\n"
        "try:\n"
        "    main(['tpoint', '--help'])\n"
        "except SystemExit:\n"
        "    pass\n"
        "print('LOADED', [m for m in ('jax', 'numpy', 'matplotlib') if m in sys.modules])\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert "LOADED []" in proc.stdout, proc.stdout + proc.stderr
    assert "missing.ptp: No such file or directory" in proc.stderr

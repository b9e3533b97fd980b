"""``pointax history`` and ``pointax fit-network --previous`` on TPOINT files written to a
temporary folder: the exact JSON, the alarm at the right run, the plot, the joint fit,
bad input answered before JAX is imported.

References: TPOINT's linear least squares in NumPy (tests/tpoint_numpy.py) on runs
simulated in NumPy (tests/history_runs.py); the change in sigmas recomputed by hand
from the previous JSON's numbers.
"""

from __future__ import annotations

import contextlib
import datetime
import io
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from history_runs import TERMS, TRUTH_ARCSEC, reference_fit, simulate_run, write_tpoint
from pointax.cli import main

FAST = ["--form", "linear", "--residuals", "tpoint"]  # TPOINT's linear fit: as the reference, and quick


@pytest.fixture(autouse=True)
def no_compilation_cache(monkeypatch):
    monkeypatch.setenv("POINTAX_JAX_CACHE", "")


def _run(argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Four yearly runs (given out of order); IE jumps by 8 sigma at the third."""
    tmp = tmp_path_factory.mktemp("history")
    _, s, _ = reference_fit(*simulate_run(TRUTH_ARCSEC, seed=7))
    step = 8.0 * math.sqrt(2.0) * s[TERMS.index("IE")]
    paths, data = [], []
    for k in range(4):
        coefs = dict(TRUTH_ARCSEC, IE=TRUTH_ARCSEC["IE"] + (step if k >= 2 else 0.0))
        observed, raw = simulate_run(coefs, seed=40 + k)
        path = tmp / f"y{2020 + k}.dat"
        write_tpoint(path, observed, raw, datetime.date(2020 + k, 6, 1), temperature=5.0 + 3 * k)
        paths.append(path)
        data.append((observed, raw))
    return paths, data


def test_history_json_is_exact_and_alarms_the_jump(runs, tmp_path):
    paths, data = runs
    given = [str(p) for p in (paths[2], paths[0], paths[3], paths[1])]
    code, out, err = _run(["history", *given, *FAST, "--json", "--plot", str(tmp_path / "h.png")])
    assert code == 0, err
    d = json.loads(out)
    assert set(d) == {"runs", "alarms"}
    assert [r["file"] for r in d["runs"]] == [str(p) for p in paths]  # ordered by date
    for r, (observed, raw) in zip(d["runs"], data):
        assert set(r) == {"file", "time", "n_obs", "sky_rms_arcsec", "terms"}
        assert [set(t) for t in r["terms"]] == [{"name", "value_arcsec", "sigma_arcsec"}] * len(TERMS)
        values, sigmas, rms = reference_fit(observed, raw)
        np.testing.assert_allclose([t["value_arcsec"] for t in r["terms"]], values, atol=1e-6)
        np.testing.assert_allclose([t["sigma_arcsec"] for t in r["terms"]], sigmas, rtol=1e-6)
    ie = [a for a in d["alarms"] if a["term"] == "IE"]
    assert [a["file"] for a in ie] == [str(paths[2])]
    assert all(set(a) == {"file", "term", "change_sigma"} for a in d["alarms"])
    (v1, s1, _), (v2, s2, _) = reference_fit(*data[1]), reference_fit(*data[2])
    j = TERMS.index("IE")
    assert ie[0]["change_sigma"] == pytest.approx((v2[j] - v1[j]) / math.hypot(s1[j], s2[j]), abs=1e-6)
    assert (tmp_path / "h.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_history_table_and_joint_fit(runs):
    paths, _ = runs
    code, out, err = _run(["history", *map(str, paths), *FAST, "--vary", "TF:temperature", "--alarm", "4"])
    assert code == 0, err
    assert "alarms (change beyond 4 sigma" in out and f"{paths[2].name}  IE  +" in out
    assert "joint fit of 4 runs; varying: TF with temperature" in out
    assert "TF@temperature.slope" in out


@pytest.mark.parametrize(
    "argv, message",
    [
        (["history", "/no/such/run.dat"], "No such file or directory"),
        (["history", "{run}", "--vary", "TF"], "expected TERM:READING"),
        (["history", "{run}", "--vary", "TF:temperature:2"], "degrees are for time"),
        (["history", "{run}", "--plot", "h.xyz"], "xyz"),
    ],
)
def test_bad_input_is_refused_before_jax(runs, argv, message):
    argv = [a.replace("{run}", str(runs[0][0])) for a in argv]
    code = (
        "import sys\nfrom pointax.cli import main\n"
        f"status = main({argv!r})\n"
        "print('jax' in sys.modules, status)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.stdout.split() == ["False", "2"], proc.stderr
    assert message in proc.stderr


def test_an_unknown_vary_term_is_bad_input(runs):
    code, _, err = _run(["history", str(runs[0][0]), *FAST, "--vary", "XX:temperature"])
    assert code == 2 and "--vary XX: not among the terms fitted" in err


# --------------------------------------------------------------------------- fit-network --previous


def test_fit_network_names_what_moved_since_the_previous_fit(runs, tmp_path):
    paths, _ = runs
    manifest = tmp_path / "sites.csv"
    manifest.write_text(
        "site,path,format,terms,form,residuals\n"
        + "".join(f"s{k},{p},tpoint,{' '.join(TERMS)},linear,tpoint\n" for k, p in enumerate(paths[:2]))
    )
    code, out, err = _run(["fit-network", str(manifest), "--json", "--quiet"])
    assert code == 0, err
    now = json.loads(out)
    # The previous fit, as written by an earlier run: s1's CA 6 sigma lower, s0 unchanged.
    previous = json.loads(out)
    ca = next(t for t in previous[1]["terms"] if t["name"] == "CA")
    ca["value_arcsec"] -= 6.0 * math.sqrt(2.0) * ca["sigma_arcsec"]
    (tmp_path / "previous.json").write_text(json.dumps(previous))
    code, out, err = _run(["fit-network", str(manifest), "--json", "--quiet", "--previous", str(tmp_path / "previous.json")])
    assert code == 0, err
    sites = json.loads(out)
    assert sites[0]["moved"] == []
    assert [m["term"] for m in sites[1]["moved"]] == ["CA"]
    ca_now = next(t for t in now[1]["terms"] if t["name"] == "CA")
    expected = (ca_now["value_arcsec"] - ca["value_arcsec"]) / math.hypot(ca_now["sigma_arcsec"], ca["sigma_arcsec"])
    assert sites[1]["moved"][0]["change_sigma"] == pytest.approx(expected, rel=1e-9)
    assert expected == pytest.approx(6.0, rel=1e-6)
    code, out, err = _run(["fit-network", str(manifest), "--quiet", "--previous", str(tmp_path / "previous.json")])
    assert code == 0 and "moved beyond 3 sigma since" in out and "s1  CA" in out
    (tmp_path / "bad.json").write_text('{"sites": 3}')
    code, out, err = _run(["fit-network", str(manifest), "--previous", str(tmp_path / "bad.json")])
    assert code == 2 and "bad.json: not the output of pointax fit-network --json" in err

"""``pointax fit --model START.mod``: start values, TPOINT's ``=`` flags and ``--fix``
at a start value (TPOINT's INMOD then FIX), against NumPy least squares with the fixed
term held (tests/tpoint_numpy.py, which imports nothing of pointax).

The run: the shared MMT run and its TPOINT model (azimuth from South through East),
where IA is +1209.2612": ``--fix IA`` without a start holds IA at 0 and the other terms
absorb it; with ``--model`` it is held at the file's value.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import tpoint_numpy as ref

from pointax.cli import main

TERMS = ["IA", "IE", "NPAE", "CA", "AN", "AW", "TF", "TX"]
IA_FILE = 1209.2612  # the model file's IA, arcsec


@pytest.fixture(autouse=True)
def no_compilation_cache(monkeypatch):
    monkeypatch.setenv("POINTAX_JAX_CACHE", "")


@pytest.fixture(scope="module")
def mmt(shared_data):
    dat = shared_data / "tpoint" / "mmt_20210821.dat"
    mod = shared_data / "tpoint" / "mmt_20210821.mod"
    observed, raw, _ = ref.read_run(dat)
    return dat, mod, observed, raw


def _fit_json(capsys, *argv) -> tuple[int, dict, str]:
    code = main(["fit", *map(str, argv), "--form", "linear", "--json"])  # the NumPy references: linear terms
    captured = capsys.readouterr()
    return code, json.loads(captured.out), captured.err


def _values(out) -> dict[str, float]:
    return {t["name"]: t["value_arcsec"] for t in out["terms"]}


def _sky_fit(names, fixed, observed, raw, start):
    """Gauss-Newton on the rigorous (sky) residuals with ``fixed`` ({name: radians})
    held: NumPy only, Jacobian by central differences."""
    fixed_names, fixed_values = list(fixed), np.array(list(fixed.values()))

    def r(c):
        return ref.sky_residuals(names + fixed_names, np.concatenate([c, fixed_values]), observed, raw).reshape(-1)

    c = np.asarray(start, np.float64)
    for _ in range(10):
        h = 1e-7
        J = np.stack([(r(c + h * e) - r(c - h * e)) / (2 * h) for e in np.eye(len(c))], axis=-1)
        step = np.linalg.lstsq(J, r(c), rcond=None)[0]
        c = c - step
        if np.max(np.abs(step)) < 1e-13:
            break
    return c


@pytest.mark.parametrize("residuals", ["tpoint", "sky"])
def test_model_and_fix_hold_ia_at_the_file_value(capsys, mmt, residuals):
    dat, mod, observed, raw = mmt
    code, out, err = _fit_json(capsys, dat, "--azimuth", "S-E", "--model", mod, "--fix", "IA", "--residuals", residuals)
    assert code == 0 and "warning" not in err
    assert out["fixed"] == {"IA": IA_FILE}
    free = [n for n in TERMS if n != "IA"]
    assert [t["name"] for t in out["terms"]] == free
    used = np.ones(len(raw), bool)
    held = {"IA": IA_FILE * ref.ARCSEC}
    expected = ref.lstsq(free, observed, raw, used, fixed=held)
    if residuals == "sky":
        expected = _sky_fit(free, held, observed, raw, expected)
    got = _values(out)
    for name, value in zip(free, expected / ref.ARCSEC):
        assert got[name] == pytest.approx(value, abs=0.01), name
    # TPOINT's own fit (IA free) is 0.93"; held at its fitted value the rest barely move
    assert out["sky_rms_arcsec"] == pytest.approx(0.9318, abs=0.005)


def test_fix_without_a_start_holds_zero_and_warns(capsys, mmt):
    """The trap the option closes: held at 0, IA's 1209" goes into NPAE and CA."""
    dat, _, observed, raw = mmt
    code, out, err = _fit_json(capsys, dat, "--azimuth", "S-E", "--fix", "IA", "--residuals", "tpoint")
    assert code == 0 and out["fixed"] == {"IA": 0.0}
    assert "pointax: warning: --fix IA: no start value (no --model START.mod): IA is held at 0" in err
    free = [n for n in TERMS if n != "IA"]
    expected = ref.lstsq(free, observed, raw, np.ones(len(raw), bool), fixed={"IA": 0.0}) / ref.ARCSEC
    got = _values(out)
    for name, value in zip(free, expected):
        assert got[name] == pytest.approx(value, abs=0.01), name
    assert out["sky_rms_arcsec"] > 50


def test_model_alone_starts_from_the_file_and_reproduces_it(capsys, mmt):
    """No --terms: the file's terms; the fit from its values lands on TPOINT's (the
    file's) values within 0.003"."""
    dat, mod, *_ = mmt
    code, out, _ = _fit_json(capsys, dat, "--azimuth", "S-E", "--model", mod)
    assert code == 0 and out["fixed"] == {} and [t["name"] for t in out["terms"]] == TERMS
    values = ref.read_model_values(mod)[0]
    for name, value in _values(out).items():
        assert value == pytest.approx(values[name], abs=0.003), name


def test_equals_flags_terms_override_and_new_terms_start_at_zero(capsys, mmt, tmp_path):
    """The file's '=' terms are held at their values; --terms chooses the set: a file
    term left out is not fitted, a term the file lacks starts at 0, and --fix of a
    term the file lacks warns and holds it at 0."""
    dat, mod, observed, raw = mmt
    start = tmp_path / "start.mod"
    start.write_text(
        mod.read_text().replace("  IA      +1209.2612     1.28477", " =IA      +1200.0").replace("  TX ", " =TX ")
    )
    code, out, err = _fit_json(
        capsys, dat, "--azimuth", "S-E", "--model", start, "--terms", "IA IE NPAE CA AN AW TF HECA", "--residuals", "tpoint"
    )
    assert code == 0 and "warning" not in err
    assert out["fixed"] == {"IA": 1200.0}  # TX is not among --terms: neither fitted nor held
    free = ["IE", "NPAE", "CA", "AN", "AW", "TF", "HECA"]
    assert [t["name"] for t in out["terms"]] == free
    expected = ref.lstsq(free, observed, raw, np.ones(len(raw), bool), fixed={"IA": 1200.0 * ref.ARCSEC}) / ref.ARCSEC
    for name, value in zip(free, expected):
        assert _values(out)[name] == pytest.approx(value, abs=0.01), name
    # --fix of a term with no start in the file: held at 0, with a warning naming the file
    code, out, err = _fit_json(
        capsys, dat, "--azimuth", "S-E", "--model", start, "--terms", "IA IE NPAE CA AN AW TF HECA", "--fix", "HECA",
        "--residuals", "tpoint",
    )  # fmt: skip
    assert code == 0 and out["fixed"] == {"IA": 1200.0, "HECA": 0.0}
    assert f"--fix HECA: no start value (HECA is not in {start})" in err
    expected = ref.lstsq(free[:-1], observed, raw, np.ones(len(raw), bool), fixed={"IA": 1200.0 * ref.ARCSEC}) / ref.ARCSEC
    for name, value in zip(free[:-1], expected):
        assert _values(out)[name] == pytest.approx(value, abs=0.01), name


def test_written_model_keeps_the_fixed_flag(capsys, mmt, tmp_path):
    from pointax.io import read_model

    dat, mod, *_ = mmt
    written = tmp_path / "out.mod"
    code, out, _ = _fit_json(capsys, dat, "--azimuth", "S-E", "--model", mod, "--fix", "IA", "--write-model", written)
    assert code == 0
    back = {t.name: t for t in read_model(written).terms}
    assert back["IA"].fixed and back["IA"].value == IA_FILE and not back["IE"].fixed
    assert back["IE"].value == pytest.approx(_values(out)["IE"], abs=1e-4)


def test_bad_start_models_name_file_line_and_field(capsys, mmt, tmp_path):
    dat, mod, *_ = mmt
    bad = tmp_path / "bad.mod"
    bad.write_text("caption\n  IA  +1209.26\n  IH  +3.0\nEND\n")  # IH: an equatorial term
    assert main(["fit", str(dat), "--azimuth", "S-E", "--model", str(bad)]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:3:" in err and "IH" in err
    bad.write_text("caption\n  IA  +12x9.26\nEND\n")
    assert main(["fit", str(dat), "--azimuth", "S-E", "--model", str(bad)]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:2:" in err and "value" in err
    assert main(["fit", str(dat), "--azimuth", "S-E", "--model", str(mod), "--fix", "HACA2"]) == 2
    assert "--fix HACA2: not among the terms fitted (IA IE NPAE CA AN AW TF TX)" in capsys.readouterr().err


def test_model_applies_to_tpoint_runs_and_offsets_tables(capsys, mmt, tmp_path):
    from conftest import REPO

    _, mod, *_ = mmt
    gpoint = REPO / "tests" / "data" / "gpoint"
    sample = next(iter(sorted(gpoint.glob("*.dat"))), None) if gpoint.is_dir() else None
    if sample is not None:
        assert main(["fit", str(sample), "--format", "gpoint", "--model", str(mod)]) == 2
        assert "--model reads TPOINT model files" in capsys.readouterr().err
    folder = tmp_path / "heliostat"
    folder.mkdir()
    assert main(["fit", str(folder), "--format", "paint", "--model", str(mod)]) == 2
    assert "--model applies to TPOINT runs" in capsys.readouterr().err


def test_a_missing_start_model_is_refused_before_any_numerical_library(mmt, tmp_path):
    dat, *_ = mmt
    code = (
        "import sys, json\n"
        "from pointax.cli import main\n"
        f"code = main(['fit', {str(dat)!r}, '--model', {str(tmp_path / 'none.mod')!r}])\n"
        "print(json.dumps({'code': code, 'loaded': [m for m in ('jax', 'numpy') if m in sys.modules]}))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    out = json.loads(proc.stdout.splitlines()[-1])
    assert out == {"code": 2, "loaded": []}
    assert f"{tmp_path / 'none.mod'}: No such file or directory" in proc.stderr


def test_start_values_are_data_the_stored_program_serves_them(mmt, tmp_path):
    """A fit from a model file runs the program its plain fit stored (nothing traced
    or compiled again), as the fixed set and the values are inputs of the compiled fit;
    so does a fit from another model file in the same process."""
    dat, mod, *_ = mmt
    code = (
        "import contextlib, io, json, sys\n"
        "from pointax.cli import main\n"
        "from pointax.fitting import programs\n"
        "runs = []\n"
        "for argv in json.loads(sys.argv[1]):\n"
        "    out = io.StringIO()\n"
        "    with contextlib.redirect_stdout(out):\n"
        "        code = main(argv)\n"
        "    runs.append({'code': code, 'stats': dict(programs.STATS), 'fit': json.loads(out.getvalue())})\n"
        "print(json.dumps(runs))\n"
    )
    env = {**os.environ, "POINTAX_JAX_CACHE": str(tmp_path / "cache")}

    def process(*extras):
        """One Python process fitting the run once per ``extras``: ``[(stats so far, fit), ...]``."""
        argvs = [["fit", str(dat), "--azimuth", "S-E", "--json", *map(str, extra)] for extra in extras]
        proc = subprocess.run([sys.executable, "-c", code, json.dumps(argvs)], capture_output=True, text=True, env=env,
                              timeout=300)  # fmt: skip
        assert proc.returncode == 0, proc.stderr
        runs = json.loads(proc.stdout.splitlines()[-1])
        assert [r["code"] for r in runs] == [0] * len(extras)
        return [(r["stats"], r["fit"]) for r in runs]

    ((stats, plain),) = process(())
    assert stats["exported"] == 1 and stats["stored"] == 1
    other = tmp_path / "other.mod"
    other.write_text(mod.read_text().replace("+1209.2612", "+1100.0000"))
    (stats, started), (stats_again, again) = process(("--model", mod, "--fix", "IA"), ("--model", other, "--fix", "IA"))
    # The first process's executable, loaded while the process imported (its data file
    # named the executable to prefetch): neither traced nor compiled.
    assert stats["exported"] == 0 and stats["executables_loaded"] == 1 and stats["prefetched"] == 1
    assert started["fixed"] == {"IA": IA_FILE}
    # The program loaded for the first runs again from memory: nothing read, nothing traced.
    assert stats_again == {**stats, "memory": stats["memory"] + 1} and again["fixed"] == {"IA": 1100.0}
    # another start, another fit (IA's 109" go mostly into CA and NPAE), from the same program
    assert abs(_values(again)["CA"] - _values(started)["CA"]) > 10

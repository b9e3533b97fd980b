"""Start-up: what ``import pointax`` and the ``pointax`` command import before they need it.

Each check runs a fresh interpreter (``sys.executable``), so that modules imported by
other tests in this process do not count.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

HEAVY = ("astropy", "torch", "kornia", "dask", "optimistix", "lineax")


NUMERICAL = HEAVY + ("jax", "jaxlib", "numpy", "scipy", "equinox", "matplotlib", "tqdm")


def run_fresh(code: str, modules=NUMERICAL) -> tuple[subprocess.CompletedProcess, dict[str, bool]]:
    """Run ``code`` in a fresh interpreter: the finished process and which of
    ``modules`` it left in sys.modules.

    ``code`` may end in SystemExit (argparse's --help and usage errors do): the answer
    is printed in a ``finally`` clause, on the last line of standard output.
    """
    wrapper = (
        "import json, sys\n"
        "try:\n"
        + "".join(f"    {line}\n" for line in code.splitlines())
        + "finally:\n"
        f"    print('\\n' + json.dumps({{m: m in sys.modules for m in {list(modules)!r}}}))\n"
    )
    proc = subprocess.run([sys.executable, "-c", wrapper], capture_output=True, text=True, timeout=120)
    assert proc.stdout.strip(), proc.stderr
    return proc, json.loads(proc.stdout.strip().splitlines()[-1])


def loaded_after(code: str, modules=NUMERICAL) -> dict[str, bool]:
    """Which of ``modules`` a fresh interpreter running ``code`` left in sys.modules."""
    return run_fresh(code, modules)[1]


def imported(loaded: dict[str, bool]) -> list[str]:
    return sorted(m for m, present in loaded.items() if present)


# --------------------------------------------------------------------------- import pointax


def test_import_pointax_imports_no_heavy_library():
    loaded = loaded_after("import pointax")
    assert not any(loaded[m] for m in HEAVY), imported(loaded)


def test_a_model_class_needs_no_astropy_torch_or_dask():
    loaded = loaded_after("import pointax\npointax.AltAz")
    assert not any(loaded[m] for m in ("astropy", "torch", "kornia", "dask")), imported(loaded)


def test_subpackages_import_no_astropy_or_torch():
    for package in ("pointax.io", "pointax.terms", "pointax.sunsensor"):
        loaded = loaded_after(f"import {package}")
        assert not any(loaded[m] for m in ("astropy", "torch", "kornia", "dask")), (package, imported(loaded))


def test_every_public_name_resolves_to_its_module_attribute():
    import importlib

    import pointax

    for name in pointax.__all__:
        value = getattr(pointax, name)
        if name in pointax._SUBMODULES:
            assert value is importlib.import_module(f"pointax.{pointax._SUBMODULES[name]}")
        else:
            assert value is getattr(importlib.import_module(f"pointax.{pointax._EXPORTS[name]}"), name), name
    assert set(pointax.__all__) <= set(dir(pointax))
    assert pointax.__version__


def test_functions_named_like_their_modules_stay_functions():
    """``pointax.terms.tpoint`` is the function even after the module defining it
    (``pointax/terms/tpoint_terms.py``) is imported by name, and so on."""
    code = (
        "import pointax, pointax.fitting, pointax.core.inverse, pointax.core.simulate, pointax.terms.tpoint_terms\n"
        "import pointax.terms.heliostat_terms, pointax.sunsensor.centroids, pointax.fitting.residuals\n"
        "from pointax.sunsensor import centroid\n"
        "assert callable(pointax.fit) and pointax.fit.__module__.startswith('pointax.'), pointax.fit\n"
        "functions = (pointax.fit, pointax.command, pointax.compare, pointax.simulate, pointax.residuals,\n"
        "             pointax.terms.tpoint, pointax.terms.heliostat, centroid)\n"
        "assert all(not isinstance(f, type(pointax)) for f in functions), functions\n"
        "from pointax import fit\n"
        "assert fit is pointax.fit"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr


def test_a_lazy_package_refuses_a_name_of_one_of_its_submodules(tmp_path, monkeypatch):
    """Importing a submodule binds it to its package's attribute of the same name, which
    would replace a function of that name exported on first use: lazy_namespace refuses
    the pair when the package is imported (every package of pointax imports, above)."""
    package = tmp_path / "lazyprobe"
    package.mkdir()
    (package / "tool.py").write_text("def tool():\n    return 1\n")
    (package / "__init__.py").write_text(
        "from pointax.core.lazy import lazy_namespace\n__getattr__, __dir__ = lazy_namespace(__name__, {'tool': 'tool'})\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ValueError, match="exported tool would be replaced by the submodule"):
        import lazyprobe  # noqa: F401
    monkeypatch.delitem(sys.modules, "lazyprobe", raising=False)


def test_unknown_name_is_an_attribute_error():
    import pointax

    with pytest.raises(AttributeError, match="no attribute 'no_such_name'"):
        pointax.no_such_name  # noqa: B018


# --------------------------------------------------------------------------- the pointax command


def run_pointax(*argv: str) -> tuple[subprocess.CompletedProcess, dict[str, bool]]:
    """``python -m pointax ARGV...`` in a fresh interpreter (through runpy, as ``-m``)."""
    return run_fresh(f"import runpy\nsys.argv = ['pointax', *{list(argv)!r}]\nrunpy.run_module('pointax', run_name='__main__')")


@pytest.mark.parametrize(
    "argv",
    [
        ("--help",),
        ("fit", "--help"),
        ("command", "--help"),
        ("fit-network", "--help"),
        ("centroid", "--help"),
        ("compare", "--help"),
        ("plot", "--help"),
        ("report", "--help"),
    ],
)
def test_help_imports_no_numerical_library(argv):
    proc, loaded = run_pointax(*argv)
    assert proc.returncode == 0, proc.stderr
    assert "usage: pointax" in proc.stdout
    assert not any(loaded.values()), imported(loaded)


@pytest.mark.parametrize(
    "argv, message",
    [
        (("fit", "/nonexistent.dat"), "pointax: error: /nonexistent.dat: No such file or directory"),
        (("fit", "/nonexistent-heliostat", "--format", "paint"), "/nonexistent-heliostat: No such file"),
        (("command", "/nonexistent.txt"), "pointax: error: /nonexistent.txt: No such file or directory"),
        (("fit-network", "/nonexistent.csv"), "pointax fit-network: error: /nonexistent.csv: No such file"),
        (("compare", "/nonexistent.dat"), "pointax compare: error: /nonexistent.dat: No such file"),
        (("fit", "x.dat", "--solver", "newton"), "invalid choice: 'newton'"),
        (("fit", "x.dat", "--bogus"), "unrecognized arguments: --bogus"),
        (("plot", "/nonexistent.dat", "-o", "x.png"), "pointax plot: error: /nonexistent.dat: No such file"),
        (("plot", "x.dat", "-o", "x.jpg"), "pointax plot: error: x.jpg: cannot tell the graphics format"),
        (("plot", "x.dat", "--kind", "pie", "-o", "x.png"), "invalid choice: 'pie'"),
        (("report", "/nonexistent.dat", "-o", "r.html"), "pointax report: error: /nonexistent.dat: No such file"),
        (("fitt", "x.dat"), "invalid choice: 'fitt'"),
        (("plan", "--site", "31,-110,2000", "--time", "2026-03-01T05:00", "--moon-avoid", "500"),
         "pointax plan: error: --moon-avoid must be between 0 and 180 degrees"),
        (("plan", "--site", "31,-110", "--time", "2026-03-01T05:00"), "pointax plan: error: --site: expected 3"),
        (("plan", "--sun", "--site", "31,-110,2000", "--time", "2026-03-01", "--cadence", "60"),
         "pointax plan: error: --cadence schedules stars"),
    ],
)
def test_argument_errors_answer_before_any_numerical_library(argv, message):
    proc, loaded = run_pointax(*argv)
    assert proc.returncode == 2
    assert message in proc.stderr
    assert not any(loaded.values()), imported(loaded)


def test_format_errors_answer_before_jax(tmp_path):
    """A file whose format cannot be told is refused by pointax.io.detect_format, which
    imports no numerical library."""
    ambiguous = tmp_path / "four.txt"
    ambiguous.write_text("1 2 3 4\n5 6 7 8\n")
    proc, loaded = run_pointax("fit", str(ambiguous))
    assert proc.returncode == 2
    assert str(ambiguous) in proc.stderr and "tpoint" in proc.stderr and "xy" in proc.stderr
    assert not any(loaded[m] for m in ("jax", "numpy")), imported(loaded)


def test_the_console_script_entry_point_is_pointax_cli_main():
    import tomllib
    from pathlib import Path

    from pointax.cli import main

    project = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())
    assert project["project"]["scripts"]["pointax"] == "pointax.cli:main"
    assert callable(main)


def test_plot_kinds_of_the_parser_equal_the_librarys():
    from pointax.cli.plot import PLOT_KINDS
    from pointax.cli.report import REPORT_KINDS
    from pointax.plots import FIT_KINDS
    from pointax.plots.report import REPORT_FIGURES

    assert PLOT_KINDS == tuple(FIT_KINDS)
    assert REPORT_KINDS == REPORT_FIGURES


def test_importing_pointax_plots_imports_no_matplotlib():
    loaded = loaded_after("import pointax.plots")
    assert not loaded["matplotlib"], imported(loaded)


def test_the_light_copies_of_library_names_equal_the_library():
    """pointax.cli.choices (what the parser is built from) cannot drift from the library."""
    import pointax.terms as terms
    from pointax.cli import choices
    from pointax.cli.centroid import METHODS
    from pointax.core.inverse import SOLUTIONS
    from pointax.fitting import LOSSES, SOLVERS
    from pointax.io import FOCAL_SPOT_METHODS, RUN_FORMATS
    from pointax.core.model import RESIDUAL_FORMS
    from pointax.core.mounts import AZIMUTH_CONVENTIONS
    from pointax.io.tpoint import MOUNTS as TPOINT_MOUNTS
    from pointax.procedures.session import MOUNTS as PROCEDURE_MOUNTS
    from pointax.sunsensor.centroids import METHODS as CENTROID_METHODS
    from pointax.terms.heliostat_terms import HELIOSTAT_DEFAULT
    from pointax.terms.sun_vector import TURNTABLE_MODELS
    from pointax.terms.model_factories import XY_FAMILIES
    from pointax.terms.xy import FAMILIES

    assert choices.SOLVERS == tuple(SOLVERS)
    assert choices.LOSSES == tuple(LOSSES)
    assert choices.TERM_FORMS == tuple(terms.FORMS)
    assert choices.DEFAULT_TERM_FORM == terms.DEFAULT_FORM
    assert choices.RESIDUAL_FORMS == tuple(RESIDUAL_FORMS)
    assert choices.AZIMUTH_CONVENTIONS == tuple(AZIMUTH_CONVENTIONS)
    assert choices.BASIC_ALTAZ == tuple(terms.BASIC_ALTAZ)
    assert choices.GPOINT_ALTAZ_TERMS == tuple(terms.GPOINT_ALTAZ_TERMS)
    assert choices.HELIOSTAT_DEFAULT == tuple(HELIOSTAT_DEFAULT)
    assert choices.FOCAL_SPOT_METHODS == tuple(FOCAL_SPOT_METHODS)
    assert choices.TURNTABLE_MODELS == tuple(TURNTABLE_MODELS)
    assert choices.XY_FAMILIES == XY_FAMILIES == tuple(FAMILIES)
    assert choices.SOLUTIONS == tuple(SOLUTIONS)
    assert choices.TPOINT_MOUNTS == tuple(PROCEDURE_MOUNTS) == tuple(TPOINT_MOUNTS)
    assert choices.BASIC_EQUATORIAL == tuple(terms.BASIC_EQUATORIAL)
    assert choices.CENTROID_METHODS == METHODS == tuple(CENTROID_METHODS)
    assert choices.RUN_FORMATS == tuple(RUN_FORMATS)


def test_no_library_module_holds_argparse_code():
    from pathlib import Path

    package = Path(__file__).resolve().parents[1] / "pointax"
    holders = [
        str(path.relative_to(package))
        for path in package.rglob("*.py")
        if "argparse" in path.read_text() and path.parent.name != "cli"
    ]
    assert holders == []


def test_the_core_imports_no_particular_term():
    """The numerical core (rotations, mounts, model, the term interface) loads no term
    of the library, no astropy, no file format and no fitting code."""
    code = (
        "import sys\n"
        "import pointax.core.rotations, pointax.core.mounts, pointax.core.model, pointax.core.term\n"
        "loaded = sorted(m for m in sys.modules if m.startswith('pointax.'))\n"
        "allowed = {'pointax.core.lazy', 'pointax.core.precision', 'pointax.core.compiled', 'pointax.core.trig', 'pointax.core.units', 'pointax.core.rotations',\n"
        "           'pointax.core.mounts', 'pointax.core.model', 'pointax.core.observations', 'pointax.core', 'pointax.core.errors', 'pointax.core.term',\n"
        "           'pointax.core.readings'}\n"
        "extra = [m for m in loaded if m not in allowed]\n"
        "assert not extra and 'astropy' not in sys.modules, extra\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr

"""Shared test set-up: float64 JAX, paths to bundled and shared data, and what keeps
the suite short: XLA's quicker-compiling CPU options at JAX's least optimisation, one
compilation cache per test session, and the longest test files scheduled first."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from pathlib import Path

# Compiling is most of the suite's time. (1) XLA's older loop emitters compile pointax's
# programs in about two thirds of the time (pointax already compiles its larger programs
# so, pointax.core.xla_options; here every program of the session is), and at JAX's
# least optimisation (JAX_DISABLE_MOST_OPTIMIZATIONS: level 0, which pointax's own
# options then leave alone) in about three quarters of that again: the suite's fits run
# on a few dozen observations, so compiling, not running, is their cost (three long test
# files, alternating runs: 208 and 188 s at level 2, 169 and 130 s at level 0).
# Subprocesses inherit both. POINTAX_TEST_XLA_DEFAULTS=1 keeps XLA's and JAX's defaults.
if os.environ.get("POINTAX_TEST_XLA_DEFAULTS") != "1":
    _flags = os.environ.get("XLA_FLAGS", "")
    if "--xla_cpu_use_fusion_emitters" not in _flags:
        os.environ["XLA_FLAGS"] = f"{_flags} --xla_cpu_use_fusion_emitters=false".strip()
    os.environ.setdefault("JAX_DISABLE_MOST_OPTIMIZATIONS", "1")
# (2) One compilation cache for the session, shared by both xdist workers (they inherit
# this process's environment) and the subprocesses tests start: the same program
# compiled in another process is loaded. A temporary folder, so that a run starts cold
# as CI does and the suite never writes to ~/.cache; set JAX_COMPILATION_CACHE_DIR (and
# POINTAX_JAX_CACHE) to keep one between runs. Tests that need the cache off or their
# own folder set POINTAX_JAX_CACHE themselves.
if "JAX_COMPILATION_CACHE_DIR" not in os.environ:
    _cache = tempfile.mkdtemp(prefix="pointax-tests-jax-")
    atexit.register(shutil.rmtree, _cache, ignore_errors=True)
    os.environ["JAX_COMPILATION_CACHE_DIR"] = _cache
    os.environ.setdefault("POINTAX_JAX_CACHE", _cache)
    os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0.5")  # pointax's own threshold

import jax  # noqa: E402  (after the environment above)
import pytest  # noqa: E402

# pointax switches x64 on inside its own entry points; tests that call low-level JAX
# functions directly want it on globally too. (tests/test_x64.py checks the default
# behaviour in a fresh subprocess.)
jax.config.update("jax_enable_x64", True)

# Property tests draw the same examples on every run, so a CI result can be reproduced;
# `pytest --hypothesis-profile=explore tests/test_properties.py` draws new ones, many more.
try:
    from hypothesis import settings as _hypothesis_settings

    _hypothesis_settings.register_profile("repeatable", derandomize=True)
    _hypothesis_settings.register_profile("explore", derandomize=False, max_examples=2000)
    _hypothesis_settings.load_profile("repeatable")
except ImportError:  # hypothesis is a dev extra; tests that need it import it themselves
    pass

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = REPO / "examples"
MMT_DAT = EXAMPLES / "data" / "mmt_20210821.dat"
MMT_MOD = EXAMPLES / "data" / "mmt_20210821.mod"
SHARED = REPO.parent / "shared"
SHARED_DATA = SHARED / "data"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """../shared/data, or skip when the shared folder is not beside the checkout."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"{SHARED_DATA} not found: the shared data folder is not beside this checkout")
    return SHARED_DATA


# The longest test files first: xdist (--dist loadfile --no-loadscope-reorder) hands the
# files out in this order, so that neither worker is left with a long file at the end
# while the other idles (the longest files of a quiet 2-core run; the rest keep their order).
_LONGEST_FILES = (
    "test_pooled.py", "test_readme_commands.py", "test_robust.py", "test_fauto.py", "test_fitting_core.py",
    "test_examples_sunsensor.py", "test_network.py", "test_examples_compare.py", "test_fit.py",
    "test_batch_fast_pass.py", "test_distributed.py", "test_cli_fit_start.py", "test_residual_form.py",
    "test_tpoint_repertoire.py", "test_io_offsets.py", "test_statuses.py", "test_shared.py",
    "test_io_tpoint_equatorial.py", "test_network_speed.py", "test_edges_cli.py", "test_fit_outputs.py",
)  # fmt: skip


@pytest.fixture(autouse=True)
def _programs_folder_restored():
    """A test that runs the CLI in-process turns the stored programs on
    (`enable_compilation_cache`); later tests in the worker would then load stored
    programs where they count traces and compilations. Restored after every test."""
    from pointax.fitting import programs

    before = programs.directory()
    yield
    programs.set_directory(before)


def pytest_collection_modifyitems(config, items):
    def rank(item):
        name = item.nodeid.split("::")[0].rsplit("/", 1)[-1]
        return _LONGEST_FILES.index(name) if name in _LONGEST_FILES else len(_LONGEST_FILES)

    items.sort(key=rank)  # stable: a file's tests keep their order

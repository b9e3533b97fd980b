"""Guards for what keeps the test suite short (tests/conftest.py): if one is lost the
suite still passes, only slower, so these fail instead."""

from __future__ import annotations

import os
from pathlib import Path

import pytest


@pytest.mark.skipif(os.environ.get("POINTAX_TEST_XLA_DEFAULTS") == "1", reason="XLA's defaults asked for")
def test_tests_compile_with_the_quicker_xla_options():
    import jax

    from pointax.core import xla_options

    assert "--xla_cpu_use_fusion_emitters=false" in os.environ.get("XLA_FLAGS", "")
    assert os.environ.get("JAX_DISABLE_MOST_OPTIMIZATIONS") == "1"
    assert jax.config.read("jax_disable_most_optimizations")
    assert "xla_backend_optimization_level" not in xla_options.fast_compile_options()


def test_one_compilation_cache_per_session_outside_the_home_folder():
    import jax

    folder = os.environ.get("JAX_COMPILATION_CACHE_DIR")
    assert folder and Path(folder).is_dir()
    assert not Path(folder).resolve().is_relative_to(Path.home() / ".cache")
    assert jax.config.jax_compilation_cache_dir == folder


def test_the_longest_files_are_handed_out_first(pytestconfig):
    import conftest

    assert "--no-loadscope-reorder" in pytestconfig.getini("addopts") or pytestconfig.getoption("dist", "no") == "no"
    for name in conftest._LONGEST_FILES:
        assert (Path(__file__).parent / name).is_file(), name

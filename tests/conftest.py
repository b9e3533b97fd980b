"""Shared test set-up: float64 JAX, paths to bundled and shared data."""

from __future__ import annotations

from pathlib import Path

import jax
import pytest

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

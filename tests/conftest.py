"""Shared test set-up: float64 JAX, paths to bundled and shared data."""

from __future__ import annotations

from pathlib import Path

import jax
import pytest

# pointax switches x64 on inside its own entry points; tests that call low-level JAX
# functions directly want it on globally too. (tests/test_x64.py checks the default
# behaviour in a fresh subprocess.)
jax.config.update("jax_enable_x64", True)

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

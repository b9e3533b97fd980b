"""float64 for pointax without changing the user's own JAX settings.

JAX computes in float32 unless its x64 mode is on. pointax needs float64 (in float32 an
optimistix fit was seen to stop 1-6 arcsec from the float64 answer), but switching the
global flag at import would change every other JAX computation in the user's process.
So each public entry point runs inside ``jax.enable_x64(True)``: the flag is on for the
duration of that call only. A user who composes pointax functions inside their own
``jit`` should switch x64 on globally (``JAX_ENABLE_X64=1`` or
``jax.config.update("jax_enable_x64", True)``).
"""

from __future__ import annotations

import functools

import jax

__all__ = ["float64"]


def float64(fn):
    """Decorator: run ``fn`` with JAX's x64 mode switched on (as it is, when it is on)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        if jax.config.jax_enable_x64:
            return fn(*args, **kwargs)
        with jax.enable_x64(True):
            return fn(*args, **kwargs)

    return wrapper

"""XLA compiler options that shorten the compilation of pointax's larger programs.

On the CPU, XLA's older loop emitters compile these programs (the batched fixed-step
fit, model building's residuals and Jacobian, the solo fit, :func:`pointax.command`'s
solve) in well under half the time of its fusion emitters, and the programs run as fast
(figures in ``benchmarks/batch_fit_notes.md`` and ``benchmarks/interactive_notes.md``).
The options go through ``jax.jit``'s public ``compiler_options``, and only where this
XLA knows them.
"""

from __future__ import annotations

import functools

import jax

__all__ = ["FAST_COMPILE_OPTIONS", "fast_compile_options", "jit"]

FAST_COMPILE_OPTIONS = {"xla_cpu_use_fusion_emitters": False, "xla_backend_optimization_level": 2}
"""The options (see the module's docstring)."""


@functools.cache
def fast_compile_options() -> dict:
    """:data:`FAST_COMPILE_OPTIONS` where this XLA knows them, else ``{}`` (its defaults).
    With JAX's ``jax_disable_most_optimizations`` on (``JAX_DISABLE_MOST_OPTIMIZATIONS=1``)
    the optimisation level is left to JAX (0): the user asked for the quickest compiles."""
    options = dict(FAST_COMPILE_OPTIONS)
    try:
        least = bool(jax.config.read("jax_disable_most_optimizations"))
    except Exception:  # a JAX without the flag
        least = False
    if least:
        options.pop("xla_backend_optimization_level")
    try:
        jax.jit(lambda x: x + 1.0, compiler_options=options).lower(1.0).compile()
    except Exception:  # an XLA without these options
        return {}
    return options


def jit(fn, fast: bool = True, **kwargs):
    """``jax.jit(fn, **kwargs)``, with :func:`fast_compile_options` when ``fast`` (found
    out when this is called: a tiny compilation the first time)."""
    return jax.jit(fn, compiler_options=(fast_compile_options() if fast else None) or None, **kwargs)

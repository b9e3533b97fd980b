"""Functions of a model compiled as one program when called outside a trace.

Run op by op, the per-observation model is many small operations, each compiled on its
first use and dispatched one at a time, which is several times slower than compiling
the whole evaluation once (figures in ``benchmarks/interactive_notes.md``).
:func:`compile_by_structure` compiles such a function once per pytree structure and
array shapes of its arguments; inside a caller's ``jit``, ``vmap`` or ``grad`` it is
traced into the caller's program as usual.
"""

from __future__ import annotations

import functools

import equinox as eqx
import jax
import numpy as np

__all__ = ["compile_by_structure"]


def _as_array(x):
    return np.float64(x) if isinstance(x, float) else x


def compile_by_structure(fn):
    """Decorator: ``eqx.filter_jit(fn)``, with Python floats among the arguments' leaves
    (a term built with a default value holds one) passed as float64 arrays, so that a
    change of a value runs the program already compiled."""
    jitted = eqx.filter_jit(fn)

    @functools.wraps(fn)
    def wrapper(*args):
        return jitted(*jax.tree.map(_as_array, args))

    return wrapper

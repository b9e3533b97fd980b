"""A solver's step limit as data.

optimistix takes ``max_steps`` as a Python integer, part of the compiled program, so
every other limit would compile the fit again. :class:`StepLimited` wraps a
least-squares solver and stops it after a number of steps held in an array instead;
the fit then tells optimistix no limit. A solve it stops ends with optimistix's
``nonlinear_max_steps_reached``, as one stopped by optimistix's own limit does.

Imported on first use (it subclasses optimistix's solver class): a process that runs a
stored fit never imports optimistix.
"""

from __future__ import annotations

from collections.abc import Callable

import jax.numpy as jnp
import optimistix as optx
from jaxtyping import Array, Int

__all__ = ["StepLimited"]


class StepLimited(optx.AbstractLeastSquaresSolver):
    """``solver``, stopped after ``max_steps`` steps (an integer array, may be traced).

    The steps, the test of convergence and the result are ``solver``'s own; only the
    stop at the limit is added, with optimistix's ``nonlinear_max_steps_reached`` when
    ``solver`` had not finished. Pass ``max_steps=None`` to :func:`optimistix.least_squares`.
    """

    solver: optx.AbstractLeastSquaresSolver
    max_steps: Int[Array, ""]

    @property
    def rtol(self) -> float:
        return self.solver.rtol

    @property
    def atol(self) -> float:
        return self.solver.atol

    @property
    def norm(self) -> Callable:
        return self.solver.norm

    def init(self, fn, y, args, options, f_struct, aux_struct, tags):
        return self.solver.init(fn, y, args, options, f_struct, aux_struct, tags), jnp.asarray(0)

    def step(self, fn, y, args, options, state, tags):
        inner, steps = state
        y, inner, aux = self.solver.step(fn, y, args, options, inner, tags)
        return y, (inner, steps + 1), aux

    def terminate(self, fn, y, args, options, state, tags):
        inner, steps = state
        done, result = self.solver.terminate(fn, y, args, options, inner, tags)
        stopped = jnp.invert(done) & (steps >= self.max_steps)
        return done | stopped, optx.RESULTS.where(stopped, optx.RESULTS.nonlinear_max_steps_reached, result)

    def postprocess(self, fn, y, aux, args, options, state, tags, result):
        return self.solver.postprocess(fn, y, aux, args, options, state[0], tags, result)


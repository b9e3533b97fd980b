"""The step limit as data (pointax.fitting.step_limit.StepLimited) stops each of the
fit's solvers where optimistix's own ``max_steps`` stops it: the same values, step
count and result, one compiled program for every limit. Reference: optimistix itself,
with the limit as its static ``max_steps``, on Rosenbrock's residuals."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest

from pointax.fitting.step_limit import StepLimited

SOLVERS = {
    "lm": optx.LevenbergMarquardt,
    "gauss-newton": optx.GaussNewton,
    "dogleg": optx.Dogleg,
}
START = jnp.array([-1.2, 1.0])


def rosenbrock(y, _):
    return jnp.array([y[0] - 1.0, 10.0 * (y[1] - y[0] ** 2)])


@pytest.mark.parametrize("name", sorted(SOLVERS))
def test_the_limit_as_data_stops_where_optimistix_stops(name):
    solver = SOLVERS[name](rtol=1e-10, atol=1e-13)
    traces = []

    @jax.jit
    def limited(limit):
        traces.append(limit)
        sol = optx.least_squares(rosenbrock, StepLimited(solver, limit), START, max_steps=None, throw=False)
        return sol.value, sol.stats["num_steps"], sol.result

    for limit in (1, 4, 200):
        want = optx.least_squares(rosenbrock, solver, START, max_steps=limit, throw=False)
        value, steps, result = limited(jnp.asarray(limit))
        # Equal to rounding: two compiled programs, whose arithmetic XLA may order
        # differently on another CPU (dogleg's fourth step differed by 1e-14 relative on
        # an AVX-512 FP16 Xeon). A step more or less moves Rosenbrock's iterate by >1e-3.
        np.testing.assert_allclose(np.asarray(value), np.asarray(want.value), rtol=1e-12, atol=0, err_msg=f"{name}, {limit} steps")
        assert int(steps) == int(want.stats["num_steps"]), (name, limit)
        assert bool(result == want.result), (name, limit)
    assert len(traces) == 1  # every limit ran the one program
    # 200 steps reach the optimum (1, 1): a success, not a stop at the limit.
    assert bool(want.result == optx.RESULTS.successful) and np.allclose(np.asarray(want.value), 1.0)
    # One step does not: the stop at the limit is optimistix's own result.
    first = limited(jnp.asarray(1))
    assert bool(first[2] == optx.RESULTS.nonlinear_max_steps_reached) and int(first[1]) == 1

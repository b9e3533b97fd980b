"""The options of a fit, as one object: solver, step limit, tolerances, loss, scale, reject.

Light on purpose (no JAX): the command line reads the names here before any numerical
library is imported.
"""

from __future__ import annotations

import dataclasses
import math
import operator

__all__ = ["FitOptions", "SOLVER_NAMES", "LOSS_NAMES"]

SOLVER_NAMES = {"lm": "Levenberg-Marquardt", "gauss-newton": "Gauss-Newton", "dogleg": "Dogleg"}
"""Solver name -> display name (the optimistix classes: :data:`pointax.fitting.SOLVERS`)."""

LOSS_NAMES = ("linear", "huber", "soft_l1", "cauchy")
"""Loss names (the functions: :data:`pointax.fitting.LOSSES`); 'linear' is least squares."""


@dataclasses.dataclass(frozen=True)
class FitOptions:
    """How a fit runs (hashable: :meth:`compiled` is part of a compiled fit's structure).

    Attributes:
        solver: 'lm' (Levenberg-Marquardt, default), 'gauss-newton' or 'dogleg'.
        max_steps: solver step limit; a fit that reaches it reports ``converged=False``.
        rtol, atol: optimistix tolerances on the parameters (radians) and the cost.
        loss: 'linear' (least squares, default) or a robust loss ('huber', 'soft_l1',
            'cauchy'; see :data:`pointax.fitting.LOSSES`).
        loss_scale: soft margin of the robust loss, radians (None: twice the robust
            standard deviation of the residuals, re-estimated after a first pass).
        reject: with a robust loss, observations whose weighted residual norm exceeds
            ``reject`` robust standard deviations are flagged as outliers and left out
            of the final least-squares fit.

    Raises:
        ValueError: naming the option, for a value out of range.
    """

    solver: str = "lm"
    max_steps: int = 256
    rtol: float = 1e-10
    atol: float = 1e-13
    loss: str = "linear"
    loss_scale: float | None = None
    reject: float = 3.0

    def __post_init__(self):
        if self.solver not in SOLVER_NAMES:
            raise ValueError(f"unknown solver {self.solver!r}; expected one of {sorted(SOLVER_NAMES)}")
        if self.loss not in LOSS_NAMES:
            raise ValueError(f"unknown loss {self.loss!r}; expected one of {sorted(LOSS_NAMES)}")
        ls = self.loss_scale
        if ls is not None and not (isinstance(ls, (int, float)) and math.isfinite(ls) and ls > 0):
            raise ValueError(f"loss_scale must be a positive number of radians, got {ls!r}")
        if not (isinstance(self.reject, (int, float)) and math.isfinite(self.reject) and self.reject > 0):
            raise ValueError(f"reject must be a positive number of robust sigmas, got {self.reject!r}")
        try:
            steps = operator.index(self.max_steps)
        except TypeError:
            steps = 0
        if steps <= 0:
            raise ValueError(f"max_steps must be a positive integer, got {self.max_steps!r}")
        for name in ("rtol", "atol"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        # Plain Python numbers: the options are static in compiled fits.
        object.__setattr__(self, "max_steps", int(self.max_steps))
        object.__setattr__(self, "rtol", float(self.rtol))
        object.__setattr__(self, "atol", float(self.atol))
        object.__setattr__(self, "reject", float(self.reject))
        if ls is not None:
            object.__setattr__(self, "loss_scale", float(ls))

    @property
    def robust(self) -> bool:
        """Whether the loss is a robust one (outliers are flagged)."""
        return self.loss != "linear"

    def compiled(self) -> "FitOptions":
        """What a compiled fit's program depends on: these options with the step limit,
        the robust loss, its scale and the rejection threshold at fixed stand-ins (``loss``
        'cauchy' for any robust loss). Those four are data of the program
        (:class:`pointax.fitting.core.FitSettings`), so that another ``max_steps``, loss,
        scale or ``reject`` refits without compiling; only least squares against robust is
        structure, with the solver and the tolerances."""
        return FitOptions(self.solver, rtol=self.rtol, atol=self.atol, loss="cauchy" if self.robust else "linear")

    def replace(self, **changes) -> "FitOptions":
        """A copy with some options changed (checked again)."""
        return dataclasses.replace(self, **changes)

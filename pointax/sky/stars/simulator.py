"""The star-run simulator: encoder readings that centre each planned star for a true
model, with noise (:func:`simulate_star_run`). See :mod:`pointax.sky.stars`."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from astropy.time import Time
from jaxtyping import Float, Int

from ...core.precision import float64
from ...core.inverse import command
from ...core.model import Model
from ...core.observations import Observations
from ...core.rotations import offset_direction
from ...core.units import ARCSEC
from .planner import StarPlan

__all__ = ["NOISE_ON", "StarRun", "simulate_star_run"]

NOISE_ON = ("encoder", "sky")
"""Values of ``simulate_star_run(..., noise_on=...)``."""


@dataclasses.dataclass(frozen=True, eq=False)
class StarRun:
    """A simulated pointing run.

    Attributes:
        observations: :class:`pointax.Observations`: the noisy encoder readings
            (``(n, 2)``, radians, the true model's mount convention) and, as targets,
            the stars' apparent directions (``(n, 3)`` ENU). Feed it to
            :func:`pointax.fit`.
        true_encoder: ``(n, 2)`` noise-free readings that centre each star exactly
            under the true model.
        plan: the :class:`StarPlan` observed (stars, times, apparent places).
        noise_arcsec: ``(2,)`` standard deviations of the noise, arcsec: per encoder
            axis (``noise_on="encoder"``) or (cross-elevation, elevation) on the sky.
        noise_on: ``"encoder"`` or ``"sky"``.
    """

    observations: Observations
    true_encoder: Float[np.ndarray, "n 2"]
    plan: StarPlan
    noise_arcsec: Float[np.ndarray, "2"]
    noise_on: str = "encoder"

    def __len__(self) -> int:
        return len(self.plan)

    def __getitem__(self, index) -> StarRun:
        """The observations selected by a NumPy index, mask or slice (order kept)."""
        index = index if isinstance(index, slice) else np.atleast_1d(np.asarray(index))
        return dataclasses.replace(
            self,
            observations=self.observations[index],
            true_encoder=self.true_encoder[index],
            plan=self.plan[index],
        )

    @property
    def hip(self) -> Int[np.ndarray, " n"]:
        """``(n,)`` HIP numbers of the stars, in observing order."""
        return self.plan.hip

    @property
    def times(self) -> Time:
        """``(n,)`` UTC times of observation."""
        return self.plan.times

    def split(self, n_fit: int, seed: int = 0) -> tuple[StarRun, StarRun]:
        """Split into a fitting set of ``n_fit`` stars, drawn at random, and a validation
        set of the rest (each kept in observing order). With an evenly spread plan both
        sets cover the sky; the paper's split is ``run.split(68)`` of 146 stars.

        Raises:
            ValueError: ``n_fit`` not in ``1 .. len(self) - 1``.
        """
        n = len(self)
        if isinstance(n_fit, bool) or not isinstance(n_fit, int | np.integer) or not 0 < n_fit < n:
            raise ValueError(f"n_fit must be an integer in 1 .. {n - 1} for a run of {n} stars, got {n_fit!r}")
        perm = np.random.default_rng(seed).permutation(n)
        return self[np.sort(perm[:n_fit])], self[np.sort(perm[n_fit:])]


def _commanded(model: Model, direction: np.ndarray, plan: StarPlan, what: str, **kwargs) -> np.ndarray:
    """Readings from :func:`pointax.command`; raises naming each star it cannot reach."""
    cmd = command(model, direction, **kwargs)
    ok = np.asarray(cmd.ok)
    if not np.all(ok):
        reasons = cmd.reasons()
        bad = np.flatnonzero(~ok)
        lines = [
            f"step {k}: HIP {plan.hip[k]} at {plan.times[k].iso} UTC "
            f"(az {math.degrees(plan.azimuth[k]):.3f}, el {math.degrees(plan.elevation[k]):.3f} deg): {reasons[k]}"
            for k in bad[:10]
        ]
        more = f"\n... and {bad.size - 10} more" if bad.size > 10 else ""
        raise ValueError(
            f"the true model cannot {what} {bad.size} of {len(plan)} planned stars "
            "(change limits or solution, or the plan):\n" + "\n".join(lines) + more
        )
    return np.asarray(cmd.reading, np.float64)


@float64
def simulate_star_run(
    model: Model,
    plan: StarPlan,
    noise_arcsec: float | tuple[float, float] = 0.0,
    *,
    seed: int = 0,
    noise_on: str = "encoder",
    solution: str = "normal",
    limits=None,
) -> StarRun:
    """The encoder readings a mount described by ``model`` reports on a star run.

    For each planned star the true model's inverse (:func:`pointax.command`) gives the
    raw readings that centre it; noise is then added. The readings are exact to
    :func:`pointax.command`'s tolerance (``model(true_encoder)`` matches the apparent
    directions to about 1e-12 rad).

    Args:
        model: the true pointing model (:class:`pointax.Model`, any mount).
        plan: the stars, times and apparent directions (:func:`plan_star_run`).
        noise_arcsec: standard deviation of Gaussian noise, arcsec: one value for both
            axes or a pair. With ``noise_on="encoder"`` (default) it is added to the
            readings of (axis 1, axis 2), e.g. ``(4.1, 2.0)`` for the paper's L and B;
            with ``"sky"`` it is a centring error (cross-elevation, elevation) in the
            tangent plane at the star, and the readings are those that point there.
        seed: seed of the NumPy random generator.
        noise_on: ``"encoder"`` or ``"sky"``.
        solution: which mechanical solution the mount uses, as in
            :func:`pointax.command` (default ``"normal"``).
        limits: axis limits in reading units, as in :func:`pointax.command` (e.g.
            ``((0, 2 * np.pi), None)`` for azimuth readings in ``[0, 2 pi)``).

    Returns:
        A :class:`StarRun`.

    Raises:
        ValueError: negative or non-finite noise, an unknown ``noise_on``, or planned
            stars the true model cannot point at within the limits (each named).
    """
    if not isinstance(plan, StarPlan):
        raise TypeError(f"plan must be a pointax.sky.stars.StarPlan, got {type(plan).__name__}")
    if noise_on not in NOISE_ON:
        raise ValueError(f"noise_on must be one of {NOISE_ON}, got {noise_on!r}")
    try:
        sigma = np.array(np.broadcast_to(np.asarray(noise_arcsec, np.float64), (2,)))
    except ValueError:
        raise ValueError(f"noise_arcsec must be one number or a pair, got {noise_arcsec!r}") from None
    if not np.all(np.isfinite(sigma) & (sigma >= 0)):
        raise ValueError(f"noise_arcsec must be finite and non-negative, got {noise_arcsec!r}")
    kwargs = dict(solution=solution, limits=limits)
    true = _commanded(model, plan.direction, plan, "point at", **kwargs)
    draws = np.random.default_rng(seed).standard_normal((len(plan), 2)) * (sigma * ARCSEC)
    if noise_on == "encoder":
        encoder = true + draws
    else:
        aim = np.asarray(offset_direction(plan.direction, draws), np.float64)
        encoder = _commanded(model, aim, plan, "point near", near=true, **kwargs)
    observations = Observations(encoder, plan.direction, convention=model.mount.convention)
    return StarRun(observations, true, plan, sigma, noise_on)

"""Plan the next pointing run: :func:`plan_run` chooses observations by the model's
own Jacobian and predicts the accuracy of the fit before the first star.

    import pointax as px
    from pointax import planning

    model = px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"))
    where = px.sky.site(31.96, -111.60, 2100)
    stars = planning.star_candidates(where, "2026-03-01T05:00")
    plan = px.plan_run(model, stars, 40, noise=px.arcsec(2), limits=((-px.deg(270), px.deg(270)), None))
    print(plan.table())                      # observing order, az/el, predicted accuracy
    plan.accuracy.skymap()                   # predicted pointing error over the sky

Steps: (1) each candidate's raw reading through the model's inverse
(:func:`pointax.planning.readings_for`, the chosen pier side ``solution``), dropping
those outside the elevation or mount ``limits``; (2) their Jacobians and the
sky-averaged ``G`` (:mod:`pointax.planning.accuracy`); (3) greedy I-optimal (or
D-optimal) selection, one compiled call (:mod:`pointax.planning.design`); (4) stop at
``n`` or where the predicted all-sky RMS reaches ``target_rms``; (5) order the chosen
targets for short slews (:mod:`pointax.planning.ordering`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from jaxtyping import Float, Int

from .._x64 import float64
from ..model import Model
from ..units import ARCSEC, angles_in_radians
from .accuracy import PredictedAccuracy, _inverse, information_matrix, noise_weights, sky_average
from .candidates import Candidates
from .design import DEFAULT_RIDGE, EXCHANGE_PASSES, exchange_design, greedy_design
from .jacobian import pointing_jacobian, reading_limits_ok, readings_for
from .ordering import order_path, path_length, sky_angle_matrix, slew_matrix

__all__ = ["Plan", "plan_run"]


@dataclasses.dataclass(frozen=True, eq=False)
class Plan:
    """A planned run (:func:`plan_run`).

    Attributes:
        targets: the chosen :class:`Candidates`, in observing order.
        index: ``(n,)`` their indices in the candidates given.
        readings: ``(n, 2)`` raw readings (on the branch inside the limits).
        predicted: ``(n,)`` predicted RMS pointing error over the sky (radians) of a fit
            to the targets in the order the greedy selection took them (``predicted[k]``
            after ``k + 1`` observations; inf until they determine the model), before the
            exchange passes; ``accuracy`` and ``summary`` are those of the final set.
        accuracy: the predicted accuracy of a fit to all the targets
            (:class:`PredictedAccuracy`).
        slew: total slew of the observing order (radians: the larger axis move per slew,
            or the sky angle for counted readings).
        criterion, noise: how it was planned; ``noise`` ``(2,)`` radians.
        n_candidates: candidates the mount could reach within the limits.
        stopped: 'n' (``n`` reached), 'target' (the target RMS reached) or
            'candidates' (ran out of candidates).
    """

    targets: Candidates
    index: Int[np.ndarray, " n"]
    readings: Float[np.ndarray, "n 2"]
    predicted: Float[np.ndarray, " n"]
    accuracy: PredictedAccuracy
    slew: float
    criterion: str
    noise: Float[np.ndarray, " 2"]
    n_candidates: int
    stopped: str
    summary: dict = dataclasses.field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.targets)

    def to_dict(self) -> dict:
        """JSON-ready: ``targets`` in observing order (``label``, ``azimuth_deg``,
        ``elevation_deg``, ``readings_deg``, ``time``, ``predicted_sigma_arcsec`` (the
        predicted pointing error of the final fit at that target)), ``predicted``
        (``rms_arcsec``, ``max_arcsec``, ``median_rms_arcsec`` over the sky) and the
        plan's ``criterion``, ``noise_arcsec``, ``n``, ``n_candidates``, ``stopped``,
        ``slew_deg``, ``rms_after_arcsec`` (after each pick, in the order chosen)."""
        t = self.targets
        sigma = self.accuracy.total(t.direction) / ARCSEC
        counted = not _angle_readings(self.accuracy.model)
        rows = []
        for k in range(len(t)):
            row = {
                "order": k + 1,
                "label": str(t.label[k]),
                "azimuth_deg": round(math.degrees(float(t.azimuth[k])), 5),
                "elevation_deg": round(math.degrees(float(t.elevation[k])), 5),
                "readings": [float(x) for x in self.readings[k]] if counted else [round(math.degrees(float(x)), 5) for x in self.readings[k]],
                "predicted_sigma_arcsec": round(float(sigma[k]), 4),
            }
            if t.time is not None:
                row["time"] = str(t.time[k])
            if t.magnitude is not None and np.isfinite(t.magnitude[k]):
                row["magnitude"] = float(t.magnitude[k])
            rows.append(row)
        return {
            "n": len(t),
            "criterion": self.criterion,
            "noise_arcsec": [float(x) / ARCSEC for x in self.noise],
            "n_candidates": self.n_candidates,
            "stopped": self.stopped,
            "slew_deg": math.degrees(self.slew),
            "readings_unit": "counts" if counted else "deg",
            "predicted": self.summary,
            "rms_after_arcsec": [None if not np.isfinite(x) else float(x) / ARCSEC for x in self.predicted],
            "targets": rows,
        }

    def table(self) -> str:
        """The observing order as text: label, azimuth, elevation, readings, predicted
        error there, then the predicted all-sky figures."""
        d = self.to_dict()
        unit = d["readings_unit"]
        lines = [f"{'#':>3} {'target':>24} {'az deg':>9} {'el deg':>8} {'axis1 ' + unit:>12} {'axis2 ' + unit:>12} {'sigma':>8}"]
        for row in d["targets"]:
            lines.append(
                f"{row['order']:>3} {row['label']:>24} {row['azimuth_deg']:9.3f} {row['elevation_deg']:8.3f} "
                f"{row['readings'][0]:12.4f} {row['readings'][1]:12.4f} {row['predicted_sigma_arcsec']:8.3f}"
            )
        s = d["predicted"]
        lines.append(
            f"{d['n']} targets of {d['n_candidates']} ({d['criterion']}, noise {d['noise_arcsec'][0]:g}\" per axis); "
            f"predicted all-sky pointing RMS {s['rms_arcsec']:.3f}\", max {s['max_arcsec']:.3f}\", "
            f"median run {s['median_rms_arcsec']:.3f}\"; total slew {d['slew_deg']:.1f} deg"
        )
        return "\n".join(lines)


def _angle_readings(model: Model) -> bool:
    from ..observations import COUNTED_READINGS

    return model.mount.convention not in COUNTED_READINGS


@float64
def plan_run(
    model: Model,
    candidates: Candidates,
    n: int,
    *,
    noise=2.0 * ARCSEC,
    criterion: str = "i-optimal",
    target_rms: float | None = None,
    sky=None,
    limits=None,
    solution: str = "normal",
    min_elevation_deg: float | None = None,
    max_elevation_deg: float | None = None,
    start: str = "d-optimal",
    ridge: float = DEFAULT_RIDGE,
    exchange: int = EXCHANGE_PASSES,
    order: bool = True,
    first: int | None = None,
) -> Plan:
    """Choose up to ``n`` observations from ``candidates`` that pin ``model`` down best.

    Args:
        model: the pointing model to be fitted (its values: where to linearise; its
            free parameters: what the run must determine).
        candidates: :class:`Candidates` (:func:`pointax.planning.star_candidates`,
            :func:`~pointax.planning.sun_candidates`, :func:`~pointax.planning.grid_candidates`).
        n: most observations.
        noise: expected measurement noise on the sky, radians (one value, or one per
            axis of the mount frame's tangent plane); default 2 arcsec.
        criterion: 'i-optimal' (least sky-averaged predicted pointing variance) or
            'd-optimal' (largest ``log det`` of the information matrix).
        target_rms: stop as soon as the predicted all-sky pointing RMS is at most this
            (radians).
        sky: ``(m, 3)`` ENU directions over which pointing matters (default
            :func:`pointax.planning.sky_grid`: 512 equal-area points, 20-85 deg).
        limits: mount limits in reading units, as for :func:`pointax.command`
            (``((axis1_min, axis1_max), (axis2_min, axis2_max))``): azimuth wrap / cable
            limits, elevation or declination limits. Candidates outside are dropped.
        solution: pier side / mechanical solution, 'normal' or 'flipped'.
        min_elevation_deg, max_elevation_deg: further elevation limits on the
            candidates (degrees).
        start, ridge: how the greedy selection starts (:mod:`pointax.planning.design`).
        exchange: passes of Fedorov exchange after the greedy selection (0: none;
            :func:`pointax.planning.design.exchange_design`). With ``target_rms`` the
            greedy sequence is cut where it reaches the target, then exchanged.
        order: order the chosen targets for short slews (else: the greedy order). Sun
            positions are always in order of time.
        first: index (into ``candidates``) of where the mount is, to start the path
            from; it is not itself a target.

    Returns:
        A :class:`Plan`.

    Raises:
        ValueError: no candidate within the limits, or too few to determine the model.
    """
    n = int(n)
    if n < 1:
        raise ValueError(f"n must be at least 1, got {n}")
    if not isinstance(candidates, Candidates):
        raise TypeError(f"candidates must be pointax.planning.Candidates, got {type(candidates).__name__}")
    weights = noise_weights(noise)
    d = candidates.direction
    el = candidates.elevation
    usable = np.ones(len(candidates), bool)
    if min_elevation_deg is not None:
        usable &= el >= math.radians(min_elevation_deg)
    if max_elevation_deg is not None:
        usable &= el <= math.radians(max_elevation_deg)
    readings, ok = readings_for(model, d, solution=solution)
    usable &= ok
    readings, inside = reading_limits_ok(model, readings, limits)
    usable &= inside
    if not usable.any():
        raise ValueError("no candidate lies within the limits and is reachable by the model")
    idx = np.flatnonzero(usable)
    jac, _ = pointing_jacobian(model, readings[idx])
    jac = np.asarray(jac)
    g, _ = sky_average(model, sky)
    a = jac * weights[None, :, None]
    p = a.shape[-1]
    n_pick = min(n, idx.size)
    picked, objective = greedy_design(a, g, n_pick, criterion=criterion, start=start, ridge=ridge)
    picked = picked[picked >= 0]
    # Exact predicted RMS after each pick (no ridge): inf until the model is determined.
    predicted = np.full(picked.size, np.inf)
    m = np.zeros((p, p))
    for k, j in enumerate(picked):
        m += a[j].T @ a[j]
        if k + 1 >= (p + 1) // 2:
            try:
                predicted[k] = math.sqrt(max(float(np.trace(g @ _inverse(m))), 0.0))
            except ValueError:
                pass
    stopped = "n" if picked.size == n else "candidates"
    if target_rms is not None:
        target = float(angles_in_radians(target_rms, "target_rms"))
        reached = np.flatnonzero(predicted <= target)
        if reached.size:
            picked, predicted = picked[: reached[0] + 1], predicted[: reached[0] + 1]
            stopped = "target"
    if exchange and picked.size:
        picked, _ = exchange_design(a, g, picked, criterion=criterion, passes=exchange, ridge=ridge)
    chosen = idx[picked]
    if candidates.kind == "sun" and candidates.time is not None:
        # The sun is where it is when it is: observing order is the order in time.
        seq = chosen[np.argsort(candidates.time[chosen], kind="stable")]
    elif order and chosen.size > 1:
        cost_pts = readings[chosen] if _angle_readings(model) else d[chosen]
        if first is not None:
            start_pt = readings[first] if _angle_readings(model) else d[first]
            pts = np.concatenate([start_pt[None], cost_pts])
            cost = slew_matrix(pts) if _angle_readings(model) else sky_angle_matrix(pts)
            path = order_path(cost, 0)[1:] - 1
        else:
            cost = slew_matrix(cost_pts) if _angle_readings(model) else sky_angle_matrix(cost_pts)
            path = order_path(cost)
        seq = chosen[path]
    else:
        seq = chosen
    pts = readings[seq] if _angle_readings(model) else d[seq]
    slew = path_length(slew_matrix(pts) if _angle_readings(model) else sky_angle_matrix(pts), np.arange(seq.size))
    jac_seq, _ = pointing_jacobian(model, readings[seq])
    try:
        cov = _inverse(information_matrix(np.asarray(jac_seq), 1.0 / weights))
    except ValueError:
        raise ValueError(
            f"{seq.size} observations (of {idx.size} candidates within the limits) do not determine the "
            f"model's {p} free parameters: allow more observations or more candidates"
        ) from None
    acc = PredictedAccuracy(model, cov, d[seq])
    summary = acc.summary(sky)
    return Plan(candidates[seq], seq, readings[seq], predicted, acc, slew, criterion, 1.0 / weights, int(idx.size), stopped, summary)

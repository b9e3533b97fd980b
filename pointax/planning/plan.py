"""Plan the next pointing run: :func:`plan_run` chooses observations by the model's
own Jacobian and predicts the accuracy of the fit before the first star.

    import pointax as px
    from pointax import planning

    model = px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"))
    where = px.sky.site(31.96, -111.60, 2100)
    stars = planning.star_candidates(where, "2026-03-01T05:00")
    plan = px.plan_run(model, stars, 40, noise=px.arcsec(2), limits=((-px.deg(270), px.deg(270)), None),
                       seconds_per_target=60)  # each star where it is when its turn comes
    print(plan.table())                      # observing order, time, az/el, predicted accuracy
    plan.accuracy.skymap()                   # predicted pointing error over the sky

Steps: (1) each candidate's raw reading through the model's inverse
(:func:`pointax.planning.readings_for`, the chosen pier side ``solution``), dropping
those outside the elevation or mount ``limits``; (2) their Jacobians and the
sky-averaged ``G`` (:mod:`pointax.planning.accuracy`; the sky: the visible sky's grid,
or for sun candidates the sun's path); (3) greedy I-optimal (or D-optimal) selection,
one compiled call (:mod:`pointax.planning.design`); (4) stop at ``n`` or where the
predicted RMS over the sky reaches ``target_rms``; (5) order the chosen targets for
short slews (:mod:`pointax.planning.ordering`); (6) with ``seconds_per_target``, give
the stars their times (start + k x cadence) and place them again there
(:func:`pointax.planning.place_stars`), dropping those that then break a limit; the
predicted accuracy is that of the directions so observed.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
from jaxtyping import Float, Int

from ..core.precision import float64
from ..core.errors import PointaxWarning
from ..core.model import Model
from ..core.units import ARCSEC, angles_in_radians, directions_enu
from .accuracy import PredictedAccuracy, information_matrix, invert_information, noise_weights, sky_average, sky_grid
from .candidates import Candidates, place_stars
from .design import DEFAULT_RIDGE, EXCHANGE_PASSES, exchange_design, greedy_design
from .jacobian import pointing_jacobian, reading_limits_ok, readings_for
from .ordering import order_path, path_length, sky_angle_matrix, slew_matrix

__all__ = ["Plan", "plan_run", "SKY_CHOICES", "MAX_PATH_SKY"]

SKY_CHOICES = ("grid", "path")
"""Named skies of :func:`plan_run`: 'grid' (:func:`pointax.planning.sky_grid`, the
visible sky 20-85 deg) and 'path' (the candidates' own directions within the limits:
for sun candidates, the sun's path over their span)."""

MAX_PATH_SKY = 4096
"""Most directions of a 'path' sky: longer paths are thinned evenly (every k-th)."""


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
        stopped: 'n' (``n`` reached), 'target' (the target RMS reached),
            'candidates' (ran out of candidates) or 'moved' (the target RMS was reached
            by the stars where they were at the start, but not by the scheduled ones).
        summary: :meth:`PredictedAccuracy.summary` over the plan's sky, with ``sky``
            ('grid', 'path' or 'given').
        seconds_per_target: the cadence the stars were scheduled at (seconds), or None
            (a snapshot: every target where it is at the candidates' time).
        dropped: ``(label, time, reason)`` of the targets left out because they broke a
            limit at their scheduled time.
        sky: ``(m, 3)`` ENU directions the selection and ``summary`` averaged over (see
            :func:`plan_run`'s ``sky``; those the model reaches count).
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
    seconds_per_target: float | None = None
    dropped: tuple = ()
    sky: Float[np.ndarray, "m 3"] | None = None

    def __len__(self) -> int:
        return len(self.targets)

    def to_dict(self) -> dict:
        """JSON-ready: ``targets`` in observing order (``label``, ``azimuth_deg``,
        ``elevation_deg``, ``readings``, ``time`` (ISO UTC: when scheduled, the
        scheduled time, at which the azimuth and elevation are given),
        ``predicted_sigma_arcsec`` (the predicted pointing error of the final fit at that
        target)), ``predicted`` (``rms_arcsec``, ``max_arcsec``, ``median_rms_arcsec``,
        ``n_sky``, ``sky`` over the plan's sky) and the plan's ``criterion``,
        ``noise_arcsec``, ``n``, ``n_candidates``, ``stopped``, ``slew_deg``,
        ``seconds_per_target``, ``dropped`` (``label``, ``time``, ``reason``) and
        ``rms_after_arcsec`` (after each pick, in the order chosen, at the candidates'
        positions)."""
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
            "seconds_per_target": self.seconds_per_target,
            "dropped": [{"label": str(a), "time": str(b), "reason": str(c)} for a, b, c in self.dropped],
            "rms_after_arcsec": [None if not np.isfinite(x) else float(x) / ARCSEC for x in self.predicted],
            "targets": rows,
        }

    def table(self) -> str:
        """The observing order as text: label, time (UTC, to the second; when the
        targets have times), azimuth, elevation, readings, predicted error there, then
        the predicted figures over the plan's sky and the targets dropped."""
        d = self.to_dict()
        unit = d["readings_unit"]
        timed = self.targets.time is not None and self.targets.kind != "sun"  # a sun position's label is its time
        when = f" {'time UTC':>19}" if timed else ""
        lines = [f"{'#':>3} {'target':>24}{when} {'az deg':>9} {'el deg':>8} {'axis1 ' + unit:>12} {'axis2 ' + unit:>12} {'sigma':>8}"]
        for row in d["targets"]:
            when = f" {row['time'][:19]:>19}" if timed else ""
            lines.append(
                f"{row['order']:>3} {row['label']:>24}{when} {row['azimuth_deg']:9.3f} {row['elevation_deg']:8.3f} "
                f"{row['readings'][0]:12.4f} {row['readings'][1]:12.4f} {row['predicted_sigma_arcsec']:8.3f}"
            )
        s = d["predicted"]
        where = {"grid": "over the sky", "path": "over the candidates' path"}.get(s.get("sky"), "over the given sky")
        if s.get("sky") == "path" and self.targets.kind == "sun":
            where = "over the sun's path"
        cadence = f"; {d['seconds_per_target']:g} s per target" if d["seconds_per_target"] else ""
        lines.append(
            f"{d['n']} targets of {d['n_candidates']} ({d['criterion']}, noise {d['noise_arcsec'][0]:g}\" per axis{cadence}); "
            f"predicted pointing RMS {where} {s['rms_arcsec']:.3f}\", max {s['max_arcsec']:.3f}\", "
            f"median run {s['median_rms_arcsec']:.3f}\"; total slew {d['slew_deg']:.1f} deg"
        )
        for row in d["dropped"]:
            lines.append(f"dropped {row['label']} (due {row['time'][:19]}): {row['reason']}")
        return "\n".join(lines)


def _angle_readings(model: Model) -> bool:
    from ..core.observations import COUNTED_READINGS

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
    seconds_per_target: float | None = None,
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
        target_rms: stop as soon as the predicted pointing RMS over ``sky`` is at most
            this (radians).
        sky: where pointing matters, the directions the selection and the summary
            average over: 'grid' (:func:`pointax.planning.sky_grid`: 512 equal-area
            points, 20-85 deg), 'path' (the candidates' own directions within the
            limits, thinned to at most :data:`MAX_PATH_SKY`: for sun candidates the
            sun's path over their span, each point standing for the same tracking time)
            or ``(m, 3)`` ENU directions. Default: 'path' for sun candidates (a sun
            tracker only ever points there), 'grid' otherwise.
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
        seconds_per_target: star candidates only: the time each observation takes
            (slew included), seconds. After ordering, target ``k`` (from 0) is scheduled
            at the candidates' time + ``k * seconds_per_target`` and placed again where
            it is then (:func:`pointax.planning.place_stars`); targets that by then
            break a limit (the candidates' elevation, Sun and Moon rules, the
            elevation arguments here, the mount ``limits``, the model's reach) are
            dropped with a :class:`pointax.io.PointaxWarning` naming them (not
            replaced), the later ones moving up, until every target keeps its limits at
            its time. The plan's readings, slew and predicted accuracy are those of
            the scheduled directions. None or 0 (default): a snapshot, every target
            where it is at the candidates' time.

    Returns:
        A :class:`Plan`.

    Raises:
        ValueError: no candidate within the limits, too few to determine the model, an
            unknown ``sky``, or ``seconds_per_target`` negative or given for candidates
            that are not stars from :func:`pointax.planning.star_candidates`.
    """
    n = int(n)
    if n < 1:
        raise ValueError(f"n must be at least 1, got {n}")
    if not isinstance(candidates, Candidates):
        raise TypeError(f"candidates must be pointax.planning.Candidates, got {type(candidates).__name__}")
    cadence = _cadence(seconds_per_target, candidates)
    weights = noise_weights(noise)
    d = candidates.direction
    readings, usable = _reachable(model, d, limits, solution, min_elevation_deg, max_elevation_deg)
    if not usable.any():
        raise ValueError("no candidate lies within the limits and is reachable by the model")
    idx = np.flatnonzero(usable)
    sky, sky_name = _plan_sky(sky, candidates, d[idx])
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
                predicted[k] = math.sqrt(max(float(np.trace(g @ invert_information(m))), 0.0))
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
    targets, seq_readings, dropped = candidates[seq], readings[seq], ()
    if cadence:
        targets, seq_readings, seq, dropped = _schedule(
            model, candidates, seq, cadence, limits, solution, min_elevation_deg, max_elevation_deg
        )
    pts = seq_readings if _angle_readings(model) else targets.direction
    slew = path_length(slew_matrix(pts) if _angle_readings(model) else sky_angle_matrix(pts), np.arange(seq.size))
    jac_seq, _ = pointing_jacobian(model, seq_readings)
    try:
        cov = invert_information(information_matrix(np.asarray(jac_seq), 1.0 / weights))
    except ValueError:
        raise ValueError(
            f"{seq.size} observations (of {idx.size} candidates within the limits"
            + (f"; {len(dropped)} dropped at their scheduled times" if dropped else "")
            + f") do not determine the model's {p} free parameters: allow more observations or more candidates"
        ) from None
    # The accuracy keeps the plan's sky, so that the sky map's title gives the plan's
    # own figures (those of the table): for a sun plan, over the sun's path.
    acc = PredictedAccuracy(model, cov, targets.direction, sky, "sun path" if sky_name == "path" and candidates.kind == "sun" else sky_name)
    summary = {**acc.summary(sky), "sky": sky_name}
    if stopped == "target" and summary["rms_arcsec"] * ARCSEC > target * (1.0 + 1e-9):
        stopped = "moved"
    return Plan(targets, seq, seq_readings, predicted, acc, slew, criterion, 1.0 / weights, int(idx.size), stopped, summary,
                cadence, dropped, sky)  # fmt: skip


def _cadence(seconds_per_target, candidates: Candidates) -> float | None:
    """``seconds_per_target`` checked: None for a snapshot (None or 0), else seconds > 0."""
    if seconds_per_target is None:
        return None
    value = float(seconds_per_target)
    if not (math.isfinite(value) and value >= 0.0):
        raise ValueError(f"seconds_per_target must be a finite number of seconds >= 0, got {seconds_per_target!r}")
    if value == 0.0:
        return None
    if candidates.kind != "stars" or candidates.stars is None or candidates.time is None:
        raise ValueError(
            f"seconds_per_target schedules stars from star_candidates; these candidates are {candidates.kind!r} "
            "(sun positions are already at their own times)"
        )
    return value


def _reachable(model: Model, directions: np.ndarray, limits, solution: str, min_elevation_deg, max_elevation_deg):
    """``(readings (n, 2), usable (n,))``: readings for ``directions`` ``(n, 3)`` on the
    branch inside ``limits``, and which lie within the elevation arguments (degrees,
    None for none) and the limits and are reachable by the model."""
    el = np.arcsin(np.clip(directions[:, 2], -1.0, 1.0))
    usable = np.ones(directions.shape[0], bool)
    if min_elevation_deg is not None:
        usable &= el >= math.radians(min_elevation_deg)
    if max_elevation_deg is not None:
        usable &= el <= math.radians(max_elevation_deg)
    readings, ok = readings_for(model, directions, solution=solution)
    readings, inside = reading_limits_ok(model, readings, limits)
    return readings, usable & ok & inside


def _plan_sky(sky, candidates: Candidates, usable_directions: np.ndarray) -> tuple[np.ndarray, str]:
    """The plan's sky ``(m, 3)`` and its name ('grid', 'path' or 'given'); see
    :func:`plan_run`'s ``sky``."""
    if sky is None:
        sky = "path" if candidates.kind == "sun" else "grid"
    if isinstance(sky, str):
        if sky == "grid":
            return sky_grid(), "grid"
        if sky == "path":
            step = max(1, -(-usable_directions.shape[0] // MAX_PATH_SKY))
            return usable_directions[::step], "path"
        raise ValueError(f"sky must be one of {', '.join(SKY_CHOICES)} or (m, 3) ENU directions, got {sky!r}")
    return np.asarray(directions_enu(sky, "sky"), np.float64).reshape(-1, 3), "given"


def _schedule(model: Model, candidates: Candidates, seq: np.ndarray, cadence: float, limits, solution: str,
              min_elevation_deg, max_elevation_deg):  # fmt: skip
    """The targets ``candidates[seq]`` (in observing order) at start + k ``cadence``
    seconds, placed again then; those that break a limit at their time are dropped (the
    later ones moving up) until none does. Returns ``(targets, readings (k, 2), seq (k,),
    dropped)``, ``dropped`` a tuple of ``(label, time, reason)``; warns naming them."""
    import astropy.units as u

    from ..sky.sun import as_time

    start = as_time(str(candidates.time[seq[0]]))
    dropped = []
    while True:
        times = start + np.arange(seq.size) * cadence * u.s
        placed, broken = place_stars(candidates[seq], times)
        r, usable = _reachable(model, placed.direction, limits, solution, min_elevation_deg, max_elevation_deg)
        broken = np.where((broken == "") & ~usable, "outside the plan's elevation or mount limits, or out of the model's reach", broken)
        bad = broken != ""
        if not bad.any():
            break
        dropped += [(str(placed.label[k]), str(placed.time[k]), str(broken[k])) for k in np.flatnonzero(bad)]
        seq = seq[~bad]
        if seq.size == 0:
            raise ValueError(
                f"every target breaks a limit by its scheduled time at {cadence:g} s per target: "
                "allow a shorter seconds_per_target or wider limits"
            )
    if dropped:
        names = "; ".join(f"{label} at {time[:19]}: {reason}" for label, time, reason in dropped)
        warnings.warn(
            PointaxWarning(f"plan: {len(dropped)} target(s) dropped, breaking a limit at their scheduled time ({names})"),
            stacklevel=4,  # the caller of plan_run (through the float64 wrapper)
        )
    return placed, r, seq, tuple(dropped)

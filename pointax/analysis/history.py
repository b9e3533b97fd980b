"""Run history: one telescope's runs fitted with the same model, coefficients over time,
drift alarms, a joint fit with coefficients that vary with time or temperature, and a
network compared with its last fit (``pointax history``, ``pointax fit-network --previous``).

    runs = [px.io.read_tpoint(p, azimuth="S-E") for p in paths]
    model = px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"), azimuth="S-E")
    h = px.history(runs, model)               # every run fitted, ordered by time
    print(h.table())                          # coefficients and sigmas per run, then the alarms
    h.alarms                                  # every change beyond 3 sigma between consecutive runs
    h.to_json()                               # {"runs": [...], "alarms": [...]}
    joint = h.joint_fit({"TF": "temperature", "IA": ("time", 1)})

A run's time (MJD UTC, days) is the median of its observations' ``time`` reading
(:data:`pointax.core.readings.READINGS`) over the observations used, else its file's date
(a TPOINT run-parameters record: 0h UTC of that day), else unknown. The runs are ordered
by time when every run has one; otherwise they keep the order given (an
:class:`pointax.io.InputWarning` names the runs without a time).

An alarm is a change of one coefficient between two consecutive runs (in time order)
beyond ``alarm`` sigma: ``|v2 - v1| / sqrt(s1^2 + s2^2) > alarm``, with each run's sigma
as TPOINT defines it (:class:`pointax.FitResult`). It is reported at the later run. A run
whose fit did not converge is in the table but left out of the comparisons (the run
before it is compared with the one after it), and said so; a coefficient whose sigma is
not finite in one of the two runs is not compared, and said so.

For stationary runs with Gaussian noise the false-alarm probability of one comparison is
``erfc(alarm / sqrt(2))`` (0.27% at 3 sigma) when the sigmas are the standard errors;
TPOINT's sigmas scale the Sky RMS, the RMS of both residual components together, so
they are larger than the standard errors (by about sqrt(2) when the two components have
the same noise) and the rate is lower.
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import math
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..core.errors import warn_input
from ..core.model import Model
from ..core.observations import Observations
from ..core.units import ARCSEC, UNITS
from ..fitting import FitOptions, FitResult

__all__ = [
    "Alarm",
    "History",
    "JointFit",
    "RunFit",
    "Move",
    "history",
    "run_time",
    "mjd_of_date",
    "date_of_mjd",
    "change_sigmas",
    "compare_with_previous",
    "read_previous",
    "moves_table",
]

_MJD_EPOCH = datetime.datetime(1858, 11, 17)
"""MJD 0: 1858-11-17 0h UTC."""


def mjd_of_date(year: int, month: int, day: int, hours: float = 0.0) -> float:
    """The MJD (UTC days) of a calendar date and time of day (hours)."""
    return (datetime.datetime(int(year), int(month), int(day)) - _MJD_EPOCH).days + hours / 24.0


def date_of_mjd(mjd: float | None) -> str:
    """An MJD as ``YYYY-MM-DD`` (with ``HH:MM`` when not at 0h UTC); '' for None."""
    if mjd is None or not math.isfinite(mjd):
        return ""
    moment = _MJD_EPOCH + datetime.timedelta(minutes=round(float(mjd) * 1440.0))
    return moment.strftime("%Y-%m-%d" if moment.hour == moment.minute == 0 else "%Y-%m-%d %H:%M")


def _observations_of(run) -> Observations:
    obs = run if isinstance(run, Observations) else getattr(run, "observations", None)
    if not isinstance(obs, Observations):
        raise TypeError(
            f"a run must be a pointax.Observations or a run read by pointax.io (with .observations), got {type(run).__name__}"
        )
    return obs


def _readings(obs: Observations) -> dict[str, Any]:
    return dict(getattr(obs, "readings", None) or {})


def run_time(run) -> tuple[float | None, str]:
    """A run's time: ``(MJD UTC days or None, where from)``, where from is 'readings'
    (median of the ``time`` reading over the observations used), 'file' (the run's
    date: a TPOINT run-parameters record, 0h UTC) or 'unknown'."""
    obs = _observations_of(run)
    times = _readings(obs).get("time")
    if times is not None:
        t = np.asarray(times, np.float64).reshape(-1)
        keep = (np.asarray(obs.weight) > 0) & np.isfinite(t)
        if keep.any():
            return float(np.median(t[keep])), "readings"
    date = getattr(getattr(run, "parameters", None), "date", None)
    if date:
        return mjd_of_date(*date), "file"
    return None, "unknown"


def _label(run, k: int) -> str:
    path = getattr(run, "path", None)
    return os.fspath(path) if path else f"run {k + 1}"


def _finite(x) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


# --------------------------------------------------------------------------- results


@dataclasses.dataclass(frozen=True)
class RunFit:
    """One run of a :class:`History`.

    Attributes:
        file: the run's name (its file, or ``'run k'``).
        time: MJD UTC (days), or None when unknown.
        time_from: 'readings', 'file', 'given' or 'unknown' (:func:`run_time`).
        result: the run's :class:`pointax.FitResult`.
        status: 'converged', 'degenerate' or 'failed' (:func:`pointax.site_statuses`).
        reason: why, for a status other than 'converged'.
        observations: the run's observations (as fitted).
        run: the run as given.
    """

    file: str
    time: float | None
    time_from: str
    result: FitResult
    status: str
    reason: str
    observations: Observations
    run: Any = None

    @property
    def n_obs(self) -> int:
        return int(self.result.n_obs)

    @property
    def sky_rms_arcsec(self) -> float | None:
        return _finite(float(self.result.sky_rms) / ARCSEC)

    @property
    def converged(self) -> bool:
        return bool(self.result.converged)

    def terms(self) -> list[dict[str, Any]]:
        """``[{"name", "value_arcsec", "sigma_arcsec"}]``: each fitted parameter in
        arcsec (a parameter in another unit converted as ``pointax fit --json`` does)."""
        return [
            {
                "name": row["name"],
                "value_arcsec": _finite(row["value"] * UNITS[row["unit"]] / ARCSEC),
                "sigma_arcsec": _finite(row["sigma"] * UNITS[row["unit"]] / ARCSEC),
            }
            for row in self.result.table()
        ]

    def to_dict(self) -> dict[str, Any]:
        """The run's entry of :meth:`History.to_dict` (exactly its keys)."""
        return {
            "file": self.file,
            "time": self.time,
            "n_obs": self.n_obs,
            "sky_rms_arcsec": self.sky_rms_arcsec,
            "terms": self.terms(),
        }


@dataclasses.dataclass(frozen=True)
class Alarm:
    """A change of one coefficient between consecutive runs beyond the alarm level.

    Attributes:
        file: the later run (where the change is seen).
        term: the parameter's name.
        change_sigma: ``(v2 - v1) / sqrt(s1^2 + s2^2)``, signed.
        previous: the earlier run.
        before, after: the values in the two runs, arcsec.
    """

    file: str
    term: str
    change_sigma: float
    previous: str = ""
    before: float | None = None
    after: float | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"file": self.file, "term": self.term, "change_sigma": _finite(self.change_sigma)}


def change_sigmas(values, sigmas) -> np.ndarray:
    """``(R - 1, P)`` changes between consecutive rows of ``(R, P)`` values, in units of
    their combined sigma ``sqrt(s1^2 + s2^2)``; NaN where a sigma is not finite or both
    are 0."""
    values = np.asarray(values, np.float64)
    sigmas = np.asarray(sigmas, np.float64)
    combined = np.hypot(sigmas[1:], sigmas[:-1])
    ok = np.isfinite(combined) & (combined > 0) & np.isfinite(values[1:]) & np.isfinite(values[:-1])
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(ok, (values[1:] - values[:-1]) / np.where(ok, combined, 1.0), np.nan)


@dataclasses.dataclass(frozen=True)
class History:
    """Every run of one telescope fitted with the same model (:func:`history`).

    Attributes:
        runs: one :class:`RunFit` per run, in time order (or as given).
        alarms: every change beyond ``alarm`` sigma between consecutive compared runs.
        alarm: the alarm level, sigmas.
        model: the model every run was fitted with (its start values and fixed names).
        notes: what was not compared, and why (runs without a time, failed fits,
            undetermined sigmas).
        options: the fit options.
    """

    runs: tuple[RunFit, ...]
    alarms: tuple[Alarm, ...]
    alarm: float
    model: Model
    notes: tuple[str, ...] = ()
    options: FitOptions | None = None

    @property
    def names(self) -> tuple[str, ...]:
        """The fitted parameters' names (the same in every run)."""
        return tuple(self.runs[0].result.names) if self.runs else ()

    def values_arcsec(self) -> np.ndarray:
        """``(R, P)`` fitted values, arcsec (NaN where not finite)."""
        return np.array([[np.nan if t["value_arcsec"] is None else t["value_arcsec"] for t in r.terms()] for r in self.runs])

    def sigmas_arcsec(self) -> np.ndarray:
        """``(R, P)`` sigmas, arcsec (NaN where not finite)."""
        return np.array([[np.nan if t["sigma_arcsec"] is None else t["sigma_arcsec"] for t in r.terms()] for r in self.runs])

    @property
    def all_converged(self) -> bool:
        return all(r.converged for r in self.runs)

    def to_dict(self) -> dict[str, Any]:
        """``{"runs": [{"file", "time", "n_obs", "sky_rms_arcsec", "terms": [{"name",
        "value_arcsec", "sigma_arcsec"}]}], "alarms": [{"file", "term", "change_sigma"}]}``;
        ``time`` is the MJD (UTC days) or null; numbers that are not finite are null."""
        return {"runs": [r.to_dict() for r in self.runs], "alarms": [a.to_dict() for a in self.alarms]}

    def to_json(self, indent: int | None = 2) -> str:
        return json.dumps(self.to_dict(), indent=indent)

    def table(self) -> str:
        """The runs in order, one line each: date, observations, Sky RMS, each
        coefficient as ``value(sigma)`` in arcsec; then the alarms and the notes."""
        names = self.names
        cells = [[_value_sigma(t["value_arcsec"], t["sigma_arcsec"]) for t in r.terms()] for r in self.runs]
        widths = [max([len(n)] + [len(c[j]) for c in cells]) for j, n in enumerate(names)]
        files = [os.path.basename(r.file) or r.file for r in self.runs]
        fw = max([3] + [len(f) for f in files])
        dw = max([4] + [len(date_of_mjd(r.time)) for r in self.runs])
        alarmed = {(a.file, a.term) for a in self.alarms}
        head = f"{'run':<{fw}s}  {'date':<{dw}s}  n_obs  Sky RMS  " + "  ".join(f"{n:>{w}s} " for n, w in zip(names, widths))
        lines = [head.rstrip(), "  (coefficients in arcsec: value(sigma); * marks an alarm, the change from the run above)"]
        for r, f, row in zip(self.runs, files, cells):
            rms = r.sky_rms_arcsec
            flags = ["*" if (r.file, n) in alarmed else " " for n in names]
            text = "  ".join(f"{c:>{w}s}{m}" for c, w, m in zip(row, widths, flags))
            status = "" if r.status == "converged" else f"  [{r.status}]"
            lines.append(
                f"{f:<{fw}s}  {date_of_mjd(r.time):<{dw}s}  {r.n_obs:>5d}  {'' if rms is None else f'{rms:6.3f}':>7s}  {text}"
                .rstrip() + status
            )
        lines.append("")
        if self.alarms:
            lines.append(f"alarms (change beyond {self.alarm:g} sigma between consecutive runs):")
            for a in self.alarms:
                lines.append(
                    f"  {os.path.basename(a.file) or a.file}  {a.term}  {a.change_sigma:+.1f} sigma "
                    f"({_arcsec(a.before)} -> {_arcsec(a.after)}, from {os.path.basename(a.previous) or a.previous})"
                )
        else:
            lines.append(f"no alarms (no change beyond {self.alarm:g} sigma between consecutive runs)")
        lines.extend(f"note: {n}" for n in self.notes)
        return "\n".join(lines)

    def figure(self, **kwargs):
        """Each coefficient against time, with error bars and alarms:
        :func:`pointax.plots.history.history_figure`."""
        from ..plots.history import history_figure

        return history_figure(self, **kwargs)

    def joint_fit(
        self,
        varying: Mapping[str, str | tuple[str, int]],
        *,
        reference: Mapping[str, float] | None = None,
        options: FitOptions | None = None,
    ) -> "JointFit":
        """One fit of every run together, in which the coefficients named in ``varying``
        are smooth functions of a reading and the others are the same in every run.

        Args:
            varying: term name -> reading name, or ``(reading, degree)``:
                ``"temperature"`` (or any reading but time) makes the term
                :func:`pointax.terms.thermal` (linear in the reading);
                ``"time"`` or ``("time", d)`` makes it :func:`pointax.terms.in_time`,
                a polynomial of degree d (default 1) in days.
            reference: reading name -> the reading's reference value (the varying
                coefficients' values are at it). Default: the median of the reading
                over every observation used (time: rounded to a whole day).
            options: fit options (default: the history's).

        Observations whose ``time`` reading is not recorded take their run's time
        (:func:`run_time`), and those whose ``temperature`` is not recorded their run's
        header temperature (a TPOINT run-parameters record) where it has one; any
        other missing reading makes the fit refuse, naming the reading and the rows.

        Returns:
            :class:`JointFit`.
        """
        return _joint_fit(self, varying, reference, options or self.options)


@dataclasses.dataclass(frozen=True)
class JointFit:
    """A joint fit of a history's runs (:meth:`History.joint_fit`).

    Attributes:
        result: the :class:`pointax.FitResult` of every run together.
        varying: term name -> ``(reading, degree)``.
        reference: reading name -> reference value (the readings' units).
        files: the runs, in the order their observations were concatenated.
        rows: ``(R + 1,)`` where each run's observations start and end in the
            concatenated observations.
        observations: the concatenated observations, with their readings.
    """

    result: FitResult
    varying: dict[str, tuple[str, int]]
    reference: dict[str, float]
    files: tuple[str, ...]
    rows: tuple[int, ...]
    observations: Observations

    def report(self) -> str:
        refs = ", ".join(f"{k} {v:g}" for k, v in self.reference.items())
        how = ", ".join(f"{t} with {r}" + (f" (degree {d})" if r == "time" else "") for t, (r, d) in self.varying.items())
        return f"joint fit of {len(self.files)} runs; varying: {how}; reference: {refs}\n" + self.result.report()

    def to_dict(self) -> dict[str, Any]:
        return {
            "files": list(self.files),
            "varying": {t: {"reading": r, "degree": d} for t, (r, d) in self.varying.items()},
            "reference": dict(self.reference),
            **self.result.to_dict(),
        }


def _value_sigma(value, sigma) -> str:
    if value is None:
        return "-"
    if sigma is None:
        return f"{value:+.2f}(inf)"
    return f"{value:+.2f}({sigma:.2f})"


def _arcsec(x) -> str:
    return "?" if x is None else f'{x:+.2f}"'


# --------------------------------------------------------------------------- the history


def history(
    runs: Sequence[Any],
    model: Model,
    *,
    alarm: float = 3.0,
    names: Sequence[str] | None = None,
    times: Sequence[float | None] | None = None,
    options: FitOptions | None = None,
    chunk_size: int | str | None = "auto",
) -> History:
    """Fit every run with the same model; coefficients per run in time order, and alarms.

    Args:
        runs: the runs: each a run read by :mod:`pointax.io` (``.observations``) or a
            :class:`pointax.Observations`, all in the model's encoder convention.
        model: the model every run is fitted with (start values, fixed parameters).
        alarm: the alarm level: a change beyond this many sigma between consecutive
            runs is an :class:`Alarm` (default 3).
        names: a name per run (default: the run's file, else 'run k').
        times: a time per run, MJD UTC days (None: :func:`run_time`, from the run).
        options: fit options (:class:`pointax.FitOptions`; default least squares, LM).
        chunk_size: as :func:`pointax.fit_batch`.

    Every run is fitted in one batched call (:func:`pointax.fit_batch`: the same values
    and sigmas as :func:`pointax.fit` of each run).

    Returns:
        :class:`History`.

    Raises:
        ValueError: no runs, a non-positive alarm level, ``names`` or ``times`` of the
            wrong length, runs in another encoder convention than the model's.
    """
    from ..fitting.batch import fit_batch, site_result, site_statuses, stack_observations
    from ..fitting.result import first_rows

    runs = list(runs)
    if not runs:
        raise ValueError("history: no runs")
    if not (float(alarm) > 0 and math.isfinite(float(alarm))):
        raise ValueError(f"history: alarm must be a positive number of sigmas, got {alarm!r}")
    for what, given in (("names", names), ("times", times)):
        if given is not None and len(given) != len(runs):
            raise ValueError(f"history: {len(given)} {what} for {len(runs)} runs")
    observations = [_observations_of(run) for run in runs]
    labels = list(names) if names is not None else [_label(run, k) for k, run in enumerate(runs)]
    convention = model.mount.convention
    for label, obs in zip(labels, observations):
        if obs.convention != convention:
            raise ValueError(
                f"{label}: encoder convention {obs.convention!r}, the model's is {convention!r}: "
                "every run must be read as the model counts its angles (e.g. the same azimuth convention)"
            )
    found = [run_time(run) for run in runs]
    if times is not None:
        found = [(None if t is None else float(t), "given" if t is not None else "unknown") for t in times]

    options = options or FitOptions()
    batch = fit_batch(model, stack_observations(observations), options=options, chunk_size=chunk_size)
    batch = _to_numpy(batch)
    statuses = site_statuses(batch)
    fits = [
        RunFit(
            file=labels[k], time=found[k][0], time_from=found[k][1], result=first_rows(site_result(batch, k), len(observations[k])),
            status=statuses[k]["status"], reason=statuses[k]["reason"], observations=observations[k], run=runs[k],
        )  # fmt: skip
        for k in range(len(runs))
    ]
    notes: list[str] = []
    missing = [f.file for f in fits if f.time is None]
    if missing and len(missing) < len(fits):
        warn_input(
            "history", None,
            f"no time for {', '.join(missing)} (no 'time' reading, no date in the file): the runs keep the order given",
        )  # fmt: skip
        notes.append(f"no time for {', '.join(missing)}: the runs keep the order given")
    elif not missing:
        fits.sort(key=lambda f: f.time)  # stable: runs of the same time keep the order given
    alarms = _alarms(fits, float(alarm), notes)
    return History(runs=tuple(fits), alarms=tuple(alarms), alarm=float(alarm), model=model, notes=tuple(notes), options=options)


def _to_numpy(result):
    import jax

    return jax.tree.map(np.asarray, result)


def _alarms(fits: list[RunFit], level: float, notes: list[str]) -> list[Alarm]:
    """Alarms between consecutive compared runs (failed fits left out, with a note)."""
    compared = [f for f in fits if f.status != "failed"]
    for f in fits:
        if f.status == "failed":
            notes.append(f"{f.file}: fit failed ({f.reason}); not compared with its neighbours")
    if len(compared) < 2:
        return []
    names = compared[0].result.names
    values = np.array([[np.nan if t["value_arcsec"] is None else t["value_arcsec"] for t in f.terms()] for f in compared])
    sigmas = np.array([[np.nan if t["sigma_arcsec"] is None else t["sigma_arcsec"] for t in f.terms()] for f in compared])
    z = change_sigmas(values, sigmas)
    out = []
    for i, j in zip(*np.nonzero(~np.isfinite(z))):
        notes.append(
            f"{names[j]}: not compared between {compared[i].file} and {compared[i + 1].file} (its value or sigma is not finite)"
        )
    for i, j in zip(*np.nonzero(np.isfinite(z) & (np.abs(np.nan_to_num(z)) > level))):
        out.append(
            Alarm(
                file=compared[i + 1].file, term=names[j], change_sigma=float(z[i, j]), previous=compared[i].file,
                before=_finite(values[i, j]), after=_finite(values[i + 1, j]),
            )  # fmt: skip
        )
    return out


# --------------------------------------------------------------------------- the joint fit


def _joint_fit(h: History, varying, reference, options) -> JointFit:
    from .. import terms as term_library
    from ..fitting import fit

    spec: dict[str, tuple[str, int]] = {}
    known = {t.name for t in h.model.terms}
    for name, how in dict(varying).items():
        if name not in known:
            raise ValueError(f"joint_fit: no term {name!r} in the model (terms: {' '.join(sorted(known))})")
        reading, degree = (how, 1) if isinstance(how, str) else (str(how[0]), int(how[1]))
        if degree < 1:
            raise ValueError(f"joint_fit: {name}: degree must be at least 1, got {degree}")
        if reading != "time" and degree != 1:
            raise ValueError(f"joint_fit: {name}: a coefficient varies linearly with {reading} (degree 1), not degree {degree}")
        spec[name] = (reading, degree)
    readings_needed = sorted({r for r, _ in spec.values()})
    obs = _concatenated(h, readings_needed)
    used = np.asarray(obs.weight) > 0
    refs: dict[str, float] = {}
    for reading in readings_needed:
        if reference is not None and reading in reference:
            refs[reading] = float(reference[reading])
            continue
        values = np.asarray(obs.readings[reading], np.float64)[used]
        values = values[np.isfinite(values)]
        middle = float(np.median(values)) if values.size else 0.0
        refs[reading] = float(round(middle)) if reading == "time" else middle
    terms = []
    for term in h.model.terms:
        if term.name not in spec:
            terms.append(term)
            continue
        reading, degree = spec[term.name]
        if reading == "time":
            terms.append(term_library.in_time(term, degree=degree, reference=refs["time"]))
        else:
            terms.append(term_library.thermal(term, reading=reading, reference=refs[reading]))
    model = Model(
        h.model.mount, terms, fixed=h.model.fixed, sky_iterations=h.model.sky_iterations, residual_form=h.model.residual_form
    )
    result = fit(model, obs, options=options or FitOptions())
    rows = np.cumsum([0] + [len(r.observations) for r in h.runs])
    return JointFit(
        result=result, varying=spec, reference=refs, files=tuple(r.file for r in h.runs),
        rows=tuple(int(x) for x in rows), observations=obs,
    )  # fmt: skip


def _concatenated(h: History, needed: Sequence[str]) -> Observations:
    """Every run's observations in one, with the readings ``needed`` (missing times from
    the run's time, missing temperatures from the run's header)."""
    encoder = np.concatenate([np.asarray(r.observations.encoder) for r in h.runs])
    target = np.concatenate([np.asarray(r.observations.target) for r in h.runs])
    weight = np.concatenate([np.asarray(r.observations.weight) for r in h.runs])
    names = set(needed)
    for r in h.runs:
        names |= set(_readings(r.observations))
    readings = {}
    for name in sorted(names):
        parts = []
        for r in h.runs:
            n = len(r.observations)
            given = _readings(r.observations).get(name)
            column = np.full(n, np.nan) if given is None else np.asarray(given, np.float64).reshape(n).copy()
            fill = _run_default(r, name)
            if fill is not None:
                column = np.where(np.isfinite(column), column, fill)
            parts.append(column)
        readings[name] = np.concatenate(parts)
    return Observations(encoder, target, weight, h.runs[0].observations.convention, readings=readings)


def _run_default(r: RunFit, name: str) -> float | None:
    """The value a run gives a reading its observations do not record: its time, its
    header temperature."""
    if name == "time":
        return r.time
    if name == "temperature":
        value = getattr(getattr(r.run, "parameters", None), "temperature_c", None)
        return None if value is None else float(value)
    return None


# --------------------------------------------------------------------------- a network against its last fit


@dataclasses.dataclass(frozen=True)
class Move:
    """A coefficient of one site that moved beyond the alarm level since a previous fit.

    Attributes:
        site: the site's name.
        term: the parameter's name.
        change_sigma: ``(now - before) / sqrt(s_now^2 + s_before^2)``, signed.
        before, after: the values (arcsec for telescope and sun-tracker terms, the
            parameter's own unit for a PAINT heliostat's, ``unit``).
        unit: 'arcsec', or the heliostat parameter's unit.
    """

    site: str
    term: str
    change_sigma: float
    before: float
    after: float
    unit: str = "arcsec"

    def to_dict(self) -> dict[str, Any]:
        return {"site": self.site, "term": self.term, "change_sigma": _finite(self.change_sigma)}


def read_previous(path: str | os.PathLike) -> list[dict[str, Any]]:
    """A previous ``pointax fit-network --json`` output: the list of per-site dicts.

    Raises:
        ValueError: the file is not JSON, not a list of objects with a ``site``, or a
            site's terms lack values (the message names the file and the site).
    """
    from ..io.errors import FileFormatError

    name = os.fspath(path)
    with open(name, encoding="utf-8") as f:
        text = f.read()
    try:
        data = json.loads(text)
    except json.JSONDecodeError as err:
        raise FileFormatError(name, err.lineno, f"not JSON: {err.msg} (column {err.colno})") from None
    if isinstance(data, dict) and isinstance(data.get("sites"), list):
        data = data["sites"]
    if not isinstance(data, list) or not all(isinstance(d, dict) for d in data):
        raise FileFormatError(name, None, "not the output of pointax fit-network --json (a list of one object per site)")
    for k, d in enumerate(data):
        if not isinstance(d.get("site"), str):
            raise FileFormatError(name, None, f"entry {k + 1}: no 'site' name", where="site")
        for t in _site_terms(d) or []:
            if not isinstance(t, dict) or "name" not in t:
                raise FileFormatError(name, None, f"site {d['site']}: a term without a 'name'", where="terms")
    return data


def _site_terms(d: Mapping[str, Any]) -> list[dict[str, Any]] | None:
    return d.get("terms") if d.get("terms") is not None else d.get("params")


def _value_of(t: Mapping[str, Any]) -> tuple[float | None, float | None, str]:
    if "value_arcsec" in t:
        return t.get("value_arcsec"), t.get("sigma_arcsec"), "arcsec"
    return t.get("value"), t.get("sigma"), str(t.get("unit", ""))


def compare_with_previous(
    sites: Sequence[Mapping[str, Any]], previous: Sequence[Mapping[str, Any]], alarm: float = 3.0
) -> tuple[list[Move], list[str]]:
    """The sites and terms that moved beyond ``alarm`` sigma since a previous fit.

    Args:
        sites: this fit's per-site dicts (:attr:`pointax.analysis.network.NetworkResult.sites`).
        previous: the previous fit's (:func:`read_previous`).
        alarm: the alarm level, sigmas.

    Returns:
        ``(moves, notes)``: every :class:`Move` (site order, then term order), and what
        was not compared and why (a site new or gone, a failed fit, a term fitted in
        only one of the two, a sigma that is not finite).
    """
    if not (float(alarm) > 0 and math.isfinite(float(alarm))):
        raise ValueError(f"alarm must be a positive number of sigmas, got {alarm!r}")
    before = {d["site"]: d for d in previous}
    now_names = [d["site"] for d in sites]
    moves: list[Move] = []
    notes: list[str] = []
    gone = [s for s in before if s not in set(now_names)]
    if gone:
        notes.append(f"in the previous fit, not in this one: {', '.join(gone)}")
    new = [s for s in now_names if s not in before]
    if new:
        notes.append(f"new since the previous fit (not compared): {', '.join(new)}")
    for d in sites:
        site = d["site"]
        if site not in before:
            continue
        old = before[site]
        failed = [w for w, x in (("now", d), ("before", old)) if x.get("status") == "failed" or not _site_terms(x)]
        if failed:
            notes.append(f"{site}: not compared (no fitted values {' and '.join(failed)})")
            continue
        old_terms = {t["name"]: t for t in _site_terms(old)}
        new_terms = {t["name"]: t for t in _site_terms(d)}
        only = sorted(set(old_terms) ^ set(new_terms))
        if only:
            notes.append(f"{site}: fitted in only one of the two fits, not compared: {' '.join(only)}")
        for name, t in new_terms.items():
            if name not in old_terms:
                continue
            v2, s2, unit = _value_of(t)
            v1, s1, unit1 = _value_of(old_terms[name])
            if unit1 != unit:
                notes.append(f"{site} {name}: in {unit1} before and {unit} now, not compared")
                continue
            z = change_sigmas([[_nan(v1)], [_nan(v2)]], [[_nan(s1)], [_nan(s2)]])[0, 0]
            if not np.isfinite(z):
                notes.append(f"{site} {name}: not compared (a value or sigma is not finite)")
            elif abs(z) > alarm:
                moves.append(Move(site=site, term=name, change_sigma=float(z), before=float(v1), after=float(v2), unit=unit))
    return moves, notes


def _nan(x) -> float:
    return np.nan if x is None else float(x)


def moves_table(moves: Sequence[Move], notes: Sequence[str], previous: str, alarm: float) -> str:
    """The moves as text: a line per site and term, then the notes."""
    if not moves:
        lines = [f"no site moved beyond {alarm:g} sigma since {previous}"]
    else:
        lines = [f"moved beyond {alarm:g} sigma since {previous}:"]
        width = max(len(m.site) for m in moves)
        for m in moves:
            unit = '"' if m.unit == "arcsec" else f" {m.unit}"
            change = f"({m.before:+.4g}{unit} -> {m.after:+.4g}{unit})"
            lines.append(f"  {m.site:<{width}s}  {m.term:<8s}  {m.change_sigma:+.1f} sigma  {change}")
    lines.extend(f"note: {n}" for n in notes)
    return "\n".join(lines)

"""Refit a network of sites listed in a manifest: one batched fit per model, a status
per site, a progress bar and a summary for people (the command line:
``pointax fit-network``, :mod:`pointax.cli.fit_network`).

    result = px.network.fit_network("sites.csv", progress=True)
    print(result.summary())              # how many converged; which did not, and why
    result.sites[0]["status"]            # per site: the keys of `pointax fit --json`, plus site, status, reason

The manifest is a CSV file with a header row and one row per site; ``#`` starts a
comment line, blank lines are skipped, spaces around fields are ignored::

    # site,  data file (relative to this manifest), format, options...
    site,    path,                 format, terms,                       azimuth
    ts-01,   sites/ts-01.txt,      sun,    full,
    ts-02,   sites/ts-02.txt,      sun,    ,
    mmt,     ../mmt_20210821.dat,  tpoint, IA IE NPAE CA AN AW TF TX,   S-E
    aa39,    /data/paint/AA39,     paint,  ,

==========  ========  ============================================================
column      needed    meaning
==========  ========  ============================================================
site        yes       the site's name, unique in the manifest
path        yes       its data file (a folder for paint), relative to the manifest
format      yes       ``sun``: sun observations of a mirror turntable
                      (:mod:`pointax.io.sun`), fitted with :func:`pointax.Turntable`;
                      ``tpoint``: a TPOINT input file, fitted with
                      :func:`pointax.AltAz`; ``paint``: a PAINT heliostat folder,
                      calibrated with :func:`pointax.calibrate_heliostat`
terms       no        terms to fit, separated by spaces (default: sun ``full``;
                      tpoint TPOINT's eight basic terms; paint ``t1n t1u t2e t2n``)
form        no        tpoint: ``rigorous`` (default) or ``linear``
residuals   no        tpoint: what the fit minimises, ``sky`` (default) or ``tpoint``
                      (TPOINT's own residuals, as ``pointax fit --residuals``)
azimuth     no        tpoint: how the file counts azimuth, ``N-E`` (default), ``S-E``, ``S-W``
focal_spot  no        paint: ``HeliOS`` (default) or ``UTIS``
==========  ========  ============================================================

A row that is wrong (unknown format or option, bad terms, a duplicate site name, a
data file that does not exist) raises :class:`ManifestError`, naming the manifest, the
line and the field. Data files are read later: a site whose file cannot be read is
reported ``failed`` with the reader's message (file, line, field) and the others go on.

Sites with the same format and model (terms, form, residuals, azimuth) go through one
:func:`pointax.fit_batch` call (or :func:`pointax.fitting.distributed.fit_batch_distributed`
when a Dask ``client`` is given), each with its own starting values (turntables: encoder
zeros from their data). A group of fewer than :data:`SMALL_GROUP` sites skips the batch's
fast pass (``steps=0``: every site through the full loop, the solo fit's algorithm),
and the groups are fitted side by side in threads, one per CPU: for a handful of sites
compiling is nearly all the time, and the full loop alone compiles in about half the
time of the fast pass and the full loop together. PAINT heliostats each have their own
actuator geometry, so they are calibrated one by one (:func:`pointax.calibrate_heliostat`,
robust fit and leave-one-out), in this process.

Per site, ``status`` is ``"converged"``, ``"degenerate"`` (converged, but the data
cannot tell some parameters apart: ``reason`` names them) or ``"failed"`` (``reason``
says why: unreadable data, non-finite residuals, no convergence).
"""

from __future__ import annotations

import csv
import contextlib
import dataclasses
import functools
import json
import os
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .. import terms as term_library
from ..core.precision import float64
from ..fitting.batch import fit_batch, stack_observations
from ..fitting.batch_records import site_dicts, site_statuses
from ..fitting.progress import activity, progress_bar
from .batch_listing import batch_observation_entries
from ..fitting.core import SOLVERS
from ..fitting.result import FitResult
from .heliostat import calibrate_heliostat
from ..io.errors import FileFormatError
from ..io.load import load_run
from ..io.paint import FOCAL_SPOT_METHODS
from ..core.model import RESIDUAL_FORMS
from ..terms.model_factories import AltAz, Turntable
from ..core.mounts import AZIMUTH_CONVENTIONS
from ..terms.heliostat_terms import HELIOSTAT_DEFAULT
from ..terms.sun_vector import TURNTABLE_MODELS

__all__ = [
    "FORMATS",
    "MANIFEST_COLUMNS",
    "ManifestError",
    "SiteEntry",
    "read_manifest",
    "NetworkResult",
    "fit_network",
    "SMALL_GROUP",
]

SMALL_GROUP = 16
"""A group of fewer sites than this is fitted with the full loop alone (``fit_batch(...,
steps=0)``): the fast pass pays off only when there are many sites to fit at once."""

FORMATS = ("sun", "tpoint", "paint")
"""Data formats a manifest row may name."""

MANIFEST_COLUMNS = ("site", "path", "format", "terms", "form", "residuals", "azimuth", "focal_spot")
"""Every column a manifest may have; the first three are required."""

_REQUIRED = MANIFEST_COLUMNS[:3]
_OPTION_FORMATS = {"form": ("tpoint",), "residuals": ("tpoint",), "azimuth": ("tpoint",), "focal_spot": ("paint",)}
_DEFAULT_TERMS = {"sun": "full", "tpoint": " ".join(term_library.BASIC_ALTAZ), "paint": " ".join(HELIOSTAT_DEFAULT)}
_STATUSES = ("converged", "degenerate", "failed")


class ManifestError(FileFormatError):
    """A manifest could not be read; the message names the file, line and field."""

    def __init__(self, path: str, line: int | None, message: str, field: str | None = None):
        self.field = field
        super().__init__(path, line, message, None if field is None else f"field '{field}'")


@dataclasses.dataclass(frozen=True)
class SiteEntry:
    """One manifest row, checked.

    Attributes:
        site: the site's name.
        path: its data file or folder (resolved against the manifest's folder).
        format: one of :data:`FORMATS`.
        terms: names of the terms to fit.
        form: TPOINT term form ('rigorous', the default, or 'linear'; tpoint only).
        residuals: the model's ``residual_form`` ('sky' or 'tpoint'; tpoint only).
        azimuth: azimuth convention of a TPOINT file (tpoint only).
        focal_spot: PAINT focal-spot method (paint only).
        line: the row's line number in the manifest.
    """

    site: str
    path: Path
    format: str
    terms: tuple[str, ...]
    form: str = "rigorous"
    residuals: str = "sky"
    azimuth: str = "N-E"
    focal_spot: str = FOCAL_SPOT_METHODS[0]
    line: int = 0

    @property
    def model_key(self) -> tuple:
        """Sites with equal keys share one batched fit."""
        return (self.format, self.terms, self.form, self.residuals, self.azimuth)


# --------------------------------------------------------------------------- manifest


@functools.lru_cache(maxsize=256)
def _check_terms(fmt: str, spec: str) -> tuple[str, ...]:
    """Term names for ``spec`` (validated by building the terms); ValueError if bad.
    Remembered: a network's rows mostly repeat a few specs, and building terms costs."""
    if fmt == "sun":
        chosen = TURNTABLE_MODELS.get(spec) or tuple(spec.replace(",", " ").split())
        return tuple(t.name for t in term_library.turntable(chosen))
    if fmt == "tpoint":
        return tuple(t.name for t in term_library.tpoint(spec))
    return tuple(t.name for t in term_library.heliostat(spec))


def read_manifest(path: str | os.PathLike) -> list[SiteEntry]:
    """Read and check a network manifest (format: this module's docstring).

    Returns:
        One :class:`SiteEntry` per site, in file order.

    Raises:
        ManifestError: naming the manifest, line and field of the first problem
            (unknown column, format or option, bad terms, duplicate site name, missing
            data file, no sites).
        OSError: the manifest itself cannot be opened.
    """
    name = os.fspath(path)
    try:
        text = Path(name).read_text(encoding="utf-8")
    except UnicodeDecodeError as err:
        raise ManifestError(name, None, f"not a text file ({err})") from None
    base = Path(name).parent
    header: list[str] | None = None
    entries: list[SiteEntry] = []
    seen: dict[str, int] = {}
    for number, line in enumerate(text.splitlines(), 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        fields = [f.strip() for f in next(csv.reader([line], skipinitialspace=True))]
        if header is None:
            header = fields
            for column in header:
                if column not in MANIFEST_COLUMNS:
                    raise ManifestError(
                        name, number, f"unknown column {column!r}; columns are {', '.join(MANIFEST_COLUMNS)}"
                    )
            repeated = sorted({c for c in header if header.count(c) > 1})
            if repeated:
                raise ManifestError(name, number, f"column(s) {', '.join(repeated)} appear more than once in the header")
            missing = [c for c in _REQUIRED if c not in header]
            if missing:
                raise ManifestError(
                    name, number, f"the header row lacks the column(s) {', '.join(missing)} (it must name site, path, format)"
                )
            continue
        if len(fields) > len(header):
            raise ManifestError(name, number, f"{len(fields)} fields, but the header names {len(header)} columns")
        row = dict(zip(header, fields + [""] * (len(header) - len(fields))))
        entries.append(_entry(name, number, base, row, seen))
    if header is None or not entries:
        raise ManifestError(name, None, "no sites (expected a header row 'site, path, format, ...' and one row per site)")
    return entries


def _entry(name: str, number: int, base: Path, row: dict[str, str], seen: dict[str, int]) -> SiteEntry:
    def error(field, message):
        return ManifestError(name, number, message, field)

    for column in _REQUIRED:
        if not row[column]:
            raise error(column, "is empty")
    site, fmt = row["site"], row["format"]
    if site in seen:
        raise error("site", f"site {site!r} appears twice (first on line {seen[site]})")
    seen[site] = number
    if fmt not in FORMATS:
        raise error("format", f"unknown format {fmt!r}; expected one of {', '.join(FORMATS)}")
    for option, formats in _OPTION_FORMATS.items():
        if row.get(option) and fmt not in formats:
            raise error(option, f"applies to format {' or '.join(formats)}, not to {fmt}")
    path = base / row["path"]
    if fmt == "paint" and not path.is_dir():
        raise error("path", f"no such folder: {path} (a PAINT heliostat folder)")
    if fmt != "paint" and not path.is_file():
        raise error("path", f"no such file: {path}")
    options: dict[str, Any] = {}
    if row.get("form"):
        if row["form"] not in term_library.FORMS:
            raise error("form", f"unknown term form {row['form']!r}; expected one of {', '.join(sorted(term_library.FORMS))}")
        options["form"] = row["form"]
    if row.get("residuals"):
        if row["residuals"] not in RESIDUAL_FORMS:
            raise error("residuals", f"unknown residual form {row['residuals']!r}; expected one of {', '.join(RESIDUAL_FORMS)}")
        options["residuals"] = row["residuals"]
    if row.get("azimuth"):
        if row["azimuth"] not in AZIMUTH_CONVENTIONS:
            raise error("azimuth", f"unknown azimuth convention {row['azimuth']!r}; expected one of {', '.join(AZIMUTH_CONVENTIONS)}")
        options["azimuth"] = row["azimuth"]
    if row.get("focal_spot"):
        if row["focal_spot"] not in FOCAL_SPOT_METHODS:
            raise error("focal_spot", f"unknown focal-spot method {row['focal_spot']!r}; expected one of {', '.join(FOCAL_SPOT_METHODS)}")
        options["focal_spot"] = row["focal_spot"]
    try:
        terms = _check_terms(fmt, row.get("terms") or _DEFAULT_TERMS[fmt])
    except ValueError as err:
        raise error("terms", str(err)) from None
    if not terms:
        raise error("terms", "names no terms")
    return SiteEntry(site=site, path=path, format=fmt, terms=terms, line=number, **options)


# --------------------------------------------------------------------------- results


@dataclasses.dataclass(frozen=True)
class NetworkResult:
    """Per-site results of :func:`fit_network`, in manifest order.

    Attributes:
        manifest: the manifest's path.
        sites: one JSON-ready dict per site: ``site``, ``format``, ``file`` (or
            ``directory`` for paint), ``status``, ``reason``, and the keys of
            ``pointax fit --json`` for that format (for a site whose data could not be
            read: ``converged`` false and nothing else).
        seconds: wall time of the whole run.
    """

    manifest: str
    sites: tuple[dict[str, Any], ...]
    seconds: float = 0.0

    @property
    def counts(self) -> dict[str, int]:
        """Number of sites per status."""
        return {s: sum(1 for d in self.sites if d["status"] == s) for s in _STATUSES}

    @property
    def all_converged(self) -> bool:
        """Whether every site has status 'converged'."""
        return all(d["status"] == "converged" for d in self.sites)

    def summary(self) -> str:
        """How many sites converged; which did not, and why (one line each)."""
        counts = self.counts
        head = f"{len(self.sites)} sites: " + ", ".join(f"{counts[s]} {s}" for s in _STATUSES)
        if self.seconds:
            head += f" ({self.seconds:.1f} s)"
        lines = [head]
        width = max([4] + [len(d["site"]) for d in self.sites])
        for d in self.sites:
            if d["status"] != "converged":
                lines.append(f"  {d['status']:<10s}  {d['site']:<{width}s}  {d['reason']}")
        return "\n".join(lines)

    def table(self) -> str:
        """One line per site: status, observations, Sky RMS, iterations, fitted values."""
        width = max([4] + [len(d["site"]) for d in self.sites])
        lines = [f"{'site':<{width}s}  format  status      n_obs  Sky RMS           iter  values"]
        for d in self.sites:
            n_obs = d.get("n_obs")
            rms = _sky_rms_text(d)
            iterations = d.get("iterations")
            values = "  ".join(
                f"{p['name']} {p['value']:+.6g}" for p in _params(d) if p.get("value") is not None
            )
            unit = _params(d)[0]["unit"] if _params(d) else ""
            lines.append(
                f"{d['site']:<{width}s}  {d['format']:<6s}  {d['status']:<10s}  "
                f"{'' if n_obs is None else n_obs:>5}  {rms:<16s}  {'' if iterations is None else iterations:>4}  "
                + (f"{values} ({unit})" if values else "")
            )
        return "\n".join(lines)

    def to_json(self, indent: int | None = 2) -> str:
        """The per-site dicts as a JSON list."""
        return json.dumps(list(self.sites), indent=indent)


def _params(d: dict[str, Any]) -> list[dict[str, Any]]:
    return d.get("terms") or d.get("params") or []


def _sky_rms_text(d: dict[str, Any]) -> str:
    if d["format"] == "paint" and d.get("error_mrad"):
        rms = d["error_mrad"]["rms"]["after"]
        return "" if rms is None else f"{rms:.3f} mrad"
    rms = d.get("sky_rms_arcsec")
    if rms is None:
        return ""
    if d["format"] == "sun":
        return f"{rms / 3600:.4f} deg"
    return f'{rms:.3f}"'


# --------------------------------------------------------------------------- fitting


def _status_of(result: FitResult) -> dict[str, str]:
    """:func:`pointax.site_statuses` of one (unbatched) fit."""
    return site_statuses(jax.tree.map(lambda x: jnp.asarray(x)[None], result))[0]


def _read_sites(entries) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
    """Every site's data, read: ``(loaded, failed)``, each keyed by site; a site whose file
    cannot be read is ``failed`` with the reason (file, line and field), not dropped."""
    loaded: dict[str, Any] = {}
    failed: dict[str, dict[str, Any]] = {}
    for entry in entries:
        try:
            loaded[entry.site] = _read(entry)
        except (ValueError, OSError) as err:
            reason = str(err) if not isinstance(err, OSError) else f"{err.filename or entry.path}: {err.strerror or err}"
            failed[entry.site] = {**_header(entry), "status": "failed", "reason": reason, "converged": False}
    return loaded, failed

def _read(entry: SiteEntry):
    """The site's data, or raise with the reader's message (file, line, field)."""
    if entry.format == "sun":
        run = load_run(entry.path, "sun")
        if not np.any(run.weight > 0):
            raise ValueError(f"{entry.path}: no observation has a positive weight: nothing to fit")
        return run
    if entry.format == "tpoint":
        return load_run(entry.path, "tpoint", azimuth=entry.azimuth)
    return load_run(entry.path, "paint", focal_spot=entry.focal_spot)


def _header(entry: SiteEntry) -> dict[str, Any]:
    where = "directory" if entry.format == "paint" else "file"
    return {"site": entry.site, "format": entry.format, where: str(entry.path)}


def _batch_model(entry: SiteEntry):
    if entry.format == "sun":
        return Turntable(entry.terms)
    return AltAz(term_library.tpoint(entry.terms, form=entry.form), azimuth=entry.azimuth, residual_form=entry.residuals)


def _start_values(members: list[SiteEntry], runs: list, model) -> np.ndarray:
    """``(S, M)`` starting values: the model's, with turntables' encoder zeros taken from
    each site's data (as ``Turntable(terms, start=observations)`` takes them)."""
    values = np.tile(np.asarray(model.values("free"), np.float64), (len(members), 1))
    if members[0].format != "sun":
        return values
    free = [p.name for p in model.free_parameters]
    columns = [(k, free.index(name)) for k, name in enumerate(("alpha0", "beta0")) if name in free]
    if columns:
        zeros = _encoder_zeros(runs)
        for k, column in columns:
            values[:, column] = zeros[:, k]
    return values


def _encoder_zeros(runs: list) -> np.ndarray:
    """``(S, 2)`` :func:`~pointax.terms.sun_vector.estimate_zeros` of every run's rows of
    positive weight, to the bit: the same NumPy operations on the sites with as many
    such rows stacked (one call per count, not per site: 0.75 -> 0.3 s at 10,000)."""
    out = np.empty((len(runs), 2))
    used = [np.asarray(run.weight) > 0 for run in runs]
    counts = np.array([int(u.sum()) for u in used])
    for n in np.unique(counts).tolist():
        sites = np.flatnonzero(counts == n).tolist()
        encoder = np.stack([np.asarray(runs[k].observations.encoder, np.float64)[used[k]] for k in sites])
        target = np.stack([np.asarray(runs[k].observations.target, np.float64)[used[k]] for k in sites])
        azimuth = np.arctan2(target[..., 0], target[..., 1])
        elevation = np.arctan2(target[..., 2], np.hypot(target[..., 0], target[..., 1]))
        for j, x in enumerate((encoder[..., 0] + azimuth, encoder[..., 1] - elevation)):
            out[sites, j] = np.arctan2(np.mean(np.sin(x), axis=1), np.mean(np.cos(x), axis=1)) % (2 * np.pi)
    return out


@float64
def fit_network(
    manifest: str | os.PathLike,
    *,
    solver: str = "lm",
    max_steps: int = 256,
    chunk_size: int | None = 1000,
    progress: bool | Callable[[int, int], None] = False,
    client=None,
    observations: bool = True,
) -> NetworkResult:
    """Fit every site of a network manifest (format: this module's docstring).

    Args:
        manifest: the manifest file.
        solver: least-squares solver for every fit ('lm', 'gauss-newton', 'dogleg').
        max_steps: solver step limit; a site that reaches it is 'failed'.
        chunk_size: sites per compiled call of a batch (bounds memory; the progress
            bar moves once per chunk); ``None`` for one call per batch.
        progress: ``True`` for a progress bar on standard error when it is a terminal
            (:func:`pointax.fitting.progress.progress_bar`), or a callable
            ``progress(sites_done, sites_total)`` called after each chunk and each
            heliostat; ``False`` for none.
        client: a ``distributed.Client`` (or scheduler address) to run the batches on
            a Dask cluster (:func:`pointax.fitting.distributed.fit_batch_distributed`); PAINT
            heliostats are still calibrated here.
        observations: give each batched site its ``observations`` entries (and empty
            ``masked``, ``masked_rows``), as ``pointax fit --json``; ``False`` leaves the
            three keys out (the table and the summary do not need them).

    Returns:
        :class:`NetworkResult`: per site, in manifest order, the keys of
        ``pointax fit --json`` for its format plus ``site``, ``format``, ``status`` and
        ``reason``.

    Raises:
        ManifestError: the manifest is wrong (nothing is fitted then).
    """
    if solver not in SOLVERS:
        raise ValueError(f"unknown solver {solver!r}; expected one of {sorted(SOLVERS)}")
    if chunk_size is not None and (isinstance(chunk_size, bool) or int(chunk_size) < 1):
        raise ValueError(f"chunk_size must be a positive number of sites or None, got {chunk_size!r}")
    start_time = time.perf_counter()
    entries = read_manifest(manifest)
    loaded, out = _read_sites(entries)

    to_fit = [e for e in entries if e.site in loaded]
    groups = _model_groups(to_fit)
    with _sites_progress(progress, len(to_fit), len(groups) + 1) as counts:
        fits = [
            (members, [loaded[e.site] for e in members], solver, max_steps, chunk_size, counts.part(k), client, observations)
            for k, members in enumerate(groups.values())
        ]
        if len(fits) > 1 and (os.cpu_count() or 1) > 1:
            # Side by side: a thread traces (holding the GIL) while another's program compiles.
            with ThreadPoolExecutor(max_workers=min(len(fits), os.cpu_count() or 1)) as pool:
                for part in list(pool.map(lambda args: _fit_group(*args), fits)):
                    out.update(part)
        else:
            for args in fits:
                out.update(_fit_group(*args))
        out.update(_calibrate_heliostats(to_fit, loaded, solver, max_steps, counts.part(len(groups))))
    return NetworkResult(
        manifest=os.fspath(manifest),
        sites=tuple(out[e.site] for e in entries),
        seconds=time.perf_counter() - start_time,
    )


def _model_groups(to_fit: list[SiteEntry]) -> dict[tuple, list[SiteEntry]]:
    """The sites to fit in batches (all but PAINT heliostats), grouped by model, in
    manifest order."""
    groups: dict[tuple, list[SiteEntry]] = {}
    for entry in to_fit:
        if entry.format != "paint":
            groups.setdefault(entry.model_key, []).append(entry)
    return groups


@contextlib.contextmanager
def _sites_progress(progress, total: int, n_parts: int):
    """A network fit's :class:`_SitesDone` over ``n_parts`` parts: a bar of ``total``
    sites when ``progress`` is True (closed at the end), the callable ``progress``, or
    nothing."""
    bar = progress_bar(total, "fitting", "site", enabled=True) if progress is True else None
    try:
        yield _SitesDone(bar if bar is not None else (progress if callable(progress) else None), total, n_parts)
    finally:
        if bar is not None:
            bar.close()


def _calibrate_heliostats(to_fit, loaded, solver: str, max_steps: int, step) -> dict[str, dict[str, Any]]:
    """Every PAINT heliostat of ``to_fit`` calibrated (:func:`_calibrate`), one by one,
    ``step(n)`` after the n-th."""
    out = {}
    for n, entry in enumerate((e for e in to_fit if e.format == "paint"), start=1):
        out[entry.site] = _calibrate(entry, loaded[entry.site], solver, max_steps)
        step(n)
    return out


class _SitesDone:
    """The sites done of every part of a network's fit (its groups, fitted side by side,
    then the heliostats), summed into one ``report(done, total)`` (a progress bar's
    activities, a compilation, shown too)."""

    def __init__(self, report, total: int, n_parts: int):
        self.report, self.total, self.done = report, total, [0] * n_parts
        self.lock = threading.Lock()

    def part(self, k: int):
        def step(n_done, _part_total=None):
            with self.lock:
                self.done[k] = int(n_done)
                if self.report is not None:
                    self.report(sum(self.done), self.total)

        step.activity = lambda text: activity(self.report, text)
        return step


@float64
def _fit_group(members, runs, solver, max_steps, chunk_size, step, client, observations=True) -> dict[str, dict[str, Any]]:
    """One batched fit of sites sharing a model; per-site dicts (in a thread of its own:
    x64 is switched on per thread), with the observation entries when ``observations``."""
    model = _batch_model(members[0])
    batch = stack_observations([run.observations for run in runs])
    values = _start_values(members, runs, model)
    options = {"values": values, "solver": solver, "max_steps": max_steps, "progress": step}
    if len(members) < SMALL_GROUP:
        options["steps"] = 0
    if client is None:
        result = fit_batch(model, batch, chunk_size=chunk_size, **options)
    else:
        from ..fitting.distributed import fit_batch_distributed

        result = fit_batch_distributed(model, batch, client=client, chunk_size=chunk_size or len(members), **options)
    result = jax.tree.map(np.asarray, result)  # one transfer to NumPy: per-site slices are cheap
    # Column-wise over the sites (a FitResult per site cost 0.3 ms each: seconds at 10,000).
    statuses = site_statuses(result)
    dicts = site_dicts(result)
    # As pointax fit --json: no masks, one entry per observation (only when asked for:
    # the table and the summary do not show them).
    entries = batch_observation_entries(runs, result) if observations else None
    out = {}
    for k, (entry, run) in enumerate(zip(members, runs)):
        head = _header(entry)
        if entry.format == "tpoint":
            head.update(caption=run.caption, form=entry.form, residuals=entry.residuals, start_model=None)
        out[entry.site] = {**head, **statuses[k], **dicts[k]}
        if entries is not None:
            out[entry.site].update(masked=[], masked_rows=[], observations=entries[k])
    return out


def _calibrate(entry: SiteEntry, run, solver: str, max_steps: int) -> dict[str, Any]:
    """One PAINT heliostat: robust fit and leave-one-out (not batched)."""
    try:
        cal = calibrate_heliostat(run, entry.terms, solver=solver, max_steps=max_steps)
    except ValueError as err:
        return {**_header(entry), "status": "failed", "reason": str(err), "converged": False}
    return {**_header(entry), **_status_of(cal.result), **cal.to_dict()}

"""A network manifest fitted with partial pooling (``pointax fit-network --pooled``):
the sites of one design (same format and model, :mod:`pointax.analysis.network`) go
through one :func:`pointax.fit_pooled`, their populations estimated from them all.

    result = pooled_network("sites.csv")
    print(result.table()); print(result.summary())

Encoder zeros are set at each installation and have no population: they stay per site
(turntables ``alpha0`` and ``beta0``, TPOINT's ``IA`` and ``IE``). A design with fewer
than :data:`MIN_SITES` sites is fitted site by site as without ``--pooled`` (the reason
says so); PAINT heliostats are calibrated one by one, as without it.
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
from collections.abc import Callable
from typing import Any

from ..core.precision import float64
from ..fitting.batch import stack_observations
from ..fitting.pooled import fit_pooled
from .network import (
    _batch_model, _calibrate_heliostats, _fit_group, _header, _model_groups, _read_sites, _sites_progress, _start_values,
    read_manifest,
)  # fmt: skip

__all__ = ["MIN_SITES", "ENCODER_ZEROS", "PooledNetworkResult", "pooled_network"]

MIN_SITES = 3
"""Fewest sites of one design that are pooled."""

ENCODER_ZEROS = {"sun": ("alpha0", "beta0"), "tpoint": ("IA", "IE")}
"""Per format, the parameters left per site (no population)."""


@dataclasses.dataclass(frozen=True)
class PooledNetworkResult:
    """Per-site results of :func:`pooled_network`, in manifest order.

    Attributes:
        manifest: the manifest's path.
        sites: one JSON-ready dict per site: ``site``, ``format``, ``file``,
            ``status``, ``reason``, ``pooled`` (whether its design was pooled) and,
            for a pooled site, :meth:`pointax.PooledFit.site_dict`'s keys; otherwise
            ``pointax fit-network --json``'s.
        populations: per pooled design, :meth:`pointax.PooledFit.report`.
        seconds: wall time of the whole run.
    """

    manifest: str
    sites: tuple[dict[str, Any], ...]
    populations: tuple[str, ...] = ()
    seconds: float = 0.0

    @property
    def all_converged(self) -> bool:
        return all(d["status"] == "converged" for d in self.sites)

    def table(self) -> str:
        """One line per site: status, observations, Sky RMS, Mahalanobis distance from its
        population (``!`` beyond k sigma), pooled values with sigma and shrinkage."""
        width = max([4] + [len(d["site"]) for d in self.sites])
        lines = [f"{'site':<{width}s}  format  status      n_obs  Sky RMS (\")  Mahal.   values +- sigma [shrinkage] (unit)"]
        for d in self.sites:
            rms = d.get("sky_rms_arcsec")
            mahal = d.get("mahalanobis")
            flag = "!" if d.get("disagrees") else " "
            values = "  ".join(
                f"{p['name']} {p['value']:+.6g}"
                + (f" +- {p['sigma']:.2g}" if p.get("sigma") is not None else "")
                + (f" [{p['shrinkage']:.2f}]" if p.get("shrinkage") is not None else "")
                for p in d.get("params") or d.get("terms") or []
                if p.get("value") is not None
            )
            params = d.get("params") or d.get("terms") or []
            unit = f" ({params[0]['unit']})" if params and values else ""
            lines.append(
                f"{d['site']:<{width}s}  {d['format']:<6s}  {d['status']:<10s}  {d.get('n_obs') or '':>5}  "
                f"{'' if rms is None else f'{rms:.3f}':>11s}  {'' if mahal is None else f'{mahal:.2f}':>6s}{flag}  {values}{unit}"
            )
        return "\n".join(lines)

    def summary(self) -> str:
        """The populations, then how many sites converged and which did not, and why."""
        counts = {s: sum(1 for d in self.sites if d["status"] == s) for s in ("converged", "degenerate", "failed")}
        head = f"{len(self.sites)} sites: " + ", ".join(f"{n} {s}" for s, n in counts.items())
        if self.seconds:
            head += f" ({self.seconds:.1f} s)"
        lines = list(self.populations) + [head]
        for d in self.sites:
            if d["status"] != "converged" or d.get("disagrees"):
                lines.append(f"  {d['status']:<10s}  {d['site']}  {d['reason']}")
        return "\n".join(lines)

    def to_json(self, indent: int | None = 2) -> str:
        return json.dumps(list(self.sites), indent=indent)


@float64
def pooled_network(manifest: str | os.PathLike, *, k: float = 3.0, solver: str = "lm", max_steps: int = 256,
                   chunk_size: int | None = 1000,
                   progress: bool | Callable[[int, int], None] = False) -> PooledNetworkResult:  # fmt: skip
    """Fit every site of a network manifest, each design pooled (see the module).

    Args:
        manifest: the manifest file (:mod:`pointax.analysis.network`).
        k: sites whose own estimate lies beyond ``k`` sigma of their population are flagged.
        solver, max_steps, chunk_size: for the sites fitted without pooling.
        progress: as :func:`pointax.analysis.network.fit_network`'s: ``True`` for a bar on
            standard error when it is a terminal (naming compilations), or a callable
            ``progress(sites_done, sites_total)``.

    Raises:
        ManifestError: the manifest is wrong (nothing is fitted then).
    """
    start_time = time.perf_counter()
    entries = read_manifest(manifest)
    loaded, out = _read_sites(entries)
    out = {site: {**record, "pooled": False} for site, record in out.items()}
    to_fit = [e for e in entries if e.site in loaded]
    groups = _model_groups(to_fit)
    populations = []
    with _sites_progress(progress, len(to_fit), len(groups) + 1) as counts:
        for g, members in enumerate(groups.values()):
            runs = [loaded[e.site] for e in members]
            if len(members) < MIN_SITES:
                note = f"not pooled: {len(members)} site(s) of this design, {MIN_SITES} needed"
                for site, d in _fit_group(members, runs, solver, max_steps, chunk_size, counts.part(g), None).items():
                    out[site] = {**d, "pooled": False, "reason": "; ".join(r for r in (d.get("reason"), note) if r)}
                continue
            model = _batch_model(members[0])
            free = [p.name for p in model.free_parameters]
            unpooled = tuple(n for n in ENCODER_ZEROS.get(members[0].format, ()) if n in free)
            n_pooled = len(free) - len(unpooled)
            covariance = "full" if len(members) > n_pooled else "diagonal"
            fit = fit_pooled(model, stack_observations([r.observations for r in runs]), values=_start_values(members, runs, model),
                             unpooled=unpooled, covariance=covariance, k=k, progress=counts.part(g))  # fmt: skip
            name = f"{members[0].format} {' '.join(members[0].terms)}"
            populations.append(f"[{name}] " + fit.report().replace("group all:", "population:"))
            statuses = fit.statuses()
            for s, entry in enumerate(members):
                out[entry.site] = {**_header(entry), **statuses[s], "pooled": True, "covariance": covariance, **fit.site_dict(s)}
        for site, record in _calibrate_heliostats(to_fit, loaded, solver, max_steps, counts.part(len(groups))).items():
            out[site] = {**record, "pooled": False}
    return PooledNetworkResult(
        manifest=os.fspath(manifest),
        sites=tuple(out[e.site] for e in entries),
        populations=tuple(populations),
        seconds=time.perf_counter() - start_time,
    )

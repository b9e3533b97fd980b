"""The observation entries (``pointax fit --json``'s ``observations``) of every site of a
batched fit at once, as :func:`pointax.analysis.listing.observation_entries` gives them
for one site.

    entries = batch_observation_entries(runs, result)   # one list of dicts per site

The batched fit holds the residuals of every row it used; a site whose file gave every
row a positive weight needs nothing else, and all such sites' columns are cut from the
batch in one pass, converted to Python numbers once (``tolist``) and dealt out per site.
A site with weight-0 rows (their residuals are evaluated with its fitted model) goes
through :func:`~pointax.analysis.listing.observation_entries` on its own. Same dicts,
key order and numbers (``tests/test_batch_records.py``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..core.units import ARCSEC, DEG
from ..fitting.batch_records import site_result
from ..fitting.result import FitResult, first_rows
from .listing import EQUATORIAL_KEYS, LISTING_KEYS, observation_entries

__all__ = ["batch_observation_entries"]


def batch_observation_entries(runs, result: FitResult) -> list[list[dict[str, Any]]]:
    """Per site of a batched ``result`` (NumPy leaves, a leading site axis; ``runs[k]``
    fitted as site ``k``, its rows first), the entries of
    :func:`~pointax.analysis.listing.observation_entries` with no masks.

    Args:
        runs: the runs read by :mod:`pointax.io`, one per site, in the batch's order.
        result: the batched :class:`pointax.FitResult`, ``(S, N, ...)`` per-row fields.
    """
    lengths = np.array([len(run) for run in runs], np.int64)
    every_row = np.array([bool(np.all(np.asarray(run.observations.weight) > 0)) for run in runs], bool)
    out: list[list[dict[str, Any]] | None] = [None] * len(runs)
    for k in np.flatnonzero(~every_row).tolist():
        out[k] = observation_entries(runs[k], first_rows(site_result(result, k), int(lengths[k])))
    fast = np.flatnonzero(every_row)
    for keys in (LISTING_KEYS, EQUATORIAL_KEYS):
        chosen = [k for k in fast.tolist() if (EQUATORIAL_KEYS if _equatorial(runs[k]) else LISTING_KEYS) == keys]
        if chosen:
            _fill(out, keys, chosen, [runs[k] for k in chosen], lengths[chosen], result)
    return out  # type: ignore[return-value]


def _equatorial(run) -> bool:
    return getattr(run, "mount", None) == "equatorial"


def _fill(out, keys, chosen, runs, lengths, result) -> None:
    """Entries of the sites ``chosen`` (every row with a positive weight), one pass."""
    n_rows = np.asarray(result.used).shape[1]
    rows = np.arange(n_rows)[None, :] < lengths[:, None]  # (C, N): each site's own rows
    index = np.asarray(chosen)
    r = np.array(np.asarray(result.residuals)[index][rows], np.float64)  # (R, 2), sites in order
    used = np.asarray(result.used, bool)[index][rows]
    rejected = np.asarray(result.outliers, bool)[index][rows]
    # As observation_entries (no masks) through observation_residuals with the batch's residuals.
    masked = np.zeros_like(used)
    outlier = rejected
    used = used & ~outlier
    r = r / ARCSEC
    line = np.concatenate(
        [np.asarray(run.lines) if getattr(run, "lines", None) is not None else np.full(len(run), -1) for run in runs]
    )
    observed = np.concatenate(
        [np.asarray(run.observed if hasattr(run, "observed") else run.sun, np.float64) for run in runs]
    ) / DEG
    raw = np.concatenate([np.asarray(run.encoder, np.float64) for run in runs]) / DEG
    whole = lambda x: np.asarray(x, np.int64).tolist()  # noqa: E731
    real = lambda x: np.asarray(x, np.float64).tolist()  # noqa: E731
    flag = lambda x: np.asarray(x, bool).tolist()  # noqa: E731
    number = np.concatenate([np.arange(1, n + 1) for n in lengths.tolist()])
    columns = (
        whole(number), whole(line), real(observed[:, 0]), real(observed[:, 1]), real(raw[:, 0]), real(raw[:, 1]),
        real(r[:, 0]), real(r[:, 1]), real(np.hypot(r[:, 0], r[:, 1])), flag(used), flag(masked), flag(outlier),
    )  # fmt: skip
    entries = [dict(zip(keys, row)) for row in zip(*columns)]
    start = 0
    for k, n in zip(chosen, lengths.tolist()):
        out[k] = entries[start : start + n]
        start += n

"""Masks of a pointing run, and a fit's residual at every observation of it.

A masked observation stays in the run and in every listing; only its weight is 0, so
the model's structure does not change and a refit does not compile again (see the
README, "Refits do not recompile").

* :func:`parse_rows` reads TPOINT-style row lists (``"17,19-21"``, rows counted from 1
  in file order, as TPOINT numbers observations).
* :func:`observation_residuals` is a fit's residual at *every* observation of its run,
  in the fit's own residual form, each flagged used, masked or outlier: what the
  listing, the plots, the HTML report and TPOINT's graphics show (a fit's own
  ``residuals`` are 0 where the weight was 0).
* :func:`all_residuals` evaluates a model's residuals at every observation.
* :func:`mask_above` is TPOINT's ``MASK R > x``: the observations whose on-sky residual
  in the current fit exceeds ``x`` arcsec.

Two ways of leaving observations out, compared on the MMT run in the README
("Masks and outlier flags"): ``MASK R > x`` uses a fixed limit in arcsec on the
residuals of a least-squares fit; a robust fit (``loss='cauchy'``) flags the
observations whose residual norm exceeds ``reject`` (default 3) robust standard
deviations, where the robust standard deviation is the median residual norm over the
used observations divided by 1.1774 (the median of a 2-D Gaussian's norm in units of
its per-axis sigma; :func:`pointax.fitting.robust_sigma`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..core.precision import float64
from ..core.units import ARCSEC

__all__ = [
    "parse_rows",
    "format_rows",
    "ObservationResiduals",
    "observation_residuals",
    "all_residuals",
    "on_sky",
    "mask_above",
]


def parse_rows(spec: str, n: int, option: str = "rows") -> np.ndarray:
    """0-based indices of the rows a TPOINT-style list names.

    Args:
        spec: comma- or space-separated row numbers and ranges, counted from 1
            (``"17,19-21"`` is rows 17, 19, 20 and 21; ``"5-"``, ``"-3"`` open ranges;
            ``"*"`` every row).
        n: number of rows in the run.
        option: what to call the list in error messages (e.g. ``'--mask'``).

    Returns:
        ``(k,)`` sorted, unique int indices (0-based).

    Raises:
        ValueError: naming ``option`` and the item, for a malformed item or a row
            outside 1..n.
    """
    rows: set[int] = set()
    for item in spec.replace(",", " ").split():
        if item == "*":
            rows.update(range(1, n + 1))
            continue
        lo_text, dash, hi_text = item.partition("-")
        try:
            lo = int(lo_text) if lo_text else 1
            hi = (int(hi_text) if hi_text else n) if dash else lo
        except ValueError:
            raise ValueError(f"{option}: {item!r} is not a row number or a range like 19-21") from None
        if lo > hi:
            raise ValueError(f"{option}: range {item!r} runs backwards")
        if lo < 1 or hi > n:
            raise ValueError(f"{option}: row {lo if lo < 1 else hi} is outside 1..{n} (rows count from 1 in file order)")
        rows.update(range(lo, hi + 1))
    return np.asarray(sorted(r - 1 for r in rows), dtype=int)


def format_rows(indices) -> str:
    """The inverse of :func:`parse_rows`: ``[16, 18, 19, 20]`` -> ``"17,19-21"``."""
    rows = sorted(int(i) + 1 for i in indices)
    parts, k = [], 0
    while k < len(rows):
        j = k
        while j + 1 < len(rows) and rows[j + 1] == rows[j] + 1:
            j += 1
        parts.append(str(rows[k]) if j == k else f"{rows[k]}-{rows[j]}")
        k = j + 1
    return ",".join(parts)


@float64
def all_residuals(model, observations) -> np.ndarray:
    """``(n, 2)`` residuals of ``model`` at every observation, masked or not:
    observed minus model, (cross-elevation, elevation) radians, in the model's
    residual form (:func:`pointax.residuals`), evaluated in float64. A row that lacks
    an auxiliary reading the model reads (NaN) gets NaN."""
    from ..core.observations import Observations
    from .residuals import residuals

    obs = Observations(
        observations.encoder, observations.target, None, observations.convention, getattr(observations, "readings", None)
    )
    return np.asarray(residuals(model, obs), np.float64)


class ObservationResiduals(NamedTuple):
    """A fit's residual at every observation of its run (:func:`observation_residuals`).

    Attributes:
        residuals: ``(n, 2)`` observed minus model, radians, in the fit's residual form
            (the mount's cross-axis and second-axis components): the fit's own where it
            had them, the fitted model's for the observations it left out.
        used: ``(n,)`` used by the fit and not flagged an outlier.
        masked: ``(n,)`` left out of the fit (weight 0, TPOINT's MASK).
        outlier: ``(n,)`` rejected by a robust fit, or flagged by the caller; not masked.
    """

    residuals: np.ndarray
    used: np.ndarray
    masked: np.ndarray
    outlier: np.ndarray

    @property
    def distance(self) -> np.ndarray:
        """``(n,)`` on-sky length of each residual, radians (TPOINT's R, :func:`on_sky`)."""
        return on_sky(self.residuals)


def observation_residuals(result, observations, *, masked=None, outliers=None, residuals=None) -> ObservationResiduals:
    """A fit's residual at every observation of the run it was fitted to, flagged.

    The one source of per-observation residuals for display: the listing
    (:mod:`pointax.analysis.listing`), the plots and the HTML report
    (:func:`pointax.plots.residual_data`) and TPOINT's graphics commands all take
    theirs from here, so that they agree to the last bit.

    Args:
        result: a single fit's :class:`pointax.FitResult`.
        observations: the run's :class:`pointax.Observations` (its weights are not
            read: what the fit used is ``result.used``).
        masked: ``(n,)`` bool, the observations the fit was told to leave out (default:
            those the fit neither used nor rejected, i.e. its weight-0 rows).
        outliers: more observations to flag as outliers (0-based indices or an ``(n,)``
            bool mask), besides ``result.outliers``.
        residuals: ``(n, 2)`` the fitted model's residuals at every observation, radians,
            when the caller has them (a batched fit's, cut to the run): nothing is
            evaluated then.

    Returns:
        :class:`ObservationResiduals`: the fit's own residuals for every observation
        with a positive weight (outliers included), the fitted model's
        (:func:`all_residuals`, same residual form) for the others.

    Raises:
        ValueError: a batched result, or a run of another length.
    """
    r = np.array(result.residuals if residuals is None else residuals, np.float64)
    n = len(observations.encoder)
    if r.shape != (n, 2):
        raise ValueError(
            f"a single fit's result with residuals of shape ({n}, 2), one per observation of the run, is needed; "
            f"got residuals of shape {r.shape}"
        )
    fit_used = np.asarray(result.used, bool).reshape(n)
    rejected = np.asarray(result.outliers, bool).reshape(n)
    given = fit_used | rejected
    if residuals is None and not given.all():
        r[~given] = all_residuals(result.model, observations)[~given]
    masked = ~given if masked is None else np.asarray(masked, bool)
    if masked.shape != (n,):
        raise ValueError(f"masked must have shape ({n},), got {masked.shape}")
    outlier = (rejected | _flags(n, outliers)) & ~masked
    return ObservationResiduals(r, fit_used & ~outlier & ~masked, masked, outlier)


def _flags(n: int, outliers) -> np.ndarray:
    """``outliers`` (None, indices or a boolean mask of length n) as a boolean mask."""
    if outliers is None:
        return np.zeros(n, bool)
    arr = np.asarray(outliers)
    if arr.dtype == bool:
        if arr.shape != (n,):
            raise ValueError(f"outliers: a boolean mask must have shape ({n},), got {arr.shape}")
        return arr
    idx = arr.astype(int).ravel()
    if idx.size and (idx.min() < -n or idx.max() >= n):
        raise ValueError(f"outliers: indices must be within 0..{n - 1}")
    mask = np.zeros(n, bool)
    mask[idx] = True
    return mask


def on_sky(residuals) -> np.ndarray:
    """``(n,)`` on-sky length ``sqrt(r1^2 + r2^2)`` of ``(n, 2)`` residuals, in their unit
    (TPOINT's R of ``MASK R > x``)."""
    r = np.asarray(residuals, np.float64)
    return np.hypot(r[:, 0], r[:, 1])


def mask_above(model, observations, limit_arcsec: float, masked=None) -> np.ndarray:
    """TPOINT's ``MASK R > x``: which observations' on-sky residual under ``model``
    (the current fit's) exceeds ``limit_arcsec``.

    Args:
        model: the fitted model (e.g. ``result.model``).
        observations: the run's :class:`pointax.Observations`.
        limit_arcsec: x, arcsec.
        masked: optional ``(n,)`` bool, the mask so far; the answer includes it.

    Returns:
        ``(n,)`` bool: the new mask (those above the limit, or'ed with ``masked``).
    """
    if not limit_arcsec > 0:
        raise ValueError(f"MASK R > x needs a positive x in arcsec, got {limit_arcsec!r}")
    above = on_sky(all_residuals(model, observations)) / ARCSEC > limit_arcsec
    return above if masked is None else above | np.asarray(masked, bool)

"""Masks of a pointing run: which observations a fit leaves out (weight 0).

A masked observation stays in the run and in every listing; only its weight is 0, so
the model's structure does not change and a refit does not compile again (see the
README, "Refits do not recompile").

* :func:`parse_rows` reads TPOINT-style row lists (``"17,19-21"``, rows counted from 1
  in file order, as TPOINT numbers observations).
* :func:`all_residuals` evaluates a model's residuals at *every* observation, masked or
  not (a fit's own ``residuals`` are 0 where the weight was 0).
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

import numpy as np

from ..core.precision import float64
from ..core.units import ARCSEC

__all__ = ["parse_rows", "format_rows", "all_residuals", "fit_residuals", "on_sky", "mask_above"]


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
    residual form (:func:`pointax.residuals`), evaluated in float64."""
    from ..core.observations import Observations

    obs = Observations(observations.encoder, observations.target, None, observations.convention)
    return np.asarray(_residuals_compiled()(model, obs), np.float64)


_COMPILED: list = []


def _residuals_compiled():
    """:func:`pointax.residuals`, compiled (op by op, the vmap over observations
    compiled some 70 small programs: 4 s of every ``pointax fit --json``)."""
    if not _COMPILED:
        import equinox as eqx

        from . import residuals

        _COMPILED.append(eqx.filter_jit(residuals))
    return _COMPILED[0]


def fit_residuals(result, observations) -> np.ndarray:
    """``(n, 2)`` residuals of ``result.model`` at every observation of the run it was
    fitted to, radians: the fit's own where it had them (every observation with a
    positive weight, outliers included), :func:`all_residuals` for the masked ones."""
    r = np.array(result.residuals, np.float64)
    given = np.asarray(result.used, bool) | np.asarray(result.outliers, bool)
    if r.shape != (len(given), 2) or len(given) != len(observations.encoder):
        raise ValueError(f"the fit has residuals for {len(given)} observations, the run holds {len(observations.encoder)}")
    if not given.all():
        r[~given] = all_residuals(result.model, observations)[~given]
    return r


def on_sky(residuals) -> np.ndarray:
    """``(n,)`` on-sky distance, arcsec, of ``(n, 2)`` residuals in radians."""
    r = np.asarray(residuals, np.float64)
    return np.hypot(r[:, 0], r[:, 1]) / ARCSEC


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
    above = on_sky(all_residuals(model, observations)) > limit_arcsec
    return above if masked is None else above | np.asarray(masked, bool)

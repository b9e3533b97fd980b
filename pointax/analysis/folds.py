"""Out-of-sample schemes: holdout sets and k-fold cross-validation.

The out-of-sample RMS (the level-mount paper's "outer precision"): a model fitted on some
stars predicts others it never saw, and eqs 21-23 (:func:`pointax.analysis.axis_rms`) are
applied to those predictions. The schemes (``holdout`` and ``folds`` of
:func:`pointax.compare` and :func:`pointax.build_model`), all resolved by
:func:`evaluation_scheme`:

* ``holdout=validation`` (observations, or a run with ``.observations``): fit on
  ``observations``, predict ``validation`` (the paper's 68 + 78 stars).
* ``holdout=(fit_rows, validation_rows)``: index arrays or boolean masks into
  ``observations``; ``holdout=(fit_obs, validation_obs)`` with ``observations=None``.
* ``holdout=fraction``: that fraction of the stars (rounded), drawn at random with
  ``seed`` (:func:`holdout_indices`), is held back.
* ``folds=k``: k-fold cross-validation (:func:`fold_indices`); each star is predicted by
  the fit of the other folds, and the statistics pool all ``n`` predictions.

With a holdout, in-sample figures are those of the fit on the fitting stars (the model
that is then validated); with k folds, of the fit of all stars.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..fitting.residuals import as_observations
from ..core.observations import Observations

__all__ = ["Scheme", "evaluation_scheme", "fold_indices", "holdout_indices", "integer_at_least"]


def fold_indices(n: int, k: int, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    """The k-fold split of ``n`` observations: ``np.random.default_rng(seed).permutation(n)``
    cut into ``k`` nearly equal parts (``np.array_split``); fold ``i`` validates on part
    ``i`` and fits the rest. Returns ``[(fit_rows, validation_rows), ...]``, each sorted."""
    n, k = integer_at_least("n", n, 2), integer_at_least("folds", k, 2)
    if k > n:
        raise ValueError(f"folds={k} is more than the {n} observations")
    perm = np.random.default_rng(seed).permutation(n)
    parts = np.array_split(perm, k)
    return [(np.sort(np.concatenate(parts[:i] + parts[i + 1 :])), np.sort(p)) for i, p in enumerate(parts)]


def holdout_indices(n: int, fraction: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``(fit_rows, validation_rows)``: ``round(fraction * n)`` observations drawn at random
    (the first of ``np.random.default_rng(seed).permutation(n)``) are held back; both sorted.

    Raises:
        ValueError: a fraction outside (0, 1), or a split leaving fewer than 2 stars on
            either side.
    """
    n = integer_at_least("n", n, 2)
    f = float(fraction)
    if not (math.isfinite(f) and 0.0 < f < 1.0):
        raise ValueError(f"holdout fraction must lie strictly between 0 and 1, got {fraction!r}")
    n_val = int(round(f * n))
    if n_val < 2 or n - n_val < 2:
        raise ValueError(
            f"holdout fraction {f:g} of {n} observations leaves {n - n_val} to fit and {n_val} to validate; "
            "each side needs at least 2"
        )
    perm = np.random.default_rng(seed).permutation(n)
    return np.sort(perm[n_val:]), np.sort(perm[:n_val])


def integer_at_least(name: str, value, minimum: int) -> int:
    """``value`` as an int, checked to be an integer (not a bool) of at least ``minimum``.

    Raises:
        ValueError: naming ``name``.
    """
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


@dataclasses.dataclass(frozen=True)
class Scheme:
    """All observations in one set, which rows the in-sample fit uses, and the
    (fit rows, validation rows) splits whose predictions are pooled out of sample."""

    obs: Observations
    fit_rows: np.ndarray  # (n,) bool
    splits: tuple[tuple[np.ndarray, np.ndarray], ...]  # bool masks
    kind: str  # 'none', 'validation set', 'split', 'holdout', 'k-fold'
    description: str
    n_dropped: int

    @property
    def n_fit(self) -> int:
        return int(self.fit_rows.sum())

    @property
    def n_validation(self) -> int:
        return int(sum(v.sum() for _, v in self.splits))


def _clean(data, what: str) -> tuple[Observations, np.ndarray]:
    """Observations as float64 NumPy with the weight-0 rows removed, and the ``(n,)`` mask
    of the rows kept; the kept rows must have equal weights."""
    obs = as_observations(data)
    weight = np.asarray(obs.weight, np.float64)
    keep = weight > 0
    if not np.any(keep):
        raise ValueError(f"{what}: no observation has a positive weight")
    if not np.allclose(weight[keep], weight[keep][0], rtol=1e-12, atol=0):
        raise ValueError(
            f"{what}: compare and build_model compare unweighted fits, but the observations' weights differ "
            f"({weight[keep].min():g} to {weight[keep].max():g}); give equal weights (or 0 to leave rows out)"
        )
    encoder = np.asarray(obs.encoder, np.float64)[keep]
    target = np.asarray(obs.target, np.float64)[keep]
    if not (np.all(np.isfinite(encoder)) and np.all(np.isfinite(target))):
        bad = np.flatnonzero(~(np.all(np.isfinite(encoder), axis=1) & np.all(np.isfinite(target), axis=1)))
        raise ValueError(
            f"{what}: non-finite encoder or target values in rows {bad[:10].tolist()} (0-based, weight > 0)"
        )
    return Observations(encoder, target, np.ones(len(encoder)), obs.convention), keep


def _is_observations(x) -> bool:
    return isinstance(x, Observations) or isinstance(getattr(x, "observations", None), Observations)


def _rows(index, n: int, what: str) -> np.ndarray:
    a = np.asarray(index)
    if a.dtype == bool:
        if a.shape != (n,):
            raise ValueError(f"{what}: a boolean mask must have shape ({n},), got {a.shape}")
        return a.copy()
    if a.ndim != 1 or not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"{what}: expected integer row indices or a boolean mask, got {a.dtype} of shape {a.shape}")
    if a.size and (a.min() < -n or a.max() >= n):
        raise ValueError(f"{what}: row index out of range for {n} observations")
    mask = np.zeros(n, bool)
    mask[a] = True
    if mask.sum() != a.size:
        raise ValueError(f"{what}: row indices repeat")
    return mask


def evaluation_scheme(observations, holdout, folds, seed) -> Scheme:
    """The :class:`Scheme` of ``observations`` with ``holdout`` or ``folds`` (the module
    docstring): weight-0 rows left out (and counted), the others checked to have equal
    weights and finite values.

    Raises:
        ValueError, TypeError: a scheme that cannot be used (the message says why).
    """
    if holdout is not None and folds is not None:
        raise ValueError("give holdout or folds, not both")
    kind = "validation set"
    if isinstance(holdout, tuple) and len(holdout) == 2 and all(_is_observations(h) for h in holdout):
        if observations is not None:
            raise ValueError(
                "holdout=(fit_observations, validation_observations) takes the place of observations: pass observations=None"
            )
        observations, holdout = holdout
        kind = "split"
    if observations is None:
        raise ValueError("no observations given")
    obs, kept = _clean(observations, "observations")
    dropped = int(np.sum(~kept))
    n = len(obs)
    if n < 2:
        raise ValueError(f"need at least 2 observations, got {n}")
    everything = np.ones(n, bool)
    if holdout is None and folds is None:
        return Scheme(obs, everything, (), "none", f"{n} stars, no out-of-sample test", dropped)
    if folds is not None:
        k = integer_at_least("folds", folds, 2)
        splits = tuple((_rows(f, n, "fold"), _rows(v, n, "fold")) for f, v in fold_indices(n, k, seed))
        return Scheme(
            obs, everything, splits, "k-fold", f"{n} stars, {k}-fold cross-validation (seed {seed})", dropped
        )
    if _is_observations(holdout):
        val, kept_val = _clean(holdout, "validation observations")
        if len(val) < 2:
            raise ValueError(f"validation observations: need at least 2 with positive weight, got {len(val)}")
        if val.convention != obs.convention:
            raise ValueError(
                f"validation observations follow the {val.convention!r} convention, the fitting ones {obs.convention!r}"
            )
        both = Observations(
            np.concatenate([obs.encoder, val.encoder]), np.concatenate([obs.target, val.target]), None, obs.convention
        )
        fit_rows = np.concatenate([everything, np.zeros(len(val), bool)])
        return Scheme(
            both,
            fit_rows,
            ((fit_rows, ~fit_rows),),
            kind,
            f"{n} fitting stars, {len(val)} validation stars",
            dropped + int(np.sum(~kept_val)),
        )
    if isinstance(holdout, tuple | list) and len(holdout) == 2:
        # Rows of the observations as given: weight-0 rows are taken out of both sides.
        n_given = kept.size
        fit_rows = _rows(holdout[0], n_given, "holdout fit rows")[kept]
        val_rows = _rows(holdout[1], n_given, "holdout validation rows")[kept]
        if np.any(fit_rows & val_rows):
            raise ValueError("holdout: the fitting and validation rows overlap")
        if fit_rows.sum() < 2 or val_rows.sum() < 2:
            raise ValueError("holdout: each side of the split needs at least 2 observations")
        description = f"{int(fit_rows.sum())} fitting stars, {int(val_rows.sum())} validation stars (given split)"
        return Scheme(obs, fit_rows, ((fit_rows, val_rows),), "split", description, dropped)
    if isinstance(holdout, int | float | np.floating | np.integer) and not isinstance(holdout, bool):
        fit_idx, val_idx = holdout_indices(n, holdout, seed)
        fit_rows, val_rows = _rows(fit_idx, n, "holdout"), _rows(val_idx, n, "holdout")
        description = (
            f"{len(fit_idx)} fitting stars, {len(val_idx)} held back at random ({float(holdout):g}, seed {seed})"
        )
        return Scheme(obs, fit_rows, ((fit_rows, val_rows),), "holdout", description, dropped)
    raise TypeError(
        "holdout must be a fraction, validation observations, (fit_rows, validation_rows) or "
        f"(fit_observations, validation_observations), got {type(holdout).__name__}"
    )

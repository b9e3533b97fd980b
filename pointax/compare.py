"""Fair comparison of pointing-model families, and FAUTO-style automatic model building.

:func:`compare` fits several model families to the same observations and reports, per
family, what a pointing engineer needs to choose between them; :func:`build_model`
grows a model term by term from candidates, in the spirit of TPOINT's ``FAUTO``.

**Statistics** (every figure is computed from residuals *observed minus model* in the
tangent plane, :func:`pointax.residuals`):

* *Per-axis and total RMS*, the level-mount paper's eqs 21-23 (Li, Li & Liu, Laser &
  Infrared 47(5) 2017), which divide by ``n - 1`` (``n`` the number of stars in the set,
  not ``n - m``)::

      sigma_1 = sqrt( sum_i d1_i^2 / (n - 1) ),  sigma_2 = sqrt( sum_i d2_i^2 / (n - 1) )
      sigma   = sqrt( sigma_1^2 + sigma_2^2 )

  With ``per_axis="angle"`` (the paper's eq 20: ``DL = L - L0``; the default on an X-Y
  mount) ``d1`` is the residual of the first axis *angle*, the cross-axis residual
  divided by ``cos a2`` (``a2`` the star's second-axis angle: B, elevation,
  declination), to first order in the residual; with ``per_axis="sky"`` it is the cross-axis offset on the sky
  (TPOINT's ``dA cos E``; the default on other mounts, where ``DA`` grows as ``sec E``
  towards the zenith). ``d2`` is the second-axis residual in both.
* *Sky RMS*, TPOINT's ``sqrt(sum |r_i|^2 / n)`` (:class:`pointax.FitResult`).
* *AIC and BIC* of the in-sample fit. The likelihood: the ``2n`` sky residual components
  (cross-axis and second-axis, arcsec) are independent Gaussians with one common
  variance, set to its maximum-likelihood value ``s^2 = RSS / (2n)``; least squares is
  then the maximum-likelihood fit, and ::

      ln L = -n ( ln(2 pi s^2) + 1 ),   k = m + 1  (m fitted parameters, plus s^2)
      AIC = 2k - 2 ln L,                BIC = k ln(2n) - 2 ln L

  Only differences between families fitted to the same stars mean anything.
* *Significance* of each fitted parameter: ``value / sigma`` with TPOINT's sigma; 0 for
  a parameter the data cannot determine (infinite sigma).

**Out-of-sample** RMS (the paper's "outer precision"): a model fitted on some stars
predicts others it never saw, and eqs 21-23 are applied to those predictions. The
schemes (``holdout`` and ``folds`` of :func:`compare` and :func:`build_model`):

* ``holdout=validation`` (observations, or a run with ``.observations``): fit on
  ``observations``, predict ``validation`` (the paper's 68 + 78 stars).
* ``holdout=(fit_rows, validation_rows)``: index arrays or boolean masks into
  ``observations``; ``holdout=(fit_obs, validation_obs)`` with ``observations=None``.
* ``holdout=fraction``: that fraction of the stars (rounded), drawn at random with
  ``seed`` (:func:`holdout_indices`), is held back.
* ``folds=k``: k-fold cross-validation (:func:`fold_indices`); each star is predicted by
  the fit of the other folds, and the statistics pool all ``n`` predictions.

With a holdout, in-sample figures are those of the fit on the fitting stars (the model
that is then validated); with k folds, of the fit of all stars. Every fit is
:func:`pointax.fit` (held-back stars get weight 0, so a family compiles once for all its
fits) and every prediction is :func:`pointax.residuals` of the fitted model on the
held-back observations.

**Families** are :class:`pointax.Model` objects or names resolved on the mount of the
observations (:func:`family_model`): for an X-Y mount the level-mount paper's families
(``basic``, ``harmonic``, ``rotation``, ``linearised``) and term names of
:mod:`pointax.terms.xy`; for an alt-az mount ``basic`` (TPOINT's eight terms),
``harmonic`` (those plus :data:`ALTAZ_HARMONICS`) and TPOINT term names.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from . import terms as term_library
from ._x64 import float64
from .fit import DEGENERATE_RCOND, FitResult, as_observations, fit, residuals
from .model import Model
from .mounts import AZIMUTH_CONVENTIONS, AltAzMount, Mount, SphericalMount, XYMount
from .observations import Observations
from .terms import xy as xy_terms
from .terms.base import Term
from .units import ARCSEC, UNITS

__all__ = [
    "ALTAZ_FAMILIES",
    "ALTAZ_HARMONICS",
    "PER_AXIS",
    "AxisRMS",
    "FamilyStats",
    "Comparison",
    "BuildStep",
    "ModelBuild",
    "compare",
    "build_model",
    "family_model",
    "axis_rms",
    "information_criteria",
    "fold_indices",
    "holdout_indices",
]

ALTAZ_HARMONICS: tuple[str, ...] = ("HACA2", "HASA2", "HECA2", "HESA2", "HSCA2", "HSSA2")
"""The harmonic set the alt-az ``harmonic`` family adds to TPOINT's basic eight: the
second azimuth harmonics (cos 2A', sin 2A') of azimuth, elevation and cross-elevation
(TPOINT's names, :mod:`pointax.terms.harmonic`)."""

ALTAZ_FAMILIES: dict[str, tuple[str, ...]] = {
    "basic": term_library.BASIC_ALTAZ,
    "harmonic": term_library.BASIC_ALTAZ + ALTAZ_HARMONICS,
    "gpoint": tuple(term_library.gpoint_names(term_library.GPOINT_ALTAZ_TERMS)),
}
"""Alt-az family name -> term names: ``basic`` is TPOINT's eight basic terms,
``harmonic`` adds :data:`ALTAZ_HARMONICS`, ``gpoint`` is RTS2 gpoint's default seven
(only with ``naming="gpoint"``)."""

PER_AXIS = ("angle", "sky")
"""What the per-axis RMS measures on the first axis: its angle (the paper's ``DL``) or
the cross-axis offset on the sky (TPOINT's ``dA cos E``)."""

BEFORE = "before correction"

STEP_TOLERANCE = 1e-12
"""build_model's Gauss-Newton fits stop when the next step is below this (radians)."""
"""Label of the row with no terms fitted."""


# ----------------------------------------------------------------------------- statistics


@dataclasses.dataclass(frozen=True)
class AxisRMS:
    """Per-axis and total RMS of one set of residuals (the paper's eqs 21-23), radians.

    Attributes:
        axis1, axis2: ``sqrt(sum d^2 / (n - 1))`` per axis.
        total: ``sqrt(axis1^2 + axis2^2)``.
        n: number of residuals (stars).
    """

    axis1: float
    axis2: float
    total: float
    n: int

    def arcsec(self) -> dict[str, Any]:
        """The three figures in arcsec, and ``n``."""
        return {"axis1": self.axis1 / ARCSEC, "axis2": self.axis2 / ARCSEC, "total": self.total / ARCSEC, "n": self.n}


def axis_rms(residuals: Float[np.ndarray, "n 2"], cos_axis2: Float[np.ndarray, " n"] | None = None) -> AxisRMS:
    """The level-mount paper's eqs 21-23 for ``(n, 2)`` sky residuals (radians).

    Args:
        residuals: ``(n, 2)`` observed minus model, (cross-axis, second axis) radians,
            as :func:`pointax.residuals` gives them.
        cos_axis2: ``(n,)`` cosine of each star's second-axis angle. Given, the first
            column is divided by it (the residual of the first axis angle, the paper's
            ``DL``); ``None`` keeps the cross-axis offset on the sky.

    Returns:
        :class:`AxisRMS` with ``n - 1`` in the denominators (NaN for fewer than 2 rows).
    """
    r = np.asarray(residuals, np.float64).reshape(-1, 2)
    d1 = r[:, 0] if cos_axis2 is None else r[:, 0] / np.asarray(cos_axis2, np.float64)
    n = r.shape[0]
    if n < 2:
        return AxisRMS(math.nan, math.nan, math.nan, n)
    s1 = math.sqrt(float(np.sum(d1**2)) / (n - 1))
    s2 = math.sqrt(float(np.sum(r[:, 1] ** 2)) / (n - 1))
    return AxisRMS(s1, s2, math.hypot(s1, s2), n)


def information_criteria(residuals: Float[np.ndarray, "n 2"], n_params: int) -> tuple[float, float, float]:
    """``(ln L, AIC, BIC)`` of a least-squares fit from its ``(n, 2)`` sky residuals
    (radians) and its number of fitted parameters (see the module docstring: Gaussian
    residual components in arcsec with the maximum-likelihood common variance; the
    variance counts as a parameter)."""
    r = np.asarray(residuals, np.float64).reshape(-1) / ARCSEC
    n_components = r.size
    variance = float(np.sum(r**2)) / n_components
    log_l = -0.5 * n_components * (math.log(2 * math.pi * variance) + 1.0)
    k = n_params + 1
    return log_l, 2 * k - 2 * log_l, k * math.log(n_components) - 2 * log_l


def fold_indices(n: int, k: int, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    """The k-fold split of ``n`` observations: ``np.random.default_rng(seed).permutation(n)``
    cut into ``k`` nearly equal parts (``np.array_split``); fold ``i`` validates on part
    ``i`` and fits the rest. Returns ``[(fit_rows, validation_rows), ...]``, each sorted."""
    n, k = _count("n", n, 2), _count("folds", k, 2)
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
    n = _count("n", n, 2)
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


def _count(name: str, value, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


# ----------------------------------------------------------------------------- families


def _mount_of(obs: Observations) -> Mount:
    convention = obs.convention
    if convention == "xy":
        return XYMount()
    if convention in AZIMUTH_CONVENTIONS:
        return AltAzMount(azimuth=convention)
    raise ValueError(
        f"cannot build a model family by name for observations with convention {convention!r}: "
        "names are known for X-Y ('xy') and alt-az ('N-E', 'S-E', 'S-W') data; pass pointax.Model objects"
    )


def _tokens(spec: str | Iterable[str]) -> list[str]:
    if isinstance(spec, str):
        return spec.replace(",", " ").split()
    return [s.strip() for s in spec if s.strip()]


_XY_ROTATIONS = {
    "tilt_rot": xy_terms.PrimaryAxisTilt,
    "nonperp_rot": xy_terms.AxesNonPerpendicularity,
    "collim_rot": xy_terms.Collimation,
}


def _xy_terms(tokens: list[str]) -> tuple[Term, ...]:
    out: list[Term] = []
    for token in tokens:
        key = "linearised" if token == "linearized" else token
        if key in xy_terms.FAMILIES:
            out.extend(xy_terms.FAMILIES[key]())
        elif token in xy_terms.Basic.TABLE:
            out.append(xy_terms.Basic(token))
        elif token in xy_terms.Linearised.TABLE:
            out.append(xy_terms.Linearised(token))
        elif token in xy_terms.SphericalHarmonic.TABLE:
            out.append(xy_terms.SphericalHarmonic(token))
        elif token in _XY_ROTATIONS:
            out.append(_XY_ROTATIONS[token]())
        else:
            raise ValueError(
                f"unknown X-Y family or term {token!r}; families: {', '.join(xy_terms.FAMILIES)}; terms: the names of "
                "pointax.terms.xy (Basic, Linearised, SphericalHarmonic tables) and tilt_rot, nonperp_rot, collim_rot"
            )
    return tuple(out)


def _altaz_terms(tokens: list[str], naming: str, form: str) -> tuple[Term, ...]:
    names: list[str] = []
    for token in tokens:
        key = token.lower()
        if key in ALTAZ_FAMILIES and (key != "gpoint" or naming == "gpoint"):
            names.extend(ALTAZ_FAMILIES[key])
        else:
            names.append(token)
    if naming == "gpoint":
        return term_library.gpoint_terms(names, form=form)
    return term_library.tpoint(names, form=form)


def family_model(
    spec: str | Iterable[str], mount: Mount | Observations, *, naming: str = "tpoint", form: str = "linear"
) -> Model:
    """A model named by a family or a list of terms, for the mount at hand.

    Args:
        spec: family names and term names separated by spaces or commas (a family name
            expands to its terms), e.g. ``"basic"``, ``"rotation dL_tanL_secB"``,
            ``"basic HACA2 HESE2"``, ``"IA IE CA NPAE AN AW"``.

            * X-Y mount: families ``basic``, ``harmonic``, ``rotation``, ``linearised``
              (:data:`pointax.XY_FAMILIES`); terms of :mod:`pointax.terms.xy` by name.
            * Alt-az mount: ``basic`` (TPOINT's eight), ``harmonic`` (those and
              :data:`ALTAZ_HARMONICS`), ``gpoint`` (gpoint's seven, with
              ``naming="gpoint"``); TPOINT term names (:func:`pointax.terms.tpoint`), or
              with ``naming="gpoint"`` gpoint's names too
              (:func:`pointax.terms.gpoint_terms`: lower-case ``ia``, extras).
        mount: the mount, or observations whose convention names it ('xy', or an
            azimuth convention for alt-az).
        naming: 'tpoint' or 'gpoint' (alt-az term names only).
        form: 'linear' or 'rigorous' (alt-az TPOINT terms only).

    Raises:
        ValueError: an unknown name, a term named twice, or a mount without names.
    """
    if naming not in ("tpoint", "gpoint"):
        raise ValueError(f"naming must be 'tpoint' or 'gpoint', got {naming!r}")
    if isinstance(mount, Observations):
        mount = _mount_of(mount)
    tokens = _tokens(spec)
    if not tokens:
        raise ValueError("empty model family: give a family name or term names")
    if isinstance(mount, XYMount):
        return Model(mount, _xy_terms(tokens))
    if isinstance(mount, AltAzMount):
        return Model(mount, _altaz_terms(tokens, naming, form))
    raise ValueError(f"no named families for a {type(mount).__name__}; pass pointax.Model objects")


def _families(families, obs: Observations, naming: str, form: str) -> dict[str, Model]:
    if isinstance(families, Mapping):
        items = list(families.items())
    elif isinstance(families, str):
        items = [(families, families)]
    else:
        items = [(f, f) if isinstance(f, str) else (None, f) for f in families]
        if any(label is None for label, _ in items):
            raise TypeError("families must map labels to models (a dict), or be a sequence of family names")
    if not items:
        raise ValueError("no model families to compare")
    out: dict[str, Model] = {}
    for label, family in items:
        if not isinstance(label, str) or not label or label == BEFORE:
            raise ValueError(f"bad family label {label!r}: use a non-empty string other than {BEFORE!r}")
        if isinstance(family, str) or (isinstance(family, Sequence) and all(isinstance(t, str) for t in family)):
            model = family_model(family, obs, naming=naming, form=form)
        elif isinstance(family, Model):
            model = family
        else:
            raise TypeError(f"family {label!r}: expected a pointax.Model or a family name, got {type(family).__name__}")
        convention = model.mount.convention
        if convention is not None and obs.convention is not None and convention != obs.convention:
            raise ValueError(
                f"family {label!r}: its mount expects readings in the {convention!r} convention, "
                f"the observations are {obs.convention!r}"
            )
        if not model.free_parameters:
            raise ValueError(f"family {label!r} has no free parameters to fit")
        out[label] = model
    mounts = {type(m.mount) for m in out.values()}
    if len(mounts) > 1:
        raise ValueError(f"all families must share one mount kind, got {sorted(t.__name__ for t in mounts)}")
    return out


# ----------------------------------------------------------------------------- evaluation scheme


@dataclasses.dataclass(frozen=True)
class _Scheme:
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


def _scheme(observations, holdout, folds, seed) -> _Scheme:
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
        return _Scheme(obs, everything, (), "none", f"{n} stars, no out-of-sample test", dropped)
    if folds is not None:
        k = _count("folds", folds, 2)
        splits = tuple((_rows(f, n, "fold"), _rows(v, n, "fold")) for f, v in fold_indices(n, k, seed))
        return _Scheme(
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
        return _Scheme(
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
        return _Scheme(obs, fit_rows, ((fit_rows, val_rows),), "split", description, dropped)
    if isinstance(holdout, int | float | np.floating | np.integer) and not isinstance(holdout, bool):
        fit_idx, val_idx = holdout_indices(n, holdout, seed)
        fit_rows, val_rows = _rows(fit_idx, n, "holdout"), _rows(val_idx, n, "holdout")
        description = (
            f"{len(fit_idx)} fitting stars, {len(val_idx)} held back at random ({float(holdout):g}, seed {seed})"
        )
        return _Scheme(obs, fit_rows, ((fit_rows, val_rows),), "holdout", description, dropped)
    raise TypeError(
        "holdout must be a fraction, validation observations, (fit_rows, validation_rows) or "
        f"(fit_observations, validation_observations), got {type(holdout).__name__}"
    )


def _per_axis(mount: Mount, per_axis: str | None) -> str:
    """The default: the paper's axis angles on an X-Y mount, TPOINT's sky offsets elsewhere."""
    if per_axis is None:
        return "angle" if isinstance(mount, XYMount) else "sky"
    return per_axis


def _cos_axis2(mount: Mount, obs: Observations, per_axis: str) -> np.ndarray | None:
    """cos of each target's second-axis angle in the mount frame (None for 'sky')."""
    if per_axis not in PER_AXIS:
        raise ValueError(f"per_axis must be one of {PER_AXIS}, got {per_axis!r}")
    if per_axis == "sky":
        return None
    if not isinstance(mount, SphericalMount):
        raise ValueError(
            f"per_axis='angle' needs a mount with perpendicular axes (alt-az, X-Y, equatorial); "
            f"a {type(mount).__name__} has no first-axis angle residual: use per_axis='sky'"
        )
    t = np.asarray(obs.target) @ np.asarray(mount.frame)
    return np.hypot(t[:, 0], t[:, 1])


# ----------------------------------------------------------------------------- compare


_residuals = eqx.filter_jit(residuals)


@dataclasses.dataclass(frozen=True)
class FamilyStats:
    """One row of a :class:`Comparison` (radians inside; :meth:`to_dict` in arcsec).

    Attributes:
        label: the family's label.
        model: the model fitted on the in-sample stars (for the before-correction row,
            the mount with no terms).
        result: its :class:`pointax.FitResult` (``None`` for the before-correction row).
        n_params: number of fitted parameters.
        in_sample: :class:`AxisRMS` of the in-sample residuals (eqs 21-23).
        sky_rms: TPOINT's Sky RMS of the in-sample fit, radians.
        out_of_sample: :class:`AxisRMS` of the out-of-sample predictions, or ``None``.
        log_likelihood, aic, bic: of the in-sample fit (module docstring).
        significance: ``value / sigma`` of each fitted parameter, by name.
        warnings: the fit's warnings (:meth:`pointax.FitResult.warnings`: parameters the
            data cannot tell apart, strong correlations, non-convergence), and the
            out-of-sample fits' non-convergence.
        converged: whether the in-sample fit and every out-of-sample fit converged.
    """

    label: str
    model: Model
    result: FitResult | None
    n_params: int
    in_sample: AxisRMS
    sky_rms: float
    out_of_sample: AxisRMS | None
    log_likelihood: float
    aic: float
    bic: float
    significance: dict[str, float]
    warnings: tuple[str, ...]
    converged: bool

    def weak(self, threshold: float = 2.0) -> list[str]:
        """Parameters with ``|value / sigma|`` below ``threshold``."""
        return [n for n, z in self.significance.items() if abs(z) < threshold]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (arcsec; ``null`` for what is not finite or not computed)."""
        terms = []
        if self.result is not None:
            for row in self.result.table():
                terms.append(
                    {
                        "name": row["name"],
                        "value": _number(row["value"]),
                        "sigma": _number(row["sigma"]),
                        "unit": row["unit"],
                        "significance": _number(self.significance[row["name"]]),
                    }
                )
        return {
            "label": self.label,
            "n_params": self.n_params,
            "in_sample": _rms_dict(self.in_sample),
            "sky_rms": _number(self.sky_rms / ARCSEC),
            "out_of_sample": None if self.out_of_sample is None else _rms_dict(self.out_of_sample),
            "log_likelihood": _number(self.log_likelihood),
            "aic": _number(self.aic),
            "bic": _number(self.bic),
            "converged": self.converged,
            "terms": terms,
            "warnings": list(self.warnings),
        }


def _number(x) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def _rms_dict(r: AxisRMS) -> dict[str, Any]:
    return {k: (_number(v) if k != "n" else v) for k, v in r.arcsec().items()}


@dataclasses.dataclass(frozen=True)
class Comparison:
    """The outcome of :func:`compare`: one :class:`FamilyStats` per family, the first
    row the observations before correction (no terms).

    Attributes:
        rows: the rows, before correction first, then the families in the order given.
        scheme: 'none', 'validation set', 'split', 'holdout' or 'k-fold'.
        description: the scheme in words (stars fitted, validated, seed).
        n_fit: stars in the in-sample fit.
        n_validation: out-of-sample predictions (0 without a scheme).
        per_axis: 'angle' or 'sky' (:data:`PER_AXIS`).
        axis_names: the mount's names of its axes, e.g. ('L', 'B').
        n_dropped: observations left out because their weight was 0.
    """

    rows: tuple[FamilyStats, ...]
    scheme: str
    description: str
    n_fit: int
    n_validation: int
    per_axis: str
    axis_names: tuple[str, str]
    n_dropped: int = 0

    def __getitem__(self, label: str) -> FamilyStats:
        for row in self.rows:
            if row.label == label:
                return row
        raise KeyError(f"no family {label!r}; the comparison has {[r.label for r in self.rows]}")

    @property
    def labels(self) -> list[str]:
        return [r.label for r in self.rows]

    def _axis_headers(self) -> tuple[str, str]:
        a1, a2 = (a[:1].upper() + a[1:] for a in self.axis_names)  # L, B; Az, El; Ha, Dec
        if self.per_axis == "sky":
            return f"d{a1} cos {a2}", f"d{a2}"
        return f"d{a1}", f"d{a2}"

    def table(self, *, notes: bool = True) -> str:
        """The comparison laid out like the level-mount paper's Table 3, one row per
        family (arcsec): in-sample per-axis and total RMS (eqs 21-23), the same out of
        sample, TPOINT's Sky RMS, number of parameters, AIC and BIC; then each family's
        warnings and its parameters with ``|value/sigma| < 2``."""
        h1, h2 = self._axis_headers()
        width = max(18, *(len(r.label) for r in self.rows))
        lines = [
            f"Model comparison: {self.description}.",
            "RMS in arcsec as the level-mount paper's eqs 21-23 (n - 1); per axis: "
            + ("axis-angle residuals" if self.per_axis == "angle" else "offsets on the sky")
            + "; Sky RMS as TPOINT's.",
        ]
        if self.n_dropped:
            lines.append(f"{self.n_dropped} observation(s) with weight 0 left out.")
        col = max(9, len(h1) + 1, len(h2) + 1)
        top = (
            f"{'':<{width}s} | {'in-sample':^{3 * col + 2}s} | {'out-of-sample':^{3 * col + 2}s} |"
            f" {'Sky RMS':>8s} {'params':>6s} {'AIC':>9s} {'BIC':>9s}"
        )
        head = (
            f"{'family':<{width}s} | {h1:>{col}s} {h2:>{col}s} {'total':>{col}s} | "
            f"{h1:>{col}s} {h2:>{col}s} {'total':>{col}s} | {'':>8s} {'':>6s} {'':>9s} {'':>9s}"
        )
        lines += ["", top, head, "-" * len(head)]

        def cells(r: AxisRMS | None) -> str:
            if r is None:
                return " ".join(f"{'-':>{col}s}" for _ in range(3))
            return " ".join(
                f"{v / ARCSEC:{col}.2f}" if math.isfinite(v) else f"{'nan':>{col}s}"
                for v in (r.axis1, r.axis2, r.total)
            )

        for row in self.rows:
            lines.append(
                f"{row.label:<{width}s} | {cells(row.in_sample)} | {cells(row.out_of_sample)} | "
                f"{row.sky_rms / ARCSEC:8.2f} {row.n_params:6d} {row.aic:9.1f} {row.bic:9.1f}"
            )
        if notes:
            extra = []
            for row in self.rows[1:]:
                extra.extend(f"  {row.label}: WARNING: {w}" for w in row.warnings)
                weak = row.weak()
                if weak:
                    extra.append(f"  {row.label}: |value/sigma| < 2: {', '.join(weak)}")
            if extra:
                lines += ["", "Notes:", *extra]
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: the scheme and one entry per row (arcsec; see :meth:`FamilyStats.to_dict`)."""
        return {
            "scheme": self.scheme,
            "description": self.description,
            "n_fit": self.n_fit,
            "n_validation": self.n_validation,
            "per_axis": self.per_axis,
            "axes": list(self._axis_headers()),
            "unit": "arcsec",
            "rms_definition": "sqrt(sum d^2 / (n - 1)) per axis, total = hypot (level-mount paper eqs 21-23)",
            "likelihood": "iid Gaussian on the 2n sky residual components (arcsec), ML variance RSS/(2n); k = params + 1",
            "n_dropped": self.n_dropped,
            "families": [r.to_dict() for r in self.rows],
        }


def _row(label, model, result, n_params, r_in, r_out, cos_in, cos_out, warnings_, converged) -> FamilyStats:
    ins = axis_rms(r_in, cos_in)
    out = None if r_out is None else axis_rms(r_out, cos_out)
    log_l, aic, bic = information_criteria(r_in, n_params)
    sky = math.sqrt(float(np.sum(np.asarray(r_in) ** 2)) / len(r_in))
    if result is not None:
        values, sigmas = np.asarray(result.values), np.asarray(result.sigmas)
        z = np.where(np.isfinite(sigmas) & (sigmas > 0), values / np.where(sigmas > 0, sigmas, 1.0), 0.0)
        significance = {n: float(v) for n, v in zip(result.names, z)}
    else:
        significance = {}
    return FamilyStats(
        label, model, result, n_params, ins, sky, out, log_l, aic, bic, significance, tuple(warnings_), converged
    )


@float64
def compare(
    families: Mapping[str, Model | str] | Sequence[str] | str,
    observations,
    *,
    holdout=None,
    folds: int | None = None,
    seed: int = 0,
    per_axis: str | None = None,
    naming: str = "tpoint",
    form: str = "linear",
    solver: str = "lm",
    max_steps: int = 256,
) -> Comparison:
    """Fit several model families to the same stars and compare them fairly.

    Args:
        families: ``{label: model}`` with :class:`pointax.Model` values or family names
            (:func:`family_model`), or a sequence of family names (labels = names).
        observations: :class:`pointax.Observations` or a run with ``.observations``
            (``None`` with ``holdout=(fit_obs, validation_obs)``). Rows with weight 0
            are left out (and counted); the others must have equal weights.
        holdout: out-of-sample scheme: validation observations, a fraction to hold back,
            ``(fit_rows, validation_rows)`` or ``(fit_obs, validation_obs)`` (module
            docstring).
        folds: k-fold cross-validation instead (k >= 2).
        seed: seed of the random holdout or fold assignment.
        per_axis: 'angle' (the paper's ``DL``) or 'sky' (``dL cos B``, TPOINT's ``dA cos
            E``); default 'angle' on an X-Y mount (the paper's eqs 21-23), 'sky' on
            others (the first-axis angle residual grows as ``sec E`` towards the zenith).
        naming, form: how family names resolve (:func:`family_model`).
        solver, max_steps: passed to :func:`pointax.fit`.

    Returns:
        A :class:`Comparison`: ``.table()`` prints it like the paper's Table 3,
        ``.to_dict()`` gives JSON.

    Raises:
        ValueError, TypeError: bad families, observations or scheme (the message says which).
    """
    scheme = _scheme(observations, holdout, folds, seed)
    models = _families(families, scheme.obs, naming, form)
    mount = next(iter(models.values())).mount
    per_axis = _per_axis(mount, per_axis)
    cos2 = _cos_axis2(mount, scheme.obs, per_axis)
    obs = scheme.obs
    fit_rows = scheme.fit_rows
    obs64 = jax.tree.map(lambda x: jnp.asarray(x, jnp.float64), obs)

    def cos(mask):
        return None if cos2 is None else cos2[mask]

    def predict(model: Model, rows: np.ndarray) -> np.ndarray:
        """``px.residuals(model, the observations of rows)``: the rows are picked by
        weight, so every set of rows shares one compiled evaluation per model."""
        chosen = Observations(obs64.encoder, obs64.target, jnp.asarray(rows, jnp.float64), obs.convention)
        return np.asarray(_residuals(model, chosen))[rows]

    out_rows = np.zeros(len(obs), bool)
    for _, v_rows in scheme.splits:
        out_rows |= v_rows
    rows: list[FamilyStats] = []
    # Before correction: the mount alone, nothing fitted.
    bare = Model(mount, ())
    r_bare = predict(bare, np.ones(len(obs), bool))
    if scheme.splits:
        r_out, cos_out = r_bare[np.flatnonzero(out_rows)], cos(out_rows)
    else:
        r_out, cos_out = None, None
    rows.append(_row(BEFORE, bare, None, 0, r_bare[fit_rows], r_out, cos(fit_rows), cos_out, (), True))

    for label, model in models.items():
        result = fit(model, obs, weights=fit_rows.astype(np.float64), solver=solver, max_steps=max_steps)
        warnings_ = list(result.warnings())
        converged = bool(result.converged)
        r_in = np.asarray(result.residuals)[fit_rows]
        r_out, cos_out = None, None
        if scheme.splits:
            # Each held-back star is predicted by the model fitted without it; the
            # splits' validation rows are disjoint, so the predictions fill r_all.
            r_all = np.zeros((len(obs), 2))
            for k, (f_rows, v_rows) in enumerate(scheme.splits):
                if np.array_equal(f_rows, fit_rows):
                    fitted = result.model
                else:
                    fold = fit(model, obs, weights=f_rows.astype(np.float64), solver=solver, max_steps=max_steps)
                    fitted = fold.model
                    if not bool(fold.converged):
                        converged = False
                        warnings_.append(f"the fit of fold {k + 1} did not converge: {fold.message}")
                r_all[v_rows] = predict(fitted, v_rows)
            r_out, cos_out = r_all[out_rows], cos(out_rows)
        n_params = len(result.names)
        rows.append(
            _row(label, result.model, result, n_params, r_in, r_out, cos(fit_rows), cos_out, warnings_, converged)
        )

    return Comparison(
        rows=tuple(rows),
        scheme=scheme.kind,
        description=scheme.description,
        n_fit=scheme.n_fit,
        n_validation=scheme.n_validation,
        per_axis=per_axis,
        axis_names=tuple(type(mount).axis_names),
        n_dropped=scheme.n_dropped,
    )


# ----------------------------------------------------------------------------- automatic model building


@dataclasses.dataclass(frozen=True)
class BuildStep:
    """One step of :func:`build_model`'s path.

    Attributes:
        action: 'start', 'add' or 'drop'.
        term: the term added or dropped (for 'start', a summary of the start model).
        n_params: fitted parameters after the step.
        rms_in: in-sample total RMS after the step (eqs 21-23), radians.
        rms_out: out-of-sample total RMS after the step, radians.
        significance: the term's ``|value / sigma|`` (largest over its parameters): when
            added, in the model it joined; when dropped, in the model it left.
        sky_rms: TPOINT's Sky RMS of the in-sample fit, radians.
        converged: whether the step's in-sample and fold fits converged.
    """

    action: str
    term: str
    n_params: int
    rms_in: float
    rms_out: float
    significance: float
    sky_rms: float
    converged: bool = True

    def to_dict(self) -> dict[str, Any]:
        return {
            "converged": self.converged,
            "action": self.action,
            "term": self.term,
            "n_params": self.n_params,
            "rms_in_arcsec": _number(self.rms_in / ARCSEC),
            "rms_out_arcsec": _number(self.rms_out / ARCSEC),
            "significance": _number(self.significance),
            "sky_rms_arcsec": _number(self.sky_rms / ARCSEC),
        }


@dataclasses.dataclass(frozen=True)
class ModelBuild:
    """The outcome of :func:`build_model`.

    Attributes:
        model: the final model, its parameters fitted on the in-sample stars.
        path: the :class:`BuildStep` s taken, 'start' first.
        stopped: why the building stopped, in words.
        names: the final model's fitted parameter names.
        values, sigmas: their values and TPOINT sigmas (internal units, radians).
        units: their display units.
        rules: the rules used, in words.
        skipped: candidates left out before the search, with the reason.
    """

    model: Model
    path: tuple[BuildStep, ...]
    stopped: str
    names: tuple[str, ...]
    values: np.ndarray
    sigmas: np.ndarray
    units: tuple[str, ...]
    rules: str
    skipped: tuple[str, ...] = ()

    @property
    def added(self) -> list[str]:
        """Terms added and not dropped again, in the order they were added."""
        final = {t.name for t in self.model.terms}
        return [s.term for s in self.path if s.action == "add" and s.term in final]

    @property
    def dropped(self) -> list[str]:
        """Terms dropped and not added again."""
        final = {t.name for t in self.model.terms}
        return [s.term for s in self.path if s.action == "drop" and s.term not in final]

    def report(self) -> str:
        """The path as a table (arcsec), the stopping reason and the final parameters."""
        width = max(24, *(len(s.term) for s in self.path))
        head = f"{'step':>4s}  {'action':<6s}  {'term':<{width}s} {'params':>6s} {'RMS in':>8s} {'RMS out':>8s} {'|v/sigma|':>9s}"
        lines = [f"Automatic model building ({self.rules})", "", head, "-" * len(head)]
        for k, s in enumerate(self.path):
            sig = "" if s.action == "start" else f"{s.significance:9.1f}"
            lines.append(
                f"{k:4d}  {s.action:<6s}  {s.term:<{width}s} {s.n_params:6d} {s.rms_in / ARCSEC:8.2f} "
                f"{s.rms_out / ARCSEC:8.2f} {sig:>9s}"
            )
        lines.append(f"stopped: {self.stopped}")
        for k, s in enumerate(self.path):
            if not s.converged:
                lines.append(f"WARNING: the fits of step {k} did not converge; its figures may be off")
        if self.skipped:
            lines.append("candidates left out: " + "; ".join(self.skipped))
        lines += ["", f"final model: {self.model.describe()}"]
        for n, v, s, u in zip(self.names, self.values, self.sigmas, self.units):
            scale = UNITS[u]
            unit = "" if u == "arcsec" else f"  ({u})"
            lines.append(f"  {n:<{width}s} {v / scale:+12.4f} {s / scale:11.4f}{unit}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        return {
            "rules": self.rules,
            "stopped": self.stopped,
            "skipped": list(self.skipped),
            "path": [s.to_dict() for s in self.path],
            "terms": [
                {"name": n, "value": _number(v / UNITS[u]), "sigma": _number(s / UNITS[u]), "unit": u}
                for n, v, s, u in zip(self.names, self.values, self.sigmas, self.units)
            ],
        }


def _linearise(model: Model, obs: Observations, y: Float[Array, " p"]) -> tuple[Array, Array]:
    """Residuals ``(2n,)`` of ``model`` with free values ``y`` and their Jacobian ``(2n, p)``."""

    def r(y):
        return residuals(model.with_values(y, "free"), obs).reshape(-1)

    return r(y), jax.jacfwd(r)(y)


@dataclasses.dataclass
class _State:
    """A converged fit of one set of active terms: in-sample and out-of-sample figures."""

    active: frozenset[int]  # term indices of the superset
    y: np.ndarray  # (p,) free values, 0 for inactive parameters
    r: np.ndarray  # (n, 2) residuals of the in-sample fit (all rows)
    jac: np.ndarray  # (2n, p) Jacobian there
    sigmas: np.ndarray  # (p,) TPOINT sigmas (inf: degenerate; nan: inactive)
    rms_in: float
    rms_out: float
    sky_rms: float
    n_params: int
    converged: bool


class _Builder:
    """Least-squares fits of any subset of a superset model's terms, with one compiled
    residual-and-Jacobian function (:func:`_linearise`); Gauss-Newton in NumPy."""

    def __init__(self, superset: Model, scheme: _Scheme, cos2, max_iterations: int = 30):
        self.model = superset
        self.scheme = scheme
        obs = jax.tree.map(lambda x: jnp.asarray(x, jnp.float64), scheme.obs)
        # One compilation per build, model and observations closed over: a call then
        # costs the evaluation only (equinox's filter_jit re-partitions a model of many
        # terms on every call, which cost more than the evaluation here).
        self._lin = jax.jit(lambda y: _linearise(superset, obs, y))
        self.cos2 = cos2
        self.max_iterations = max_iterations
        free = superset.free_parameters
        self.p = len(free)
        self.columns: dict[int, list[int]] = {}
        for j, info in enumerate(free):
            self.columns.setdefault(info.term, []).append(j)
        self.y_start = np.asarray(superset.values("free"), np.float64)

    def lin(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r, jac = self._lin(jnp.asarray(y, jnp.float64))
        return np.asarray(r), np.asarray(jac)

    def cols(self, active: Iterable[int]) -> np.ndarray:
        return np.array(sorted(c for t in active for c in self.columns.get(t, [])), dtype=int)

    def solve(self, active, rows: np.ndarray, y0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        """Gauss-Newton (step-halving) on the rows ``rows`` (bool (n,)) for the columns
        of the ``active`` terms; inactive parameters are 0. Returns y, r, J at the end
        and whether it converged (the next step below :data:`STEP_TOLERANCE`, or below
        1e-10 rad where no step lowers the cost any more)."""
        cols = self.cols(active)
        rr = np.repeat(rows, 2)
        y = np.where(np.isin(np.arange(self.p), cols), y0, 0.0)
        r, jac = self.lin(y)
        cost = float(np.sum(r[rr] ** 2))
        if cols.size == 0:
            return y, r, jac, True
        converged = False
        for _ in range(self.max_iterations):
            step, *_ = np.linalg.lstsq(jac[np.ix_(rr, cols)], -r[rr], rcond=DEGENERATE_RCOND)
            if np.max(np.abs(step)) < STEP_TOLERANCE:
                converged = True  # the next step is below 2e-7 arcsec
                break
            scale, accepted = 1.0, False
            for _ in range(10):  # step halving: never accept a step that raises the cost
                trial = y.copy()
                trial[cols] += scale * step
                r_t, jac_t = self.lin(trial)
                cost_t = float(np.sum(r_t[rr] ** 2))
                if cost_t <= cost:
                    accepted = True
                    break
                scale *= 0.5
            if not accepted:
                converged = bool(np.max(np.abs(step)) < 1e-10)
                break
            y, r, jac, cost = trial, r_t, jac_t, cost_t
        return y, r, jac, converged

    def sigmas(self, jac_rows: np.ndarray, cols: np.ndarray, sky_rms: float) -> np.ndarray:
        """TPOINT sigmas of ``cols`` (inf where degenerate, as :func:`pointax.fit`)."""
        out = np.full(self.p, np.nan)
        if cols.size == 0:
            return out
        _, s, vt = np.linalg.svd(jac_rows[:, cols], full_matrices=False)
        small = s <= DEGENERATE_RCOND * s[0]
        inv = np.where(small, 0.0, 1.0 / np.where(small, 1.0, s) ** 2)
        var = np.einsum("ki,k,ki->i", vt, inv, vt) * sky_rms**2
        degenerate = np.any(small[:, None] & (np.abs(vt) > 0.1), axis=0)
        out[cols] = np.where(degenerate, np.inf, np.sqrt(var))
        return out

    def total(self, r: np.ndarray, rows: np.ndarray) -> float:
        return axis_rms(r[rows], None if self.cos2 is None else self.cos2[rows]).total

    def state(self, active: frozenset[int], y0: np.ndarray) -> _State:
        """Converged in-sample fit and out-of-sample predictions of ``active``."""
        fit_rows = self.scheme.fit_rows
        y, r_flat, jac, converged = self.solve(active, fit_rows, y0)
        r = r_flat.reshape(-1, 2)
        cols = self.cols(active)
        n = int(fit_rows.sum())
        sky = math.sqrt(float(np.sum(r[fit_rows] ** 2)) / n)
        sig = self.sigmas(jac[np.repeat(fit_rows, 2)], cols, sky)
        pieces, cos = [], []
        for f_rows, v_rows in self.scheme.splits:
            if np.array_equal(f_rows, fit_rows):
                r_fold = r
            else:
                _, r_fold_flat, _, ok = self.solve(active, f_rows, y)
                r_fold = r_fold_flat.reshape(-1, 2)
                converged = converged and ok
            pieces.append(r_fold[v_rows])
            if self.cos2 is not None:
                cos.append(self.cos2[v_rows])
        rms_out = axis_rms(np.concatenate(pieces), np.concatenate(cos) if cos else None).total
        return _State(active, y, r, jac, sig, self.total(r, fit_rows), rms_out, sky, int(cols.size), converged)

    def screen(self, state: _State, term: int) -> tuple[float, float, bool]:
        """``(|value/sigma|, out-of-sample RMS, degenerate)`` with ``term`` added: one
        Gauss-Newton step from the current fit, with its Jacobian, for the in-sample fit
        and for every fold."""
        fit_rows = self.scheme.fit_rows
        active = state.active | {term}
        cols = self.cols(active)
        new = self.columns[term]
        r0 = state.r.reshape(-1)
        jac = state.jac
        rr = np.repeat(fit_rows, 2)
        delta, *_ = np.linalg.lstsq(jac[np.ix_(rr, cols)], -r0[rr], rcond=DEGENERATE_RCOND)
        r_new = (r0 + jac[:, cols] @ delta).reshape(-1, 2)
        n = int(fit_rows.sum())
        sky = math.sqrt(float(np.sum(r_new[fit_rows] ** 2)) / n)
        sig = self.sigmas(jac[rr], cols, sky)
        y_new = state.y.copy()
        y_new[cols] += delta
        if np.any(~np.isfinite(sig[new])):
            return 0.0, math.inf, True
        z = float(np.max(np.abs(y_new[new] / sig[new])))
        pieces, cos = [], []
        for f_rows, v_rows in self.scheme.splits:
            if np.array_equal(f_rows, fit_rows):
                r_fold = r_new
            else:
                fr = np.repeat(f_rows, 2)
                d_fold, *_ = np.linalg.lstsq(jac[np.ix_(fr, cols)], -r0[fr], rcond=DEGENERATE_RCOND)
                r_fold = (r0 + jac[:, cols] @ d_fold).reshape(-1, 2)
            pieces.append(r_fold[v_rows])
            if self.cos2 is not None:
                cos.append(self.cos2[v_rows])
        rms_out = axis_rms(np.concatenate(pieces), np.concatenate(cos) if cos else None).total
        return z, rms_out, False

    def significance(self, state: _State, term: int) -> float:
        cols = self.columns[term]
        s = state.sigmas[cols]
        if np.any(~np.isfinite(s)) or np.any(s <= 0):
            return 0.0
        return float(np.max(np.abs(state.y[cols] / s)))


def _candidate_terms(candidates, obs: Observations, naming: str, form: str) -> tuple[Term, ...]:
    if isinstance(candidates, Model):
        return candidates.terms
    if isinstance(candidates, str):
        return family_model(candidates, obs, naming=naming, form=form).terms
    candidates = tuple(candidates)
    if all(isinstance(t, str) for t in candidates):
        return family_model(candidates, obs, naming=naming, form=form).terms
    for t in candidates:
        if not isinstance(t, Term):
            raise TypeError(f"candidates must be pointax.Term objects, a model or names, got {type(t).__name__}")
    return candidates


@float64
def build_model(
    candidates,
    observations,
    *,
    start: Model | str,
    folds: int | None = 5,
    holdout=None,
    seed: int = 0,
    add_threshold: float = 3.0,
    drop_threshold: float = 2.0,
    keep: Iterable[str] = (),
    max_steps: int = 40,
    per_axis: str | None = None,
    naming: str = "tpoint",
    form: str = "linear",
) -> ModelBuild:
    """Build a model automatically, in the spirit of TPOINT's FAUTO: add candidate terms
    that are significant and predict unseen stars better, drop terms that are not
    significant, and record the path.

    The rules, applied in turn until neither changes the model (or after ``max_steps``
    add and drop steps):

    1. **Add.** Each candidate not in the model is tried. Eligible are those whose
       ``|value / sigma|`` in the enlarged model is at least ``add_threshold`` (largest
       over the term's parameters), that the data can tell apart from the model's
       terms (no rank deficiency), that lower the out-of-sample RMS, and whose addition
       leads to a set of terms not visited before. The eligible one with the lowest
       out-of-sample RMS is added.
    2. **Drop.** While a term of the model (other than those in ``keep``) has
       ``|value / sigma| < drop_threshold`` (0 when the data cannot determine it), the
       least significant one is dropped and the model refitted. Adding comes first, so
       a term is not judged while the model still misses a large error (the residual
       then inflates every sigma).

    Out-of-sample RMS is the total of eqs 21-23 (:func:`axis_rms`) over k-fold
    predictions (``folds``, default 5) or a holdout (``holdout``, as in :func:`compare`;
    then ``folds`` is ignored). Candidates are screened with the Jacobian at the current
    fit (one Gauss-Newton step from it: the neglected change is of second order in the
    coefficients' change, about ``dc^2 / 1 rad``, 0.002" for a 20" term); every step's
    reported figures come from converged Gauss-Newton fits, which agree with
    :func:`pointax.fit` to its tolerance. Candidates must leave the pointing unchanged
    when their parameters are 0 (every library term does; checked).

    Args:
        candidates: terms that may be added: :class:`pointax.Term` objects, a model
            (its terms) or names (:func:`family_model`, e.g. ``"harmonic linearised"``).
            Candidates named like a term of ``start`` are left out (and listed).
        observations: as for :func:`compare` (equal weights).
        start: the starting model, or a family name for the observations' mount. Its
            fixed parameters stay fixed.
        folds, holdout, seed: the out-of-sample scheme.
        add_threshold, drop_threshold: significance thresholds (defaults 3 and 2).
        keep: names of terms of ``start`` that are never dropped.
        max_steps: most add and drop steps.
        per_axis: as for :func:`compare` (what the RMS measures on the first axis).
        naming, form: how names resolve (:func:`family_model`).

    Returns:
        :class:`ModelBuild`: the final model (fitted on the in-sample stars), the path
        and why it stopped; ``print(build.report())``.
    """
    if holdout is not None:
        folds = None
    elif folds is None:
        raise ValueError("build_model needs an out-of-sample scheme: folds=k (default 5) or holdout")
    if not (
        math.isfinite(add_threshold) and math.isfinite(drop_threshold) and add_threshold > 0 and drop_threshold >= 0
    ):
        raise ValueError(f"thresholds must be finite and positive, got add {add_threshold!r}, drop {drop_threshold!r}")
    max_steps = _count("max_steps", max_steps, 0)
    scheme = _scheme(observations, holdout, folds, seed)
    start_label = start if isinstance(start, str) else "start model"
    if isinstance(start, str):
        start = family_model(start, scheme.obs, naming=naming, form=form)
    if not isinstance(start, Model):
        raise TypeError(f"start must be a pointax.Model or a family name, got {type(start).__name__}")
    conv = start.mount.convention
    if conv is not None and scheme.obs.convention is not None and conv != scheme.obs.convention:
        raise ValueError(
            f"start's mount expects the {conv!r} convention, the observations are {scheme.obs.convention!r}"
        )
    keep = set(keep)
    unknown = keep - {t.name for t in start.terms}
    if unknown:
        raise ValueError(f"keep names terms not in the start model: {sorted(unknown)}")
    pool = _candidate_terms(candidates, scheme.obs, naming, form)
    names = {t.name for t in start.terms}
    chosen, skipped = [], []
    for t in pool:
        if t.name in names:
            skipped.append(f"{t.name} (already in the model)")
            continue
        names.add(t.name)
        chosen.append(t)
    superset = start.with_terms(*chosen)
    superset = superset.set(**{p.name: 0.0 for p in superset.parameters[len(start.parameters) :]})
    cos2 = _cos_axis2(start.mount, scheme.obs, _per_axis(start.mount, per_axis))
    builder = _Builder(superset, scheme, cos2)
    n_start = len(start.terms)
    candidate_ids = [i for i in range(n_start, len(superset.terms)) if builder.columns.get(i)]
    for i in range(n_start, len(superset.terms)):
        if not builder.columns.get(i):
            skipped.append(f"{superset.terms[i].name} (no free parameters)")

    # Candidates at 0 must leave the pointing as it is.
    obs64 = jax.tree.map(lambda x: jnp.asarray(x, jnp.float64), scheme.obs)
    r_start = np.asarray(eqx.filter_jit(residuals)(start, obs64)).reshape(-1)
    r_super, _ = builder.lin(builder.y_start)
    if not np.allclose(r_start, r_super, rtol=0, atol=1e-12):
        raise ValueError(
            "some candidate terms change the pointing when their parameters are 0; build_model needs terms that do not"
        )

    term_name = [t.name for t in superset.terms]
    active = frozenset(i for i in range(n_start) if builder.columns.get(i))
    state = builder.state(active, builder.y_start)
    label = f"{start_label} ({len(start.terms)} terms)"
    path = [
        BuildStep("start", label, state.n_params, state.rms_in, state.rms_out, math.nan, state.sky_rms, state.converged)
    ]
    visited = {active}
    stopped = f"max_steps={max_steps} reached"
    steps = 0
    while steps < max_steps:
        # 1. Add the candidate that predicts best among the significant ones.
        best = None
        for t in candidate_ids:
            if t in state.active or (state.active | {t}) in visited:
                continue
            zt, out, degenerate = builder.screen(state, t)
            if degenerate or zt < add_threshold or not out < state.rms_out:
                continue
            if best is None or out < best[1]:
                best = (t, out)
        if best is not None:
            t = best[0]
            state = builder.state(state.active | {t}, state.y)
            visited.add(state.active)
            z_t = builder.significance(state, t)
            path.append(
                BuildStep(
                    "add",
                    term_name[t],
                    state.n_params,
                    state.rms_in,
                    state.rms_out,
                    z_t,
                    state.sky_rms,
                    state.converged,
                )
            )
            steps += 1
        # 2. Drop the least significant term below the threshold, one at a time.
        dropped = False
        while steps < max_steps:
            z = {t: builder.significance(state, t) for t in sorted(state.active) if term_name[t] not in keep}
            weak = [t for t in z if z[t] < drop_threshold]
            if not weak:
                break
            t = min(weak, key=lambda k: z[k])
            state = builder.state(state.active - {t}, state.y)
            visited.add(state.active)
            path.append(
                BuildStep(
                    "drop",
                    term_name[t],
                    state.n_params,
                    state.rms_in,
                    state.rms_out,
                    z[t],
                    state.sky_rms,
                    state.converged,
                )
            )
            steps += 1
            dropped = True
        if best is None and not dropped:
            stopped = (
                f"no candidate has |value/sigma| >= {add_threshold:g} and lowers the out-of-sample RMS, "
                f"and every term has |value/sigma| >= {drop_threshold:g}"
            )
            break

    # The active terms, and the start's terms without free parameters (all fixed).
    final_terms = [
        i for i in range(len(superset.terms)) if i in state.active or (i < n_start and not builder.columns.get(i))
    ]
    fitted = superset.with_values(jnp.asarray(state.y), "free")
    model = start.restructured(terms=[fitted.terms[i] for i in final_terms])
    cols = builder.cols(state.active)
    free = superset.free_parameters
    rules = (
        f"add: |value/sigma| >= {add_threshold:g} and lower out-of-sample RMS; drop: |value/sigma| < {drop_threshold:g}; "
        f"{scheme.description}"
    )
    return ModelBuild(
        model=model,
        path=tuple(path),
        stopped=stopped,
        names=tuple(free[c].name for c in cols),
        values=state.y[cols],
        sigmas=state.sigmas[cols],
        units=tuple(free[c].unit for c in cols),
        rules=rules,
        skipped=tuple(skipped),
    )

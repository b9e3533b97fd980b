"""Choosing a pointing model: fair comparison of model families and FAUTO-style
automatic model building.

    pointax/analysis/per_axis.py        per-axis figures: axis angles or sky offsets (the figures: fitting/statistics.py)
    pointax/analysis/folds.py           out-of-sample schemes: holdout sets, k-fold cross-validation
    pointax/analysis/families.py        model families by name (X-Y paper families, TPOINT alt-az sets)
    pointax/analysis/comparison.py      compare(): families side by side, the paper's Table 3
    pointax/analysis/fauto_search.py    fauto(): TPOINT-style FAUTO: physical terms, then harmonics, by significance
    pointax/analysis/model_building.py  build_model(): grow and prune a model term by term, by cross-validation
    pointax/analysis/building_fits.py   build_model's least-squares fits over masks of terms and rows

:func:`compare` and :func:`build_model` are also ``pointax.compare`` and
``pointax.build_model``.
"""

from __future__ import annotations

from ..core.lazy import lazy_namespace

# Public name -> the module that defines it, loaded on first use: ``pointax fit`` reads
# the residual listing (:mod:`.listing`) without the families' term libraries.
_EXPORTS = {
    "STEP_TOLERANCE": "building_fits",
    "BEFORE": "comparison",
    "Comparison": "comparison",
    "FamilyStats": "comparison",
    "compare": "comparison",
    "FAUTO_PHYSICAL": "fauto_search",
    "Fauto": "fauto_search",
    "FautoStep": "fauto_search",
    "fauto": "fauto_search",
    "harmonic_candidates": "fauto_search",
    "ALTAZ_FAMILIES": "families",
    "ALTAZ_HARMONICS": "families",
    "EQUATORIAL_FAMILIES": "families",
    "EQUATORIAL_HARMONICS": "families",
    "family_model": "families",
    "fold_indices": "folds",
    "holdout_indices": "folds",
    "BuildStep": "model_building",
    "ModelBuild": "model_building",
    "build_model": "model_building",
    "PER_AXIS": "per_axis",
    # the per-axis statistics, defined with the fits' own (a path relative to this package)
    "AxisRMS": ".fitting.statistics",
    "axis_rms": ".fitting.statistics",
    "information_criteria": ".fitting.statistics",
}

__getattr__, __dir__ = lazy_namespace(__name__, _EXPORTS)

__all__ = [
    "ALTAZ_FAMILIES",
    "ALTAZ_HARMONICS",
    "EQUATORIAL_FAMILIES",
    "EQUATORIAL_HARMONICS",
    "BEFORE",
    "PER_AXIS",
    "STEP_TOLERANCE",
    "AxisRMS",
    "FamilyStats",
    "Comparison",
    "BuildStep",
    "ModelBuild",
    "compare",
    "build_model",
    "fauto",
    "Fauto",
    "FautoStep",
    "FAUTO_PHYSICAL",
    "harmonic_candidates",
    "family_model",
    "axis_rms",
    "information_criteria",
    "fold_indices",
    "holdout_indices",
]

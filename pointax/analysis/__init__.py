"""Choosing a pointing model: fair comparison of model families and FAUTO-style
automatic model building.

    pointax/analysis/per_axis.py        per-axis figures: axis angles or sky offsets (the figures: fitting/statistics.py)
    pointax/analysis/folds.py           out-of-sample schemes: holdout sets, k-fold cross-validation
    pointax/analysis/families.py        model families by name (X-Y paper families, TPOINT alt-az sets)
    pointax/analysis/comparison.py      compare(): families side by side, the paper's Table 3
    pointax/analysis/fauto.py           fauto(): TPOINT-style FAUTO: physical terms, then harmonics, by significance
    pointax/analysis/model_building.py  build_model(): grow and prune a model term by term, by cross-validation
    pointax/analysis/building_fits.py   build_model's least-squares fits over masks of terms and rows

:func:`compare` and :func:`build_model` are also ``pointax.compare`` and
``pointax.build_model``.
"""

from __future__ import annotations

from .building_fits import STEP_TOLERANCE
from .comparison import BEFORE, Comparison, FamilyStats, compare
from .fauto import FAUTO_PHYSICAL, Fauto, FautoStep, fauto, harmonic_candidates
from .families import ALTAZ_FAMILIES, ALTAZ_HARMONICS, EQUATORIAL_FAMILIES, EQUATORIAL_HARMONICS, family_model
from .folds import fold_indices, holdout_indices
from .model_building import BuildStep, ModelBuild, build_model
from ..fitting.statistics import AxisRMS, axis_rms, information_criteria
from .per_axis import PER_AXIS

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

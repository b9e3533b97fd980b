"""The names the ``pointax`` command's options accept, as plain tuples.

The parser is built from these, so that ``pointax --help`` and argument errors answer
without importing JAX or any numerical library. Each is a copy of a library constant
(named in its comment), in the library's order; ``tests/test_startup.py`` checks that
the copies equal the originals.
"""

from __future__ import annotations

from ..fitting.options import LOSS_NAMES, SOLVER_NAMES  # light: no JAX
from ..io.offset_columns import UNIT_NAMES  # light: no numerical library

__all__ = [
    "SOLVERS",
    "LOSSES",
    "TERM_FORMS",
    "DEFAULT_TERM_FORM",
    "RESIDUAL_FORMS",
    "AZIMUTH_CONVENTIONS",
    "BASIC_ALTAZ",
    "GPOINT_ALTAZ_TERMS",
    "HELIOSTAT_DEFAULT",
    "FOCAL_SPOT_METHODS",
    "TURNTABLE_MODELS",
    "XY_FAMILIES",
    "SOLUTIONS",
    "CENTROID_METHODS",
    "RUN_FORMATS",
    "TPOINT_MOUNTS",
    "BASIC_EQUATORIAL",
    "OFFSET_UNITS",
    "OFFSET_SIGNS",
]

SOLVERS = tuple(SOLVER_NAMES)
"""Least-squares solvers: the keys of :data:`pointax.fitting.SOLVERS`."""

LOSSES = LOSS_NAMES
"""Least-squares losses: the keys of :data:`pointax.fitting.LOSSES`."""

TERM_FORMS = ("linear", "rigorous")
"""TPOINT term forms: the keys of :data:`pointax.terms.FORMS`."""

DEFAULT_TERM_FORM = "rigorous"
"""The term form when ``--form`` is not given: :data:`pointax.terms.DEFAULT_FORM`."""

RESIDUAL_FORMS = ("sky", "tpoint")
"""What a fit minimises: :data:`pointax.core.model.RESIDUAL_FORMS`."""

AZIMUTH_CONVENTIONS = ("N-E", "S-E", "S-W")
"""Ways of counting azimuth: the keys of :data:`pointax.core.mounts.AZIMUTH_CONVENTIONS`."""

BASIC_ALTAZ = ("IA", "IE", "NPAE", "CA", "AN", "AW", "TF", "TX")
"""TPOINT's eight basic alt-az terms: :data:`pointax.terms.BASIC_ALTAZ`."""

GPOINT_ALTAZ_TERMS = ("ia", "tn", "te", "npae", "npoa", "ie", "tf")
"""gpoint's alt-az terms: :data:`pointax.terms.GPOINT_ALTAZ_TERMS`."""

HELIOSTAT_DEFAULT = ("t1n", "t1u", "t2e", "t2n")
"""A PAINT calibration's default terms: :data:`pointax.terms.heliostat_terms.HELIOSTAT_DEFAULT`."""

FOCAL_SPOT_METHODS = ("HeliOS", "UTIS")
"""PAINT focal-spot methods: :data:`pointax.io.paint.FOCAL_SPOT_METHODS`."""

TURNTABLE_MODELS = ("full", "simple")
"""Named turntable models: the keys of :data:`pointax.terms.sun_vector.TURNTABLE_MODELS`."""

XY_FAMILIES = ("harmonic", "basic", "rotation", "linearised")
"""X-Y model families: the keys of :data:`pointax.terms.xy.FAMILIES`."""

SOLUTIONS = ("nearest", "normal", "flipped")
"""Mechanical solutions of ``pointax command``: :data:`pointax.core.inverse.SOLUTIONS`."""

CENTROID_METHODS = ("auto", "intensity", "limb")
"""Centroid methods: :data:`pointax.sunsensor.centroids.METHODS`."""

RUN_FORMATS = ("tpoint", "gpoint", "paint", "sun", "xy", "offsets")
"""Pointing-run formats :func:`pointax.io.load_run` reads: :data:`pointax.io.RUN_FORMATS`."""

TPOINT_MOUNTS = ("altaz", "equatorial")
"""Mounts of TPOINT runs (``--mount``): :data:`pointax.io.tpoint.MOUNTS`."""

BASIC_EQUATORIAL = ("IH", "ID", "CH", "NP", "MA", "ME")
"""TPOINT's six basic equatorial terms: :data:`pointax.terms.BASIC_EQUATORIAL`."""

OFFSET_UNITS = UNIT_NAMES
"""Units of offsets tables (``--units``): the keys of :data:`pointax.io.offsets.OFFSET_UNITS`."""

OFFSET_SIGNS = ("observed-raw", "raw-observed")
"""Signs of offsets tables (``--sign``): :data:`pointax.io.offsets.OFFSET_SIGNS`."""

"""The error-term library.

* :mod:`pointax.terms.tpoint_terms`: TPOINT's alt-az terms in TPOINT's linear form.
* :mod:`pointax.terms.rigorous`: the same terms as exact rotations.
* :mod:`pointax.terms.equatorial`: TPOINT's equatorial terms (IH ID CH NP MA ME TF FO
  DAF HCES HCEC DCES DCEC), linear and rigorous; ``tpoint(..., mount="equatorial")``.
* :mod:`pointax.terms.tpoint_special`, :mod:`pointax.terms.equatorial_special`: more
  of TPOINT's named terms (NRX NRY CRX CRY FLOP TFP ...; TX DAB DNP and the AAT's).
* :mod:`pointax.terms.harmonic`: TPOINT's harmonic terms, generated from their names
  (``HACA2``, ``HESE5``, ``HESACE``, ``HSCA5CE8``, ``HZSZ2``), in both forms.
* :mod:`pointax.terms.polynomial`: TPOINT's polynomial terms (``PAA1``, ``PEE2``,
  ``PAA1E2``), generated from their names.
* :mod:`pointax.terms.repertoire`: which TPOINT names are built, and why the others
  (TX10, the other mount's terms, ...) raise :class:`NotYetInPointax`; auxiliary-reading terms
  (AUX1E, ZE, A3Z ...) are :mod:`pointax.terms.tpoint_auxiliary`.
* :mod:`pointax.terms.gpoint`: RTS2 gpoint's alt-az terms (ia ie tn te npae npoa tf),
  its German-equatorial terms (ih id ch np ma me tf fo daf)
  and its "extra" terms (``az:sincos:az;el:2;2``).
* :mod:`pointax.terms.sun_vector`: the sun-vector turntable model's five parameters.
* :mod:`pointax.terms.xy`: the level-mount (X-Y) paper's families: spherical-harmonic,
  basic, rotation-matrix (rigorous) and its linearised expansion.
* :mod:`pointax.terms.camera`: the sun-sensor camera's mounting on the mirror.
* :mod:`pointax.terms.heliostat_terms`: axis tilts and joint zeros of a tilt-tilt heliostat.
* :mod:`pointax.terms.varying`: any term's coefficients as functions of an auxiliary
  reading: ``thermal("TF")`` (linear in temperature), ``in_time("IA", reference=mjd)``
  (a polynomial, piecewise-linear or cubic B-spline in time).
* :class:`Term`, :func:`param`: the base class and field helper for new terms.

``tpoint("IA IE NPAE CA AN AW TF TX HACA2")``, ``gpoint_terms("ia,ie,tn,az:sin:az:2")``
and ``turntable("full")`` build terms by name.
"""

from ..core.lazy import lazy_namespace

_TPOINT_ALTAZ_NAMES = (
    "IA", "IE", "CA", "NPAE", "AN", "AW", "TF", "TX", "ACEC", "ACES", "ECEC", "ECES", "PAA1", "PEE1",
)  # fmt: skip
"""TPOINT's alt-az terms of :mod:`.tpoint_terms` (linear form) and :mod:`.rigorous` (the
same names as rotations), listed once here: those modules' ``__all__`` and name tables,
and ``_NAMES`` below, are built from it (this package reads it without importing them)."""

_TPOINT_EQUATORIAL_NAMES = ("IH", "ID", "CH", "NP", "MA", "ME", "FO", "DAF", "HCES", "HCEC", "DCES", "DCEC")
"""TPOINT's equatorial terms of :mod:`.equatorial` but TF (whose name is the alt-az TF's:
``pointax.terms.equatorial.TF``), listed once here as the alt-az names above."""

_NAMES = (
    "Term",
    "SkyPoint",
    "param",
    "param_fields",
    "param_unit",
    "LinearTerm",
    "tpoint",
    "names",
    "rigorous",
    "FORMS",
    "DEFAULT_FORM",
    "BASIC_ALTAZ",
    "BASIC_EQUATORIAL",
    "MOUNTS",
    "EQUATORIAL_LINEAR_TERMS",
    "EQUATORIAL_RIGOROUS_TERMS",
    "EQUATORIAL_FORMS",
    *_TPOINT_EQUATORIAL_NAMES,
    *_TPOINT_ALTAZ_NAMES,
    "NRX",
    "NRY",
    "CRX",
    "CRY",
    "FLOP",
    "TFP",
    "ANL",
    "AWL",
    "CAL",
    "NPAEL",
    "TXL",
    "LINEAR_TERMS",
    "NotYetInPointax",
    "Polynomial",
    "RigorousPolynomial",
    "polynomial_term",
    "parse_polynomial",
    "is_polynomial_name",
    "turntable",
    "sun_vector",
    "heliostat",
    "heliostat_terms",
    "xy",
    "camera",
    "CameraMounting",
    "Harmonic",
    "RigorousHarmonic",
    "harmonic_term",
    "parse_harmonic",
    "is_harmonic_name",
    "harmonic_library",
    "GpointTerm",
    "GpointExtra",
    "GPOINT_ALTAZ_TERMS",
    "GPOINT_GEM_TERMS",
    "GpointGemTerm",
    "gpoint_model_terms",
    "gpoint_extra",
    "gpoint_terms",
    "gpoint_names",
    "gpoint_library",
)

_SUBMODULES = (
    "camera", "equatorial", "equatorial_special", "gpoint", "harmonic", "heliostat_terms", "library", "polynomial",
    "repertoire", "rigorous", "sun_vector", "tpoint_special", "xy", "varying", "tpoint_auxiliary",
)  # fmt: skip

_VARYING = ("thermal", "in_time", "VaryingTerm", "Thermal", "InTime")
"""Loaded from :mod:`.varying` (not through :mod:`.library`)."""

# Every public name loads from :mod:`.library`, which imports the term modules: importing
# :mod:`pointax.core.term` (the term interface, as the core does) loads no particular term.
# ``heliostat`` and ``tpoint`` are the functions (their modules: ``heliostat_terms``,
# ``tpoint_terms``: no module is named like an exported name). The
# equatorial TF (its name is the alt-az TF's) is ``pointax.terms.equatorial.TF``.
_EXPORTS = {name: "library" for name in _NAMES if name not in _SUBMODULES}
_EXPORTS.update({name: "varying" for name in _VARYING})
_EXPORTS["auxiliary_term"] = "tpoint_auxiliary"  # TPOINT's AUX1H ... AUX2E, ZH, ZE, A1H ... A3Z
__getattr__, __dir__ = lazy_namespace(__name__, _EXPORTS, _SUBMODULES)

__all__ = list(_NAMES) + list(_VARYING) + ["auxiliary_term"]

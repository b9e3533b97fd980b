"""The error-term library.

* :mod:`pointax.terms.tpoint`: TPOINT's alt-az terms in TPOINT's linear form.
* :mod:`pointax.terms.rigorous`: the same terms as exact rotations.
* :mod:`pointax.terms.sun_vector`: the sun-vector turntable model's five parameters.
* :mod:`pointax.terms.heliostat`: axis tilts and joint zeros of a tilt-tilt heliostat.
* :class:`Term`, :func:`param`: the base class and field helper for new terms.

``tpoint("IA IE NPAE CA AN AW TF TX")`` and ``turntable("full")`` build terms by name.
"""

from __future__ import annotations

from collections.abc import Iterable

from . import heliostat as heliostat_terms
from . import rigorous, sun_vector
from .base import Term, param, param_fields, param_unit
from .heliostat import heliostat
from .tpoint import (
    ACEC,
    ACES,
    AN,
    AW,
    CA,
    ECEC,
    ECES,
    IA,
    IE,
    LINEAR_TERMS,
    NPAE,
    PAA1,
    PEE1,
    TF,
    TX,
    LinearTerm,
)

__all__ = [
    "Term",
    "param",
    "param_fields",
    "param_unit",
    "LinearTerm",
    "tpoint",
    "names",
    "rigorous",
    "FORMS",
    "BASIC_ALTAZ",
    "IA",
    "IE",
    "CA",
    "NPAE",
    "AN",
    "AW",
    "TF",
    "TX",
    "ACEC",
    "ACES",
    "ECEC",
    "ECES",
    "PAA1",
    "PEE1",
    "LINEAR_TERMS",
    "turntable",
    "sun_vector",
    "heliostat",
    "heliostat_terms",
]

FORMS = {"linear": LINEAR_TERMS, "rigorous": rigorous.RIGOROUS_TERMS}
"""Term form name -> {TPOINT name: term class}."""

BASIC_ALTAZ = ("IA", "IE", "NPAE", "CA", "AN", "AW", "TF", "TX")
"""TPOINT's eight basic alt-az terms."""


def names(spec: str | Iterable[str]) -> list[str]:
    """Split a term list given as 'IA IE CA', 'IA,IE,CA' or a sequence of names."""
    if isinstance(spec, str):
        spec = spec.replace(",", " ").split()
    return [s.strip().upper() for s in spec if s.strip()]


def tpoint(spec: str | Iterable[str] = BASIC_ALTAZ, form: str = "linear", values: dict | None = None) -> tuple[Term, ...]:
    """TPOINT terms by name, e.g. ``tpoint("IA IE NPAE CA AN AW TF TX")``.

    Args:
        spec: names separated by spaces or commas, or a sequence of names.
        form: 'linear' (TPOINT's own definitions, the default) or 'rigorous'
            (exact rotations, :mod:`pointax.terms.rigorous`).
        values: optional starting values in radians, by name.

    Raises:
        ValueError: for an unknown form or term name (the message lists the known ones).
    """
    if form not in FORMS:
        raise ValueError(f"unknown term form {form!r}; expected one of {sorted(FORMS)}")
    library = FORMS[form]
    values = dict(values or {})
    out = []
    for name in names(spec):
        if name not in library:
            raise ValueError(f"unknown TPOINT term {name!r}; known alt-az terms: {' '.join(library)}")
        out.append(library[name](coef=values.pop(name, 0.0)))
    if values:
        raise ValueError(f"values given for terms not in the list: {sorted(values)}")
    return tuple(out)


def turntable(spec: str | Iterable[str] = "full", values: dict | None = None) -> tuple[Term, ...]:
    """Terms of the sun-vector turntable model (:mod:`pointax.terms.sun_vector`).

    Args:
        spec: 'full' (the paper's five parameters mu0 nu0 omega0 alpha0 beta0),
            'simple' (its two-parameter model, alpha0 beta0), or parameter names
            separated by spaces or commas.
        values: optional starting values in radians, by parameter name.
    """
    library = sun_vector.TURNTABLE_TERMS
    if isinstance(spec, str) and spec in sun_vector.TURNTABLE_MODELS:
        chosen = sun_vector.TURNTABLE_MODELS[spec]
    else:
        chosen = spec.replace(",", " ").split() if isinstance(spec, str) else list(spec)
    values = dict(values or {})
    out = []
    for name in chosen:
        if name not in library:
            raise ValueError(
                f"unknown turntable parameter {name!r}; expected 'full', 'simple' or names from {' '.join(library)}"
            )
        out.append(library[name](values.pop(name, 0.0)))
    if values:
        raise ValueError(f"values given for parameters not in the list: {sorted(values)}")
    # Keep the paper's order of the chain whatever order the names came in.
    order = list(library)
    return tuple(sorted(out, key=lambda t: order.index(t.name)))

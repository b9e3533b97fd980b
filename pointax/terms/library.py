"""Building terms by name: :func:`tpoint`, :func:`gpoint_terms`, :func:`turntable` and
the name lists they read (re-exported by :mod:`pointax.terms`)."""


from __future__ import annotations

from collections.abc import Iterable

from . import _NAMES, camera, rigorous, sun_vector, xy
from . import gpoint as gpoint_library
from . import harmonic as harmonic_library
from . import heliostat as heliostat_terms
from .base import SkyPoint, Term, param, param_fields, param_unit
from .camera import CameraMounting
from .gpoint import GPOINT_ALTAZ_TERMS, GpointExtra, GpointTerm, gpoint_extra
from .harmonic import (
    Harmonic,
    RigorousHarmonic,
    harmonic_term,
    is_harmonic_name,
    parse_harmonic,
)
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

__all__ = list(_NAMES)  # listed once, in pointax/terms/__init__.py (read without importing this)

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
    """TPOINT terms by name, e.g. ``tpoint("IA IE NPAE CA AN AW TF TX HACA2 HESE5")``.

    Names starting with ``H`` are TPOINT's harmonic terms, generated from the name
    (:mod:`pointax.terms.harmonic`); the others are the named terms of
    :mod:`pointax.terms.tpoint`. Names are case-insensitive.

    Args:
        spec: names separated by spaces or commas, or a sequence of names.
        form: 'linear' (TPOINT's own definitions, the default) or 'rigorous'
            (exact rotations and encoder corrections, :mod:`pointax.terms.rigorous`,
            :class:`pointax.terms.harmonic.RigorousHarmonic`).
        values: optional starting values in radians, by (upper-case) name.

    Raises:
        ValueError: for an unknown form or term name (the message lists the known ones,
            or says which character of a harmonic name is wrong).
    """
    if form not in FORMS:
        raise ValueError(f"unknown term form {form!r}; expected one of {sorted(FORMS)}")
    library = FORMS[form]
    values = {k.upper() if isinstance(k, str) else k: v for k, v in (values or {}).items()}
    out = []
    for name in names(spec):
        if name in library:
            out.append(library[name](coef=values.pop(name, 0.0)))
        elif is_harmonic_name(name):
            out.append(harmonic_term(name, coef=values.pop(name, 0.0), form=form))
        else:
            raise ValueError(
                f"unknown TPOINT term {name!r}; known alt-az terms: {' '.join(library)}, "
                "and harmonic terms named H{A|E|S}{S|C}{A|E}[m][{S|C}{A|E}[m]] (e.g. HACA2, HSCA5CE8)"
            )
    if values:
        raise ValueError(f"values given for terms not in the list: {sorted(values)}")
    return tuple(out)


def gpoint_names(spec: str | Iterable[str]) -> list[str]:
    """The parameter names :func:`gpoint_terms` gives for ``spec``, in order: gpoint's
    names lower-case (``ia``), extras in canonical form (``az:sincos:az;el:2;2``),
    TPOINT names upper-case (``IA``). Use it to split a ``--fix`` list."""
    return gpoint_library.split_names(spec)


def gpoint_terms(spec: str | Iterable[str], form: str = "linear", values: dict | None = None) -> tuple[Term, ...]:
    """Terms named as RTS2 gpoint names them, mixed with TPOINT's names.

    * gpoint's alt-az terms, written lower-case as gpoint writes them: ``ia ie tn te
      npae npoa tf`` (:class:`pointax.terms.gpoint.GpointTerm`);
    * gpoint's extra terms, ``axis:function:variables:multipliers`` (e.g.
      ``az:sincos:az;el:2;2`` = coef sin(2 az) cos(2 el) on azimuth;
      :func:`pointax.terms.gpoint.gpoint_extra`);
    * any other name is a TPOINT name (:func:`tpoint`, case-insensitive), so ``IA``,
      ``CA`` and ``HACA2`` are TPOINT's and ``ia`` is gpoint's.

    gpoint terms are defined on the azimuth as gpoint counts it, from South through
    West: use them in ``pointax.AltAz(terms, azimuth="S-W")`` (``run.azimuth`` of a run
    read by :func:`pointax.io.read_gpoint`).

    Args:
        spec: names separated by commas or spaces, or a sequence of names.
        form: the form of the TPOINT terms ('linear' or 'rigorous'); gpoint's terms
            are always exactly gpoint's formulas.
        values: optional starting values in radians, by the names of
            :func:`gpoint_names`.

    Raises:
        ValueError: for an unknown name or a malformed extra (the message says which).
    """
    tpoint([], form=form)  # an unknown form raises even when no TPOINT name is given
    values = dict(values or {})
    out = []
    for token in gpoint_library.split_tokens(spec):
        kind, name = gpoint_library.classify(token)
        coef = values.pop(name, 0.0)
        if kind == "tpoint":
            out.extend(tpoint([name], form=form, values={name: coef}))
        else:
            out.append(gpoint_library.gpoint_term(token, coef=coef))
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

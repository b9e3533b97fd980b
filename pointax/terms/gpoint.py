"""RTS2 gpoint's pointing terms (alt-az and German equatorial) and its "extra" terms,
exactly as gpoint defines them.

Source, taken as the definition: RTS2's ``python/rts2/gpoint.py`` (repository
``RTS2/rts2``, commit ``6480a7eb549d3158ee178ce557fab6d75de8eba9``), functions
``GPoint.model_az_hadec``, ``GPoint.model_el_hadec``, ``GPoint.model_ha``,
``GPoint.model_dec``, ``GPoint.cal_extra``, ``GPoint.get_extra_val``,
``GPoint.equ_to_hrz`` and ``GPoint.add_extra_multi``; the ``--extra`` option of
``scripts/gpoint`` (same repository) splits an extra on ``:`` into four fields.

The terms, one module per job, all re-exported here (the public module):

* :mod:`pointax.terms.gpoint_altaz`: the alt-az terms ``ia ie tn te npae npoa tf``
  (:class:`GpointTerm`), gpoint's model and azimuth convention, their TPOINT equivalents;
* :mod:`pointax.terms.gpoint_gem`: the German-equatorial terms ``ih id ch np ma me tf fo
  daf`` (:class:`GpointGemTerm`), gpoint's GEM model, their TPOINT equivalents;
* :mod:`pointax.terms.gpoint_extras`: the extra terms ``axis:function:variables:multipliers``
  (:class:`GpointExtra`) and their spec.

This module holds the names: the model lines' term lists (:data:`GPOINT_ALTAZ_TERMS`,
:data:`GPOINT_GEM_TERMS`), the mount check, and the functions that build terms from their
names (:func:`gpoint_term`, :func:`gpoint_extra`, :func:`gpoint_model_terms`,
:func:`classify`, :func:`split_names`). For mixing TPOINT's names in, see
:func:`pointax.terms.gpoint_terms`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from . import gpoint_altaz, gpoint_extras, gpoint_gem
from ..core.term import Term
from .gpoint_altaz import (
    GPOINT_TERMS,
    GpointIA,
    GpointIE,
    GpointNPAE,
    GpointNPOA,
    GpointTE,
    GpointTerm,
    GpointTF,
    GpointTN,
)
from .gpoint_extras import GPOINT_FUNCTIONS, GpointExtra, parse_extra
from .gpoint_gem import (
    GPOINT_GEM_TERM_CLASSES,
    GpointCH,
    GpointDAF,
    GpointFO,
    GpointGemTerm,
    GpointGemTF,
    GpointID,
    GpointIH,
    GpointMA,
    GpointME,
    GpointNP,
    gem_horizontal,
)

__all__ = [
    "GPOINT_SOURCE",
    "GPOINT_ALTAZ_TERMS",
    "GPOINT_GEM_TERMS",
    "GPOINT_MOUNTS",
    "check_gpoint_mount",
    "gpoint_extra",
    "gpoint_term",
    "gpoint_model_terms",
    "split_tokens",
    "classify",
    "split_names",
    *gpoint_altaz.__all__,
    *gpoint_gem.__all__,
    *gpoint_extras.__all__,
]

GPOINT_SOURCE = ("RTS2/rts2", "python/rts2/gpoint.py", "6480a7eb549d3158ee178ce557fab6d75de8eba9")
"""(repository, path, commit) of the gpoint source these definitions follow."""

GPOINT_ALTAZ_TERMS = ("ia", "tn", "te", "npae", "npoa", "ie", "tf")
"""gpoint's alt-az terms, in the order of its ``RTS2_ALTAZ`` model line (``_altaz_params``)."""

GPOINT_GEM_TERMS = ("id", "me", "ma", "tf", "ih", "ch", "np", "daf", "fo")
"""gpoint's German-equatorial terms, in the order of its ``RTS2_GEM`` model line
(``_gem_params``)."""

GPOINT_MOUNTS = ("altaz", "gem")
"""gpoint's two models: ``"altaz"`` (terms on azimuth, elevation) and ``"gem"`` (German
equatorial: terms on hour angle, declination)."""


def check_gpoint_mount(mount: str) -> str:
    """``"altaz"`` or ``"gem"``, checked; ``"equatorial"`` (pointax's name for the mount) is
    taken as ``"gem"``.

    Raises:
        ValueError: for another name.
    """
    if mount == "equatorial":
        return "gem"
    if mount not in GPOINT_MOUNTS:
        raise ValueError(f"unknown gpoint model {mount!r}; expected 'altaz' or 'gem' (German equatorial)")
    return mount


def _check_latitude(latitude, what: str) -> float:
    """The latitude as a Python float (radians), refused when it cannot be one."""
    try:
        value = float(latitude)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: latitude must be one number in radians, got {latitude!r}") from None
    if not (math.isfinite(value) and abs(value) <= math.pi / 2 + 1e-12):
        raise ValueError(
            f"{what}: latitude {value!r} rad is not within [-pi/2, pi/2] (give it in radians: pointax.deg(latitude_deg))"
        )
    return value



def gpoint_extra(spec: str, coef: float = 0.0, latitude: float | None = None, mount: str | None = None) -> GpointExtra:
    """A gpoint extra term from its spec ``axis:function:variables:multipliers``, e.g.
    ``gpoint_extra("az:sincos:az;el:2;2")`` or ``gpoint_extra("ha:sin:dec:2")``; ``coef``
    in radians.

    Args:
        spec: the spec (gpoint's ``--extra``).
        coef: starting value, radians.
        latitude: radians; required by a GEM (ha/dec) extra with ``az``, ``el`` or ``zd``
            among its variables.
        mount: ``"altaz"`` or ``"gem"`` to require the model's axes; None: the axis says.

    Raises:
        ValueError: naming the field that is wrong.
    """
    if mount is not None:
        mount = check_gpoint_mount(mount)
    axis, function, names, numbers = parse_extra(spec, mount)
    term = GpointExtra(coef=coef, axis=axis, function=function, variables=names, multipliers=numbers)
    if latitude is not None:
        term = GpointExtra(coef=coef, axis=axis, function=function, variables=names, multipliers=numbers,
                           latitude=_check_latitude(latitude, f"gpoint extra term {spec!r}"))
    elif term.uses_latitude:
        raise ValueError(
            f"gpoint extra term {spec!r}: its variables {';'.join(names)} are gpoint's equ_to_hrz of the GEM reading, "
            "which needs the site's latitude: pass latitude= (radians)"
        )
    return term



def split_tokens(spec: str | Iterable[str]) -> list[str]:
    """Split a term list given as ``"ia,ie,az:sin:az:2"`` (commas or spaces) or a
    sequence of names, keeping each name's case."""
    if isinstance(spec, str):
        spec = spec.replace(",", " ").split()
    return [s.strip() for s in spec if s.strip()]


def classify(token: str, mount: str = "altaz") -> tuple[str, str]:
    """``(kind, name)`` of one term name in a ``mount`` model (``"altaz"`` or ``"gem"``):
    kind ``"gpoint"`` for gpoint's lower-case names of that model, ``"extra"`` for
    ``axis:function:...`` specs (name = canonical spec), ``"tpoint"`` otherwise (name
    upper-case).

    Raises:
        ValueError: for gpoint's lower-case name of the other model (``ma`` in an alt-az
            model, ``ia`` in a GEM one) or an extra on the other model's axes.
    """
    mount = check_gpoint_mount(mount)
    own = GPOINT_TERMS if mount == "altaz" else GPOINT_GEM_TERM_CLASSES
    other = GPOINT_GEM_TERM_CLASSES if mount == "altaz" else GPOINT_TERMS
    if token in own:
        return "gpoint", token
    if token in other:
        kind, others = ("GEM", "gem") if mount == "altaz" else ("alt-az", "altaz")
        names = GPOINT_ALTAZ_TERMS if mount == "altaz" else GPOINT_GEM_TERMS
        raise ValueError(
            f"{token!r} is gpoint's {kind} term, not a term of a gpoint {mount} model (whose terms are "
            f"{' '.join(names)}); it belongs in {'a GEM' if kind == 'GEM' else 'an alt-az'} model (mount={others!r})"
        )
    if ":" in token:
        axis, function, names, numbers = parse_extra(token, mount)
        return "extra", GpointExtra(axis=axis, function=function, variables=names, multipliers=numbers).name
    return "tpoint", token.upper()


def split_names(spec: str | Iterable[str], mount: str = "altaz") -> list[str]:
    """Parameter names of the terms in ``spec`` (see :func:`classify`)."""
    mount = check_gpoint_mount(mount)
    return [classify(token, mount)[1] for token in split_tokens(spec)]


def gpoint_term(token: str, coef: float = 0.0, mount: str = "altaz", latitude: float | None = None) -> Term:
    """gpoint's term called ``token`` in a ``mount`` model, ``coef`` in radians.

    Args:
        token: ``ia ie tn te npae npoa tf`` (alt-az), ``ih id ch np ma me tf fo daf``
            (GEM), or an extra spec ``axis:function:variables:multipliers``.
        coef: starting value, radians.
        mount: ``"altaz"`` (default) or ``"gem"``; ``tf`` differs between them.
        latitude: radians; required by GEM ``tf`` and ``daf`` and by GEM extras of
            ``az``, ``el`` or ``zd``; checked for range.

    Raises:
        ValueError: for a name that is none of these.
    """
    mount = check_gpoint_mount(mount)
    lat = None if latitude is None else _check_latitude(latitude, f"gpoint term {token!r}")
    if mount == "altaz" and token in GPOINT_TERMS:
        return GPOINT_TERMS[token](coef=coef)
    if mount == "gem" and token in GPOINT_GEM_TERM_CLASSES:
        return GPOINT_GEM_TERM_CLASSES[token](coef=coef, latitude=lat)
    if ":" in token:
        return gpoint_extra(token, coef, latitude=lat, mount=mount)
    kind = classify(token, mount)[0]  # raises for the other model's names
    names = GPOINT_ALTAZ_TERMS if mount == "altaz" else GPOINT_GEM_TERMS
    raise ValueError(
        f"unknown gpoint term {token!r} ({kind} name); gpoint's {mount} terms are {' '.join(names)} (lower-case), "
        "extras are axis:function:variables:multipliers"
    )


def gpoint_model_terms(
    spec: str | Iterable[str], mount: str = "altaz", latitude: float | None = None, values: dict | None = None
) -> tuple[Term, ...]:
    """gpoint's own terms only (no TPOINT names), as a gpoint model file holds them: e.g.
    ``gpoint_model_terms("ih id ch np ma me tf fo daf ha:sin:dec:2", "gem", latitude=lat)``.

    ``values`` by parameter name (radians). For mixing TPOINT's names in, see
    :func:`pointax.terms.gpoint_terms`.

    Raises:
        ValueError: for a name that is not gpoint's, a repeated name, or values of terms
            not in the list.
    """
    mount = check_gpoint_mount(mount)
    values = dict(values or {})
    out, seen = [], set()
    for token in split_tokens(spec):
        kind, name = classify(token, mount)
        if kind == "tpoint":
            names = GPOINT_ALTAZ_TERMS if mount == "altaz" else GPOINT_GEM_TERMS
            raise ValueError(f"{token!r} is not a gpoint {mount} term ({' '.join(names)} or an extra)")
        if name in seen:
            raise ValueError(f"gpoint term {name!r} is given twice")
        seen.add(name)
        out.append(gpoint_term(token, coef=values.pop(name, 0.0), mount=mount, latitude=latitude))
    if values:
        raise ValueError(f"values given for terms not in the list: {sorted(values)}")
    return tuple(out)

"""Building terms by name: :func:`tpoint`, :func:`gpoint_terms`, :func:`turntable` and
the name lists they read (re-exported by :mod:`pointax.terms`)."""


from __future__ import annotations

import importlib
from collections.abc import Iterable, Iterator, Mapping

from . import _NAMES
from ..core.term import SkyPoint, Term, param, param_fields, param_unit
from .harmonic import (
    Harmonic,
    RigorousHarmonic,
    harmonic_term,
    is_harmonic_name,
    parse_harmonic,
)
from .polynomial import Polynomial, RigorousPolynomial, is_polynomial_name, parse_polynomial, polynomial_term
from ..core.units import check_pointing_term, is_quantity
from .repertoire import not_yet_error, not_yet_reason
from .tpoint_auxiliary import auxiliary_term, is_auxiliary_name
from .tpoint_terms import (
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
    NotYetInPointax,
    PAA1,
    PEE1,
    TF,
    TX,
    LinearTerm,
)
from .tpoint_special import ANL, AWL, CAL, CRX, CRY, FLOP, NPAEL, NRX, NRY, TFP, TXL

harmonic_library = importlib.import_module(".harmonic", __package__)

# The equatorial, gpoint, sun-vector, X-Y, camera and heliostat terms load on first use
# (PEP 562): building the alt-az terms of a ``pointax fit`` does not create their
# classes, a noticeable part of every such process's start. Name -> (module, attribute; None: the module).
_ON_FIRST_USE = {
    **{
        name: ("equatorial", name)
        for name in (
            "BASIC_EQUATORIAL", "CH", "DAF", "DCEC", "DCES", "EQUATORIAL_FORMS", "EQUATORIAL_LINEAR_TERMS",
            "EQUATORIAL_RIGOROUS_TERMS", "FO", "HCEC", "HCES", "ID", "IH", "MA", "ME", "NP",
        )
    },
    **{
        name: ("gpoint", name)
        for name in (
            "GPOINT_ALTAZ_TERMS", "GPOINT_GEM_TERMS", "GpointExtra", "GpointGemTerm", "GpointTerm", "gpoint_extra",
            "gpoint_model_terms",
        )
    },
    "equatorial": ("equatorial", None),
    "rigorous": ("rigorous", None),
    "gpoint_library": ("gpoint", None),
    "sun_vector": ("sun_vector", None),
    "xy": ("xy", None),
    "camera": ("camera", None),
    "CameraMounting": ("camera", "CameraMounting"),
    "heliostat_terms": ("heliostat_terms", None),
    "heliostat": ("heliostat_terms", "heliostat"),
}  # fmt: skip


def __getattr__(name: str):
    if name not in _ON_FIRST_USE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module, attribute = _ON_FIRST_USE[name]
    value = importlib.import_module(f".{module}", __package__)
    value = value if attribute is None else getattr(value, attribute)
    globals()[name] = value
    return value


__all__ = list(_NAMES)  # listed once, in pointax/terms/__init__.py (read without importing this)

class _Forms(Mapping):
    """Term form name -> {TPOINT name: term class}; the rigorous classes load on first use."""

    def __getitem__(self, form: str) -> dict:
        if form == "linear":
            return LINEAR_TERMS
        if form == "rigorous":
            from .rigorous import RIGOROUS_TERMS

            return RIGOROUS_TERMS
        raise KeyError(form)

    def __iter__(self) -> Iterator[str]:
        return iter(("linear", "rigorous"))

    def __len__(self) -> int:
        return 2


FORMS: Mapping[str, dict] = _Forms()
"""Term form name -> {TPOINT name: term class}."""

DEFAULT_FORM = "rigorous"
"""The term form used when none is named: the model applied as TPOINT applies it (exact
rotations and encoder corrections), which reproduces TPOINT's fitted values on every
real run with a TPOINT model file (``tests/test_conformance.py``; the figures are in
``benchmarks/tpoint_conformance_notes.md``). ``form="linear"`` keeps TPOINT's formulas
as first-order offsets at the sky position."""

BASIC_ALTAZ = ("IA", "IE", "NPAE", "CA", "AN", "AW", "TF", "TX")
"""TPOINT's eight basic alt-az terms."""


def names(spec: str | Iterable[str]) -> list[str]:
    """Split a term list given as 'IA IE CA', 'IA,IE,CA' or a sequence of names."""
    if isinstance(spec, str):
        spec = spec.replace(",", " ").split()
    return [s.strip().upper() for s in spec if s.strip()]


MOUNTS = ("altaz", "equatorial")
"""Mounts :func:`tpoint` builds terms for."""


def tpoint(
    spec: str | Iterable[str] | None = None,
    form: str = DEFAULT_FORM,
    values: dict | None = None,
    mount: str = "altaz",
    latitude: float | None = None,
) -> tuple[Term, ...]:
    """TPOINT terms by name, e.g. ``tpoint("IA IE NPAE CA AN AW TF TX HACA2 HESE5")`` or
    ``tpoint("IH ID CH NP MA ME TF HHSH", mount="equatorial", latitude=px.deg(33.4))``.

    Named terms are those of :mod:`pointax.terms.tpoint_terms` and
    :mod:`pointax.terms.tpoint_special` (alt-az) or :mod:`pointax.terms.equatorial` and
    :mod:`pointax.terms.equatorial_special`; other names starting with ``H`` are TPOINT's
    harmonic terms (:mod:`pointax.terms.harmonic`), with ``P`` its polynomial terms
    (:mod:`pointax.terms.polynomial`), generated from the name. Names are
    case-insensitive. :mod:`pointax.terms.repertoire` lists what is built and what not.

    Args:
        spec: names separated by spaces or commas, or a sequence of names (default:
            TPOINT's basic terms of the mount, :data:`BASIC_ALTAZ` or
            :data:`BASIC_EQUATORIAL`).
        form: 'rigorous' (the default, :data:`DEFAULT_FORM`: exact rotations and
            encoder corrections, :mod:`pointax.terms.rigorous`,
            :class:`pointax.terms.harmonic.RigorousHarmonic`, the model applied as
            TPOINT applies it) or 'linear' (TPOINT's formulas as first-order offsets
            at the sky position: the same to first order, off by up to 0.06" where
            corrections reach tens of arcseconds). Terms with no rigorous form are
            the same in both.
        values: optional starting values in radians, by (upper-case) name.
        mount: 'altaz' (default) or 'equatorial': the same name may mean different
            terms on the two (TF).
        latitude: the site's latitude in radians, for the equatorial terms that need it
            (TF, DAF: :data:`pointax.terms.equatorial.NEEDS_LATITUDE`); use the value
            given to ``pointax.Equatorial``. Not used by alt-az terms.

    Raises:
        NotYetInPointax: (a ``ValueError``) for a name that is TPOINT's but that pointax
            cannot build yet (TX10, the other mount's terms (auxiliary ones included) and
            coordinates, the parallactic angle); the message says why.
        ValueError: for an unknown form, mount or term name (the message lists the
            known ones, or says which character of a harmonic or polynomial name is
            wrong), or an equatorial term that needs ``latitude`` when none is given.
    """
    if mount not in MOUNTS:
        raise ValueError(f"unknown mount {mount!r}; expected one of {list(MOUNTS)}")
    equatorial_mount = mount == "equatorial"
    if equatorial_mount:
        from . import equatorial
    forms = equatorial.EQUATORIAL_FORMS if equatorial_mount else FORMS
    if form not in forms:
        raise ValueError(f"unknown term form {form!r}; expected one of {sorted(forms)}")
    if spec is None:
        spec = equatorial.BASIC_EQUATORIAL if equatorial_mount else BASIC_ALTAZ
    library = forms[form]
    values = {k.upper() if isinstance(k, str) else k: v for k, v in (values or {}).items()}
    wanted = names(spec)
    unused = sorted(set(values) - set(wanted), key=str)
    if unused:  # before the values' units: a value for no term is refused, not warned of
        raise ValueError(f"values given for terms not in the list: {unused}")
    for key, value in values.items():  # radians assumed: a value in arcsec or degrees is named here
        if not is_quantity(value):
            check_pointing_term(value, str(key))
    out = []
    for name in wanted:
        if name in library:
            kwargs = {}
            if equatorial_mount and name in equatorial.NEEDS_LATITUDE:
                if latitude is None:
                    raise ValueError(
                        f"equatorial term {name} needs the site's latitude: "
                        "pointax.terms.tpoint(..., mount='equatorial', latitude=<radians>), "
                        "the value given to pointax.Equatorial"
                    )
                kwargs["latitude"] = float(latitude)
            out.append(library[name](coef=values.pop(name, 0.0), **kwargs))
        elif is_auxiliary_name(name):  # TPOINT's auxiliary-reading terms (AUX1E, ZE, A3Z ...)
            out.append(auxiliary_term(name, coef=values.pop(name, 0.0), mount=mount))
        elif (reason := not_yet_reason(name, mount)) is not None:
            raise not_yet_error(name, reason)
        elif is_harmonic_name(name):
            out.append(harmonic_term(name, coef=values.pop(name, 0.0), form=form, mount=mount))
        elif is_polynomial_name(name):
            out.append(polynomial_term(name, coef=values.pop(name, 0.0), form=form, mount=mount))
        elif equatorial_mount:
            raise ValueError(
                f"unknown TPOINT equatorial term {name!r}; known equatorial terms: {' '.join(library)}, "
                "harmonic terms named H{H|D|X}{S|C}{H|D}[m][{S|C}{H|D}[m]] (e.g. HHSH, HDCD2, HXSH2CD) "
                "and polynomial terms named P{H|D|X}{H|D}[n][{H|D}[n]] (e.g. PHH1, PDD2)"
            )
        else:
            raise ValueError(
                f"unknown TPOINT term {name!r}; known alt-az terms: {' '.join(library)}, "
                "harmonic terms named H{A|E|S|Z}{S|C}{A|E|Z}[m][{S|C}{A|E|Z}[m]] (e.g. HACA2, HSCA5CE8) "
                "and polynomial terms named P{A|E|S|Z}{A|E|Z}[n][{A|E|Z}[n]] (e.g. PAA1, PEE2, PAA1E2)"
            )
    return tuple(out)


def gpoint_names(spec: str | Iterable[str], mount: str = "altaz") -> list[str]:
    """The parameter names :func:`gpoint_terms` gives for ``spec``, in order: gpoint's
    names lower-case (``ia``), extras in canonical form (``az:sincos:az;el:2;2``),
    TPOINT names upper-case (``IA``). Use it to split a ``--fix`` list. ``mount``:
    'altaz' or 'gem', as :func:`gpoint_terms`."""
    from . import gpoint as gpoint_library

    return gpoint_library.split_names(spec, mount)


def gpoint_terms(
    spec: str | Iterable[str],
    form: str = DEFAULT_FORM,
    values: dict | None = None,
    mount: str = "altaz",
    latitude: float | None = None,
) -> tuple[Term, ...]:
    """Terms named as RTS2 gpoint names them, mixed with TPOINT's names.

    * gpoint's alt-az terms, written lower-case as gpoint writes them: ``ia ie tn te
      npae npoa tf`` (:class:`pointax.terms.gpoint.GpointTerm`); with ``mount='gem'``
      its German-equatorial terms ``ih id ch np ma me tf fo daf``
      (:class:`pointax.terms.gpoint.GpointGemTerm`);
    * gpoint's extra terms, ``axis:function:variables:multipliers`` (e.g.
      ``az:sincos:az;el:2;2`` = coef sin(2 az) cos(2 el) on azimuth, ``ha:...`` and
      ``dec:...`` on a GEM; :func:`pointax.terms.gpoint.gpoint_extra`);
    * any other name is a TPOINT name (:func:`tpoint`, case-insensitive; equatorial
      names on a GEM), so ``IA``, ``CA`` and ``HACA2`` are TPOINT's and ``ia`` is
      gpoint's.

    gpoint's alt-az terms are defined on the azimuth as gpoint counts it, from South
    through West: use them in ``pointax.AltAz(terms, azimuth="S-W")`` (``run.azimuth``
    of a run read by :func:`pointax.io.read_gpoint`); its GEM terms in
    ``pointax.Equatorial(terms, latitude=run.latitude)``.

    Args:
        spec: names separated by commas or spaces, or a sequence of names.
        form: the form of the TPOINT terms ('rigorous', the default, or 'linear'); gpoint's terms
            are always exactly gpoint's formulas.
        values: optional starting values in radians, by the names of
            :func:`gpoint_names`.
        mount: 'altaz' (default) or 'gem' ('equatorial' is taken as 'gem').
        latitude: radians: for GEM ``tf``, ``daf``, extras of az/el/zd and TPOINT's
            TF and DAF.

    Raises:
        ValueError: for an unknown name or a malformed extra (the message says which).
    """
    from . import gpoint as gpoint_library

    gmount = gpoint_library.check_gpoint_mount(mount)
    where = {} if gmount == "altaz" else {"mount": "equatorial", "latitude": latitude}
    tpoint([], form=form, **where)  # an unknown form raises even when no TPOINT name is given
    values = dict(values or {})
    out = []
    for token in gpoint_library.split_tokens(spec):
        kind, name = gpoint_library.classify(token, gmount)
        coef = values.pop(name, 0.0)
        if kind == "tpoint":
            out.extend(tpoint([name], form=form, values={name: coef}, **where))
        else:
            out.append(gpoint_library.gpoint_term(token, coef=coef, mount=gmount, latitude=latitude))
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
    from . import sun_vector

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

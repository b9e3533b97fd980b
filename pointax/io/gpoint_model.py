"""RTS2 gpoint's model files (``RTS2_ALTAZ``, ``RTS2_GEM``): :func:`format_gpoint_model`,
:func:`write_gpoint_model`, :func:`read_gpoint_model`. gpoint's run files are
:mod:`pointax.io.gpoint`.

The definition is gpoint's model writer and reader, ``GPoint.to_string``,
``GPoint.save`` and ``GPoint.load`` in RTS2's ``python/rts2/gpoint.py`` (repository
``RTS2/rts2``, commit ``6480a7eb549d3158ee178ce557fab6d75de8eba9``; ``gpoint -o FILE``
calls ``save``). The file is what ``gpoint -o FILE`` writes (``GPoint.save`` writes
``str(self)``, i.e. ``to_string()`` in arcseconds), byte for byte::

    RTS2_GEM <id>" <me>" <ma>" <tf>" <ih>" <ch>" <np>" <daf>" <fo>"
    HA<TAB><value>"<TAB><function><TAB><variables ;-joined><TAB><multipliers ;-joined>

(``RTS2_ALTAZ <ia>" <tn>" <te>" <npae>" <npoa>" <ie>" <tf>"`` for alt-az; one line per
extra term, axis upper-case; no newline after the last line). Each value is
``str(numpy.degrees(value) * 3600.0)``, the shortest text that reads back to the same
double in arcseconds; multipliers are written ``str(float(m))`` (``2.0``). gpoint's
reader (``GPoint.load``) takes ``RTS2_MODEL`` or ``RTS2_GEM`` with 9 values,
``RTS2_ALTAZ`` with 7, 5-field extra lines and ``#`` comments; a value is radians unless
it ends in ``d`` (degrees), ``'`` or ``m`` (arcminutes), ``"`` or ``s`` (arcseconds).
The file holds no latitude (RTS2 takes it from the telescope's configuration).
pointax's reader also skips blank lines (gpoint's would stop at one) and reads the
function name in any case (as RTS2's C++ loader does; gpoint's own needs lower case).

RTS2's telescope drivers load the file with C++ (``GPointModel::load`` in RTS2's
``lib/rts2tel/gpointmodel.cpp``), which reads the same layout (``RTS2_GEM`` as a GEM
model, ``readDeg`` with the same unit suffixes) but needs the model line before any
extra line, and evaluates three extra functions differently from gpoint's fit: its
``csc`` divides by the cosine and ``sec`` by the sine (swapped), and its ``sinsin``
leaves out the coefficient. A model with such extras does not point in RTS2 as gpoint
(and pointax) fitted it; that is RTS2's, not the file's, concern here.

Every error is a :class:`GpointFormatError` naming the file, line and field.
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path

import numpy as np

from ..terms.gpoint import (
    GPOINT_ALTAZ_TERMS,
    GPOINT_GEM_TERMS,
    GpointExtra,
    GpointGemTerm,
    GpointTerm,
    gpoint_model_terms,
    parse_extra,
)
from .gpoint_conventions import GPOINT_AZIMUTH, GpointFormatError
from .errors import file_errors
from ..core.units import ARCSEC, POINTING_TERM_LIMIT
from .text import read_text

__all__ = [
    "GpointModelFile",
    "format_gpoint_model",
    "write_gpoint_model",
    "read_gpoint_model",
    "parse_gpoint_model",
]

_MODEL_KEYWORDS = {"RTS2_MODEL": "gem", "RTS2_GEM": "gem", "RTS2_ALTAZ": "altaz"}
_BASE_NAMES = {"altaz": GPOINT_ALTAZ_TERMS, "gem": GPOINT_GEM_TERMS}
_WRITTEN_KEYWORD = {"altaz": "RTS2_ALTAZ", "gem": "RTS2_GEM"}


def _gpoint_number(x) -> str:
    """gpoint's text of a value in radians: ``str(numpy.degrees(x) * 3600.0)`` (arcseconds)."""
    return str(np.degrees(np.float64(float(x))) * 3600.0)


def _model_of(source):
    from ..fitting import FitResult

    return source.model if isinstance(source, FitResult) else source


def format_gpoint_model(source) -> str:
    """The text ``gpoint -o`` writes for a model of gpoint's terms (see
    :mod:`pointax.io.gpoint_model`): ``RTS2_ALTAZ`` for an alt-az model (azimuth ``"S-W"``),
    ``RTS2_GEM`` for an equatorial one, then one line per extra term, values in
    arcseconds, no newline at the end. Base terms the model lacks are written as 0, as
    gpoint fits and writes all of them.

    Args:
        source: a :class:`pointax.Model` or :class:`pointax.FitResult` whose terms are
            all gpoint's terms of its mount (:mod:`pointax.terms.gpoint`).

    Raises:
        ValueError: naming the term gpoint's file cannot hold (a TPOINT term, a term of
            the other mount, a repeated term), a mount gpoint has no model for, an
            alt-az model whose azimuth is not counted from South through West, or a GEM
            term whose latitude is not the model's.
    """
    from ..core.mounts import AltAzMount, EquatorialMount

    model = _model_of(source)
    mount = model.mount
    if isinstance(mount, EquatorialMount):
        kind, base_class = "gem", GpointGemTerm
        latitude = float(np.asarray(mount.latitude))
    elif isinstance(mount, AltAzMount):
        kind, base_class, latitude = "altaz", GpointTerm, None
        if mount.azimuth != GPOINT_AZIMUTH:
            raise ValueError(
                f"gpoint's alt-az terms are defined on the azimuth counted from South through West; this model "
                f"counts it {mount.azimuth!r}: build it with pointax.AltAz(terms, azimuth='S-W')"
            )
    else:
        raise ValueError(
            f"gpoint's model files hold alt-az (RTS2_ALTAZ) and German-equatorial (RTS2_GEM) models; this model's "
            f"mount is {type(mount).__name__}"
        )
    base_names = _BASE_NAMES[kind]
    values: dict[str, float] = {}
    extras: list[GpointExtra] = []
    seen: set[str] = set()
    for term in model.terms:
        ok = isinstance(term, base_class) or (isinstance(term, GpointExtra) and term.gpoint_mount == kind)
        if not ok:
            raise ValueError(
                f"term {term.name} ({type(term).__name__}) cannot be written to a gpoint model file: it holds only "
                f"gpoint's {kind} terms ({' '.join(base_names)} and {'ha/dec' if kind == 'gem' else 'az/el'} extras)"
            )
        if term.name in seen:
            raise ValueError(f"term {term.name} appears twice in the model; gpoint's model file holds it once")
        seen.add(term.name)
        if kind == "gem" and getattr(term, "uses_latitude", False) and term.latitude is not None:
            if abs(float(term.latitude) - latitude) > 1e-12:
                raise ValueError(
                    f"term {term.name} was built for latitude {math.degrees(term.latitude):.9g} deg, the model's "
                    f"mount is at {math.degrees(latitude):.9g} deg"
                )
        if isinstance(term, GpointExtra):
            extras.append(term)
        else:
            values[term.name] = term.coef
    out = _WRITTEN_KEYWORD[kind] + " " + '" '.join(_gpoint_number(values.get(n, 0.0)) for n in base_names) + '"'
    for e in extras:
        # gpoint: '\n{0}\t{1}"\t{2}'.format(e.axis.upper(), value, e) with
        # str(e) = '{function}\t{params ;-joined}\t{consts ;-joined}' and consts floats.
        out += '\n{0}\t{1}"\t{2}\t{3}\t{4}'.format(
            e.axis.upper(),
            _gpoint_number(e.coef),
            e.function,
            ";".join(e.variables),
            ";".join(str(float(m)) for m in e.multipliers),
        )
    return out


def write_gpoint_model(path: str | os.PathLike, source) -> None:
    """Write the model file ``gpoint -o`` writes (:func:`format_gpoint_model`) to ``path``.

    Nothing is written when the model cannot be (ValueError, see
    :func:`format_gpoint_model`)."""
    text = format_gpoint_model(source)
    Path(os.fspath(path)).write_text(text, encoding="utf-8")


@dataclasses.dataclass(frozen=True)
class GpointModelFile:
    """A gpoint model file as read (:func:`read_gpoint_model`).

    Values are radians, as gpoint holds them after ``GPoint.load``. The file has no
    latitude: give it to :meth:`terms` / :meth:`model` for a GEM model.
    """

    path: str
    keyword: str
    """``"RTS2_ALTAZ"``, ``"RTS2_GEM"`` or ``"RTS2_MODEL"`` (gpoint reads the last two alike)."""
    mount: str
    """``"altaz"`` or ``"gem"``."""
    values: dict
    """Base terms by gpoint name, in the file's order, radians."""
    extras: tuple
    """``(spec, value)`` per extra line, in the file's order: the canonical spec
    (``ha:sin:dec:2``) and the value in radians."""
    lines: dict
    """Line number of each parameter, by name."""

    @property
    def names(self) -> list[str]:
        """Parameter names: the base terms, then the extras' specs."""
        return list(self.values) + [spec for spec, _ in self.extras]

    def terms(self, latitude: float | None = None) -> tuple:
        """The model's terms with the file's values (:mod:`pointax.terms.gpoint`);
        ``latitude`` (radians) is required for a GEM model."""
        if self.mount == "gem" and latitude is None:
            raise ValueError(f"{self.path}: a GEM model file holds no latitude; give latitude= (radians)")
        values = dict(self.values)
        values.update(dict(self.extras))
        return gpoint_model_terms(self.names, self.mount, latitude=latitude, values=values)

    def model(self, latitude: float | None = None):
        """A :class:`pointax.Model`: ``pointax.AltAz(terms, azimuth="S-W")`` or
        ``pointax.Equatorial(terms, latitude=latitude)``."""
        from ..terms.model_factories import AltAz, Equatorial

        terms = self.terms(latitude)
        if self.mount == "altaz":
            return AltAz(terms, azimuth=GPOINT_AZIMUTH)
        return Equatorial(terms, latitude=latitude)


def _model_value(path: str, lineno: int, token: str, what: str) -> float:
    """gpoint's ``_str_to_rad``: a number in radians, or in degrees (``d``), arcminutes
    (``'``, ``m``) or arcseconds (``"``, ``s``) by its last character."""
    scale = {"d": math.pi / 180.0, "'": math.pi / 10800.0, "m": math.pi / 10800.0, '"': None, "s": None}
    body, unit = (token[:-1], token[-1]) if token and token[-1] in scale else (token, "")
    try:
        number = float(body)
    except ValueError:
        raise GpointFormatError(path, lineno, f"{what} is {token!r}, not a number (radians, or with d ' m \" s)") from None
    if not math.isfinite(number):
        raise GpointFormatError(path, lineno, f"{what} is {token!r}, not finite")
    if unit in ('"', "s"):
        return float(np.radians(number / 3600.0))  # as gpoint: np.radians(float(s[:-1]) / 3600.0)
    if unit in ("'", "m"):
        return float(np.radians(number / 60.0))
    if unit == "d":
        return float(np.radians(number))
    if abs(number) > POINTING_TERM_LIMIT:  # a bare number is radians (gpoint's rule): checked, not trusted
        raise GpointFormatError(
            path,
            lineno,
            f"{what} is {token!r} with no unit suffix, which gpoint reads as radians ({number:g} rad = "
            f"{number / ARCSEC:,.0f}\"), beyond any pointing term (10 deg); it is most likely in arcseconds, the "
            f"unit gpoint writes ({number:g}\" = {number * ARCSEC:.6g} rad): write the unit, {token}\" "
            "(or d for degrees, ' for arcminutes)",
        )
    return number


def parse_gpoint_model(text: str, path: str = "<string>") -> GpointModelFile:
    """Parse the text of a gpoint model file (see :func:`read_gpoint_model`)."""
    keyword = mount = None
    values: dict[str, float] = {}
    lines: dict[str, int] = {}
    extras: list[tuple[str, float, int, str]] = []
    for lineno, line in enumerate(text.splitlines(), 1):
        if line.startswith("#") or not line.strip():
            continue  # gpoint skips '#' lines (and would stop at a blank one)
        tokens = line.split()
        if tokens[0] in _MODEL_KEYWORDS:
            kind = _MODEL_KEYWORDS[tokens[0]]
            names = _BASE_NAMES[kind]
            if keyword is not None:
                raise GpointFormatError(path, lineno, f"a second model line ({tokens[0]}; the first is {keyword})")
            if len(tokens) != len(names) + 1:
                raise GpointFormatError(
                    path,
                    lineno,
                    f"{tokens[0]} line has {len(tokens) - 1} values; gpoint's has {len(names)}: {' '.join(names)}",
                )
            keyword, mount = tokens[0], kind
            for k, (name, token) in enumerate(zip(names, tokens[1:])):
                values[name] = _model_value(path, lineno, token, f"{tokens[0]} line: field {k + 2} ({name})")
                lines[name] = lineno
        elif len(tokens) == 5:
            axis, multi, function, params, consts = tokens
            spec = f"{axis}:{function}:{params}:{consts}"
            try:
                parsed = parse_extra(spec)
            except ValueError as err:
                raise GpointFormatError(path, lineno, f"extra line: {err}") from None
            name = GpointExtra(axis=parsed[0], function=parsed[1], variables=parsed[2], multipliers=parsed[3]).name
            value = _model_value(path, lineno, multi, f"extra line: field 2 (value of {name})")
            extras.append((name, value, lineno, parsed[0]))
        else:
            raise GpointFormatError(
                path,
                lineno,
                f"not a gpoint model line: expected RTS2_ALTAZ (7 values), RTS2_GEM or RTS2_MODEL (9 values), or an "
                f"extra term 'AXIS VALUE FUNCTION VARIABLES MULTIPLIERS' (5 fields), got {len(tokens)} field(s) "
                f"starting {tokens[0]!r}",
            )
    if keyword is None:
        raise GpointFormatError(path, None, "no model line (RTS2_ALTAZ, RTS2_GEM or RTS2_MODEL)")
    seen: dict[str, int] = {}
    for spec, _, lineno, axis in extras:
        if spec in seen:
            raise GpointFormatError(path, lineno, f"extra term {spec} is given twice (first on line {seen[spec]}); gpoint refuses it")
        seen[spec] = lineno
        own = ("az", "el") if mount == "altaz" else ("ha", "dec")
        if axis not in own:
            raise GpointFormatError(
                path, lineno, f"extra term {spec} corrects {axis}, which a {keyword} model does not have (gpoint "
                f"would ignore it): its extras correct {' or '.join(own)}"
            )
        lines[spec] = lineno
    return GpointModelFile(
        path=path,
        keyword=keyword,
        mount=mount,
        values=values,
        extras=tuple((spec, value) for spec, value, _, _ in extras),
        lines=lines,
    )


@file_errors(GpointFormatError)
def read_gpoint_model(path: str | os.PathLike) -> GpointModelFile:
    """Read a gpoint model file (``RTS2_ALTAZ`` / ``RTS2_GEM`` / ``RTS2_MODEL`` line and
    extra-term lines), as gpoint's ``GPoint.load`` reads it.

    Values written by :func:`write_gpoint_model` read back as the arcsecond values
    written, exactly (the shortest text of each double); converted back to radians
    (``np.radians(arcsec / 3600)``, as gpoint does) they come within 2 units in the last
    place of the values written (relative 4.4e-16).

    Raises:
        GpointFormatError: naming file, line and field of the first malformed line.
    """
    path = os.fspath(path)
    return parse_gpoint_model(read_text(path, GpointFormatError, comments="#"), path)

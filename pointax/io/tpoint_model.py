"""TPOINT model files (``.mod``): reading (:func:`read_model`) and writing
(:func:`write_model`, :func:`format_model`). TPOINT's input files are
:mod:`pointax.io.tpoint`; the record syntax both share, :mod:`pointax.io.tpoint_records`.

Model file layout::

    Caption line
    T  80   0.9318   42.060  -0.0485           method letter (T or S), N obs,
                                               Sky RMS ("), refraction A, B
      IA      +1209.2612     1.28477           term, value ("), sigma (")
    & HSCASE3   -6.7565     1.60735            '&': applied in parallel with the previous
     =NPAE      +0.0000                        '=': fixed (no sigma)
    END

or TPOINT's one-line layout, every field of the model on one line between ``|``, no
END (as TPOINT wrote it for the MMT; fields numbered from 1)::

    MMT ...|T|   70|   0.7909|   0.5310|   0.4401|   0.8449|   0.9526|   41.771|  -0.0488|         |  |IA      |  +14.2662|     2.24687|  |IE      | ...|3-5

    1 caption, 2 method letter, 3 N, 4-5 two numbers pointax does not interpret,
    6-7 the RMS of the x and y residuals (alt-az: dA cos E, dE), 8 Sky RMS,
    9-10 refraction A and B, 11 a field pointax does not interpret (blank here),
    then four fields a term: flags ('&', '='), name, value, sigma; last, the
    observations masked in the fit ('3-5': the 3rd to 5th, counted from 1).

A fit of the MMT run of 2020-07-08 with its observations 3-5 masked reproduces
fields 6, 7 and 8 and every term of such a file (tests/test_tpoint_files.py).
pointax's earlier one-line form, the line layout's records between ``|`` (``caption |
T 80 ... | IA +1209.2612 1.28477 | ... | END``), is read too.

pointax sums all sky offsets of a model (TPOINT's "parallel"); TPOINT's default of
chaining terms one after another differs only in second order of the coefficients.
Harmonic terms (``HACA2``, ``HSCA5CE8``) are read and written under their names and
rebuilt by :func:`pointax.terms.tpoint` (:mod:`pointax.terms.harmonic`).

Any malformed record raises :class:`TpointFormatError`, whose message names the file,
the line and the field.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import warnings
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from ..core.errors import InputWarning
from ..core.units import ARCSEC
from .text import read_text
from .errors import file_errors, warn_input
from .tpoint_records import MOUNTS, TpointFormatError, record_numbers, records

__all__ = [
    "ModelTerm",
    "TpointModelFile",
    "read_model",
    "parse_model",
    "write_model",
    "format_model",
    "exact_decimal",
    "refraction_arcsec",
    "MODEL_LAYOUTS",
]

MODEL_LAYOUTS = ("lines", "one-line")
"""The layouts of model files pointax reads and writes: a record a line, or TPOINT's
one-line layout."""
_MASK_ITEM = re.compile(r"(\d+)(?:-(\d+))?")


@dataclasses.dataclass(frozen=True)
class ModelTerm:
    """One term line of a TPOINT model file; values in arcseconds."""

    name: str
    value: float
    sigma: float | None = None
    fixed: bool = False
    """Marked '=' in the file: held fixed in TPOINT's fit."""
    parallel: bool = False
    """Marked '&': applied in parallel with the previous term."""
    line: int | None = dataclasses.field(default=None, compare=False)
    """Line number in the file it was read from (not compared)."""


@dataclasses.dataclass(frozen=True)
class TpointModelFile:
    """A TPOINT model file: caption, fit summary and terms (arcseconds)."""

    caption: str
    terms: tuple[ModelTerm, ...]
    n_obs: int | None = None
    sky_rms: float | None = None
    refraction: tuple[float, float] | None = None
    method: str | None = None
    """The letter that starts the fit-summary record ('T' or 'S')."""
    path: str = "<string>"
    xy_rms: tuple[float, float] | None = None
    """RMS of the x and y residuals, arcsec (alt-az: dA cos E and dE), where the
    file gives them (the one-line layout)."""
    masked: tuple[int, ...] = ()
    """Observations masked in the fit, numbered from 1 in the run's order (the one-line
    layout's last field)."""
    uninterpreted: tuple[str, ...] = ()
    """Fields 4, 5 and 11 of a one-line file as written (stripped): their meaning is
    not known to pointax; written back as they were."""
    layout: str = "lines"
    """The layout the file was read from (:data:`MODEL_LAYOUTS`)."""

    @property
    def names(self) -> list[str]:
        return [t.name for t in self.terms]

    def text(self, layout: str | None = None) -> str:
        """This model file's text in ``layout`` (default: the one it was read from),
        every field it holds written back (:func:`format_model`)."""
        return format_model(
            self.terms, self.caption, self.n_obs, self.sky_rms, self.refraction or (0.0, 0.0), layout or self.layout,
            xy_rms=self.xy_rms, masked=self.masked, uninterpreted=self.uninterpreted,
        )

    def values(self) -> dict[str, float]:
        """Term values in radians, by name."""
        return {t.name: t.value * ARCSEC for t in self.terms}

    def check_terms(self, form: str = "rigorous", mount: str = "altaz", latitude: float | None = None, names=None) -> tuple:
        """The terms of this file (or those of ``names`` it holds) built for ``mount``
        with their values (:func:`pointax.terms.tpoint`): what INMOD and ``--model``
        read. Every term pointax cannot build is refused here, with the file and its
        line, the library's reason kept (an equatorial term in an alt-az model: "TPOINT's
        equatorial term ...", :class:`pointax.terms.NotYetInPointax`'s message).

        Raises:
            TpointFormatError: ``path:line: term record NAME: why``.
            ValueError: for an unknown ``form`` or ``mount``.
        """
        from ..terms import tpoint

        if mount not in MOUNTS:
            raise ValueError(f"unknown mount {mount!r}; expected one of {', '.join(MOUNTS)}")
        where = {} if mount == "altaz" else {"mount": mount, "latitude": latitude}
        tpoint([], form=form, **where)  # an unknown form raises here, not as a term's error
        wanted = None if names is None else {str(n).upper() for n in names}
        terms = []
        for t in self.terms:
            if wanted is not None and t.name not in wanted:
                continue
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", InputWarning)
                try:
                    terms.extend(tpoint([t.name], form=form, values={t.name: t.value * ARCSEC}, **where))
                except ValueError as err:
                    raise TpointFormatError(self.path, t.line, f"term record {t.name}: {err}") from None
            for w in caught:
                if issubclass(w.category, InputWarning):
                    # The library's warning speaks of radians and px.deg; the file's unit
                    # is the arcsecond, and its line is what the user needs.
                    warn_input(self.path, t.line, f"term record {t.name} = {t.value:g}\" ({t.value / 3600:.4g} deg): "
                               "larger than pointax expects of this term (model files give arcseconds)")
                else:
                    warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        return tuple(terms)

    def model(self, form: str = "rigorous", azimuth: str = "N-E", mount: str = "altaz", latitude: float | None = None):
        """The :class:`pointax.Model` these terms describe, with their values.

        ``mount``: 'altaz' (``azimuth`` its convention) or 'equatorial' (``latitude``
        in radians required: a model file does not record it; ``run.latitude``).

        Harmonic terms (``HACA2``, ``HSCA5CE8``, ...) are generated from their names
        (:mod:`pointax.terms.harmonic`). ``azimuth`` must be how the run the model was
        fitted to counts azimuth: TPOINT's AN, AW and every harmonic term with an
        azimuth argument are defined on the azimuth as written in that file.

        Raises:
            TpointFormatError: for a term pointax does not know, naming the file, the
                term's line and what is wrong with the name.
            ValueError: for an unknown ``form``.
        """
        from ..terms.model_factories import AltAz, Equatorial

        if mount not in MOUNTS:
            raise ValueError(f"unknown mount {mount!r}; expected one of {', '.join(MOUNTS)}")
        if mount == "equatorial" and latitude is None:
            raise ValueError(
                f"{self.path}: an equatorial model needs the site's latitude (radians; a model file does not "
                "record it): model(mount='equatorial', latitude=run.latitude)"
            )
        terms = self.check_terms(form, mount, latitude)
        fixed = [t.name for t in self.terms if t.fixed]
        if mount == "equatorial":
            return Equatorial(terms, latitude=latitude, fixed=fixed)
        return AltAz(terms, azimuth=azimuth, fixed=fixed)


def _model_records(text: str, path: str):
    """The records of a model file in either layout: a line per record, or every
    record on one line separated by ``|`` (caption first, END last). A ``|`` in a
    caption of the line layout is text."""
    stream = records(text, path)
    for lineno, line in stream:
        pieces = [p.strip() for p in line.split("|")]
        if len(pieces) > 1 and pieces[-1].upper() == "END":
            rest = [n for n, _ in stream]
            if rest:
                raise TpointFormatError(
                    path, rest[0], "a record after a one-line model (caption | records | END on one line)"
                )
            for piece in pieces:
                if piece:
                    yield lineno, piece
            return
        yield lineno, line
        break
    yield from stream


ONE_LINE_HEADER = (
    "caption",
    "method letter",
    "number of observations",
    "uninterpreted",
    "uninterpreted",
    "x RMS (arcsec)",
    "y RMS (arcsec)",
    "Sky RMS (arcsec)",
    "refraction A (arcsec)",
    "refraction B (arcsec)",
    "uninterpreted",
)
"""The fields that open a model file of TPOINT's one-line layout."""
ONE_LINE_TERM = ("flags", "term name", "value (arcsec)", "sigma (arcsec)")
"""The four fields of each term of the one-line layout."""


def _is_tpoint_one_line(line: str) -> bool:
    """Whether ``line`` is a whole model in TPOINT's one-line layout: the opening
    fields, four a term, the masked observations last (and no END field)."""
    fields = [f.strip() for f in line.split("|")]
    body = len(fields) - len(ONE_LINE_HEADER)
    method = fields[1] if len(fields) > 1 else "?"
    letter = method == "" or (len(method) == 1 and method.isalpha())
    return body >= 1 and body % 4 == 1 and fields[-1].upper() != "END" and letter


def _one_line_number(path: str, lineno: int, fields: list[str], k: int, name: str) -> float | None:
    """Field ``k`` (from 0) of a one-line model as a number, None if blank."""
    if not fields[k]:
        return None
    return record_numbers(path, lineno, [fields[k]], (name,), "one-line model", first=k + 1)[0]


def _one_line_term(path: str, lineno: int, fields: list[str], k: int) -> ModelTerm:
    """The term whose four fields start at field ``k`` (from 0)."""
    flags, name = fields[k], fields[k + 1].upper()
    if set(flags) - set("&="):
        raise TpointFormatError(path, lineno, f"one-line model: field {k + 1} (flags) {flags!r}: expected '&', '=' or blank")
    if not name or not name[0].isalpha():
        raise TpointFormatError(path, lineno, f"one-line model: field {k + 2} (term name) {fields[k + 1]!r} is not a name")
    value = _one_line_number(path, lineno, fields, k + 2, ONE_LINE_TERM[2])
    if value is None:
        raise TpointFormatError(path, lineno, f"one-line model: field {k + 3} (value of {name}) is blank")
    sigma = _one_line_number(path, lineno, fields, k + 3, ONE_LINE_TERM[3])
    return ModelTerm(name, value, sigma, fixed="=" in flags, parallel="&" in flags, line=lineno)


def _masked_numbers(path: str, lineno: int, text: str, field: int) -> tuple[int, ...]:
    """The observation numbers of a mask field: ``3-5``, ``3-5,9``, ``3 4 9``."""
    numbers: list[int] = []
    for item in text.replace(",", " ").split():
        match = _MASK_ITEM.fullmatch(item)
        first, last = (int(match[1]), int(match[2] or match[1])) if match else (0, 0)
        if not 1 <= first <= last:
            raise TpointFormatError(
                path, lineno, f"one-line model: field {field} (masked observations) {text!r}: expected numbers "
                "and ranges such as '3-5,9'"
            )
        numbers.extend(range(first, last + 1))
    return tuple(numbers)


def _mask_ranges(numbers) -> str:
    """``(3, 4, 5, 9)`` -> ``'3-5,9'``."""
    ranges: list[list[int]] = []
    for n in sorted(set(int(k) for k in numbers)):
        if ranges and n == ranges[-1][1] + 1:
            ranges[-1][1] = n
        else:
            ranges.append([n, n])
    return ",".join(f"{a}-{b}" if b > a else f"{a}" for a, b in ranges)


def _parse_tpoint_one_line(path: str, lineno: int, line: str) -> TpointModelFile:
    """A model file in TPOINT's one-line layout (see the module's description)."""
    fields = [f.strip() for f in line.split("|")]
    head = len(ONE_LINE_HEADER)
    number = {k: _one_line_number(path, lineno, fields, k, ONE_LINE_HEADER[k]) for k in range(2, head) if k not in (3, 4, 10)}
    n_obs = number[2]
    if n_obs is not None and (n_obs != int(n_obs) or n_obs < 0):
        raise TpointFormatError(path, lineno, f"one-line model: field 3 (number of observations) {fields[2]!r} is not a count")
    terms = [_one_line_term(path, lineno, fields, k) for k in range(head, len(fields) - 1, 4)]
    _check_unique(path, terms)
    if not terms:
        raise TpointFormatError(path, lineno, "one-line model holds no terms: the model is empty")
    x_rms, y_rms = number[5], number[6]
    refraction = None if number[8] is None or number[9] is None else (number[8], number[9])
    return TpointModelFile(
        caption=fields[0],
        terms=tuple(terms),
        n_obs=None if n_obs is None else int(n_obs),
        sky_rms=number[7],
        refraction=refraction,
        method=fields[1] or None,
        path=path,
        xy_rms=None if x_rms is None or y_rms is None else (x_rms, y_rms),
        masked=_masked_numbers(path, lineno, fields[-1], len(fields)),
        uninterpreted=(fields[3], fields[4], fields[10]),
        layout="one-line",
    )


def _check_unique(path: str, terms: list[ModelTerm]) -> None:
    seen: set[str] = set()
    for t in terms:
        if t.name in seen:
            raise TpointFormatError(path, t.line, f"term {t.name} appears twice")
        seen.add(t.name)


def parse_model(text: str, path: str = "<string>") -> TpointModelFile:
    """Parse the text of a TPOINT model file (see :func:`read_model`)."""
    stream = records(text, path)
    first = next(stream, None)
    if first is not None and _is_tpoint_one_line(first[1]):
        rest = [n for n, _ in stream]
        if rest:
            raise TpointFormatError(path, rest[0], "a record after a one-line model (the whole model on one line)")
        return _parse_tpoint_one_line(path, *first)
    return _parse_line_records(text, path)


def _parse_line_records(text: str, path: str) -> TpointModelFile:
    """A model file of records: a line each, or pointax's earlier one-line form."""
    caption = None
    header: dict = {}
    terms: list[ModelTerm] = []
    ended = False
    for lineno, line in _model_records(text, path):
        if caption is None:
            caption = line
            continue
        if line.upper() == "END":
            ended = True
            break
        tokens = line.split()
        if len(tokens[0]) == 1 and tokens[0].isalpha() and not terms and not header:
            record = f"fit-summary record '{tokens[0]}'"
            if len(tokens) not in (3, 5):
                raise TpointFormatError(
                    path, lineno, f"{record} has {len(tokens)} fields; expected letter, N, Sky RMS and optionally refraction A, B"
                )
            v = record_numbers(
                path, lineno, tokens[1:], ("number of observations", "Sky RMS", "refraction A", "refraction B"), record, first=2
            )
            header = {"method": tokens[0], "n_obs": int(round(v[0])), "sky_rms": v[1]}
            if len(v) == 4:
                header["refraction"] = (v[2], v[3])
            continue
        flags = ""
        while tokens and tokens[0][0] in "&=":
            flags += tokens[0][0]
            tokens[0] = tokens[0][1:]
            if not tokens[0]:
                tokens.pop(0)
        if not tokens:
            raise TpointFormatError(path, lineno, "term record: field 1 (term name) is missing")
        name = tokens[0].upper()
        if not name[0].isalpha():
            raise TpointFormatError(path, lineno, f"term record: field 1 (term name) {tokens[0]!r} is not a name")
        if len(tokens) not in (2, 3):
            raise TpointFormatError(
                path, lineno, f"term record has {len(tokens)} fields; expected name, value (arcsec) and optionally sigma"
            )
        v = record_numbers(path, lineno, tokens[1:], ("value (arcsec)", "sigma (arcsec)"), f"term record {name}", first=2)
        if name in (t.name for t in terms):
            raise TpointFormatError(path, lineno, f"term {name} appears twice")
        terms.append(
            ModelTerm(name, v[0], v[1] if len(v) > 1 else None, fixed="=" in flags, parallel="&" in flags, line=lineno)
        )
    if caption is None:
        raise TpointFormatError(path, None, "empty file: no caption line")
    if not ended:
        raise TpointFormatError(path, None, "no END line: the file may be truncated")
    if not terms:
        raise TpointFormatError(path, None, "no term records between the caption and END: the model is empty")
    return TpointModelFile(caption=caption, terms=tuple(terms), path=path, **header)


@file_errors(TpointFormatError)
def read_model(path: str | os.PathLike) -> TpointModelFile:
    """Read a TPOINT model file (``.mod``).

    Raises:
        TpointFormatError: naming file, line and field of the first malformed record.
    """
    path = os.fspath(path)
    return parse_model(read_text(path, TpointFormatError, comments="!;", caption=True), path)


def exact_decimal(value: float, decimals: int, sign: bool = False) -> str:
    """``value`` in fixed-point notation with at least ``decimals`` decimals and as many
    more as it takes to read back the same float64, so that a model file
    gives back every value exactly (to well below 1e-12 rad). ``sign``: always write
    the sign (TPOINT's ``+1209.2612``).

    Raises:
        ValueError: for NaN or infinity, which a model file cannot hold (the reader
            refuses them).
    """
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{value!r} is not finite")
    plus = "+" if sign else ""
    for d in range(decimals, 26):
        text = f"{value:{plus}.{d}f}"
        if float(text) == value:
            return text
    return f"{value:{plus}.17e}"  # below 1e-8: exponent notation (the reader takes it)


def _checked(value: float, what: str) -> float:
    if value is not None and not math.isfinite(value):
        raise ValueError(
            f"{what} is {value!r}: a TPOINT model file cannot hold NaN or infinity "
            "(the reader refuses them); fix or drop the term before writing"
        )
    return value


def format_model(
    terms: Iterable[ModelTerm],
    caption: str = "pointax model",
    n_obs: int | None = None,
    sky_rms: float | None = None,
    refraction: tuple[float, float] = (0.0, 0.0),
    layout: str = "lines",
    *,
    xy_rms: tuple[float, float] | None = None,
    masked: Iterable[int] = (),
    uninterpreted: tuple[str, ...] = (),
) -> str:
    """Text of a TPOINT model file. Values, ``sky_rms`` and ``refraction`` (TPOINT's
    constants A and B) in arcseconds. ``layout``: 'lines' (a record per line, TPOINT's
    classic layout) or 'one-line' (TPOINT's one-line layout, fields between ``|``: see
    the module's description).

    The one-line layout also holds ``xy_rms`` (the x and y RMS residuals, arcsec),
    ``masked`` (the observations masked in the fit, numbered from 1) and the three
    fields pointax does not interpret (``uninterpreted``, as read; blank when not
    given); the line layout has no place for them.

    Numbers are written in TPOINT's fixed-point layout with as many decimals as it
    takes to read back the same float64 (at least TPOINT's 4 for values, 5 for sigmas),
    so a model written and read back is the same model. A sigma that is ``None`` or not
    finite (a degenerate parameter) is left out.

    Raises:
        ValueError: for a NaN or infinite value, Sky RMS or refraction constant, naming
            the term or field (the reader would refuse the file).
    """
    if layout not in MODEL_LAYOUTS:
        raise ValueError(f"unknown model-file layout {layout!r}; expected one of {', '.join(MODEL_LAYOUTS)}")
    caption = caption.strip()
    if layout == "one-line" and "|" in caption:
        raise ValueError(f"a one-line model file's caption cannot hold '|': {caption!r}")
    if not caption or caption[0] in "!;":
        raise ValueError(f"a model-file caption must be non-empty text not starting with '!' or ';', got {caption!r}")
    for t in terms:
        _checked(t.value, f"the value of term {t.name}")
    if layout == "one-line":
        summary = _one_line_summary(n_obs, sky_rms, refraction, xy_rms, uninterpreted)
        fields = [caption, *summary, *(f for t in terms for f in _one_line_term_fields(t)), _mask_ranges(masked)]
        return "|".join(fields) + "\n"
    lines = [caption]
    if n_obs is not None:
        rms = _checked(sky_rms if sky_rms is not None else 0.0, "the Sky RMS")
        ref_a = _checked(refraction[0], "refraction constant A")
        ref_b = _checked(refraction[1], "refraction constant B")
        lines.append(
            f"T  {n_obs:3d}  {exact_decimal(rms, 4):>8s}  {exact_decimal(ref_a, 3):>8s}  {exact_decimal(ref_b, 4):>8s}"
        )
    for t in terms:
        sigma = f"  {exact_decimal(t.sigma, 5):>10s}" if _written_sigma(t) else ""
        lines.append(f"{_flags(t)}{t.name:<8s} {exact_decimal(t.value, 4, sign=True):>12s}{sigma}")
    lines.append("END")
    return "\n".join(lines) + "\n"


def _flags(t: ModelTerm) -> str:
    return ("&" if t.parallel else " ") + ("=" if t.fixed else " ")


def _written_sigma(t: ModelTerm) -> bool:
    return t.sigma is not None and math.isfinite(t.sigma) and not t.fixed


def _one_line_summary(n_obs, sky_rms, refraction, xy_rms, uninterpreted) -> list[str]:
    """Fields 2-11 of the one-line layout (blank where not known)."""

    def number(value, decimals: int, what: str) -> str:
        return " " * 9 if value is None else f"{exact_decimal(_checked(value, what), decimals):>9s}"

    if len(uninterpreted) not in (0, 3):
        raise ValueError(f"uninterpreted: fields 4, 5 and 11 of a one-line model (3 strings), got {uninterpreted!r}")
    field4, field5, field11 = (f"{u:>9s}" for u in (uninterpreted or ("", "", "")))
    x_rms, y_rms = xy_rms if xy_rms is not None else (None, None)
    ref_a, ref_b = refraction if refraction is not None else (None, None)
    return [
        "T" if n_obs is not None else " ",
        f"{int(n_obs):5d}" if n_obs is not None else " " * 5,
        field4,
        field5,
        number(x_rms, 4, "the x RMS"),
        number(y_rms, 4, "the y RMS"),
        number(sky_rms, 4, "the Sky RMS"),
        number(ref_a, 3, "refraction constant A"),
        number(ref_b, 4, "refraction constant B"),
        field11,
    ]


def _one_line_term_fields(t: ModelTerm) -> list[str]:
    sigma = f"{exact_decimal(t.sigma, 5):>12s}" if _written_sigma(t) else " " * 12
    return [_flags(t), f"{t.name:<8s}", f"{exact_decimal(t.value, 4, sign=True):>10s}", sigma]


def refraction_arcsec(run) -> tuple[float, float]:
    """A run's refraction constants ``(A, B)`` in arcseconds, as a model file holds
    them: those of a :class:`TpointRun` (from its weather), ``(0, 0)`` for runs of
    other formats or None."""
    a, b = getattr(run, "refraction", (0.0, 0.0)) if run is not None else (0.0, 0.0)
    return float(a) / ARCSEC, float(b) / ARCSEC


def write_model(
    path: str | os.PathLike,
    source,
    caption: str | None = None,
    refraction: tuple[float, float] | None = None,
    layout: str = "lines",
    *,
    run=None,
    parallel: Iterable[str] = (),
) -> None:
    """Write a TPOINT model file from a :class:`pointax.FitResult` or a :class:`pointax.Model`.

    ``parallel``: names of terms flagged ``&`` (TPOINT's mark of the terms FAUTO added,
    applied in parallel with the previous term; pointax sums every term either way).

    ``run``: the run the result was fitted to (a :class:`pointax.io.TpointRun`): its
    refraction constants, from its weather, go into the fit-summary record, as
    ``pointax fit --write-model`` writes them, so that the same run gives the same
    file through the command line and the API. ``refraction``: TPOINT's refraction
    constants A and B in arcseconds, given explicitly (default: the run's,
    :func:`refraction_arcsec`; ``(0, 0)`` without a run, with a warning for a fit
    result, since TPOINT writes the run's).
    ``layout``: 'lines' or 'one-line' (:func:`format_model`); the one-line layout also
    records, for a fit result, the RMS of the x and y residuals and the observations
    the fit did not use (masked, numbered from 1 in the run's order).

    Only one-parameter terms in arcseconds with upper-case (TPOINT) names can be written
    (TPOINT's format holds one number per term, and reads names case-insensitively);
    other parameters, e.g. gpoint's lower-case terms, raise ``ValueError``. Harmonic
    terms are written under their names (``HACA2``) and read back as the same terms.
    For a fit result the sigmas, N and Sky RMS are written too.
    """
    from ..fitting import FitResult

    if refraction is None:
        if run is None and isinstance(source, FitResult):
            import warnings

            warnings.warn(
                "write_model: no run given, so the refraction constants are written as 0 (pointax fit --write-model "
                "writes the run's): pass run=<the run fitted> or refraction=(A, B)",
                UserWarning,
                stacklevel=2,
            )
        refraction = refraction_arcsec(run)
    fit_fields: dict = {}
    if isinstance(source, FitResult):
        model, sigmas = source.model, dict(zip(source.names, np.asarray(source.sigmas)))
        n_obs, sky_rms = int(source.n_obs), float(source.sky_rms) / ARCSEC
        caption = caption or source.caption or "pointax model"
        fit_fields = _fit_fields(source)
    else:
        model, sigmas, n_obs, sky_rms = source, {}, None, None
        caption = caption or "pointax model"
    terms = []
    for p in model.parameters:
        if p.unit != "arcsec" or "." in p.name:
            raise ValueError(f"parameter {p.name} ({p.unit}) cannot be written to a TPOINT model file")
        if p.name != p.name.upper():
            # TPOINT names are case-insensitive: gpoint's 'ie' would read back as TPOINT's IE,
            # which has the opposite sign.
            raise ValueError(
                f"parameter {p.name} cannot be written to a TPOINT model file: its name is not a TPOINT name "
                f"(TPOINT names are upper-case; it would read back as {p.name.upper()!r})"
            )
        sigma = sigmas.get(p.name)
        terms.append(
            ModelTerm(
                p.name,
                float(model.get(p.name)) / ARCSEC,
                None if sigma is None else float(sigma) / ARCSEC,
                fixed=p.name in model.fixed,
                parallel=p.name in parallel,
            )
        )
    if layout != "one-line":
        fit_fields = {}
    Path(path).write_text(format_model(terms, caption, n_obs, sky_rms, refraction, layout, **fit_fields))


def _fit_fields(result) -> dict:
    """The one-line layout's RMS of the x and y residuals (arcsec) and masked
    observations (numbered from 1) of a fit result."""
    used = np.asarray(result.used, bool)
    residuals = np.asarray(result.residuals)[used] / ARCSEC
    xy_rms = tuple(float(np.sqrt(np.mean(residuals[:, k] ** 2))) for k in (0, 1)) if used.any() else None
    return {"xy_rms": xy_rms, "masked": tuple(int(k) + 1 for k in np.flatnonzero(~used))}

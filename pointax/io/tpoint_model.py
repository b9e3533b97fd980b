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

or the same records on one line, separated by ``|`` (``caption | T 80 ... | IA
+1209.2612 1.28477 | ... | END``).

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
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from ..units import ARCSEC
from .text import read_text
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
"""The layouts of model files pointax reads and writes."""


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

    @property
    def names(self) -> list[str]:
        return [t.name for t in self.terms]

    def values(self) -> dict[str, float]:
        """Term values in radians, by name."""
        return {t.name: t.value * ARCSEC for t in self.terms}

    def model(self, form: str = "linear", azimuth: str = "N-E", mount: str = "altaz", latitude: float | None = None):
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
        from ..mount_models import AltAz, Equatorial
        from ..terms import tpoint

        if mount not in MOUNTS:
            raise ValueError(f"unknown mount {mount!r}; expected one of {', '.join(MOUNTS)}")
        if mount == "equatorial" and latitude is None:
            raise ValueError(
                f"{self.path}: an equatorial model needs the site's latitude (radians; a model file does not "
                "record it): model(mount='equatorial', latitude=run.latitude)"
            )
        where = {} if mount == "altaz" else {"mount": mount, "latitude": latitude}
        tpoint([], form=form, **where)  # an unknown form raises here, not as a term's error
        terms = []
        for t in self.terms:
            try:
                terms.extend(tpoint([t.name], form=form, values={t.name: t.value * ARCSEC}, **where))
            except ValueError as err:
                raise TpointFormatError(self.path, t.line, f"term record {t.name}: {err}") from None
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


def parse_model(text: str, path: str = "<string>") -> TpointModelFile:
    """Parse the text of a TPOINT model file (see :func:`read_model`)."""
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


def read_model(path: str | os.PathLike) -> TpointModelFile:
    """Read a TPOINT model file (``.mod``).

    Raises:
        TpointFormatError: naming file, line and field of the first malformed record.
    """
    path = os.fspath(path)
    return parse_model(read_text(path, TpointFormatError), path)


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
) -> str:
    """Text of a TPOINT model file. Values, ``sky_rms`` and ``refraction`` (TPOINT's
    constants A and B) in arcseconds. ``layout``: 'lines' (a record per line, TPOINT's
    classic layout) or 'one-line' (every record on one line, separated by `` | ``).

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
    if not caption or caption.startswith("!"):
        raise ValueError(f"a model-file caption must be non-empty text not starting with '!', got {caption!r}")
    lines = [caption]
    if n_obs is not None:
        rms = _checked(sky_rms if sky_rms is not None else 0.0, "the Sky RMS")
        ref_a = _checked(refraction[0], "refraction constant A")
        ref_b = _checked(refraction[1], "refraction constant B")
        lines.append(
            f"T  {n_obs:3d}  {exact_decimal(rms, 4):>8s}  {exact_decimal(ref_a, 3):>8s}  {exact_decimal(ref_b, 4):>8s}"
        )
    for t in terms:
        _checked(t.value, f"the value of term {t.name}")
        finite_sigma = t.sigma is not None and math.isfinite(t.sigma) and not t.fixed
        sigma = f"  {exact_decimal(t.sigma, 5):>10s}" if finite_sigma else ""
        flags = ("&" if t.parallel else " ") + ("=" if t.fixed else " ")
        lines.append(f"{flags}{t.name:<8s} {exact_decimal(t.value, 4, sign=True):>12s}{sigma}")
    lines.append("END")
    if layout == "one-line":
        return " | ".join(" ".join(line.split()) if k else line for k, line in enumerate(lines)) + "\n"
    return "\n".join(lines) + "\n"


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
    refraction: tuple[float, float] = (0.0, 0.0),
    layout: str = "lines",
) -> None:
    """Write a TPOINT model file from a :class:`pointax.FitResult` or a :class:`pointax.Model`.

    ``refraction``: TPOINT's refraction constants A and B in arcseconds (a run's
    ``refraction`` divided by ``pointax.ARCSEC``), written in the fit-summary record.
    ``layout``: 'lines' or 'one-line' (:func:`format_model`).

    Only one-parameter terms in arcseconds with upper-case (TPOINT) names can be written
    (TPOINT's format holds one number per term, and reads names case-insensitively);
    other parameters, e.g. gpoint's lower-case terms, raise ``ValueError``. Harmonic
    terms are written under their names (``HACA2``) and read back as the same terms.
    For a fit result the sigmas, N and Sky RMS are written too.
    """
    from ..fitting.result import FitResult

    if isinstance(source, FitResult):
        model, sigmas = source.model, dict(zip(source.names, np.asarray(source.sigmas)))
        n_obs, sky_rms = int(source.n_obs), float(source.sky_rms) / ARCSEC
        caption = caption or source.caption or "pointax model"
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
            )
        )
    Path(path).write_text(format_model(terms, caption, n_obs, sky_rms, refraction, layout))

"""TPOINT files: pointing-run input files (``.dat``) and model files (``.mod``).

Input file layout (as TPOINT reads it)::

    ! comment lines start with '!' (a '!' later on a line starts a trailing comment)
    Caption line                               first non-comment line, free text
    : ALTAZ                                    option records, ':' then keywords
    +31 41 19.6 2021 8 21 13.0 741 2608 0.75   run parameters: latitude d m s, then optional
                                               date, temperature C, pressure mB,
                                               height m, humidity, wavelength, lapse
    192.386 77.347 -167.278 77.348             observed az, el, raw encoder az, el
    ...                                        (degrees; an optional 5th number, e.g.
    END                                         a rotator angle, is kept as `extra`;
                                                END is optional)

Model file layout::

    Caption line
    T  80   0.9318   42.060  -0.0485           method letter (T or S), N obs,
                                               Sky RMS ("), refraction A, B
      IA      +1209.2612     1.28477           term, value ("), sigma (")
    & HSCASE3   -6.7565     1.60735            '&': applied in parallel with the previous
     =NPAE      +0.0000                        '=': fixed (no sigma)
    END

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

from ..mounts import AZIMUTH_CONVENTIONS
from ..observations import Observations
from ..rotations import azel_to_enu_numpy
from ..units import ARCSEC, DEG
from .errors import FileFormatError
from .sanity import check_azimuth, check_not_radians, check_observed_elevation, warn_after_end, warn_duplicates

__all__ = [
    "TpointFormatError",
    "RunParameters",
    "TpointRun",
    "TpointModelFile",
    "ModelTerm",
    "read_tpoint",
    "parse_tpoint",
    "read_model",
    "parse_model",
    "write_model",
    "format_model",
]

RUN_PARAMETER_FIELDS = (
    "latitude degrees",
    "latitude minutes",
    "latitude seconds",
    "year",
    "month",
    "day",
    "temperature (C)",
    "pressure (mB)",
    "height (m)",
    "relative humidity",
    "wavelength (micron)",
    "lapse rate (K/m)",
)
ALTAZ_FIELDS = ("observed azimuth", "observed elevation", "raw azimuth", "raw elevation", "extra (5th column)")
MOUNT_OPTIONS = {"ALTAZ", "EQUAT", "GERMAN", "ALTALT", "XY", "FORK"}


class TpointFormatError(FileFormatError):
    """A TPOINT file could not be read; the message names file, line and field."""


@dataclasses.dataclass(frozen=True)
class RunParameters:
    """TPOINT's run-parameters record: the latitude, then optional fields (``None``
    when absent) in this order."""

    latitude: float
    """Site latitude, radians (north positive)."""
    date: tuple[int, int, int] | None = None
    """UTC date (year, month, day)."""
    temperature_c: float | None = None
    pressure_mb: float | None = None
    height_m: float | None = None
    humidity: float | None = None
    """Relative humidity, 0-1."""
    wavelength_um: float | None = None
    lapse_rate: float | None = None


@dataclasses.dataclass(frozen=True)
class TpointRun:
    """A pointing run read from a TPOINT input file.

    Angles are radians. ``observed`` and ``encoder`` are as the file gives them (its
    azimuth convention, ``azimuth``); ``observations`` holds the encoder angles
    unchanged and the observed directions converted to East-North-Up.
    """

    path: str
    caption: str
    options: tuple[str, ...]
    parameters: RunParameters
    observed: np.ndarray
    """``(n, 2)`` observed (catalogue) azimuth and elevation, radians, file convention."""
    encoder: np.ndarray
    """``(n, 2)`` raw encoder azimuth and elevation, radians, file convention."""
    extra: np.ndarray
    """``(n, k)`` further numbers per row (k = 0 or 1, e.g. a rotator angle), as written."""
    lines: np.ndarray
    """``(n,)`` line number of each observation in the file."""
    azimuth: str
    observations: Observations

    def __len__(self) -> int:
        return self.encoder.shape[0]


def _records(text: str, path: str = "<string>"):
    """Yield ``(line number, text)`` for the caption (first) and each later record.

    Comment lines ('!' first), trailing '!' comments and blank lines are skipped;
    iteration stops at an END line, after yielding ``(line number, "END")``. Records
    after END are ignored, as TPOINT does, with an
    :class:`~pointax.io.errors.InputWarning` naming them.
    """
    have_caption = False
    lines = text.splitlines()
    for lineno, raw in enumerate(lines, 1):
        if raw.lstrip().startswith("!"):
            continue
        if not have_caption:
            if raw.strip():
                have_caption = True
                yield lineno, raw.strip()
            continue
        line = raw.split("!", 1)[0].strip()
        if not line:
            continue
        if line.upper() == "END":
            after = [
                k
                for k, rest in enumerate(lines[lineno:], lineno + 1)
                if rest.split("!", 1)[0].strip() and not rest.lstrip().startswith("!")
            ]
            warn_after_end(path, lineno, after)
            yield lineno, "END"
            return
        yield lineno, line


def _read_text(path: str) -> str:
    try:
        return Path(path).read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as err:
        raise TpointFormatError(path, None, f"not a text file ({err})") from None


def _numbers(
    path: str, lineno: int, tokens: list[str], names: tuple[str, ...], record: str, first: int = 1
) -> list[float]:
    """Parse numbers; ``first`` is the field number of ``tokens[0]`` on its line."""
    values = []
    for k, token in enumerate(tokens):
        field = names[k] if k < len(names) else "unnamed"
        number = first + k
        try:
            value = float(token)
        except ValueError:
            raise TpointFormatError(path, lineno, f"{record}: field {number} ({field}) is {token!r}, not a number") from None
        if not math.isfinite(value):
            raise TpointFormatError(path, lineno, f"{record}: field {number} ({field}) is {token!r}, not finite")
        values.append(value)
    return values


def _run_parameters(path: str, lineno: int, tokens: list[str]) -> RunParameters:
    record = "run-parameters record"
    if len(tokens) < 3:
        raise TpointFormatError(
            path,
            lineno,
            f"{record} has {len(tokens)} fields; it needs at least the latitude (deg min sec), then optionally "
            "the UTC date (year month day), temperature, pressure, height, humidity, wavelength, lapse rate",
        )
    if 3 < len(tokens) < 6:
        raise TpointFormatError(path, lineno, f"{record} has {len(tokens)} fields: a date needs year, month and day")
    if len(tokens) > len(RUN_PARAMETER_FIELDS):
        raise TpointFormatError(
            path, lineno, f"{record} has {len(tokens)} fields; at most {len(RUN_PARAMETER_FIELDS)} are defined"
        )
    v = _numbers(path, lineno, tokens, RUN_PARAMETER_FIELDS, record)
    negative = tokens[0].startswith("-")
    deg, minutes, seconds = abs(v[0]), v[1], v[2]
    if not (0 <= minutes < 60 and 0 <= seconds < 60 and deg + minutes / 60 + seconds / 3600 <= 90):
        raise TpointFormatError(path, lineno, f"{record}: latitude {tokens[0]} {tokens[1]} {tokens[2]} is not a valid d m s")
    latitude = (deg + minutes / 60 + seconds / 3600) * DEG * (-1 if negative else 1)
    date = None
    if len(v) >= 6:
        date = tuple(int(round(x)) for x in v[3:6])
        if not (1 <= date[1] <= 12 and 1 <= date[2] <= 31):
            raise TpointFormatError(path, lineno, f"{record}: date {tokens[3]} {tokens[4]} {tokens[5]} is not year month day")
    optional = v[6:] + [None] * (len(RUN_PARAMETER_FIELDS) - max(len(v), 6))
    return RunParameters(latitude, date, *optional)


def parse_tpoint(text: str, path: str = "<string>", azimuth: str = "N-E") -> TpointRun:
    """Parse the text of a TPOINT input file (see :func:`read_tpoint`)."""
    if azimuth not in AZIMUTH_CONVENTIONS:
        raise ValueError(f"unknown azimuth convention {azimuth!r}; expected one of {sorted(AZIMUTH_CONVENTIONS)}")
    caption = None
    options: list[str] = []
    params = None
    rows, extra, lines = [], [], []
    n_columns = None
    for lineno, line in _records(text, path):
        if caption is None:
            caption = line
            continue
        if line == "END":
            break
        if line.startswith(":"):
            if params is not None:
                raise TpointFormatError(path, lineno, f"option record {line!r} after the run-parameters record")
            options.extend(word.upper() for word in line[1:].split())
            continue
        tokens = line.split()
        if params is None:
            mounts = MOUNT_OPTIONS.intersection(options)
            if "ALTAZ" not in options:
                found = ", ".join(sorted(mounts)) or "none (TPOINT's default is equatorial)"
                raise TpointFormatError(
                    path, lineno, f"pointax reads alt-az runs (option ': ALTAZ'); this file's mount option: {found}"
                )
            params = _run_parameters(path, lineno, tokens)
            continue
        if len(tokens) not in (4, 5):
            raise TpointFormatError(
                path,
                lineno,
                f"observation record has {len(tokens)} fields; an alt-az record is observed az, el, "
                "raw az, el in degrees, optionally a 5th number",
            )
        if n_columns is None:
            n_columns = len(tokens)
        elif len(tokens) != n_columns:
            raise TpointFormatError(
                path, lineno, f"observation record has {len(tokens)} fields, earlier records have {n_columns}"
            )
        v = _numbers(path, lineno, tokens, ALTAZ_FIELDS, "observation record")
        if not -90.0 <= v[1] <= 90.0:
            raise TpointFormatError(path, lineno, f"observation record: field 2 (observed elevation) {tokens[1]} is outside -90..90 deg")
        check_azimuth(TpointFormatError, path, lineno, v[0], "observation record: field 1 (observed azimuth)")
        check_azimuth(TpointFormatError, path, lineno, v[2], "observation record: field 3 (raw azimuth)")
        check_observed_elevation(TpointFormatError, path, lineno, v[1], "observation record: field 2 (observed elevation)")
        if not -90.0 <= v[3] <= 180.0:
            raise TpointFormatError(path, lineno, f"observation record: field 4 (raw elevation) {tokens[3]} is outside -90..180 deg")
        rows.append(v[:4])
        extra.append(v[4:])
        lines.append(lineno)
    if caption is None:
        raise TpointFormatError(path, None, "empty file: no caption line")
    if params is None:
        raise TpointFormatError(path, None, "no run-parameters record (latitude, date, ...) after the caption and options")
    if not rows:
        raise TpointFormatError(path, None, "no observation records")
    degrees = np.asarray(rows, np.float64)
    check_not_radians(
        TpointFormatError,
        path,
        lines,
        {
            "field 1 (observed azimuth)": (degrees[:, 0], 2 * math.pi),
            "field 2 (observed elevation)": (degrees[:, 1], math.pi / 2),
            "field 3 (raw azimuth)": (degrees[:, 2], 2 * math.pi),
            "field 4 (raw elevation)": (degrees[:, 3], math.pi),
        },
    )
    warn_duplicates(path, np.column_stack([degrees, np.asarray(extra, np.float64).reshape(len(rows), -1)]), lines)
    data = degrees * DEG
    observed, encoder = data[:, :2], data[:, 2:]
    frame = np.asarray(AZIMUTH_CONVENTIONS[azimuth])
    az, el = observed[:, 0], observed[:, 1]
    in_mount_frame = azel_to_enu_numpy(az, el)
    target = in_mount_frame @ frame.T
    return TpointRun(
        path=path,
        caption=caption,
        options=tuple(options),
        parameters=params,
        observed=observed,
        encoder=encoder,
        extra=np.asarray(extra, np.float64).reshape(len(rows), -1),
        lines=np.asarray(lines),
        azimuth=azimuth,
        observations=Observations(encoder, target, convention=azimuth),
    )


def read_tpoint(path: str | os.PathLike, azimuth: str = "N-E") -> TpointRun:
    """Read a TPOINT input file of an alt-az pointing run.

    Args:
        path: the file.
        azimuth: how the file counts azimuth: 'N-E' (TPOINT's standard, default),
            'S-E' (from South through East, as in the MMT files) or 'S-W'. It decides
            the East-North-Up directions of the observed positions; TPOINT-form fits do
            not depend on it as long as the model uses the same convention.

    Raises:
        TpointFormatError: naming file, line and field of the first malformed record.
    """
    path = os.fspath(path)
    return parse_tpoint(_read_text(path), path, azimuth)


# --------------------------------------------------------------------------- models


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

    def model(self, form: str = "linear", azimuth: str = "N-E"):
        """The :class:`pointax.Model` (alt-az) these terms describe, with their values.

        Harmonic terms (``HACA2``, ``HSCA5CE8``, ...) are generated from their names
        (:mod:`pointax.terms.harmonic`). ``azimuth`` must be how the run the model was
        fitted to counts azimuth: TPOINT's AN, AW and every harmonic term with an
        azimuth argument are defined on the azimuth as written in that file.

        Raises:
            TpointFormatError: for a term pointax does not know, naming the file, the
                term's line and what is wrong with the name.
            ValueError: for an unknown ``form``.
        """
        from ..mount_models import AltAz
        from ..terms import tpoint

        tpoint([], form=form)  # an unknown form raises here, not as a term's error
        terms = []
        for t in self.terms:
            try:
                terms.extend(tpoint([t.name], form=form, values={t.name: t.value * ARCSEC}))
            except ValueError as err:
                raise TpointFormatError(self.path, t.line, f"term record {t.name}: {err}") from None
        fixed = [t.name for t in self.terms if t.fixed]
        return AltAz(terms, azimuth=azimuth, fixed=fixed)


def parse_model(text: str, path: str = "<string>") -> TpointModelFile:
    """Parse the text of a TPOINT model file (see :func:`read_model`)."""
    caption = None
    header: dict = {}
    terms: list[ModelTerm] = []
    ended = False
    for lineno, line in _records(text, path):
        if caption is None:
            caption = line
            continue
        if line == "END":
            ended = True
            break
        tokens = line.split()
        if len(tokens[0]) == 1 and tokens[0].isalpha() and not terms and not header:
            record = f"fit-summary record '{tokens[0]}'"
            if len(tokens) not in (3, 5):
                raise TpointFormatError(
                    path, lineno, f"{record} has {len(tokens)} fields; expected letter, N, Sky RMS and optionally refraction A, B"
                )
            v = _numbers(
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
        v = _numbers(path, lineno, tokens[1:], ("value (arcsec)", "sigma (arcsec)"), f"term record {name}", first=2)
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
    return parse_model(_read_text(path), path)


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
) -> str:
    """Text of a TPOINT model file. Values and ``sky_rms`` in arcseconds.

    Numbers are written in TPOINT's fixed-point layout with as many decimals as it
    takes to read back the same float64 (at least TPOINT's 4 for values, 5 for sigmas),
    so a model written and read back is the same model. A sigma that is ``None`` or not
    finite (a degenerate parameter) is left out.

    Raises:
        ValueError: for a NaN or infinite value, Sky RMS or refraction constant, naming
            the term or field (the reader would refuse the file).
    """
    caption = caption.strip()
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
    return "\n".join(lines) + "\n"


def write_model(path: str | os.PathLike, source, caption: str | None = None, refraction: tuple[float, float] = (0.0, 0.0)) -> None:
    """Write a TPOINT model file from a :class:`pointax.FitResult` or a :class:`pointax.Model`.

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
    Path(path).write_text(format_model(terms, caption, n_obs, sky_rms, refraction))

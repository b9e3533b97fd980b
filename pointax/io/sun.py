"""Sun observations of a sun-tracking turntable: a plain text format.

A calibration of a mirror turntable (the sun-vector paper, :func:`pointax.Turntable`)
records, at each instant the sun is centred in the sun sensor, the two encoder
readings and the sun's direction. One observation per line, whitespace- (or comma-)
separated numbers in degrees::

    # site: turntable 7, 2024-06-21            '#' starts a comment (whole line or trailing)
    # alpha_deg  beta_deg   sun_az_deg  sun_el_deg  [weight]
    279.436      216.460    141.022     50.469
    272.655      218.653    147.820     52.704      0.5

=========  ===============================================================
column     meaning
=========  ===============================================================
1 alpha    azimuth encoder reading, degrees (as the encoder counts)
2 beta     pitch encoder reading, degrees
3 sun_az   sun azimuth, degrees from North through East
4 sun_el   sun elevation (apparent, i.e. refracted), degrees, -90..90
5 weight   optional relative weight >= 0 (default 1; 0 drops the row)
=========  ===============================================================

Every line has four or five numbers. Any malformed line raises
:class:`SunFormatError`, whose message names the file, the line and the column.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import os
from collections.abc import Sequence

import numpy as np

from ..core.observations import Observations
from ..core.rotations import azel_to_enu_numpy
from .errors import FileFormatError, file_errors
from .sanity import AZIMUTH_LIMIT_DEG, HORIZON_DEG, check_not_radians, warn_duplicates
from .text import read_text

__all__ = [
    "SUN_COLUMNS",
    "SunFormatError",
    "SunRun",
    "parse_sun_observations",
    "read_sun_observations",
    "format_sun_observations",
    "write_sun_observations",
]

SUN_COLUMNS = ("alpha_deg", "beta_deg", "sun_az_deg", "sun_el_deg", "weight")
"""Column names, in file order (the fifth, ``weight``, is optional)."""


class SunFormatError(FileFormatError):
    """A sun-observation file could not be read; the message names file, line and column."""

    def __init__(self, path: str, line: int | None, message: str, column: int | None = None):
        self.column = column
        where = None if column is None else f"column {column} ({SUN_COLUMNS[column - 1]})"
        super().__init__(path, line, message, where)


@dataclasses.dataclass(frozen=True)
class SunRun:
    """Sun observations of one turntable, read by :func:`read_sun_observations`.

    Attributes:
        path: the file.
        comments: the text of the file's whole-line comments, in order (without '#').
        encoder: ``(n, 2)`` encoder readings ``(alpha, beta)``, radians.
        sun: ``(n, 2)`` sun azimuth (North through East) and elevation, radians.
        weight: ``(n,)`` relative weights.
        lines: ``(n,)`` line number of each observation in the file.
        observations: :class:`pointax.Observations` in the ``"turntable"`` convention
            (encoder readings, sun directions in East-North-Up, weights), ready for
            :func:`pointax.fit` with a :func:`pointax.Turntable` model.
    """

    path: str
    comments: tuple[str, ...]
    encoder: np.ndarray
    sun: np.ndarray
    weight: np.ndarray
    lines: np.ndarray
    observations: Observations

    def __len__(self) -> int:
        return self.encoder.shape[0]


def parse_sun_observations(text: str, path: str = "<string>") -> SunRun:
    """Parse the text of a sun-observation file (see the module docstring).

    Raises:
        SunFormatError: naming ``path``, line and column of the first malformed value.
    """
    parsed = _parse_columns(text)
    if parsed is None:  # something to refuse: the line-by-line reading names it
        parsed = _parse_lines(text, path)
    degrees, weights, lines, comments = parsed
    return _sun_run(path, degrees, weights, lines, comments)


def _parse_columns(text: str):
    """``(degrees (n, 4), weights (n,), lines, comments)`` of a well-formed file, read
    column-wise (one ``float`` per token, the checks on whole columns: a network reads
    thousands of files, and the line-by-line loop cost a millisecond each); None when any
    line or value is not well-formed, for :func:`_parse_lines` to name."""
    raw_lines = text.splitlines()
    comments: list[str] = []
    if "#" in text:
        bodies = []
        for raw in raw_lines:
            body, hash_, comment = raw.partition("#")
            if hash_ and not body.strip():
                comments.append(comment.strip())
            bodies.append(body)
    else:
        bodies = raw_lines
    if "," in text:
        bodies = [body.replace(",", " ") for body in bodies]
    fields = [body.split() for body in bodies]
    counts = [len(f) for f in fields]
    kinds = set(counts)
    kinds.discard(0)
    if not kinds or not kinds <= {4, 5}:
        return None
    lines = [k + 1 for k, count in enumerate(counts) if count] if 0 in counts else list(range(1, len(counts) + 1))
    try:
        flat = np.array(list(map(float, itertools.chain.from_iterable(fields))), np.float64)
    except ValueError:
        return None
    if kinds == {4}:
        degrees, weights = flat.reshape(-1, 4), np.ones(len(lines))
    elif kinds == {5}:
        table = flat.reshape(-1, 5)
        degrees, weights = table[:, :4], table[:, 4].copy()
    else:
        sizes = np.array([count for count in counts if count])
        starts = np.cumsum(sizes) - sizes
        degrees = flat[starts[:, None] + np.arange(4)]
        weights = np.where(sizes == 5, flat[np.minimum(starts + 4, flat.size - 1)], 1.0)
    el = degrees[:, 3]
    well_formed = (
        np.isfinite(flat).all()
        and (np.abs(el) <= 90.0).all()
        and (el >= HORIZON_DEG).all()
        and (np.abs(degrees[:, :3]) <= AZIMUTH_LIMIT_DEG).all()
        and (weights >= 0).all()
    )
    return (np.ascontiguousarray(degrees), weights, lines, comments) if well_formed else None


def _parse_lines(text: str, path: str):
    """The line-by-line reading: raises :class:`SunFormatError` at the first malformed
    line (file, line, column); else as :func:`_parse_columns`."""
    rows, weights, lines, comments = [], [], [], []
    for number, raw in enumerate(text.splitlines(), 1):
        body, hash_, comment = raw.partition("#")
        fields = body.replace(",", " ").split()
        if not fields:
            if hash_ and not body.strip():
                comments.append(comment.strip())
            continue
        if len(fields) not in (4, 5):
            raise SunFormatError(
                path,
                number,
                f"expected 4 or 5 numbers ({' '.join(SUN_COLUMNS[:4])} [weight]), got {len(fields)}: {raw.strip()!r}",
            )
        values = []
        for column, token in enumerate(fields, 1):
            try:
                value = float(token)
            except ValueError:
                raise SunFormatError(path, number, f"{token!r} is not a number", column) from None
            if not math.isfinite(value):
                raise SunFormatError(path, number, f"{token!r} is not finite", column)
            values.append(value)
        if abs(values[3]) > 90.0:
            raise SunFormatError(path, number, f"elevation {fields[3]} is outside -90..90 deg", 4)
        if values[3] < HORIZON_DEG:
            raise SunFormatError(
                path, number, f"elevation {fields[3]} deg is below the horizon by more than refraction allows "
                f"(lowest accepted {HORIZON_DEG:g} deg)", 4
            )
        for column in (1, 2, 3):
            if abs(values[column - 1]) > AZIMUTH_LIMIT_DEG:
                raise SunFormatError(path, number, f"{fields[column - 1]} deg is outside -360..360 deg", column)
        weight = values[4] if len(values) == 5 else 1.0
        if weight < 0:
            raise SunFormatError(path, number, f"weight {fields[4]} is negative", 5)
        rows.append(values[:4])
        weights.append(weight)
        lines.append(number)
    if not rows:
        raise SunFormatError(path, None, "no observations (expected lines of alpha_deg beta_deg sun_az_deg sun_el_deg [weight])")
    return np.asarray(rows, np.float64), np.asarray(weights, np.float64), lines, comments


def _sun_run(path: str, degrees: np.ndarray, weights: np.ndarray, lines: list[int], comments: list[str]) -> SunRun:
    """The checks on whole columns (radians written as degrees, repeated rows) and the run."""
    check_not_radians(
        SunFormatError,
        path,
        lines,
        {
            "column 1 (alpha_deg)": (degrees[:, 0], 2 * math.pi),
            "column 2 (beta_deg)": (degrees[:, 1], 2 * math.pi),
            "column 3 (sun_az_deg)": (degrees[:, 2], 2 * math.pi),
            "column 4 (sun_el_deg)": (degrees[:, 3], math.pi / 2),
        },
    )
    warn_duplicates(path, np.column_stack([degrees, weights]), lines, "observations")
    rad = np.radians(degrees)
    encoder, sun = rad[:, :2], rad[:, 2:]
    weight = np.asarray(weights, np.float64)
    observations = Observations(encoder, azel_to_enu_numpy(sun[:, 0], sun[:, 1]), weight, convention="turntable")
    return SunRun(
        path=path,
        comments=tuple(comments),
        encoder=encoder,
        sun=sun,
        weight=weight,
        lines=np.asarray(lines),
        observations=observations,
    )


@file_errors(SunFormatError)
def read_sun_observations(path: str | os.PathLike) -> SunRun:
    """Read a sun-observation file (see the module docstring for the format).

    Returns:
        :class:`SunRun`; its ``observations`` go straight into :func:`pointax.fit`.

    Raises:
        SunFormatError: naming file, line and column of the first malformed value.
        OSError: the file cannot be opened.
    """
    path = os.fspath(path)
    text = read_text(path, SunFormatError, comments="#")
    return parse_sun_observations(text, path)


def format_sun_observations(
    encoder: np.ndarray,
    sun: np.ndarray,
    weight: np.ndarray | None = None,
    comments: Sequence[str] = (),
) -> str:
    """The text of a sun-observation file.

    Args:
        encoder: ``(n, 2)`` encoder readings ``(alpha, beta)``, radians.
        sun: ``(n, 2)`` sun azimuth (North through East) and elevation, radians.
        weight: optional ``(n,)`` weights (written as a fifth column when given).
        comments: lines written first as ``# ...`` comments.
    """
    encoder = np.degrees(np.asarray(encoder, np.float64))
    sun = np.degrees(np.asarray(sun, np.float64))
    if encoder.ndim != 2 or encoder.shape[1] != 2 or sun.shape != encoder.shape:
        raise ValueError(f"encoder and sun must both have shape (n, 2), got {encoder.shape} and {sun.shape}")
    out = [f"# {c}" for c in comments]
    out.append("# " + "  ".join(SUN_COLUMNS[: 4 if weight is None else 5]))
    for k in range(encoder.shape[0]):
        row = f"{encoder[k, 0]:.9f} {encoder[k, 1]:.9f} {sun[k, 0]:.9f} {sun[k, 1]:.9f}"
        if weight is not None:
            row += f" {float(weight[k]):.12g}"
        out.append(row)
    return "\n".join(out) + "\n"


def write_sun_observations(path: str | os.PathLike, encoder, sun, weight=None, comments: Sequence[str] = ()) -> None:
    """Write a sun-observation file (arguments as :func:`format_sun_observations`)."""
    with open(path, "w", encoding="utf-8") as f:
        f.write(format_sun_observations(encoder, sun, weight, comments))

"""One reader for every pointing-run format: :func:`load_run`, and :func:`detect_format`.

    run = pointax.io.load_run("examples/data/mmt_20210821.dat", azimuth="S-E")   # TPOINT
    run = pointax.io.load_run("paint/AA39")                                     # PAINT folder
    result = pointax.fit(model, run)          # every run has .observations

=========  ==========================================================  ===============
format     what it is                                                  returns
=========  ==========================================================  ===============
tpoint     TPOINT input file (:mod:`pointax.io.tpoint`)                TpointRun
gpoint     RTS2 gpoint run, alt-az or GEM (:mod:`pointax.io.gpoint`)     GpointRun
paint      PAINT heliostat folder (:mod:`pointax.io.paint`)            PaintRun
sun        sun observations of a turntable (:mod:`pointax.io.sun`)     SunRun
xy         X-Y mount run, ``L B L0 B0`` (:mod:`pointax.io.xy`)          XYRun
offsets    table of pointing offsets (:mod:`pointax.io.offsets`)       OffsetsRun
=========  ==========================================================  ===============

Detection reads at most the first 64 KiB of a file and never imports a numerical
library, so a command line can say what is wrong with its input straight away.
"""

from __future__ import annotations

import errno
import os
import re
from pathlib import Path
from typing import Any

from .errors import FileFormatError
from .text import is_number

__all__ = ["RUN_FORMATS", "RUN_OPTIONS", "FormatDetectionError", "detect_format", "load_run"]

RUN_FORMATS = ("tpoint", "gpoint", "paint", "sun", "xy", "offsets")
"""The formats :func:`load_run` reads."""

RUN_OPTIONS: dict[str, tuple[str, ...]] = {
    "tpoint": ("azimuth", "mount", "refraction", "auxiliary"),
    "gpoint": (),
    "paint": ("focal_spot", "tower", "mirror_offset"),
    "sun": (),
    "xy": (),
    "offsets": ("columns", "units", "azimuth", "cross_elevation", "sign"),
}
"""Format -> the keyword options its reader takes."""

_DESCRIPTIONS = {
    "tpoint": "a TPOINT input file (a caption line, then ':' option records, a run-parameters line, data, END)",
    "gpoint": "an RTS2 gpoint run (a '# altaz-manual|altaz|gem|observatory LON LAT ALT' header line)",
    "paint": "a PAINT heliostat folder",
    "sun": "sun observations of a turntable: 'alpha beta sun_az sun_el [weight]' in degrees per line",
    "xy": "an X-Y mount run: 'L B L0 B0' in degrees per line",
    "offsets": "a table of pointing offsets (CSV or whitespace): az el daz del [errors], with a header naming "
    "the columns, or read with --format offsets (and --columns when it has no header; columns= in Python)",
}

_GPOINT_HEADERS = ("altaz-manual", "altaz", "observatory", "gem")
_HEAD_BYTES = 65536
_HEAD_LINES = 200


class FormatDetectionError(FileFormatError):
    """The format of a run could not be told from the file (or is not known); the
    message names the file and lists the formats."""


def _formats_text() -> str:
    return "; ".join(f"{name}: {text}" for name, text in _DESCRIPTIONS.items())


def _undetected(path: str, why: str) -> FormatDetectionError:
    return FormatDetectionError(
        path, None, f"{why}; give the format (one of {', '.join(RUN_FORMATS)}): {_formats_text()}"
    )


_OFFSET_AZIMUTHS = ("az", "azimuth", "raw_az", "cmd_az", "enc_az")
_OFFSET_ELEVATIONS = ("el", "elevation", "alt", "altitude", "raw_el", "cmd_el", "enc_el")


def _offsets_header(lines: list[str]) -> bool:
    """Whether the first record is an offsets table's header: it names an azimuth, an
    elevation and at least two offsets (``daz``, ``delta_el``, ``az_off``, ``dxel``),
    units in the names allowed (``dxel [arcmin]``, ``del/arcsec``)."""
    from .offset_columns import header_fields, role_of, split_unit

    records = (line.split("#", 1)[0].split("!", 1)[0].strip() for line in lines)
    first = next((r for r in records if r), "")
    fields = [f.strip("\"'") for f in header_fields(first, "," in first)]
    roles = {role_of(f) for f in fields if f}
    if {"azimuth", "elevation", "azimuth_offset", "elevation_offset"} <= roles:
        return True
    words = [split_unit(f)[0].lower() for f in fields if f]
    offsets = sum(w.startswith(("d", "delta")) or "off" in w or "xel" in w for w in words)
    return any(w in _OFFSET_AZIMUTHS for w in words) and any(w in _OFFSET_ELEVATIONS for w in words) and offsets >= 2


def _all_numbers(record: str) -> bool:
    tokens = record.split()
    return bool(tokens) and all(is_number(t) for t in tokens)


def detect_format(path: str | os.PathLike) -> str:
    """The format of the run at ``path``, one of :data:`RUN_FORMATS`.

    A folder is a PAINT heliostat folder. A file is a gpoint run when a ``#`` line
    names a gpoint header (``altaz-manual``, ``altaz``, ``gem``, ``observatory``); a TPOINT file when, after
    its caption line, a record starts with ``:`` or reads ``END``, or a text caption is
    followed by a run-parameters record of numbers (a file with no option records); a sun file when its
    lines hold five numbers (the fifth is a weight) or its comments name the sun
    columns (``alpha``, ``sun_az``); an X-Y run when its comments name ``L0``/``B0`` or
    say ``X-Y``; an offsets table when its first record is a header naming azimuth,
    elevation and two offsets. The content need not be valid: the format's reader reports errors.

    Raises:
        FileNotFoundError: nothing at ``path``.
        FormatDetectionError: the format cannot be told (for example four numbers per
            line and no comment saying which columns they are); the message lists the
            formats.
    """
    name = os.fspath(path)
    p = Path(name)
    if p.is_dir():
        return "paint"
    if not p.exists():
        raise FileNotFoundError(errno.ENOENT, os.strerror(errno.ENOENT), name)
    with open(p, "rb") as f:
        head = f.read(_HEAD_BYTES)
    if b"\0" in head:
        raise _undetected(name, "not a text file")
    lines = head.decode("utf-8-sig", errors="replace").splitlines()[:_HEAD_LINES]
    if not any(line.strip() for line in lines):
        raise _undetected(name, "empty file")

    for line in lines:
        if line.startswith("#"):
            words = line[1:].split()
            if words and words[0] in _GPOINT_HEADERS:
                return "gpoint"

    if _offsets_header(lines):
        return "offsets"

    # TPOINT: '!' or ';' comment lines, a caption, then records; an option record starts with ':'.
    records = [re.split(r"[!;]", line, maxsplit=1)[0].strip() for line in lines if line.lstrip()[:1] not in ("!", ";")]
    records = [r for r in records if r]
    if any(r.startswith(":") or r.upper() == "END" for r in records[1:]):
        return "tpoint"
    if len(records) > 2 and not _all_numbers(records[0]) and _all_numbers(records[1]) and 3 <= len(records[1].split()) <= 12:
        return "tpoint"  # a caption, a run-parameters record, data: a TPOINT run without option records

    # Tables of numbers: '#' comments.
    comments = " ".join(line.split("#", 1)[1] for line in lines if "#" in line)
    rows = [line.split("#", 1)[0].replace(",", " ").split() for line in lines]
    rows = [r for r in rows if r]
    if rows and all(all(is_number(t) for t in r) for r in rows):
        widths = {len(r) for r in rows}
        if widths <= {4, 5}:
            if 5 in widths:
                return "sun"
            words = comments.replace(",", " ").split()
            lowered = comments.lower()
            says_xy = "L0" in words or "B0" in words or "x-y" in lowered
            says_sun = "alpha" in lowered or "sun_az" in lowered or "sun_el" in lowered
            if says_xy and not says_sun:
                return "xy"
            if says_sun and not says_xy:
                return "sun"
            raise _undetected(
                name, "four numbers per line could be sun observations (alpha beta az el) or an X-Y run (L B L0 B0)"
            )
        raise _undetected(name, f"lines of {'/'.join(str(w) for w in sorted(widths))} numbers match no format")
    raise _undetected(name, "cannot tell the format")


def load_run(path: str | os.PathLike, format: str | None = None, **options: Any):
    """Read a pointing run in any of :data:`RUN_FORMATS`.

    Args:
        path: the file (a folder for PAINT).
        format: one of :data:`RUN_FORMATS`, or None to tell it from the file
            (:func:`detect_format`).
        **options: the format's reader options (:data:`RUN_OPTIONS`): tpoint
            ``azimuth``, ``mount``, ``refraction``, ``auxiliary`` (:func:`pointax.io.read_tpoint`); paint ``focal_spot``,
            ``tower``, ``mirror_offset`` (:func:`pointax.io.read_paint`); offsets
            ``columns``, ``units``, ``azimuth``, ``cross_elevation``, ``sign``
            (:func:`pointax.io.read_offsets`).

    Returns:
        The format's run (:class:`~pointax.io.TpointRun`, :class:`~pointax.io.GpointRun`,
        :class:`~pointax.io.PaintRun`, :class:`~pointax.io.SunRun`,
        :class:`~pointax.io.XYRun`); each has ``.observations``, whose ``readings``
        hold what the file records beside the positions (TPOINT's auxiliary fields and
        run weather, an offsets table's other columns, gpoint's and PAINT's times).

    Raises:
        FileNotFoundError: nothing at ``path``.
        FormatDetectionError: ``format`` is None and the format cannot be told, or
            ``format`` is not one of :data:`RUN_FORMATS`.
        ValueError: an option the format's reader does not take.
        FileFormatError: the reader's errors (file, line, field).
    """
    name = os.fspath(path)
    fmt = detect_format(name) if format is None else format
    if fmt not in RUN_FORMATS:
        raise FormatDetectionError(name, None, f"unknown format {fmt!r}; the formats are {_formats_text()}")
    unknown = sorted(set(options) - set(RUN_OPTIONS[fmt]))
    if unknown:
        takes = ", ".join(RUN_OPTIONS[fmt]) or "none"
        raise ValueError(f"{name}: option(s) {', '.join(unknown)} do not apply to {fmt} runs (its options: {takes})")
    if fmt == "tpoint":
        from .tpoint import read_tpoint

        return read_tpoint(name, **options)
    if fmt == "gpoint":
        from .gpoint import read_gpoint

        return read_gpoint(name)
    if fmt == "paint":
        from .paint import read_paint

        return read_paint(name, **options)
    if fmt == "sun":
        from .sun import read_sun_observations

        return read_sun_observations(name)
    if fmt == "offsets":
        from .offsets import read_offsets

        return read_offsets(name, **options)
    from .xy import XYRun, read_xy_run

    return XYRun(path=name, observations=read_xy_run(name))

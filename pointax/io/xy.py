"""X-Y mount pointing runs: a plain text format (the level-mount paper's eq 20 columns).

One star per line, four numbers in degrees, ``L B L0 B0``: the encoder readings ``L, B``
and where the star is, ``L0, B0``, as X-Y angles (the direction is ``(sin L0 cos B0,
sin B0, cos L0 cos B0)`` in East-North-Up)::

    # X-Y pointing run: L B (encoder readings) L0 B0 (the star), degrees
    12.500000000 40.250000000 12.501200000 40.249100000

``#`` starts a comment; fields may be separated by spaces, tabs or commas.
:func:`write_xy_run` writes it, :func:`read_xy_run` reads it (``pointax compare
--mount xy``).
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path

import numpy as np

from ..core.observations import Observations
from .errors import FileFormatError, file_errors
from .sanity import AZIMUTH_LIMIT_DEG, check_not_radians, warn_duplicates
from .text import read_text

__all__ = ["XY_FIELDS", "XYFormatError", "XYRun", "read_xy_run", "write_xy_run"]


class XYFormatError(FileFormatError):
    """An X-Y run file could not be read; the message names file, line and field."""


XY_FIELDS = ("L", "B", "L0", "B0")
"""Column names, in file order."""


@dataclasses.dataclass(frozen=True)
class XYRun:
    """An X-Y run as :func:`pointax.io.load_run` returns it (:func:`read_xy_run` returns
    the observations alone).

    Attributes:
        path: the file.
        observations: :class:`pointax.Observations` in the ``"xy"`` convention.
    """

    path: str
    observations: Observations


@file_errors(XYFormatError)
def read_xy_run(path: str | os.PathLike) -> Observations:
    """Read an X-Y run in this module's text format (``L B L0 B0`` in degrees).

    Returns:
        :class:`pointax.Observations` with convention 'xy': encoder ``(L, B)`` radians,
        targets ``(sin L0 cos B0, sin B0, cos L0 cos B0)`` in East-North-Up.

    Raises:
        XYFormatError: naming the file, line and field of the first bad value.
        OSError: the file cannot be read.
    """
    name = os.fspath(path)
    rows, lines = [], []
    for number, line in enumerate(read_text(name, XYFormatError, comments="#").splitlines(), 1):
        fields = line.split("#", 1)[0].replace(",", " ").split()
        if not fields:
            continue
        if len(fields) != 4:
            raise XYFormatError(name, number, f"expected 4 numbers L B L0 B0 (degrees), got {len(fields)}: {line.strip()!r}")
        values = []
        for field, token in zip(XY_FIELDS, fields):
            try:
                x = float(token)
            except ValueError:
                raise XYFormatError(name, number, f"not a number: {token!r}", f"field {field}") from None
            if not math.isfinite(x):
                raise XYFormatError(name, number, f"not finite: {token!r}", f"field {field}")
            if field == "B0" and abs(x) > 90.0:
                raise XYFormatError(name, number, f"{x} is outside -90..90 deg", f"field {field}")
            if abs(x) > AZIMUTH_LIMIT_DEG:
                raise XYFormatError(name, number, f"{x} deg is outside -360..360 deg", f"field {field}")
            values.append(x)
        rows.append(values)
        lines.append(number)
    if not rows:
        raise XYFormatError(name, None, "no observations (expected lines of L B L0 B0 in degrees)")
    degrees = np.asarray(rows, np.float64)
    check_not_radians(
        XYFormatError, name, lines, {f"field {f}": (degrees[:, k], math.pi / 2) for k, f in enumerate(XY_FIELDS)}
    )
    warn_duplicates(name, degrees, lines, "observations")
    a = np.radians(degrees)
    L0, B0 = a[:, 2], a[:, 3]
    target = np.stack([np.sin(L0) * np.cos(B0), np.sin(B0), np.cos(L0) * np.cos(B0)], axis=1)
    return Observations(a[:, :2], target, convention="xy")


def write_xy_run(path: str | os.PathLike, observations, comments: tuple[str, ...] = ()) -> None:
    """Write X-Y observations (convention 'xy') in this module's text format."""
    obs = observations if isinstance(observations, Observations) else observations.observations
    if obs.convention != "xy":
        raise ValueError(f"write_xy_run writes X-Y runs; these observations are {obs.convention!r}")
    enc = np.degrees(np.asarray(obs.encoder, np.float64))
    t = np.asarray(obs.target, np.float64)
    L0 = np.degrees(np.arctan2(t[:, 0], t[:, 2]))
    B0 = np.degrees(np.arcsin(np.clip(t[:, 1], -1.0, 1.0)))
    lines = [f"# {c}" for c in comments]
    lines.append("# X-Y pointing run: L B (encoder readings) L0 B0 (the star), degrees")
    lines += [f"{a:.9f} {b:.9f} {c:.9f} {d:.9f}" for (a, b), c, d in zip(enc, L0, B0)]
    Path(path).write_text("\n".join(lines) + "\n")

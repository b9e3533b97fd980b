"""RTS2 gpoint input files of alt-az pointing runs (``altaz-manual`` and ``altaz``).

The definition is gpoint's own reader, ``GPoint.process_files`` in RTS2's
``python/rts2/gpoint.py`` (repository ``RTS2/rts2``, commit
``6480a7eb549d3158ee178ce557fab6d75de8eba9``), and the writer of ``altaz-manual``
files, ``TPVP.get_altazm_line`` in ``python/rts2/tpvp.py`` (same repository); the
gpoint manual page (``man/gpoint.txt``) shows an example. Layout::

    # model file created on ...                line 1: gpoint skips it, whatever it holds
    # altaz-manual -20.8 -32.53 1850.0         header: format, longitude (deg, East +),
                                               latitude (deg, North +), altitude (m)
    1  2457000.5  356.214  -23.34  0.01  -0.02  10.0  20.0
    ...

``altaz-manual`` rows (8 fields, as gpoint unpacks them, ``sn,mjd,ra,dec,e_alt,e_az,
a_alt,a_az``): observation id, time (gpoint calls it MJD; RTS2's writer puts the JD
there), target RA and Dec (deg, not used by the fit), the elevation and azimuth
errors (deg), the mount's elevation and azimuth (deg). gpoint takes the mount position
``(a_az, a_alt)`` as the raw position and ``(a_az + e_az, a_alt + e_alt)`` as the real
(observed) one.

``altaz`` rows (9 fields, ``sn,mjd,lst,a_az,a_alt,ax_az,ax_alt,r_az,r_alt``): id, time,
local sidereal time (deg), the mount's azimuth and elevation (deg), the two axis
counts, the real azimuth and elevation (deg).

**Azimuth** is counted as RTS2 and libnova count it, from South through West
(``run.azimuth == "S-W"``): gpoint's ``hrz_to_equ`` uses ``ha = atan2(sin A, ...)``
with ``A = 0`` South, and its sky plot puts ``A = 0`` at S and ``A = 90`` at W. Encoder
and observed angles are kept in that convention; the observed directions are
converted to East-North-Up (``A_NE = A + 180 deg``). Fit gpoint's terms
(:func:`pointax.terms.gpoint_terms`) with ``pointax.AltAz(terms, azimuth=run.azimuth)``.

Where pointax is stricter than gpoint (gpoint would crash, misread or silently drop):

* line 1 must be blank or a comment: gpoint skips it unread, so a header or an
  observation there would be lost;
* a header is required (without one gpoint reads the rows as an equatorial run), only
  one per file, with numeric longitude, latitude and altitude; equatorial files
  (``# gem``, ``# observatory``) are refused;
* a row must have exactly 8 (``altaz-manual``) or 9 (``altaz``) fields, every field
  after the id a finite number, observed elevations within +-90 deg;
* blank lines are skipped (gpoint would stop with an unpacking error).

Every error is a :class:`GpointFormatError` naming the file, line and field.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
from pathlib import Path

import numpy as np

from ..mounts import AZIMUTH_CONVENTIONS
from ..observations import Observations
from ..rotations import azel_to_enu_numpy
from ..units import DEG
from .errors import FileFormatError
from .sanity import check_azimuth, check_not_radians, check_observed_elevation, warn_duplicates

__all__ = ["GpointFormatError", "GpointRun", "read_gpoint", "parse_gpoint", "GPOINT_AZIMUTH", "ROW_FIELDS"]

GPOINT_AZIMUTH = "S-W"
"""How gpoint (RTS2, libnova) counts azimuth: from South through West."""

ROW_FIELDS = {
    "altaz-manual": (
        "observation id",
        "time (MJD/JD)",
        "target RA (deg)",
        "target Dec (deg)",
        "elevation error (deg)",
        "azimuth error (deg)",
        "mount elevation (deg)",
        "mount azimuth (deg)",
    ),
    "altaz": (
        "observation id",
        "time (MJD)",
        "local sidereal time (deg)",
        "mount azimuth (deg)",
        "mount elevation (deg)",
        "azimuth axis counts",
        "elevation axis counts",
        "real azimuth (deg)",
        "real elevation (deg)",
    ),
}
"""Row fields of each alt-az format, in file order."""

_HEADER = re.compile(r"#\s*(\S*)\s+(\S*)\s+(\S*)\s+(\S*)\s*")  # gpoint's own `obsmatch`
_ALTAZ_KINDS = ("altaz-manual", "altaz")
_EQUATORIAL_KINDS = ("observatory", "gem")
_HEADER_FIELDS = ("longitude (deg)", "latitude (deg)", "altitude (m)")


class GpointFormatError(FileFormatError):
    """A gpoint file could not be read; the message names file, line and field."""


@dataclasses.dataclass(frozen=True)
class GpointRun:
    """An alt-az pointing run read from a gpoint input file.

    Angles are radians; azimuths are counted from South through West (:attr:`azimuth`
    is ``"S-W"``), as in the file. ``observations`` holds the encoder angles unchanged
    and the observed directions in East-North-Up.
    """

    path: str
    caption: str
    """Line 1 without its ``#`` (gpoint skips it; RTS2 writes 'model file created on ...');
    :func:`pointax.fit` shows it as the report's title."""
    kind: str
    """``"altaz-manual"`` or ``"altaz"``."""
    longitude: float
    """Site longitude from the header, radians, East positive."""
    latitude: float
    """Site latitude from the header, radians, North positive."""
    altitude_m: float
    """Site altitude from the header, metres."""
    ids: tuple[str, ...]
    """Observation id of each row (field 1), as written."""
    time: np.ndarray
    """``(n,)`` field 2 as written (gpoint calls it MJD; RTS2's manual writer puts the JD)."""
    encoder: np.ndarray
    """``(n, 2)`` the mount's (raw) azimuth and elevation, radians, South through West."""
    observed: np.ndarray
    """``(n, 2)`` the real (observed) azimuth and elevation, radians, South through West."""
    columns: dict
    """The row fields gpoint's fit does not use, by name, as ``(n,)`` arrays: ``"ra"``,
    ``"dec"`` (radians) for altaz-manual; ``"lst"`` (radians), ``"axis_az"``,
    ``"axis_el"`` (counts) for altaz."""
    lines: np.ndarray
    """``(n,)`` line number of each observation in the file."""
    azimuth: str
    """The azimuth convention of ``encoder`` and ``observed``: ``"S-W"``."""
    observations: Observations

    def __len__(self) -> int:
        return self.encoder.shape[0]


def _number(path: str, lineno: int, token: str, field: int, name: str, record: str) -> float:
    try:
        value = float(token)
    except ValueError:
        raise GpointFormatError(path, lineno, f"{record}: field {field} ({name}) is {token!r}, not a number") from None
    if not math.isfinite(value):
        raise GpointFormatError(path, lineno, f"{record}: field {field} ({name}) is {token!r}, not finite")
    return value


def parse_gpoint(text: str, path: str = "<string>") -> GpointRun:
    """Parse the text of a gpoint input file (see :func:`read_gpoint`)."""
    lines = text.splitlines()
    if not lines or not any(line.strip() for line in lines):
        raise GpointFormatError(path, None, "empty file")
    first = lines[0]
    match = _HEADER.match(first)
    if match and match.group(1) in _ALTAZ_KINDS + _EQUATORIAL_KINDS:
        raise GpointFormatError(
            path,
            1,
            f"the header {first.strip()!r} is on line 1, which gpoint skips unread; "
            "put a comment line (e.g. '# model file created on ...') before it",
        )
    if first.strip() and not first.startswith("#"):
        raise GpointFormatError(
            path, 1, "line 1 is not a comment: gpoint skips the first line unread, so this observation would be lost"
        )
    header = None
    rows: list[tuple[int, list[str]]] = []
    for lineno, line in enumerate(lines[1:], 2):
        if line.startswith("#"):
            words = line[1:].split()
            kind = words[0] if words else ""
            if kind not in _ALTAZ_KINDS + _EQUATORIAL_KINDS:
                continue  # a comment, as for gpoint
            match = _HEADER.match(line)
            if match and match.group(1) != kind:  # gpoint's regex matched with an empty keyword
                match = None
            if kind in _EQUATORIAL_KINDS:
                raise GpointFormatError(
                    path, lineno, f"header '# {kind}' marks an equatorial (GEM) run; pointax reads gpoint's alt-az runs "
                    "('# altaz-manual' or '# altaz')"
                )
            if header is not None:
                raise GpointFormatError(path, lineno, f"a second header line (the first is on line {header[0]})")
            if not match:
                raise GpointFormatError(
                    path, lineno, f"header '# {kind}' needs longitude (deg), latitude (deg) and altitude (m) after it"
                )
            record = f"header '# {kind}'"
            values = [
                _number(path, lineno, match.group(k + 2), k + 2, _HEADER_FIELDS[k], record) for k in range(3)
            ]
            if not -90.0 <= values[1] <= 90.0:
                raise GpointFormatError(path, lineno, f"{record}: field 3 (latitude (deg)) {match.group(3)} is outside -90..90")
            header = (lineno, kind, values)
            continue
        if not line.strip():
            continue
        rows.append((lineno, line.split()))
    if header is None:
        raise GpointFormatError(
            path,
            None,
            "no header line '# altaz-manual LONGITUDE LATITUDE ALTITUDE' (or '# altaz ...'); "
            "without one gpoint reads the rows as an equatorial run",
        )
    if not rows:
        raise GpointFormatError(path, None, "no observation rows")
    _, kind, (longitude, latitude, altitude) = header
    names = ROW_FIELDS[kind]
    record = f"{kind} row"
    ids, numbers, line_numbers = [], [], []
    for lineno, tokens in rows:
        if len(tokens) != len(names):
            raise GpointFormatError(
                path,
                lineno,
                f"{record} has {len(tokens)} fields; gpoint's {kind} rows have {len(names)}: " + ", ".join(names),
            )
        ids.append(tokens[0])
        numbers.append(
            [_number(path, lineno, token, k + 2, names[k + 1], record) for k, token in enumerate(tokens[1:])]
        )
        line_numbers.append(lineno)
    v = np.asarray(numbers, np.float64)
    if kind == "altaz-manual":
        # gpoint: (a_az, a_alt, a_az + e_az, a_alt + e_alt) from sn,mjd,ra,dec,e_alt,e_az,a_alt,a_az
        encoder_deg = v[:, [6, 5]]
        observed_deg = np.stack([v[:, 6] + v[:, 4], v[:, 5] + v[:, 3]], axis=-1)
        columns = {"ra": v[:, 1] * DEG, "dec": v[:, 2] * DEG}
        observed_fields = "mount elevation + elevation error"
    else:
        # gpoint: (a_az, a_alt, r_az, r_alt) from sn,mjd,lst,a_az,a_alt,ax_az,ax_alt,r_az,r_alt
        encoder_deg = v[:, [2, 3]]
        observed_deg = v[:, [6, 7]]
        columns = {"lst": v[:, 1] * DEG, "axis_az": v[:, 4], "axis_el": v[:, 5]}
        observed_fields = "field 9 (real elevation (deg))"
    for k, lineno in enumerate(line_numbers):
        if not -90.0 <= observed_deg[k, 1] <= 90.0:
            raise GpointFormatError(
                path, lineno, f"{record}: observed elevation ({observed_fields}) {observed_deg[k, 1]:.6f} deg is outside -90..90"
            )
        if not -90.0 <= encoder_deg[k, 1] <= 180.0:
            raise GpointFormatError(
                path, lineno, f"{record}: mount elevation {encoder_deg[k, 1]:.6f} deg is outside -90..180"
            )
        check_observed_elevation(GpointFormatError, path, lineno, observed_deg[k, 1], f"{record}: observed elevation ({observed_fields})")
        check_azimuth(GpointFormatError, path, lineno, encoder_deg[k, 0], f"{record}: mount azimuth")
        check_azimuth(GpointFormatError, path, lineno, observed_deg[k, 0], f"{record}: observed azimuth")
    check_not_radians(
        GpointFormatError,
        path,
        line_numbers,
        {
            "mount azimuth": (encoder_deg[:, 0], 2 * math.pi),
            "mount elevation": (encoder_deg[:, 1], math.pi),
            "observed elevation": (observed_deg[:, 1], math.pi / 2),
        },
    )
    warn_duplicates(path, v, line_numbers, f"{record}s")
    encoder = encoder_deg * DEG
    observed = observed_deg * DEG
    frame = np.asarray(AZIMUTH_CONVENTIONS[GPOINT_AZIMUTH])
    target = azel_to_enu_numpy(observed[:, 0], observed[:, 1]) @ frame.T
    return GpointRun(
        path=path,
        caption=first.lstrip("#").strip(),
        kind=kind,
        longitude=longitude * DEG,
        latitude=latitude * DEG,
        altitude_m=altitude,
        ids=tuple(ids),
        time=v[:, 0],
        encoder=encoder,
        observed=observed,
        columns=columns,
        lines=np.asarray(line_numbers),
        azimuth=GPOINT_AZIMUTH,
        observations=Observations(encoder, target, convention=GPOINT_AZIMUTH),
    )


def read_gpoint(path: str | os.PathLike) -> GpointRun:
    """Read a gpoint input file of an alt-az pointing run (``# altaz-manual`` or ``# altaz``).

    Returns a :class:`GpointRun`; fit it with
    ``pointax.fit(pointax.AltAz(pointax.terms.gpoint_terms("ia,ie,tn,te,npae,npoa,tf"),
    azimuth=run.azimuth), run)``.

    Raises:
        GpointFormatError: naming file, line and field of the first malformed record.
    """
    path = os.fspath(path)
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as err:
        raise GpointFormatError(path, None, f"not a text file ({err})") from None
    return parse_gpoint(text, path)

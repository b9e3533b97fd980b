"""Tables of pointing offsets (radio telescopes, star trackers): CSV or whitespace text.

A pointing run of a radio telescope (five-point or cross scans on point sources) or a
star tracker is often kept as a plain table: one row per source, the commanded (raw)
azimuth and elevation, and the offsets measured there::

    # MeerKAT-like pointing table                '#' or '!' starts a comment
    az, el, dxel, del, dxel_err, del_err         optional header line (names, see below)
    12.50, 45.00, 31.2, -12.0, 1.5, 1.4          one row per observation
    ...

=====================  =====================================================  ==========
role                   meaning                                                unit
=====================  =====================================================  ==========
``azimuth``            raw (commanded / encoder) azimuth, file's convention   degrees
``elevation``          raw elevation                                          degrees
``azimuth_offset``     observed minus raw azimuth: cross-elevation dA cos E   ``units``
                       (``cross_elevation=True``, default) or plain dA
``elevation_offset``   observed minus raw elevation, dE                       ``units``
``azimuth_error``      optional 1-sigma error of ``azimuth_offset``           ``units``
``elevation_error``    optional 1-sigma error of ``elevation_offset``         ``units``
``error``              optional 1-sigma error of both offsets                 ``units``
=====================  =====================================================  ==========

Columns: separated by commas when the first record (header or data) holds a comma,
else by whitespace. Comment lines start with ``#`` or ``!`` (after optional blanks);
a ``#`` or ``!`` later on a line starts a trailing comment; blank lines are skipped.
A first record with any field that is not a number is a header. Columns are found:

* by header name (default), matching common names case-insensitively, with a unit
  in brackets dropped (``"Az [deg]"`` is ``az``): ``az azimuth raw_az cmd_az enc_az``,
  ``el elevation alt altitude raw_el``, ``daz dxel xel delta_az az_off az_offset
  cross_el d_az``, ``del delta_el el_off el_offset d_el dalt alt_off``, and names
  with ``err``, ``sigma``, ``unc`` or ``std`` for the errors (``daz_err``,
  ``sigma_el``, ``err``). Columns whose name matches no role are ignored;
* by an explicit mapping ``columns={"azimuth": "AZ", "azimuth_offset": 3, ...}`` of
  roles to header names or 1-based column numbers (the mapped roles replace the
  detected ones; names need a header);
* by position, ``columns=("azimuth", "elevation", None, "azimuth_offset", ...)``: the
  role of each column in order (``None`` skips one);
* without a header and without ``columns``: ``az el daz del`` and, when present,
  one error for both (5 columns) or ``daz_err del_err`` (6 columns).

Conventions (stated once, tested in ``tests/test_io_offsets.py``):

* Sign: offsets are **observed minus raw** (TPOINT's sign): the source was found at
  ``raw + offset``. A table of raw minus observed (the correction to apply to the
  command) is read with ``sign="raw-observed"``.
* Cross-elevation: ``azimuth_offset`` is ``dA cos E`` by default (what radio pointing
  scans measure), with ``E`` the observed elevation ``E_raw + dE`` (TPOINT's
  definition); ``cross_elevation=False`` reads a plain azimuth difference ``dA``.
  Errors of the azimuth offset are read in the same sense.
* Units: ``units`` is the unit of the offsets and errors: ``"arcsec"`` (default),
  ``"arcmin"``, ``"deg"`` or ``"rad"``. Positions are always degrees.
* Weights: with errors, each row's weight is ``1 / sigma^2`` with ``sigma^2`` the mean
  of the two on-sky variances (``(sigma_xel^2 + sigma_E^2) / 2``; a plain-dA error
  counts as ``sigma_dA cos E`` on the sky), normalised to mean 1, so that the weights
  are relative: the fit's Sky RMS and parameter sigmas keep their meaning (TPOINT
  scales sigmas by the residuals, so only the ratios of the weights matter).

The result's ``observations`` (:class:`pointax.Observations`) hold the raw position as
the encoder reading, in radians in the file's azimuth convention (``azimuth``), and the
observed direction ``raw + offset`` as an East-North-Up unit vector, ready for
``px.fit(px.AltAz(terms, azimuth=azimuth), run.observations)``.

Every malformed row raises :class:`OffsetsFormatError`, whose message names the file,
the line and the column.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
from collections.abc import Mapping, Sequence

import numpy as np

from ..mounts import AZIMUTH_CONVENTIONS
from ..observations import Observations
from ..rotations import azel_to_enu_numpy
from ..units import ARCSEC, DEG
from .errors import FileFormatError
from .sanity import check_azimuth, check_not_radians, check_observed_elevation, warn_duplicates
from .text import is_number, read_text

__all__ = [
    "OFFSET_ROLES",
    "OFFSET_UNITS",
    "OffsetsFormatError",
    "OffsetsRun",
    "parse_offsets",
    "read_offsets",
]

OFFSET_ROLES = (
    "azimuth",
    "elevation",
    "azimuth_offset",
    "elevation_offset",
    "azimuth_error",
    "elevation_error",
    "error",
)
"""The roles a column can take, in the default positional order."""

OFFSET_UNITS = {"arcsec": ARCSEC, "arcmin": 60 * ARCSEC, "deg": DEG, "rad": 1.0}
"""Units of the offsets and errors -> radians per unit."""

MAX_OFFSET_DEG = 10.0
"""An offset larger than this (degrees) is refused as a unit mistake."""

_REQUIRED = ("azimuth", "elevation", "azimuth_offset", "elevation_offset")

# Header names (normalised: lower case, unit in brackets dropped, blanks and '-' as '_').
_NAMES = {
    "azimuth": {
        "az", "azimuth", "azim", "az_deg", "azimuth_deg", "raw_az", "az_raw", "cmd_az", "az_cmd", "commanded_az",
        "az_commanded", "enc_az", "az_enc", "encoder_az", "az_encoder", "requested_az", "az_req",
    },
    "elevation": {
        "el", "elevation", "elev", "alt", "altitude", "el_deg", "elevation_deg", "alt_deg", "raw_el", "el_raw",
        "cmd_el", "el_cmd", "commanded_el", "el_commanded", "enc_el", "el_enc", "encoder_el", "el_encoder",
        "raw_alt", "alt_raw", "requested_el", "el_req",
    },
    "azimuth_offset": {
        "daz", "dxel", "xel", "dx", "delta_az", "deltaaz", "delta_xel", "d_az", "d_xel", "az_off", "az_offset",
        "off_az", "offset_az", "xel_off", "xel_offset", "off_xel", "offset_xel", "cross_el", "cross_elevation",
        "crossel", "daz_cos_el", "dazcosel", "daz_cosel", "delta_cross_el", "az_offset_cos_el",
    },
    "elevation_offset": {
        "del", "delev", "delta_el", "deltael", "d_el", "el_off", "el_offset", "off_el", "offset_el", "dalt",
        "delta_alt", "d_alt", "alt_off", "alt_offset", "off_alt", "offset_alt", "dy",
    },
}
_ERROR_WORDS = ("err", "sigma", "unc", "std")
_AZ_WORDS = ("az", "xel", "cross")
_EL_TOKENS = {"el", "del", "alt", "dalt", "elev", "delev", "elevation", "altitude", "eloff"}


class OffsetsFormatError(FileFormatError):
    """A pointing-offset table could not be read; the message names file, line and
    column (``path:line: column N (name): message``)."""


@dataclasses.dataclass(frozen=True)
class OffsetsRun:
    """A pointing run read from an offset table by :func:`read_offsets`.

    Attributes:
        path: the file.
        columns: role -> ``(1-based column number, header name or None)`` of every
            column used.
        units: the unit of the offsets and errors as read (``"arcsec"``, ...).
        cross_elevation: whether the azimuth offsets were read as ``dA cos E``.
        sign: ``"observed-raw"`` or ``"raw-observed"``, as read.
        azimuth: the file's azimuth convention ('N-E', 'S-E' or 'S-W').
        raw: ``(n, 2)`` raw azimuth and elevation, radians, file convention.
        offsets: ``(n, 2)`` observed minus raw ``(dA cos E, dE)``, radians, on the sky
            (whatever the file's sign and sense; ``E`` the observed elevation).
        errors: ``(n, 2)`` 1-sigma errors of ``offsets``, radians on the sky, or
            ``None`` when the table has none.
        weight: ``(n,)`` relative weights (1 without errors; see the module docstring).
        lines: ``(n,)`` line number of each row in the file.
        observations: :class:`pointax.Observations` for an alt-az model in the
            file's azimuth convention.
    """

    path: str
    columns: dict[str, tuple[int, str | None]]
    units: str
    cross_elevation: bool
    sign: str
    azimuth: str
    raw: np.ndarray
    offsets: np.ndarray
    errors: np.ndarray | None
    weight: np.ndarray
    lines: np.ndarray
    observations: Observations

    @property
    def observed(self) -> np.ndarray:
        """``(n, 2)`` observed azimuth and elevation (raw + offset), radians, file convention."""
        el = self.raw[:, 1] + self.offsets[:, 1]
        return np.column_stack([self.raw[:, 0] + self.offsets[:, 0] / np.cos(el), el])

    @property
    def encoder(self) -> np.ndarray:
        """``(n, 2)`` the raw position as the encoder readings of the fit (``raw``)."""
        return self.raw

    def __len__(self) -> int:
        return self.raw.shape[0]


def _normalise(name: str) -> str:
    name = name.strip().strip("\"'").lower()
    name = re.sub(r"[\[(][^\])]*[\])]", "", name).strip()  # a unit in brackets
    return re.sub(r"[\s\-./]+", "_", name).strip("_")


def _role_of(name: str) -> str | None:
    """The role a header name stands for, or None."""
    n = _normalise(name)
    for role, names in _NAMES.items():
        if n in names:
            return role
    if any(w in n for w in _ERROR_WORDS):
        rest = n
        for w in ("uncertainty", "sigma", "error", "err", "unc", "std"):
            rest = rest.replace(w, "_")
        parts = [p for p in rest.split("_") if p]
        az = any(any(w in p for w in _AZ_WORDS) for p in parts)
        el = any(p in _EL_TOKENS for p in parts)
        if az and not el:
            return "azimuth_error"
        if el and not az:
            return "elevation_error"
        if set(parts) <= {"pos", "position", "offset", "off", "pointing", "total", "radial"}:
            return "error"
    return None


def _split(line: str, csv: bool) -> list[str]:
    if csv:
        return [f.strip() for f in line.split(",")]
    return line.split()


def _records(text: str):
    """``(line number, body)`` of every non-comment, non-blank line."""
    for lineno, raw in enumerate(text.splitlines(), 1):
        body = re.split(r"[#!]", raw, maxsplit=1)[0].strip()
        if body:
            yield lineno, body


def _check_columns_argument(columns):
    if columns is None:
        return
    if isinstance(columns, Mapping):
        unknown = [r for r in columns if r not in OFFSET_ROLES]
        if unknown:
            raise ValueError(f"unknown column role(s) {unknown}; expected some of {OFFSET_ROLES}")
        for role, where in columns.items():
            if isinstance(where, bool) or not isinstance(where, (int, str)) or (isinstance(where, int) and where < 1):
                raise ValueError(f"columns[{role!r}] must be a header name or a 1-based column number, got {where!r}")
        return
    if isinstance(columns, (str, bytes)) or not isinstance(columns, Sequence):
        raise ValueError(f"columns must be a mapping of roles or a sequence of roles, got {columns!r}")
    unknown = [r for r in columns if r is not None and r not in OFFSET_ROLES]
    if unknown:
        raise ValueError(f"unknown column role(s) {unknown}; expected some of {OFFSET_ROLES} or None")
    repeated = sorted({r for r in columns if r is not None and list(columns).count(r) > 1})
    if repeated:
        raise ValueError(f"column role(s) {repeated} given twice in columns")


def _mapping(path, header_line, header, n_fields, columns) -> dict[str, tuple[int, str | None]]:
    """role -> (0-based index, header name or None)."""
    names = header or [None] * n_fields

    def name_at(k):
        return names[k] if k < len(names) else None

    if columns is not None and not isinstance(columns, Mapping):
        if len(columns) > n_fields:
            raise OffsetsFormatError(
                path, header_line, f"columns names {len(columns)} columns, the table has {n_fields}"
            )
        mapping = {r: (k, name_at(k)) for k, r in enumerate(columns) if r is not None}
    else:
        mapping = {}
        if header is not None:
            found: dict[str, list[int]] = {}
            for k, name in enumerate(header):
                role = _role_of(name)
                if role is not None:
                    found.setdefault(role, []).append(k)
            given = set(columns or ())
            for role, ks in found.items():
                if role in given:
                    continue
                if len(ks) > 1:
                    both = ", ".join(f"column {k + 1} ({header[k]!r})" for k in ks)
                    raise OffsetsFormatError(
                        path, header_line, f"{both} all look like the {role} column; choose one with columns={{{role!r}: ...}}"
                    )
                mapping[role] = (ks[0], header[ks[0]])
        else:
            defaults = {4: _REQUIRED, 5: _REQUIRED + ("error",), 6: _REQUIRED + ("azimuth_error", "elevation_error")}
            if not columns and n_fields not in defaults:
                raise OffsetsFormatError(
                    path,
                    header_line,
                    f"{n_fields} columns and no header line: without names pointax reads 4 (az el daz del), 5 (... error) "
                    "or 6 (... daz_err del_err) columns; give a header or columns=",
                )
            if not columns:
                mapping = {r: (k, None) for k, r in enumerate(defaults[n_fields])}
        for role, where in (columns or {}).items():
            if isinstance(where, int):
                if where > n_fields:
                    raise OffsetsFormatError(
                        path, header_line, f"columns[{role!r}] = {where}, but the table has {n_fields} columns"
                    )
                mapping[role] = (where - 1, name_at(where - 1))
            else:
                if header is None:
                    raise OffsetsFormatError(
                        path, header_line, f"columns[{role!r}] = {where!r} names a column, but the table has no header line"
                    )
                hits = [k for k, h in enumerate(header) if h.strip().strip("\"'") == where.strip()]
                if not hits:
                    hits = [k for k, h in enumerate(header) if _normalise(h) == _normalise(where)]
                if len(hits) != 1:
                    what = "no" if not hits else "more than one"
                    raise OffsetsFormatError(
                        path, header_line, f"columns[{role!r}] = {where!r}: {what} header column of that name (header: {', '.join(header)})"
                    )
                mapping[role] = (hits[0], header[hits[0]])
    missing = [r for r in _REQUIRED if r not in mapping]
    if missing:
        shown = f"header: {', '.join(header)}" if header else "no header"
        raise OffsetsFormatError(
            path,
            header_line,
            f"no column for {', '.join(missing)} ({shown}); name the columns with columns={{'azimuth': ..., "
            "'elevation': ..., 'azimuth_offset': ..., 'elevation_offset': ...}",
        )
    if "error" in mapping and ("azimuth_error" in mapping or "elevation_error" in mapping):
        raise OffsetsFormatError(
            path, header_line, "both a common error column and per-axis error columns: map only one kind"
        )
    if ("azimuth_error" in mapping) != ("elevation_error" in mapping):
        one = "azimuth_error" if "azimuth_error" in mapping else "elevation_error"
        raise OffsetsFormatError(
            path, header_line, f"a {one} column without its partner: give both per-axis errors, or one common 'error'"
        )
    used: dict[int, str] = {}
    for role, (k, _) in mapping.items():
        if k in used:
            raise OffsetsFormatError(path, header_line, f"column {k + 1} is mapped to both {used[k]} and {role}")
        used[k] = role
    return mapping


def parse_offsets(
    text: str,
    path: str = "<string>",
    columns: Mapping[str, str | int] | Sequence[str | None] | None = None,
    units: str = "arcsec",
    azimuth: str = "N-E",
    cross_elevation: bool = True,
    sign: str = "observed-raw",
) -> OffsetsRun:
    """Parse the text of an offset table (see :func:`read_offsets`)."""
    if azimuth not in AZIMUTH_CONVENTIONS:
        raise ValueError(f"unknown azimuth convention {azimuth!r}; expected one of {sorted(AZIMUTH_CONVENTIONS)}")
    if units not in OFFSET_UNITS:
        raise ValueError(f"unknown offset unit {units!r}; expected one of {sorted(OFFSET_UNITS)}")
    if sign not in ("observed-raw", "raw-observed"):
        raise ValueError(f"sign must be 'observed-raw' (TPOINT's) or 'raw-observed', got {sign!r}")
    _check_columns_argument(columns)
    records = list(_records(text))
    if not records:
        raise OffsetsFormatError(path, None, "no data: the file holds only comments or blank lines")
    first_line, first = records[0]
    csv = "," in first
    tokens = _split(first, csv)
    header = None
    if not all(is_number(t) for t in tokens):
        header = [t.strip().strip("\"'") for t in tokens]
        if csv and any(not h for h in header):
            k = header.index("")
            raise OffsetsFormatError(path, first_line, "empty header name", f"column {k + 1}")
        records = records[1:]
    if not records:
        raise OffsetsFormatError(path, None, "no data rows" + (" after the header line" if header else ""))
    n_fields = len(header) if header else len(_split(records[0][1], csv))
    mapping = _mapping(path, first_line if header else records[0][0], header, n_fields, columns)

    def where(role):
        k, name = mapping[role]
        return f"column {k + 1} ({name})" if name else f"column {k + 1} ({role})"

    scale = OFFSET_UNITS[units]
    rows, lines = [], []
    for lineno, body in records:
        fields = _split(body, csv)
        if len(fields) != n_fields:
            raise OffsetsFormatError(
                path, lineno, f"{len(fields)} columns, the {'header' if header else 'first row'} has {n_fields}"
            )
        values = {}
        for role, (k, _) in mapping.items():
            token = fields[k]
            if token == "":
                raise OffsetsFormatError(path, lineno, "empty field: every used column needs a number", where(role))
            try:
                value = float(token)
            except ValueError:
                raise OffsetsFormatError(path, lineno, f"{token!r} is not a number", where(role)) from None
            if not math.isfinite(value):
                raise OffsetsFormatError(path, lineno, f"{token!r} is not finite", where(role))
            values[role] = value
        check_azimuth(OffsetsFormatError, path, lineno, values["azimuth"], where("azimuth"))
        if not -90.0 <= values["elevation"] <= 90.0:
            raise OffsetsFormatError(path, lineno, f"{values['elevation']:g} deg is outside -90..90 deg", where("elevation"))
        for role in ("azimuth_offset", "elevation_offset"):
            if abs(values[role]) * scale > MAX_OFFSET_DEG * DEG:
                raise OffsetsFormatError(
                    path,
                    lineno,
                    f"{values[role]:g} {units} is more than {MAX_OFFSET_DEG:g} deg: are the offsets in another unit? "
                    f"(units={units!r}; choose with units='arcsec', 'arcmin', 'deg' or 'rad')",
                    where(role),
                )
        for role in ("azimuth_error", "elevation_error", "error"):
            if role in values and not values[role] > 0:
                raise OffsetsFormatError(
                    path, lineno, f"error {values[role]:g} is not positive (a weight is 1/error^2)", where(role)
                )
        flip = 1.0 if sign == "observed-raw" else -1.0
        el_obs = values["elevation"] + flip * values["elevation_offset"] * scale / DEG
        check_observed_elevation(OffsetsFormatError, path, lineno, el_obs, f"{where('elevation')} + {where('elevation_offset')}")
        if cross_elevation and math.cos(el_obs * DEG) < 1e-9:
            raise OffsetsFormatError(
                path, lineno, "a cross-elevation offset at the zenith has no azimuth", where("azimuth_offset")
            )
        rows.append([values.get(r, math.nan) for r in OFFSET_ROLES])
        lines.append(lineno)
    data = np.asarray(rows, np.float64)
    check_not_radians(
        OffsetsFormatError,
        path,
        lines,
        {where("azimuth"): (data[:, 0], 2 * math.pi), where("elevation"): (data[:, 1], math.pi / 2)},
    )
    warn_duplicates(path, data[:, :4], lines, "rows")

    flip = 1.0 if sign == "observed-raw" else -1.0
    raw = data[:, :2] * DEG
    d_az, d_el = flip * data[:, 2] * scale, flip * data[:, 3] * scale
    el_obs = raw[:, 1] + d_el
    cos_e = np.cos(el_obs)
    if cross_elevation:
        xel = d_az
        d_az = xel / cos_e
    else:
        xel = d_az * cos_e
    offsets = np.column_stack([xel, d_el])
    errors = None
    weight = np.ones(len(lines))
    if "error" in mapping:
        errors = np.column_stack([data[:, 6], data[:, 6]]) * scale
    elif "azimuth_error" in mapping:
        errors = data[:, 4:6] * scale
    if errors is not None:
        if not cross_elevation:
            errors = np.column_stack([errors[:, 0] * np.abs(cos_e), errors[:, 1]])
        variance = np.mean(errors**2, axis=1)
        weight = 1.0 / variance
        weight = weight / np.mean(weight)
    observed_az = raw[:, 0] + d_az
    frame = np.asarray(AZIMUTH_CONVENTIONS[azimuth])
    target = azel_to_enu_numpy(observed_az, el_obs) @ frame.T
    return OffsetsRun(
        path=path,
        columns={role: (k + 1, name) for role, (k, name) in sorted(mapping.items(), key=lambda kv: kv[1][0])},
        units=units,
        cross_elevation=cross_elevation,
        sign=sign,
        azimuth=azimuth,
        raw=raw,
        offsets=offsets,
        errors=errors,
        weight=weight,
        lines=np.asarray(lines),
        observations=Observations(raw, target, weight, convention=azimuth),
    )


def read_offsets(
    path: str | os.PathLike,
    columns: Mapping[str, str | int] | Sequence[str | None] | None = None,
    units: str = "arcsec",
    azimuth: str = "N-E",
    cross_elevation: bool = True,
    sign: str = "observed-raw",
) -> OffsetsRun:
    """Read a table of pointing offsets (CSV or whitespace-separated; see the module
    docstring for the layout and the conventions).

    Args:
        path: the file.
        columns: which column is which: ``None`` (from the header names, or the
            default order ``az el daz del [errors]`` without a header), a mapping of
            roles (:data:`OFFSET_ROLES`) to header names or 1-based column numbers,
            or a sequence giving each column's role in order (``None`` skips one).
        units: unit of the offsets and their errors: ``"arcsec"`` (default),
            ``"arcmin"``, ``"deg"`` or ``"rad"``. Positions are degrees.
        azimuth: how the file counts azimuth: 'N-E' (default), 'S-E' or 'S-W'. The
            encoder readings keep it; fit with ``px.AltAz(..., azimuth=azimuth)``.
        cross_elevation: True (default): the azimuth offset is the cross-elevation
            offset ``dA cos E`` (radio pointing scans); False: a plain ``dA``.
        sign: ``"observed-raw"`` (default, TPOINT's: the source was found at raw +
            offset) or ``"raw-observed"`` (the table holds corrections).

    Returns:
        :class:`OffsetsRun`; its ``observations`` go straight into :func:`pointax.fit`.

    Raises:
        OffsetsFormatError: naming file, line and column of the first bad value, or
            a header whose columns cannot be matched.
        ValueError: an unknown ``units``, ``azimuth``, ``sign`` or column role.
        OSError: the file cannot be opened.
    """
    path = os.fspath(path)
    return parse_offsets(read_text(path, OffsetsFormatError), path, columns, units, azimuth, cross_elevation, sign)

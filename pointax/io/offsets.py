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
  dropped (``"Az [deg]"`` is ``az``; units: below): ``az azimuth raw_az cmd_az enc_az``,
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

The first record is a header when one of its fields is not a number where the next
record has a number; so a table whose rows start with a source name (``3C273 184.2
34.1 ...``) has no header, and its first row is data. On the command line
``--columns`` gives ``columns`` (``--columns _,az,el,dxel,del`` by position, ``_``
skipping a column, or ``--columns az=2,el=3,dxel=4,del=5``; names or numbers,
:func:`pointax.io.offset_columns.parse_columns_option`).

Conventions (stated once, tested in ``tests/test_io_offsets.py``):

* Sign: offsets are **observed minus raw** (TPOINT's sign): the source was found at
  ``raw + offset``. A table of raw minus observed (the correction to apply to the
  command) is read with ``sign="raw-observed"``.
* Cross-elevation: ``azimuth_offset`` is ``dA cos E`` by default (what radio pointing
  scans measure), with ``E`` the observed elevation ``E_raw + dE`` (TPOINT's
  definition); ``cross_elevation=False`` reads a plain azimuth difference ``dA``.
  Errors of the azimuth offset are read in the same sense.
* Units: a unit in a header name is read (``dxel [arcmin]``, ``el (deg)``,
  ``dxel/arcsec``, ``del_arcmin``, ``dxel ["]``: the forms and words are listed in
  :mod:`pointax.io.offset_columns`), column by column. ``units`` (``--units``) is the
  unit of the offsets and errors whose header names none: ``"arcsec"``, ``"arcmin"``,
  ``"deg"`` or ``"rad"``; a header unit that differs from it is an error. Neither
  given: **arcsec** for offsets and errors, **degrees** for positions.
* Weights: with errors, each row's weight is ``1 / sigma^2`` with ``sigma^2`` the mean
  of the two on-sky variances (``(sigma_xel^2 + sigma_E^2) / 2``; a plain-dA error
  counts as ``sigma_dA cos E`` on the sky), normalised to mean 1, so that the weights
  are relative: the fit's Sky RMS and parameter sigmas keep their meaning (TPOINT
  scales sigmas by the residuals, so only the ratios of the weights matter).

**Auxiliary readings.** Every other column of a table with a header line is an
auxiliary reading (``run.readings``, ``run.observations.readings``), one value per row:

* a header name that stands for a standard reading (:data:`pointax.core.readings.READINGS`)
  is read as it: ``temperature temp T_air air_temp t_amb`` (deg C; ``[K]``, ``[F]``
  converted), ``pressure press p_air baro`` (hPa; ``[Pa]``, ``[kPa]``, ``[mmHg]`` ...
  converted), ``humidity hum rh`` (0-1; ``[%]``, or values above 1, read as percent),
  ``rotator rot rot_angle``, ``tilt_1 tilt_x``, ``tilt_2 tilt_y`` (degrees, or the angle
  unit of the header, converted to radians), ``time mjd jd date utc timestamp date_obs``
  (MJD, UTC: ISO 8601 text such as ``2021-08-21T13:05:00Z``, or numbers: MJD, JD or Unix
  seconds as the header says, ``time [jd]``, else by their size); the full lists are
  :data:`pointax.io.offset_columns.READING_NAMES`. Two columns that could both be one
  reading keep their header names;
* any other column of numbers keeps its header name as written (unit unknown);
* an empty field, ``nan`` or ``-`` is "not recorded" (NaN); another non-number is an
  error naming the file, line and column; a column whose first value is text (a source
  name) is not a reading.

``run.notes`` says what was assumed (units taken by default, text columns).

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

from ..core.mounts import AZIMUTH_CONVENTIONS
from ..core.observations import Observations
from ..core.rotations import azel_to_enu_numpy
from ..core.units import ARCSEC, DEG
from .errors import FileFormatError, file_errors
from .offset_columns import UNIT_NAMES, header_fields, normalise, reading_of, reading_unit, role_of, split_unit
from .run_readings import JD_MINUS_MJD, as_readings, mjd_from_iso
from .sanity import check_azimuth, check_not_radians, check_observed_elevation, check_offsets_scale, warn_duplicates
from .text import is_number, read_text

__all__ = [
    "OFFSET_ROLES",
    "OFFSET_UNITS",
    "OFFSET_SIGNS",
    "DEFAULT_UNITS",
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

OFFSET_UNITS = dict(zip(UNIT_NAMES, (ARCSEC, 60 * ARCSEC, DEG, 1.0)))
"""Units of the offsets and errors (and, from a header, of any column) -> radians per unit."""

OFFSET_SIGNS = ("observed-raw", "raw-observed")
"""Signs of the offsets: observed minus raw (TPOINT's, the default) or raw minus observed."""

DEFAULT_UNITS = "arcsec"
"""The unit of offsets and errors that neither ``units`` nor the header names."""

_OFFSET_COLUMNS = ("azimuth_offset", "elevation_offset", "azimuth_error", "elevation_error", "error")

MAX_OFFSET_DEG = 10.0
"""An offset larger than this (degrees) is refused as a unit mistake."""

_REQUIRED = ("azimuth", "elevation", "azimuth_offset", "elevation_offset")

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
        units: the unit of the offsets and errors as read (``"arcsec"``, ...; ``"mixed"``
            when the header gives them different units: see ``column_units``).
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
        column_units: role -> unit of every column used, as read (from the header,
            ``units`` or the defaults: degrees for positions, arcsec for offsets).
        readings: auxiliary readings from the header's other columns, name ->
            ``(n,)`` float64 (also ``observations.readings``; see :func:`read_offsets`).
        reading_columns: reading name -> ``(1-based column number, header name)``.
        notes: what the reader assumed about the readings, one sentence each.
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
    column_units: dict[str, str] = dataclasses.field(default_factory=dict)
    readings: dict = dataclasses.field(default_factory=dict)
    reading_columns: dict[str, tuple[int, str]] = dataclasses.field(default_factory=dict)
    notes: tuple[str, ...] = ()

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


_normalise = normalise
_role_of = role_of


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
                        path, header_line, f"{both} all look like the {role} column; choose one with columns={{{role!r}: ...}} "
                        "(--columns on the command line)"
                    )
                mapping[role] = (ks[0], header[ks[0]])
        else:
            defaults = {4: _REQUIRED, 5: _REQUIRED + ("error",), 6: _REQUIRED + ("azimuth_error", "elevation_error")}
            if not columns and n_fields not in defaults:
                raise OffsetsFormatError(
                    path,
                    header_line,
                    f"{n_fields} columns and no header line: without names pointax reads 4 (az el daz del), 5 (... error) "
                    "or 6 (... daz_err del_err) columns; give a header line, or say which column is which with "
                    "columns= (--columns on the command line, e.g. --columns _,az,el,dxel,del: '_' skips a column)",
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
            "'elevation': ..., 'azimuth_offset': ..., 'elevation_offset': ...} (--columns az=N,el=N,dxel=N,del=N "
            "on the command line, N a column number or header name)",
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


def _is_header(first: list[str], second: list[str] | None) -> bool:
    """Whether the first record is a header: it has a field that is not a number where
    the next record has a number (a column of source names is data, not a header); with
    no next record, when none of its fields is a number."""
    if second is None:
        return not any(is_number(t) for t in first)
    return any(not is_number(a) and is_number(b) for a, b in zip(first, second))


def _column_units(path, header_line, header, mapping, units, assumed: set | None = None) -> dict[str, str]:
    """role -> unit of every used column: the header's (``dxel [arcmin]``), else
    ``units`` (offsets and errors) or degrees (positions). The roles whose unit neither
    the header nor ``units`` states are added to ``assumed``."""
    out = {}
    assumed = set() if assumed is None else assumed
    for role, (k, name) in mapping.items():
        default = "deg" if role in ("azimuth", "elevation") else (units or DEFAULT_UNITS)
        if name is None:
            out[role] = default
            if role in ("azimuth", "elevation") or not units:
                assumed.add(role)
            continue
        _, unit, written = split_unit(name)
        where = f"column {k + 1} ({name!r})"
        if unit is None and written is not None and not (units and role in _OFFSET_COLUMNS):
            raise OffsetsFormatError(
                path,
                header_line,
                f"unknown unit {written!r} in the header; pointax reads {', '.join(UNIT_NAMES)} "
                + ("(a position's unit)" if role in ("azimuth", "elevation") else "(or give units=, --units, to read the bracket as a note)"),
                where,
            )
        if unit is not None and units and role in _OFFSET_COLUMNS and unit != units:
            raise OffsetsFormatError(
                path,
                header_line,
                f"the header says {unit} but units={units!r} was given (--units): leave units out to read the header's",
                where,
            )
        out[role] = unit or default
        if unit is None and (role in ("azimuth", "elevation") or not units):
            assumed.add(role)
    return out


def parse_offsets(
    text: str,
    path: str = "<string>",
    columns: Mapping[str, str | int] | Sequence[str | None] | None = None,
    units: str | None = None,
    azimuth: str = "N-E",
    cross_elevation: bool = True,
    sign: str = "observed-raw",
) -> OffsetsRun:
    """Parse the text of an offset table (see :func:`read_offsets`)."""
    if azimuth not in AZIMUTH_CONVENTIONS:
        raise ValueError(f"unknown azimuth convention {azimuth!r}; expected one of {sorted(AZIMUTH_CONVENTIONS)}")
    if units is not None and units not in OFFSET_UNITS:
        raise ValueError(f"unknown offset unit {units!r}; expected one of {list(OFFSET_UNITS)}")
    if sign not in OFFSET_SIGNS:
        raise ValueError(f"sign must be 'observed-raw' (TPOINT's) or 'raw-observed', got {sign!r}")
    _check_columns_argument(columns)
    records = list(_records(text))
    if not records:
        raise OffsetsFormatError(path, None, "no data: the file holds only comments or blank lines")
    first_line, first = records[0]
    csv = "," in first
    second = _split(records[1][1], csv) if len(records) > 1 else None
    header = None
    if _is_header(_split(first, csv), second):
        header = [t.strip().strip("\"'") for t in header_fields(first, csv)]
        if csv and any(not h for h in header):
            k = header.index("")
            raise OffsetsFormatError(path, first_line, "empty header name", f"column {k + 1}")
        records = records[1:]
    if not records:
        raise OffsetsFormatError(path, None, "no data rows" + (" after the header line" if header else ""))
    n_fields = len(header) if header else len(_split(records[0][1], csv))
    header_line = first_line if header else records[0][0]
    mapping = _mapping(path, header_line, header, n_fields, columns)
    assumed: set[str] = set()
    unit_of = _column_units(path, header_line, header, mapping, units, assumed)
    scale_of = {role: OFFSET_UNITS[unit] for role, unit in unit_of.items()}

    def where(role):
        k, name = mapping[role]
        return f"column {k + 1} ({name})" if name else f"column {k + 1} ({role})"

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
            # positions in degrees, offsets and errors in radians from here on
            values[role] = value * scale_of[role] / (DEG if role in ("azimuth", "elevation") else 1.0)
        check_azimuth(OffsetsFormatError, path, lineno, values["azimuth"], where("azimuth"))
        if not -90.0 <= values["elevation"] <= 90.0:
            raise OffsetsFormatError(path, lineno, f"{values['elevation']:g} deg is outside -90..90 deg", where("elevation"))
        for role in ("azimuth_offset", "elevation_offset"):
            if abs(values[role]) > MAX_OFFSET_DEG * DEG:
                raise OffsetsFormatError(
                    path,
                    lineno,
                    f"{values[role] / scale_of[role]:g} {unit_of[role]} is more than {MAX_OFFSET_DEG:g} deg: are the offsets "
                    f"in another unit? (units={unit_of[role]!r}; choose with units='arcsec', 'arcmin', 'deg' or 'rad', "
                    "--units on the command line, or name it in the header: 'dxel [arcmin]')",
                    where(role),
                )
        for role in ("azimuth_error", "elevation_error", "error"):
            if role in values and not values[role] > 0:
                raise OffsetsFormatError(
                    path, lineno, f"error {values[role] / scale_of[role]:g} is not positive (a weight is 1/error^2)", where(role)
                )
        flip = 1.0 if sign == "observed-raw" else -1.0
        el_obs = values["elevation"] + flip * values["elevation_offset"] / DEG
        check_observed_elevation(OffsetsFormatError, path, lineno, el_obs, f"{where('elevation')} + {where('elevation_offset')}")
        if cross_elevation and math.cos(el_obs * DEG) < 1e-9:
            raise OffsetsFormatError(
                path, lineno, "a cross-elevation offset at the zenith has no azimuth", where("azimuth_offset")
            )
        rows.append([values.get(r, math.nan) for r in OFFSET_ROLES])
        lines.append(lineno)
    data = np.asarray(rows, np.float64)
    if unit_of["azimuth"] == "deg" and unit_of["elevation"] == "deg":  # a header saying rad is believed
        check_not_radians(
            OffsetsFormatError,
            path,
            lines,
            {where("azimuth"): (data[:, 0], 2 * math.pi), where("elevation"): (data[:, 1], math.pi / 2)},
        )
    for k, role in ((2, "azimuth_offset"), (3, "elevation_offset")):  # offsets too small for their unit
        check_offsets_scale(OffsetsFormatError, path, lines, data[:, k], where(role), unit_of[role], role in assumed)
    warn_duplicates(path, data[:, :4], lines, "rows")

    flip = 1.0 if sign == "observed-raw" else -1.0
    raw = data[:, :2] * DEG
    d_az, d_el = flip * data[:, 2], flip * data[:, 3]
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
        errors = np.column_stack([data[:, 6], data[:, 6]])
    elif "azimuth_error" in mapping:
        errors = data[:, 4:6].copy()
    if errors is not None:
        if not cross_elevation:
            errors = np.column_stack([errors[:, 0] * np.abs(cos_e), errors[:, 1]])
        variance = np.mean(errors**2, axis=1)
        weight = 1.0 / variance
        weight = weight / np.mean(weight)
    observed_az = raw[:, 0] + d_az
    frame = np.asarray(AZIMUTH_CONVENTIONS[azimuth])
    target = azel_to_enu_numpy(observed_az, el_obs) @ frame.T
    offset_units = {unit_of[r] for r in _OFFSET_COLUMNS if r in unit_of}
    readings, reading_columns, notes = _readings(path, header, header_line, mapping, records, csv, lines)
    return OffsetsRun(
        path=path,
        columns={role: (k + 1, name) for role, (k, name) in sorted(mapping.items(), key=lambda kv: kv[1][0])},
        units=offset_units.pop() if len(offset_units) == 1 else "mixed",
        cross_elevation=cross_elevation,
        sign=sign,
        azimuth=azimuth,
        raw=raw,
        offsets=offsets,
        errors=errors,
        weight=weight,
        lines=np.asarray(lines),
        observations=Observations(raw, target, weight, convention=azimuth, readings=readings),
        column_units={role: unit_of[role] for role in OFFSET_ROLES if role in unit_of},
        readings=readings,
        reading_columns=reading_columns,
        notes=notes,
    )


_ANGLE_READINGS = ("rotator", "tilt_1", "tilt_2")
_MISSING = ("", "nan", "na", "n/a", "-", "null", "none")
"""Fields of a reading column that mean "not recorded" (NaN)."""


def _readings(path, header, header_line, mapping, records, csv: bool, lines):
    """The readings of a header's columns that no role uses, their columns and notes
    (see :func:`read_offsets`)."""
    if header is None:
        return {}, {}, ()
    used = {k for k, _ in mapping.values()}
    rows = [_split(body, csv) for _, body in records]
    candidates = [k for k in range(len(header)) if k not in used]
    standard = {k: reading_of(header[k]) for k in candidates}
    counts: dict[str, int] = {}
    for k, name in standard.items():
        if name:
            counts[name] = counts.get(name, 0) + 1
    readings, columns, notes = {}, {}, []
    for k in candidates:
        where = f"column {k + 1} ({header[k]})"
        first = rows[0][k].strip()
        name = standard[k]
        if name and counts[name] > 1:
            others = ", ".join(f"column {j + 1} ({header[j]})" for j in candidates if standard[j] == name and j != k)
            notes.append(f"{where} and {others} could each be {name!r}: kept under their header names")
            name = None
        text_column = not is_number(first) and first.lower() not in _MISSING
        if text_column and name != "time":
            notes.append(f"{where} holds text ({first!r}): not a reading")
            continue
        key = name or header[k].strip()
        if key in readings:
            raise OffsetsFormatError(path, header_line, f"a second column is named {key!r}", where)
        readings[key] = _reading_values(path, header_line, records, rows, k, where, name, header[k], notes)
        columns[key] = (k + 1, header[k])
    return as_readings(readings, len(lines)), columns, tuple(notes)


def _reading_values(path, header_line, records, rows, k, where, name, header_name, notes) -> np.ndarray:
    """The values of reading column ``k`` in its standard unit (``name``) or as written."""
    try:
        unit = reading_unit(name, header_name) if name else None
    except ValueError as e:
        raise OffsetsFormatError(path, header_line, str(e), where) from None
    if name == "time":
        return _times(path, records, rows, k, where, header_name, unit, notes)
    values = np.empty(len(rows))
    for i, ((lineno, _), fields) in enumerate(zip(records, rows)):
        token = fields[k].strip()
        if token.lower() in _MISSING:
            values[i] = math.nan
            continue
        try:
            v = float(token)
        except ValueError:
            raise OffsetsFormatError(path, lineno, f"{token!r} is not a number (an empty field or 'nan' means not recorded)", where) from None
        if not math.isfinite(v):
            raise OffsetsFormatError(path, lineno, f"{token!r} is not finite", where)
        values[i] = v
    if name in _ANGLE_READINGS:
        scale = OFFSET_UNITS[unit[0]] if unit else DEG
        if unit is None:
            notes.append(f"{where}: {name} read in degrees (no unit in the header)")
        return values * scale
    if name == "humidity" and unit is None and np.nanmax(np.abs(values), initial=0.0) > 1.0:
        notes.append(f"{where}: humidity above 1 read as percent (no unit in the header)")
        return values / 100.0
    if unit is not None:
        return unit[1] * values + unit[2]
    return values


def _times(path, records, rows, k, where, header_name, unit, notes) -> np.ndarray:
    """A time column as MJD (days, UTC): ISO 8601 text, or numbers: MJD, JD or Unix
    seconds, from the header's unit or name, else from their size."""
    base = normalise(header_name)
    kind = unit[0] if unit else ("mjd" if "mjd" in base else "jd" if "jd" in base else "unix" if base in ("unix_time", "epoch") else None)
    values = np.empty(len(rows))
    guessed = set()
    for i, ((lineno, _), fields) in enumerate(zip(records, rows)):
        token = fields[k].strip()
        if token.lower() in _MISSING:
            values[i] = math.nan
            continue
        if not is_number(token):
            try:
                values[i] = mjd_from_iso(token)
            except ValueError as e:
                raise OffsetsFormatError(path, lineno, str(e), where) from None
            continue
        v = float(token)
        if not math.isfinite(v):
            raise OffsetsFormatError(path, lineno, f"{token!r} is not finite", where)
        this = kind or ("unix" if v > 1e8 else "jd" if v > 2e6 else "mjd")
        if kind is None:
            guessed.add(this)
        values[i] = v - JD_MINUS_MJD if this == "jd" else v / 86400.0 + 40587.0 if this in ("unix", "s") else v
    if guessed:
        said = {"mjd": "MJD", "jd": "Julian dates", "unix": "Unix seconds"}
        notes.append(f"{where}: numbers read as {', '.join(said[g] for g in sorted(guessed))} by their size (name the unit: 'time [mjd]')")
    return values


@file_errors(OffsetsFormatError)
def read_offsets(
    path: str | os.PathLike,
    columns: Mapping[str, str | int] | Sequence[str | None] | None = None,
    units: str | None = None,
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
        units: unit of the offsets and their errors: ``"arcsec"``, ``"arcmin"``,
            ``"deg"`` or ``"rad"``; None (default): the unit in each column's header
            name (``dxel [arcmin]``), else arcsec. A header unit that differs from
            ``units`` is an error. Positions are degrees unless their header names
            another unit (``az [rad]``).
        azimuth: how the file counts azimuth: 'N-E' (default), 'S-E' or 'S-W'. The
            encoder readings keep it; fit with ``px.AltAz(..., azimuth=azimuth)``.
        cross_elevation: True (default): the azimuth offset is the cross-elevation
            offset ``dA cos E`` (radio pointing scans); False: a plain ``dA``.
        sign: ``"observed-raw"`` (default, TPOINT's: the source was found at raw +
            offset) or ``"raw-observed"`` (the table holds corrections).

    Returns:
        :class:`OffsetsRun`; its ``observations`` go straight into :func:`pointax.fit`,
        with the table's other columns as auxiliary readings (``run.readings``: see the
        module docstring).

    Raises:
        OffsetsFormatError: naming file, line and column of the first bad value, or
            a header whose columns cannot be matched.
        ValueError: an unknown ``units``, ``azimuth``, ``sign`` or column role.
        OSError: the file cannot be opened.
    """
    path = os.fspath(path)
    return parse_offsets(read_text(path, OffsetsFormatError, comments="#!"), path, columns, units, azimuth, cross_elevation, sign)

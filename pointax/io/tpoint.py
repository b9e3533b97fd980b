"""TPOINT input files (``.dat``): the pointing runs of alt-az and equatorial mounts.
TPOINT's model files (``.mod``) are :mod:`pointax.io.tpoint_model` (its names are
importable from here too); the record syntax both share, :mod:`pointax.io.tpoint_records`.

Input file layout (as TPOINT reads it)::

    ! comment lines start with '!' or ';' (a '!' or ';' later on a line starts a
    ! trailing comment: "10.58 37.42 10.55 37.49 0.44 ; [0026] star 26")
    Caption line                               first non-comment line, free text
    : ALTAZ                                    option records, ':' then a keyword (each
                                               applied or warned of: read_tpoint)
    +31 41 19.6 2021 8 21 13.0 741 2608 0.75   run parameters: latitude d m s, then optional
                                               date, temperature C, pressure mB,
                                               height m, humidity, wavelength, lapse
    192.386 77.347 -167.278 77.348             observed az, el, raw encoder az, el
    ...                                        (degrees, or d m s), then up to three
    END                                        auxiliary readings (a rotator angle, a
                                               temperature ...); END is optional

An equatorial run (``: EQUAT``, ``: GERMAN`` or ``: FORK``) has records of star RA, Dec,
telescope RA, Dec and sidereal time::

    21 43 18.4460 +72 29 08.368 09 28 59.9527 +109 20 06.469  16 23.130

(``h m s  d m s  h m s  d m s  h m.m``; or decimal hours and degrees; hour angles
instead of RA without the sidereal time: see :func:`read_tpoint`).

**Auxiliary readings** (``run.readings``, also in ``run.observations.readings``): up to
three numbers after the positions of a record are TPOINT's auxiliary readings (its term
routines take ``auxil[3]``), ``aux1``, ``aux2``, ``aux3`` as written; the run
parameters' temperature, pressure and humidity, and the date (MJD at 0h UTC) are per-run
readings of every record. See :func:`read_tpoint`.

Any malformed record raises :class:`TpointFormatError`, whose message names the file,
the line and the field.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Sequence

import numpy as np

from ..core.mounts import AZIMUTH_CONVENTIONS
from ..core.observations import Observations
from ..core.rotations import azel_to_enu_numpy, hadec_to_enu_numpy
from ..core.units import DEG
from .errors import file_errors, warn_input
from .sanity import (
    HORIZON_DEG,
    check_azimuth,
    check_not_radians,
    check_observed_elevation,
    check_row_separations,
    warn_duplicates,
)
from .sexagesimal import Group, group_value
from .text import read_text
from .tpoint_model import (  # noqa: F401  (the model files' names: importable from here, as before the split)
    MODEL_LAYOUTS,
    ModelTerm,
    TpointModelFile,
    exact_decimal,
    format_model,
    parse_model,
    read_model,
    refraction_arcsec,
    write_model,
)
from .run_readings import as_readings, mjd_from_date, per_run
from .tpoint_records import (  # noqa: F401  (the option names: importable from here, as before)
    ALTAZ_OPTION,
    EQUATORIAL_OPTIONS,
    MOUNT_OPTIONS,
    MOUNTS,
    NO_DIURNAL_ABERRATION,
    ROTATOR_OPTIONS,
    UNAPPLIED_OPTIONS,
    UNSUPPORTED_MOUNT_OPTIONS,
    OptionRecord,
    TpointFormatError,
    check_options,
    misspelt_mount,
    option_records,
    record_numbers,
    records,
)

__all__ = [
    "TpointFormatError",
    "MountNotGivenError",
    "MOUNTS",
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
    "refraction_arcsec",
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

MAX_AUXILIARY = 3
"""Auxiliary readings a TPOINT observation record may carry after its positions
(P. T. Wallace's term routines ``tptPterms`` and ``tptPtermg`` take ``auxil[3]``)."""
AUXILIARY_NAMES = tuple(f"aux{k}" for k in range(1, MAX_AUXILIARY + 1))
"""The readings' names of the auxiliary fields by position, as TPOINT's terms
``AUX1H`` ... ``AUX2E`` and ``A1x`` ... ``A3x`` read them (:mod:`pointax.terms.tpoint_auxiliary`)."""
ANGLE_READINGS = frozenset({"rotator", "tilt_1", "tilt_2"})
"""Standard readings in radians: an auxiliary field given one of these names is read in
degrees, as TPOINT files write angles, and converted."""


def _altaz_layout(width: int) -> tuple[Group, ...]:
    return tuple(Group(width, name) for name in ("observed azimuth", "observed elevation", "raw azimuth", "raw elevation"))


def _equatorial_layout(width: int, time: bool) -> tuple[Group, ...]:
    angle = "RA" if time else "HA"
    groups = (
        Group(width, f"star {angle}", "h"),
        Group(width, "star Dec"),
        Group(width, f"telescope {angle}", "h"),
        Group(width, "telescope Dec"),
    )
    return groups + ((Group(min(width, 2), "sidereal time", "h"),) if time else ())


ALTAZ_LAYOUTS = {4: _altaz_layout(1), 12: _altaz_layout(3)}
"""Number of fields -> the groups of an alt-az observation record (degrees)."""
EQUATORIAL_LAYOUTS = {
    14: _equatorial_layout(3, True),
    5: _equatorial_layout(1, True),
    12: _equatorial_layout(3, False),
    4: _equatorial_layout(1, False),
}
"""Number of fields -> the groups of an equatorial observation record."""


class MountNotGivenError(TpointFormatError):
    """A TPOINT run names no mount and none was given (``mount=``, ``--mount``)."""


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
    """The option records' keywords, upper case, in file order."""
    parameters: RunParameters
    observed: np.ndarray
    """``(n, 2)`` observed (catalogue) position, radians: alt-az, azimuth and elevation
    in the file's convention; equatorial, the star's hour angle (positive West, in
    -pi..pi) and declination, before refraction."""
    encoder: np.ndarray
    """``(n, 2)`` raw encoder readings, radians: alt-az, azimuth and elevation in the
    file's convention; equatorial, the telescope's hour angle and declination as written
    (beyond +-pi/2 on the other side of the pier)."""
    extra: np.ndarray
    """``(n, k)`` further numbers per row after the positions (k = 0 to 3: TPOINT's
    auxiliary readings, such as a rotator angle), as written."""
    lines: np.ndarray
    """``(n,)`` line number of each observation in the file."""
    azimuth: str
    """The encoder convention: the alt-az azimuth convention ('N-E', 'S-E', 'S-W') or
    'ha-dec' for an equatorial run (``observations.convention``)."""
    observations: Observations
    mount: str = "altaz"
    """'altaz' or 'equatorial'."""
    refraction: tuple[float, float] = (0.0, 0.0)
    """TPOINT's refraction constants ``(A, B)``, radians, from the run's weather (or as
    given to the reader); written to model files."""
    refraction_applied: bool = False
    """Whether ``refraction`` raised the star places to the observed ones (equatorial
    runs; alt-az files give observed places)."""
    sidereal_time: np.ndarray | None = None
    """``(n,)`` local sidereal time of each equatorial record, radians (None when the
    records give hour angles)."""
    flipped: np.ndarray | None = None
    """``(n,)`` True for equatorial records on the other side of the pier (telescope
    declination beyond +-90 deg); None for alt-az runs."""
    rotator: np.ndarray | None = None
    """``(n,)`` rotator angle, radians, when a rotator option says the records carry
    one (not used by any fit)."""
    option_records: tuple[OptionRecord, ...] = ()
    """The option records with their arguments and line numbers."""
    readings: dict = dataclasses.field(default_factory=dict)
    """Auxiliary readings, name -> ``(n,)`` float64 (also ``observations.readings``):
    ``aux1`` ... ``aux3``, the auxiliary fields as written; ``rotator`` (radians) with a
    rotator option; any names given with ``auxiliary=`` (standard units); per run, from
    the run-parameters record, ``temperature`` (deg C), ``pressure`` (hPa = mB),
    ``humidity`` (0-1) and ``time`` (the date's MJD at 0h UTC: the record gives no time
    of day), where it gives them."""
    notes: tuple[str, ...] = ()
    """What the reader assumed about the readings (e.g. auxiliary fields with no name
    but their position), one sentence each."""

    @property
    def latitude(self) -> float:
        """The site's latitude, radians (from the run-parameters record)."""
        return self.parameters.latitude

    def term_options(self) -> dict:
        """How TPOINT term names resolve for this run (keywords of
        :func:`pointax.terms.tpoint`): ``{}`` alt-az, the mount and latitude equatorial."""
        return {"mount": "equatorial", "latitude": self.latitude} if self.mount == "equatorial" else {}

    def model(self, terms=(), fixed=(), residual_form: str = "sky"):
        """The model of this run's mount with ``terms``: :func:`pointax.AltAz` in the
        run's azimuth convention, or :func:`pointax.Equatorial` at its latitude."""
        from ..terms.model_factories import AltAz, Equatorial

        if self.mount == "equatorial":
            return Equatorial(terms, latitude=self.latitude, fixed=fixed, residual_form=residual_form)
        return AltAz(terms, azimuth=self.azimuth, fixed=fixed, residual_form=residual_form)

    def __len__(self) -> int:
        return self.encoder.shape[0]


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
    v = record_numbers(path, lineno, tokens, RUN_PARAMETER_FIELDS, record)
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
        try:
            mjd_from_date(*date)
        except ValueError:
            raise TpointFormatError(
                path, lineno, f"{record}: fields 4-6 (date) {tokens[3]} {tokens[4]} {tokens[5]} is not a date"
            ) from None
    optional = v[6:] + [None] * (len(RUN_PARAMETER_FIELDS) - max(len(v), 6))
    return RunParameters(latitude, date, *optional)


def _mount_of(path: str, lineno: int, options: list[OptionRecord], mount: str | None) -> str:
    """'altaz' or 'equatorial': the file's mount option, else ``mount``; refuse both
    missing, and a file that contradicts ``mount`` (a misspelt mount option, ``ALTAZZ``,
    is refused before: :func:`_refuse_misspelt_mount`)."""
    said = MOUNT_OPTIONS.intersection(o.keyword for o in options)  # supported and consistent: check_options
    in_file = "altaz" if ALTAZ_OPTION in said else ("equatorial" if said else None)
    if mount is not None and mount not in MOUNTS:
        raise ValueError(f"unknown mount {mount!r}; expected one of {', '.join(MOUNTS)}")
    if in_file and mount and in_file != mount:
        raise TpointFormatError(
            path, lineno, f"the file says {in_file} (option{'s' if len(said) > 1 else ''} {', '.join(sorted(said))}) "
            f"but mount={mount!r} (--mount {mount}) was asked for"
        )
    if in_file is None and mount is None:
        raise MountNotGivenError(
            path,
            lineno,
            "no mount option record (': ALTAZ' or ': EQUAT') before the run parameters; TPOINT's default is "
            "equatorial, but some observatories' TPOINT is set to alt-az: say which with mount='altaz' or "
            "mount='equatorial' (command line: --mount altaz|equatorial)",
        )
    return in_file or mount


def _refuse_misspelt_mount(path: str, options: list[OptionRecord], mount: str | None) -> None:
    """Where the run names no mount (no mount option, no ``mount``), refuse an option
    that misspells one, naming it (``ALTAZZ``: did you mean ALTAZ?): before
    :func:`check_options`, which would first warn of it as an option pointax does not know."""
    if mount is None and not MOUNT_OPTIONS.intersection(o.keyword for o in options):
        misspelt_mount(path, options)


def _layout(path: str, lineno: int, mount: str, n: int) -> tuple[tuple[Group, ...], int]:
    """The record layout for ``n`` fields and the number of auxiliary fields after it:
    the widest layout that leaves at most :data:`MAX_AUXILIARY` fields."""
    layouts = ALTAZ_LAYOUTS if mount == "altaz" else EQUATORIAL_LAYOUTS
    fits = [k for k in layouts if 0 <= n - k <= MAX_AUXILIARY]
    if fits:
        k = max(fits)
        return layouts[k], n - k
    described = "; ".join(f"{k} fields: {_describe(v)}" for k, v in sorted(layouts.items()))
    raise TpointFormatError(
        path, lineno, f"observation record has {n} fields; an {'alt-az' if mount == 'altaz' else 'equatorial'} "
        f"record has {described} (each optionally followed by up to {MAX_AUXILIARY} auxiliary readings, e.g. a "
        "rotator angle)"
    )


def _describe(layout: tuple[Group, ...]) -> str:
    kinds = {1: "decimal", 2: "d m.m", 3: "sexagesimal"}
    return ", ".join(f"{g.name} ({kinds[g.width] if g.unit != 'h' else kinds[g.width].replace('d m', 'h m')}"
                     f"{' hours' if g.unit == 'h' and g.width == 1 else ''})" for g in layout)


def _record_values(path: str, lineno: int, tokens: list[str], layout: tuple[Group, ...]) -> list[float]:
    values, first = [], 1
    for group in layout:
        values.append(group_value(TpointFormatError, path, lineno, tokens[first - 1 : first - 1 + group.width], first, group, "observation record"))
        first += group.width
    return values


def _field_of(layout: tuple[Group, ...], index: int) -> str:
    """``field N (name)`` of group ``index`` of a record of ``layout``."""
    first = 1 + sum(g.width for g in layout[:index])
    return f"field {first} ({layout[index].name})"


def _where(layout: tuple[Group, ...], index: int) -> str:
    return f"observation record: {_field_of(layout, index)}"


def _check_altaz(path: str, lineno: int, v: list[float], layout) -> None:
    if not -90.0 <= v[1] <= 90.0:
        raise TpointFormatError(path, lineno, f"{_where(layout, 1)} {v[1]:g} is outside -90..90 deg")
    check_azimuth(TpointFormatError, path, lineno, v[0], _where(layout, 0))
    check_azimuth(TpointFormatError, path, lineno, v[2], _where(layout, 2))
    check_observed_elevation(TpointFormatError, path, lineno, v[1], _where(layout, 1))
    if not -90.0 <= v[3] <= 180.0:
        raise TpointFormatError(path, lineno, f"{_where(layout, 3)} {v[3]:g} is outside -90..180 deg")


def _check_equatorial(path: str, lineno: int, v: list[float], layout) -> None:
    for k in (0, 2):
        if not -24.0 <= v[k] <= 24.0:
            raise TpointFormatError(path, lineno, f"{_where(layout, k)} {v[k]:g} h is outside -24..24 h")
    if not -90.0 <= v[1] <= 90.0:
        raise TpointFormatError(path, lineno, f"{_where(layout, 1)} {v[1]:g} deg is outside -90..90")
    if not -180.0 <= v[3] <= 180.0:
        raise TpointFormatError(
            path, lineno, f"{_where(layout, 3)} {v[3]:g} deg is outside -180..180 (beyond +-90: the other side of the pier)"
        )
    if len(layout) > 4 and not 0.0 <= v[4] <= 24.0:
        raise TpointFormatError(path, lineno, f"{_where(layout, 4)} {v[4]:g} h is outside 0..24 h")


def parse_tpoint(
    text: str,
    path: str = "<string>",
    azimuth: str = "N-E",
    mount: str | None = None,
    refraction: tuple[float, float] | None = None,
    auxiliary: Sequence[str | None] | None = None,
) -> TpointRun:
    """Parse the text of a TPOINT input file (see :func:`read_tpoint`)."""
    auxiliary = _check_auxiliary_names(auxiliary)
    if azimuth not in AZIMUTH_CONVENTIONS:
        raise ValueError(f"unknown azimuth convention {azimuth!r}; expected one of {sorted(AZIMUTH_CONVENTIONS)}")
    if mount is not None and mount not in MOUNTS:
        raise ValueError(f"unknown mount {mount!r}; expected one of {', '.join(MOUNTS)}")
    caption = None
    options: list[OptionRecord] = []
    params = None
    kind = None
    rows, extra, lines = [], [], []
    layout = n_columns = n_aux = None
    for lineno, line in records(text, path):
        if caption is None:
            caption = line
            continue
        if line == "END":
            break
        if line.startswith(":"):
            if params is not None:
                raise TpointFormatError(path, lineno, f"option record {line!r} after the run-parameters record")
            options.extend(option_records(path, lineno, line))
            continue
        tokens = line.split()
        if params is None:
            _refuse_misspelt_mount(path, options, mount)
            check_options(path, options)
            kind = _mount_of(path, lineno, options, mount)
            params = _run_parameters(path, lineno, tokens)
            continue
        if n_columns is None:
            n_columns = len(tokens)
            layout, n_aux = _layout(path, lineno, kind, n_columns)
        elif len(tokens) != n_columns:
            raise TpointFormatError(
                path, lineno, f"observation record has {len(tokens)} fields, earlier records have {n_columns}"
            )
        v = _record_values(path, lineno, tokens, layout)
        (_check_altaz if kind == "altaz" else _check_equatorial)(path, lineno, v, layout)
        first_aux = n_columns - n_aux
        names = tuple(f"auxiliary reading {k}" + (f", {auxiliary[k - 1]}" if k <= len(auxiliary) and auxiliary[k - 1] else "")
                      for k in range(1, n_aux + 1))
        extra.append(record_numbers(path, lineno, tokens[first_aux:], names, "observation record", first=first_aux + 1))
        rows.append(v)
        lines.append(lineno)
    if caption is None:
        raise TpointFormatError(path, None, "empty file: no caption line")
    if params is None:
        raise TpointFormatError(path, None, "no run-parameters record (latitude, date, ...) after the caption and options")
    if not rows:
        raise TpointFormatError(path, None, "no observation records")
    values = np.asarray(rows, np.float64)
    extras = np.asarray(extra, np.float64).reshape(len(rows), -1)
    if all(g.width == 1 for g in layout):
        check_not_radians(TpointFormatError, path, lines, _radian_looking_columns(kind, layout, values))
    warn_duplicates(path, np.column_stack([values, extras]), lines)
    keywords = [o.keyword for o in options]
    rotator = _rotator(path, lines, keywords, extras, n_columns - n_aux + 1)
    readings, notes = _readings(path, lines, params, extras, rotator, auxiliary, n_columns - n_aux + 1)
    constants = _refraction_constants(params) if refraction is None else tuple(float(x) for x in refraction)
    common = dict(
        path=path,
        caption=caption,
        options=tuple(keywords),
        option_records=tuple(options),
        parameters=params,
        extra=extras,
        lines=np.asarray(lines),
        mount=kind,
        rotator=rotator,
        refraction=constants,
        readings=readings,
        notes=notes,
    )
    if kind == "altaz":
        data = values * DEG
        observed, encoder = data[:, :2], data[:, 2:]
        over = encoder[:, 1] > math.pi / 2  # over the top: the reading points at az + 180, 180 - el
        sky = np.column_stack([encoder[:, 0] + np.where(over, math.pi, 0.0), np.where(over, math.pi - encoder[:, 1], encoder[:, 1])])
        check_row_separations(path, lines, observed, sky, "their observed and raw positions")
        target = azel_to_enu_numpy(observed[:, 0], observed[:, 1]) @ np.asarray(AZIMUTH_CONVENTIONS[azimuth]).T
        return TpointRun(
            observed=observed,
            encoder=encoder,
            azimuth=azimuth,
            observations=Observations(encoder, target, convention=azimuth, readings=readings),
            refraction_applied=False,
            **common,
        )
    return _equatorial_run(values, layout, params, constants, common)


def _radian_looking_columns(kind: str, layout, values: np.ndarray) -> dict:
    if kind == "altaz":
        limits = (2 * math.pi, math.pi / 2, 2 * math.pi, math.pi)
    else:  # declinations only: an RA in hours may well lie within 2 pi
        limits = (None, math.pi / 2, None, math.pi)
    return {
        _field_of(layout, k): (values[:, k], limit)
        for k, limit in enumerate(limits)
        if limit is not None
    }


def _rotator(path: str, lines: list[int], options: list[str], extras: np.ndarray, field: int) -> np.ndarray | None:
    said = sorted(ROTATOR_OPTIONS.intersection(options))
    if not said:
        return None
    if extras.shape[1] == 0:
        raise TpointFormatError(
            path, int(lines[0]), f"option {said[0]} says the records carry a rotator angle, but they have no extra field"
        )
    warn_input(
        path,
        int(lines[0]),
        f"option {said[0]}: the rotator angle (field {field}) is kept as run.rotator and as the reading "
        "'rotator' (radians); it enters a fit only through a term that reads 'rotator'",
        stacklevel=5,
    )
    return extras[:, 0] * DEG


def _check_auxiliary_names(auxiliary) -> tuple[str | None, ...]:
    if auxiliary is None:
        return ()
    if isinstance(auxiliary, str):
        auxiliary = (auxiliary,)
    names = tuple(auxiliary)
    if len(names) > MAX_AUXILIARY:
        raise ValueError(f"auxiliary names {len(names)} fields; a TPOINT record carries at most {MAX_AUXILIARY} auxiliary readings")
    for name in names:
        if name is not None and (not isinstance(name, str) or not name.strip()):
            raise ValueError(f"auxiliary: each name must be a non-empty string or None, got {name!r}")
    given = [n for n in names if n]
    if len(set(given)) < len(given):
        raise ValueError(f"auxiliary: a name is given twice in {names!r}")
    for k, name in enumerate(names):
        if name in AUXILIARY_NAMES and name != AUXILIARY_NAMES[k]:
            raise ValueError(f"auxiliary: {name!r} names field {k + 1}'s reading, but {name} is the name of field "
                             f"{AUXILIARY_NAMES.index(name) + 1}'s by position")
    return tuple(n.strip() if n else None for n in names)


def _readings(path, lines, params: RunParameters, extras: np.ndarray, rotator, auxiliary, first_field: int):
    """The run's readings and the notes on what was assumed (see :attr:`TpointRun.readings`)."""
    n, k = extras.shape
    readings = {AUXILIARY_NAMES[j]: extras[:, j].copy() for j in range(k)}
    notes = []
    if len(auxiliary) > k:
        raise TpointFormatError(
            path, int(lines[0]), f"auxiliary= names {len(auxiliary)} auxiliary readings, but the records carry {k} "
            f"(fields after the positions)"
        )
    unnamed = [j for j in range(k) if not (j < len(auxiliary) and auxiliary[j])]
    if rotator is not None:
        readings["rotator"] = rotator
        unnamed = [j for j in unnamed if j != 0]
    if unnamed:
        fields = ", ".join(f"field {first_field + j} -> {AUXILIARY_NAMES[j]}" for j in unnamed)
        notes.append(
            f"auxiliary readings known only by their position ({fields}): kept as written under those names, "
            "which TPOINT's auxiliary terms (AUX1H ... AUX2E, A1A ...) read; name them with auxiliary=(...)"
        )
    header = {
        "temperature": params.temperature_c,
        "pressure": params.pressure_mb,
        "humidity": params.humidity,
        "time": mjd_from_date(*params.date) if params.date is not None else None,
    }
    for j, name in enumerate(auxiliary):
        if not name:
            continue
        values = extras[:, j] * (DEG if name in ANGLE_READINGS else 1.0)
        if name in header and header[name] is not None:
            notes.append(f"auxiliary reading {j + 1} ({name}) replaces the run parameters' {name} for every record")
            header[name] = None
        if name == "rotator" and rotator is not None:
            raise TpointFormatError(
                path, int(lines[0]), f"auxiliary reading {j + 1} is named 'rotator', but a rotator option already "
                "says field 1 of the auxiliary readings is the rotator angle"
            )
        readings[name] = values
    if header["time"] is not None:
        notes.append("time: the run parameters' date at 0h UTC (MJD), the same for every record: the file gives no time of day")
    readings.update(per_run(n, header))
    return as_readings(readings, n), tuple(notes)


def _refraction_constants(params: RunParameters) -> tuple[float, float]:
    from .refraction import refraction_constants

    return refraction_constants(params.pressure_mb, params.temperature_c, params.humidity, params.wavelength_um)


def _equatorial_run(values: np.ndarray, layout, params: RunParameters, constants, common: dict) -> "TpointRun":
    from .refraction import refract

    hours = math.pi / 12.0
    has_time = len(layout) > 4
    if has_time:
        sidereal = values[:, 4] * hours
        ha_star, ha_tel = sidereal - values[:, 0] * hours, sidereal - values[:, 2] * hours
    else:
        sidereal = None
        ha_star, ha_tel = values[:, 0] * hours, values[:, 2] * hours
    wrap = lambda h: (h + math.pi) % (2 * math.pi) - math.pi  # noqa: E731
    dec_star, dec_tel = values[:, 1] * DEG, values[:, 3] * DEG
    observed = np.column_stack([wrap(ha_star), dec_star])
    encoder = np.column_stack([wrap(ha_tel), dec_tel])
    lat = params.latitude
    enu = hadec_to_enu_numpy(observed[:, 0], observed[:, 1], lat)
    path, lines = common["path"], common["lines"]
    elevation = np.degrees(np.arcsin(np.clip(enu[:, 2], -1.0, 1.0)))
    low = np.flatnonzero(elevation < HORIZON_DEG)
    if low.size:
        k = int(low[0])
        raise TpointFormatError(
            path, int(lines[k]), f"{_where(layout, 0)}: the star is at elevation {elevation[k]:.2f} deg, below the "
            f"horizon at latitude {math.degrees(lat):.4f} deg (wrong hour angle, sidereal time or latitude?)"
        )
    flip = np.abs(dec_tel) > math.pi / 2  # the other side of the pier: H - 12 h, +-180 deg - D on the sky
    sky = np.column_stack([encoder[:, 0] - np.where(flip, math.pi, 0.0), np.where(flip, np.sign(dec_tel) * math.pi - dec_tel, dec_tel)])
    check_row_separations(
        path, lines, observed, sky, "their star and telescope positions (pier side as the declination says)"
    )
    target = refract(enu, *constants)
    return TpointRun(
        observed=observed,
        encoder=encoder,
        azimuth="ha-dec",
        observations=Observations(encoder, target, convention="ha-dec", readings=common["readings"]),
        refraction_applied=bool(constants != (0.0, 0.0)),
        sidereal_time=sidereal,
        flipped=np.abs(dec_tel) > math.pi / 2,
        **common,
    )


@file_errors(TpointFormatError)
def read_tpoint(
    path: str | os.PathLike,
    azimuth: str = "N-E",
    mount: str | None = None,
    refraction: tuple[float, float] | None = None,
    auxiliary: Sequence[str | None] | None = None,
) -> TpointRun:
    """Read a TPOINT input file of an alt-az or equatorial pointing run.

    **Mount.** The option records say it: ``: ALTAZ`` alt-az; ``: EQUAT``, ``: GERMAN``
    or ``: FORK`` equatorial. A file with none is refused unless ``mount`` says it
    (TPOINT's default is equatorial, but some observatories' TPOINT is set to alt-az
    and their files omit ``: ALTAZ``).

    **Alt-az records**: observed azimuth and elevation, raw (encoder) azimuth and
    elevation, in decimal degrees (4 fields) or ``d m s`` (12 fields). The observed
    positions are taken as observed (refraction included), as TPOINT takes them.

    **Equatorial records**: star right ascension and declination, telescope right
    ascension and declination, then the local sidereal time: ``h m s  d m s  h m s  d m
    s  h m.m`` (14 fields, as TPOINT and TheSkyX write them) or in decimal hours and
    degrees (5 fields: RA, Dec, RA, Dec, sidereal time). Without the sidereal time
    (12 sexagesimal or 4 decimal fields) the two angles are hour angles (hours,
    positive West). The hour angle is ``H = sidereal time - RA``. The sign of an angle
    is its first field's, so ``-00 30 00`` is -0.5 deg. The star's place is its
    apparent place; refraction from the run-parameters record's weather (ERFA's
    ``refco``, :mod:`pointax.io.refraction`) raises it to the observed place, unless
    the pressure is missing or 0 or ``refraction`` gives the constants to use.

    **Pier side.** A telescope declination beyond +-90 deg (TheSkyX's German-mount
    exports) is the other side of the pier: the declination axis has turned past the
    pole. The row's mechanical reading is kept as written, ``(H, D)``; it points at
    the sky declination ``sign(D) 180 deg - D`` and hour angle ``H - 12 h``
    (:class:`pointax.EquatorialMount` reads both sides), and ``run.flipped`` marks
    it. Terms see the mechanical reading, so those of declination-index,
    collimation and non-perpendicularity type change sign on the sky across the pier,
    as TPOINT's do (:mod:`pointax.terms.equatorial`).

    **Option records** (``: KEYWORD``, any case; one record may hold several) are applied or warned
    of: the mount options above; ``: NODA`` (no diurnal aberration: pointax applies
    none); the rotator options below; ``: ALTALT``, ``: XY`` and ``: GIMBAL`` are
    refused (mounts pointax does not read from TPOINT files); ``: ALLSKY`` and any
    option pointax does not know get an :class:`~pointax.io.InputWarning` naming it,
    the file and the line. Contradictory mount options (``: ALTAZ`` with ``: EQUAT``,
    ``: GERMAN`` with ``: FORK``) raise, naming both lines. ``run.option_records``
    keeps them with their lines.

    **Comments**: '!' or ';' starts a comment, at the start of a line or after a
    record (``10.58 37.42 10.55 37.49 0.44 ; [0026] ...``).

    **Auxiliary readings.** Every record may end with up to three more numbers, the
    same count on every record: TPOINT's auxiliary readings (P. T. Wallace's term
    routines ``tptPterms``/``tptPtermg`` take ``auxil[3]``, which its terms ``AUX1H`` ...
    ``AUX2E`` and ``A1A`` ... ``A3Z`` multiply by a coefficient). They are kept in
    ``run.extra`` as written and in ``run.readings`` (and ``run.observations.readings``)
    as ``aux1``, ``aux2``, ``aux3`` by position (``run.notes`` says so), which is what
    :mod:`pointax.terms.tpoint_auxiliary` reads. With a rotator option (``: ROTNR``,
    ``: ROTNL``, ``: ROTTEL``, ``: ROTCL``, ``: ROTCR``) the first is the rotator angle,
    also kept in ``run.rotator`` and ``readings["rotator"]`` (radians), with an
    :class:`~pointax.io.InputWarning` saying so. ``auxiliary=("temperature", None,
    "tilt_1")`` names the fields by position as well (standard names in their units:
    ``rotator``, ``tilt_1``, ``tilt_2`` written in degrees are converted to radians;
    others are kept as written). The run-parameters record's temperature (deg C),
    pressure (mB = hPa) and humidity (0-1) are readings of every record, and its date
    is ``readings["time"]``, the MJD of 0h UTC that day (TPOINT's record has no time of
    day). A malformed auxiliary field raises, naming file, line and field.

    Args:
        path: the file.
        azimuth: how an alt-az file counts azimuth: 'N-E' (TPOINT's standard,
            default), 'S-E' (from South through East, as in the MMT files) or 'S-W'.
            It decides the East-North-Up directions of the observed positions; TPOINT-form
            fits do not depend on it as long as the model uses the same convention.
        mount: 'altaz' or 'equatorial' for files without a mount option (or to check
            the file says so).
        refraction: the refraction constants ``(A, B)`` in radians (e.g. a model
            file's ``refraction`` times ``pointax.core.units.ARCSEC``), instead of those computed
            from the run's weather; they are applied to equatorial runs.
        auxiliary: names of the auxiliary fields by position (``None`` leaves one
            known as ``aux<k>`` only); at most as many as the records carry.

    Raises:
        TpointFormatError: naming file, line and field of the first malformed record.
    """
    path = os.fspath(path)
    return parse_tpoint(
        read_text(path, TpointFormatError, comments="!;", caption=True), path, azimuth, mount, refraction, auxiliary
    )

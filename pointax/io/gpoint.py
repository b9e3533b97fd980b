"""RTS2 gpoint files of pointing runs: alt-az runs (``altaz-manual``, ``altaz``) and
German-equatorial runs (``gem``, ``observatory``). gpoint's model files (``RTS2_ALTAZ``,
``RTS2_GEM``) are :mod:`pointax.io.gpoint_model` (its names are importable from here too).

The definition is gpoint's own reader, ``GPoint.process_files`` in RTS2's
``python/rts2/gpoint.py`` (repository ``RTS2/rts2``, commit
``6480a7eb549d3158ee178ce557fab6d75de8eba9``), the writer of ``altaz-manual`` files,
``TPVP.get_altazm_line`` in ``python/rts2/tpvp.py``, and of GEM files,
``python/rts2/fits2model.py`` (same repository); the gpoint manual page
(``man/gpoint.txt``) shows examples. Layout::

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

**German-equatorial files** (header ``# gem LON LAT ALT`` or ``# observatory LON LAT
ALT``, as ``fits2model.py`` writes it; gpoint treats both alike, and a file without a
header as GEM too) have 9-field rows, ``sn,mjd,lst,a_ra,a_dec,ax_ra,ax_dec,r_ra,r_dec``:
id, time (RTS2's writer puts the JD), local sidereal time (deg), the mount's RA and Dec
*in telescope coordinates* (deg: the man page's "DEC axis values continue to count
above 90/below -90" on the flipped side of the pier, with the RA 180 deg from the
sky's), the two axis counts, and the real (true, astrometric) RA and Dec of the field
(deg, on the sky). gpoint's raw position is ``(lst - a_ra, a_dec)``, unchanged; its real
one is brought to the mount's side of the pier: for ``|a_dec| > 90`` the real RA is
turned by 180 deg and the real Dec mirrored (``flip_ra``, ``flip_dec``: ``180 - r_dec``
for ``a_dec > 90``, ``-180 - r_dec`` for ``a_dec < -90``). That is pointax's
:class:`~pointax.EquatorialMount` reading of the flipped side, ``(H + 180 deg, 180 deg
- dec)`` (``-180 deg - dec`` names the same direction): so ``run.encoder`` holds the
readings ``(lst - a_ra, a_dec)`` in radians as they are (hour angle positive West, not
wrapped), ``run.observed`` gpoint's real position in the same side's reading
(``lst - flip_ra(r_ra), flip_dec(r_dec)``), ``run.flipped`` which rows are on the
flipped side (``|a_dec| > 90``: gpoint's ``--flip east`` keeps these, ``--flip west`` the
others) and ``run.observations`` the readings with the real directions in East-North-Up
at the header's latitude (``E = -cos d sin H``, ``N = cos(lat) sin d - sin(lat) cos d
cos H``, ``U = sin(lat) sin d + cos(lat) cos d cos H`` with ``H = lst - r_ra``,
``d = r_dec``), convention ``"ha-dec"``. Fit gpoint's GEM terms with
``pointax.Equatorial(terms, latitude=run.latitude)``.

Where pointax is stricter than gpoint (gpoint would crash, misread or silently drop):

* line 1 must be blank or a comment: gpoint skips it unread, so a header or an
  observation there would be lost;
* a header is required (without one gpoint reads the rows as a GEM run at the latitude
  of its ``--latitude`` option), only one per file, with numeric longitude, latitude
  and altitude;
* a row must have exactly 8 (``altaz-manual``) or 9 (``altaz``, ``gem``) fields (gpoint
  reads the first 9 of a longer row), every field after the id a finite number,
  observed elevations within +-90 deg; in GEM rows the mount's Dec within +-270 deg
  (``180 - dec`` on the flipped side of a northern mount reaches 270 deg),
  the real Dec within +-90 deg, LST and RAs within +-360 deg, and the real position above
  the horizon at the header's latitude (an LST in hours, or a wrong latitude, puts it
  below); a real position more than 5 deg from the mount's, beyond the run's common
  offset, gives a warning naming the line and both positions (a pier flip written on one
  of them only? a mistyped field?), in every format, as for TPOINT runs;
* blank lines are skipped (gpoint would stop with an unpacking error).

The time field becomes the reading ``time`` (``run.readings``, ``run.observations.readings``),
MJD in UTC days: a JD (above 2,000,000, as RTS2 writes it) is converted.

Every error is a :class:`GpointFormatError` naming the file, line and field.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re

import numpy as np

from ..core.mounts import AZIMUTH_CONVENTIONS
from ..core.observations import Observations
from ..core.rotations import azel_to_enu_numpy, hadec_to_enu_numpy
from ..core.units import DEG
from .errors import file_errors
from .gpoint_conventions import GPOINT_AZIMUTH, GpointFormatError
from .gpoint_model import (  # the model files' names: importable from here, as before the split
    GpointModelFile,
    format_gpoint_model,
    parse_gpoint_model,
    read_gpoint_model,
    write_gpoint_model,
)
from .run_readings import mjd_from_jd_or_mjd
from .sanity import (
    ROW_SEPARATION_DEG,
    check_azimuth,
    check_not_radians,
    check_observed_elevation,
    check_row_separations,
    finite_number,
    warn_duplicates,
)
from .text import read_text

__all__ = [
    "GpointFormatError",
    "GpointRun",
    "GpointModelFile",
    "read_gpoint",
    "parse_gpoint",
    "format_gpoint_model",
    "write_gpoint_model",
    "read_gpoint_model",
    "parse_gpoint_model",
    "GPOINT_AZIMUTH",
    "ROW_FIELDS",
    "FAR_DEG",
]

FAR_DEG = ROW_SEPARATION_DEG
"""A row whose real position lies farther than this (deg) from the mount's, beyond the run's
common offset, gives a warning naming its line and both positions (the same check and
limit as TPOINT runs': :data:`pointax.io.sanity.ROW_SEPARATION_DEG`)."""

_GEM_FIELDS = (
    "observation id",
    "time (MJD/JD)",
    "local sidereal time (deg)",
    "mount RA (deg)",
    "mount Dec (deg)",
    "RA axis counts",
    "Dec axis counts",
    "real RA (deg)",
    "real Dec (deg)",
)

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
    "gem": _GEM_FIELDS,
    "observatory": _GEM_FIELDS,
}
"""Row fields of each format, in file order."""

_HEADER = re.compile(r"#\s*(\S*)\s+(\S*)\s+(\S*)\s+(\S*)\s*")  # gpoint's own `obsmatch`
_ALTAZ_KINDS = ("altaz-manual", "altaz")
_EQUATORIAL_KINDS = ("observatory", "gem")
_HEADER_FIELDS = ("longitude (deg)", "latitude (deg)", "altitude (m)")


@dataclasses.dataclass(frozen=True)
class GpointRun:
    """A pointing run read from a gpoint input file: alt-az (``mount == "altaz"``) or
    German equatorial (``mount == "gem"``).

    Angles are radians. Alt-az: azimuths are counted from South through West
    (:attr:`azimuth` is ``"S-W"``), as in the file. GEM: readings are (hour angle
    positive West, declination) as the axes read them (see :mod:`pointax.io.gpoint`).
    ``observations`` holds the encoder angles unchanged and the observed directions in
    East-North-Up.
    """

    path: str
    caption: str
    """Line 1 without its ``#`` (gpoint skips it; RTS2 writes 'model file created on ...');
    :func:`pointax.fit` shows it as the report's title."""
    kind: str
    """The header's keyword: ``"altaz-manual"``, ``"altaz"``, ``"gem"`` or ``"observatory"``."""
    longitude: float
    """Site longitude from the header, radians, East positive."""
    latitude: float
    """Site latitude from the header, radians, North positive."""
    altitude_m: float
    """Site altitude from the header, metres."""
    ids: tuple[str, ...]
    """Observation id of each row (field 1), as written."""
    time: np.ndarray
    """``(n,)`` field 2 as written (gpoint calls it MJD; RTS2's writers put the JD)."""
    encoder: np.ndarray
    """``(n, 2)`` the mount's (raw) position, radians: azimuth (South through West) and
    elevation, or hour angle ``lst - a_ra`` and declination ``a_dec`` as the axes read
    them (GEM)."""
    observed: np.ndarray
    """``(n, 2)`` the real (observed) position, radians, as gpoint takes it: azimuth and
    elevation, or (GEM) hour angle and declination on the mount's side of the pier
    (``flip_ra``/``flip_dec`` applied to flipped rows)."""
    columns: dict
    """The row fields gpoint's fit does not use, by name, as ``(n,)`` arrays: ``"ra"``,
    ``"dec"`` (radians) for altaz-manual; ``"lst"`` (radians), ``"axis_az"``,
    ``"axis_el"`` (counts) for altaz; ``"lst"``, ``"ra"`` (the mount's, as written),
    ``"real_ra"``, ``"real_dec"`` (radians, as written), ``"axis_ra"``, ``"axis_dec"``
    (counts) for GEM."""
    lines: np.ndarray
    """``(n,)`` line number of each observation in the file."""
    azimuth: str | None
    """The azimuth convention of ``encoder`` and ``observed``: ``"S-W"``; None for GEM runs."""
    observations: Observations
    mount: str = "altaz"
    """``"altaz"`` or ``"gem"``: the pointax model to fit (``pointax.AltAz(terms,
    azimuth=run.azimuth)`` or ``pointax.Equatorial(terms, latitude=run.latitude)``)."""
    flipped: np.ndarray | None = None
    """GEM: ``(n,)`` True where the row is on the flipped side of the pier (the mount's
    Dec beyond +-90 deg: gpoint's ``--flip east`` keeps these rows, ``--flip west`` those
    with ``|Dec| < 90``); None for alt-az runs."""
    readings: dict = dataclasses.field(default_factory=dict)
    """Auxiliary readings (also ``observations.readings``): ``time``, each row's field 2
    as MJD (UTC days): a value above 2,000,000 is a Julian date (RTS2's writers put the
    JD there), converted; below, an MJD as gpoint names the field."""

    def __len__(self) -> int:
        return self.encoder.shape[0]


def _number(path: str, lineno: int, token: str, field: int, name: str, record: str) -> float:
    return finite_number(GpointFormatError, path, lineno, token, f"{record}: field {field} ({name})")


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
            "no header line '# altaz-manual LONGITUDE LATITUDE ALTITUDE' (or '# altaz ...', '# gem ...', "
            "'# observatory ...'); without one gpoint reads the rows as an equatorial run at the latitude "
            "given on its command line",
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
    common = dict(
        path=path,
        caption=first.lstrip("#").strip(),
        kind=kind,
        longitude=longitude * DEG,
        latitude=latitude * DEG,
        altitude_m=altitude,
        ids=tuple(ids),
        time=v[:, 0],
        lines=np.asarray(line_numbers),
        readings={"time": mjd_from_jd_or_mjd(v[:, 0])},
    )
    if kind in _EQUATORIAL_KINDS:
        return _gem_run(path, v, line_numbers, latitude, record, common)
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
    over = encoder[:, 1] > math.pi / 2  # over the top: the reading points at az + 180, 180 - el
    sky_raw = np.stack([encoder[:, 0] + np.where(over, math.pi, 0.0), np.where(over, math.pi - encoder[:, 1], encoder[:, 1])], -1)
    check_row_separations(
        path,
        line_numbers,
        observed,
        sky_raw,
        "their real and mount positions",
        describe=lambda k: (
            f"real az {observed_deg[k, 0]:g} el {observed_deg[k, 1]:g}, "
            f"mount az {encoder_deg[k, 0]:g} el {encoder_deg[k, 1]:g} deg"
        ),
        stacklevel=6,  # the caller of read_gpoint
    )
    frame = np.asarray(AZIMUTH_CONVENTIONS[GPOINT_AZIMUTH])
    target = azel_to_enu_numpy(observed[:, 0], observed[:, 1]) @ frame.T
    return GpointRun(
        **common,
        encoder=encoder,
        observed=observed,
        columns=columns,
        azimuth=GPOINT_AZIMUTH,
        observations=Observations(encoder, target, convention=GPOINT_AZIMUTH, readings=common["readings"]),
        mount="altaz",
    )


def _gem_run(path, v, line_numbers, latitude_deg, record, common) -> GpointRun:
    """The GEM part of :func:`parse_gpoint`: ``v`` holds fields 2..9 of each row."""
    _, lst, a_ra, a_dec, ax_ra, ax_dec, r_ra, r_dec = v.T
    fields = {name: k + 1 for k, name in enumerate(_GEM_FIELDS)}
    for k, lineno in enumerate(line_numbers):
        for name, value, limit in (
            ("local sidereal time (deg)", lst[k], 360.0),
            ("mount RA (deg)", a_ra[k], 360.0),
            ("real RA (deg)", r_ra[k], 360.0),
            ("mount Dec (deg)", a_dec[k], 270.0),
            ("real Dec (deg)", r_dec[k], 90.0),
        ):
            if not -limit <= value <= limit:
                why = {
                    360.0: "(an angle in other units?)",
                    270.0: "(on the flipped side the axis reads 180 - dec, or -180 - dec, for a sky dec within +-90)",
                    90.0: "(a declination on the sky)",
                }[limit]
                raise GpointFormatError(
                    path, lineno, f"{record}: field {fields[name]} ({name}) {value:g} is outside -{limit:g}..{limit:g} {why}"
                )
    check_not_radians(
        GpointFormatError,
        path,
        line_numbers,
        {
            "field 3 (local sidereal time)": (lst, 2 * math.pi),
            "field 4 (mount RA)": (a_ra, 2 * math.pi),
            "field 5 (mount Dec)": (a_dec, 1.5 * math.pi),
            "field 9 (real Dec)": (r_dec, math.pi / 2),
        },
    )
    lat = latitude_deg * DEG
    # The real position on the sky -> East-North-Up.
    real_ha, real_dec = (lst - r_ra) * DEG, r_dec * DEG
    target = hadec_to_enu_numpy(real_ha, real_dec, lat)
    elevation = np.degrees(np.arcsin(np.clip(target[:, 2], -1.0, 1.0)))
    for k, lineno in enumerate(line_numbers):
        check_observed_elevation(
            GpointFormatError,
            path,
            lineno,
            float(elevation[k]),
            f"{record}: elevation of the real position (fields 3, 8, 9: LST - real RA, real Dec, at the header's "
            f"latitude {latitude_deg:g} deg)",
        )
    # gpoint: (lst - a_ra, a_dec, lst - flip_ra(r_ra, a_dec), flip_dec(r_dec, a_dec)).
    flipped = np.abs(a_dec) > 90.0
    flip_ra = np.where(flipped, np.mod(r_ra + 180.0, 360.0), r_ra)
    flip_dec = np.where(a_dec > 90.0, 180.0 - r_dec, np.where(a_dec < -90.0, -180.0 - r_dec, r_dec))
    encoder = np.stack([lst - a_ra, a_dec], axis=-1) * DEG
    observed = np.stack([lst - flip_ra, flip_dec], axis=-1) * DEG
    # The mount's reading brought back to the sky (H - 180 deg, +-180 deg - Dec on the flipped side).
    sky_raw = np.stack([lst - a_ra - np.where(flipped, 180.0, 0.0), np.where(flipped, np.sign(a_dec) * 180.0 - a_dec, a_dec)], -1)
    check_row_separations(
        path,
        line_numbers,
        np.stack([real_ha, real_dec], -1),
        sky_raw * DEG,
        "their real and mount positions (fields 8-9 and 4-5, pier side as the mount's Dec says)",
        describe=lambda k: f"real RA {r_ra[k]:g} Dec {r_dec[k]:g}, mount RA {a_ra[k]:g} Dec {a_dec[k]:g} deg",
        stacklevel=7,  # the caller of read_gpoint
    )
    warn_duplicates(path, v, line_numbers, f"{record}s")
    return GpointRun(
        **common,
        encoder=encoder,
        observed=observed,
        columns={
            "lst": lst * DEG,
            "ra": a_ra * DEG,
            "real_ra": r_ra * DEG,
            "real_dec": r_dec * DEG,
            "axis_ra": ax_ra,
            "axis_dec": ax_dec,
        },
        azimuth=None,
        observations=Observations(encoder, target, convention="ha-dec", readings=common["readings"]),
        mount="gem",
        flipped=flipped,
    )


@file_errors(GpointFormatError)
def read_gpoint(path: str | os.PathLike) -> GpointRun:
    """Read a gpoint input file: an alt-az run (``# altaz-manual`` or ``# altaz``) or a
    German-equatorial one (``# gem`` or ``# observatory``).

    Returns a :class:`GpointRun`; fit an alt-az run with
    ``pointax.fit(pointax.AltAz(pointax.terms.gpoint_terms("ia,ie,tn,te,npae,npoa,tf"),
    azimuth=run.azimuth), run)`` and a GEM run with ``pointax.fit(pointax.Equatorial(
    pointax.terms.gpoint.gpoint_model_terms("ih id ch np ma me tf fo daf", "gem",
    latitude=run.latitude), latitude=run.latitude), run)`` (``run.mount`` says which).

    Raises:
        GpointFormatError: naming file, line and field of the first malformed record.
    """
    path = os.fspath(path)
    return parse_gpoint(read_text(path, GpointFormatError, comments="#"), path)


"""RTS2 gpoint files: input files of alt-az runs (``altaz-manual``, ``altaz``) and of
German-equatorial runs (``gem``, ``observatory``), and gpoint's model files
(``RTS2_ALTAZ``, ``RTS2_GEM``).

The definition is gpoint's own reader, ``GPoint.process_files`` in RTS2's
``python/rts2/gpoint.py`` (repository ``RTS2/rts2``, commit
``6480a7eb549d3158ee178ce557fab6d75de8eba9``), its model writer and reader
(``GPoint.to_string``, ``GPoint.save``, ``GPoint.load``, same file; ``gpoint -o FILE``
calls ``save``), the writer of ``altaz-manual`` files, ``TPVP.get_altazm_line`` in
``python/rts2/tpvp.py``, and of GEM files, ``python/rts2/fits2model.py`` (same
repository); the gpoint manual page (``man/gpoint.txt``) shows examples. Layout::

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
  below); a real position more than 10 deg from the mount's gives a warning (a pier
  flip written on one of them only?);
* blank lines are skipped (gpoint would stop with an unpacking error).

Every error is a :class:`GpointFormatError` naming the file, line and field.

**Model files** (:func:`format_gpoint_model`, :func:`write_gpoint_model`,
:func:`read_gpoint_model`): what ``gpoint -o FILE`` writes (``GPoint.save`` writes
``str(self)``, i.e. ``to_string()`` in arcseconds), byte for byte::

    RTS2_GEM <id>" <me>" <ma>" <tf>" <ih>" <ch>" <np>" <daf>" <fo>"
    HA<TAB><value>"<TAB><function><TAB><variables ;-joined><TAB><multipliers ;-joined>

(``RTS2_ALTAZ <ia>" <tn>" <te>" <npae>" <npoa>" <ie>" <tf>"`` for alt-az; one line per
extra term, axis upper-case; no newline after the last line). Each value is
``str(numpy.degrees(value) * 3600.0)``, the shortest text that reads back to the same
double in arcseconds; multipliers are written ``str(float(m))`` (``2.0``). gpoint's
reader (``GPoint.load``) takes ``RTS2_MODEL`` or ``RTS2_GEM`` with 9 values,
``RTS2_ALTAZ`` with 7, 5-field extra lines and ``#`` comments; a value is radians unless
it ends in ``d`` (degrees), ``'`` or ``m`` (arcminutes), ``"`` or ``s`` (arcseconds).
The file holds no latitude (RTS2 takes it from the telescope's configuration).
pointax's reader also skips blank lines (gpoint's would stop at one) and reads the
function name in any case (as RTS2's C++ loader does; gpoint's own needs lower case).

RTS2's telescope drivers load the file with C++ (``GPointModel::load`` in RTS2's
``lib/rts2tel/gpointmodel.cpp``), which reads the same layout (``RTS2_GEM`` as a GEM
model, ``readDeg`` with the same unit suffixes) but needs the model line before any
extra line, and evaluates three extra functions differently from gpoint's fit: its
``csc`` divides by the cosine and ``sec`` by the sine (swapped), and its ``sinsin``
leaves out the coefficient. A model with such extras does not point in RTS2 as gpoint
(and pointax) fitted it; that is RTS2's, not the file's, concern here.
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
from ..rotations import azel_to_enu_numpy, hadec_to_enu_numpy
from ..terms.gpoint import (
    GPOINT_ALTAZ_TERMS,
    GPOINT_GEM_TERMS,
    GpointExtra,
    GpointGemTerm,
    GpointTerm,
    _parse_extra,
    gpoint_model_terms,
)
from ..units import DEG
from .errors import FileFormatError, warn_input
from .sanity import (
    check_azimuth,
    check_not_radians,
    check_observed_elevation,
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

GPOINT_AZIMUTH = "S-W"
"""How gpoint (RTS2, libnova) counts azimuth: from South through West."""

FAR_DEG = 10.0
"""A GEM row whose real position lies farther than this from the mount's (deg) gives a warning."""

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


class GpointFormatError(FileFormatError):
    """A gpoint file could not be read; the message names file, line and field."""


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
    frame = np.asarray(AZIMUTH_CONVENTIONS[GPOINT_AZIMUTH])
    target = azel_to_enu_numpy(observed[:, 0], observed[:, 1]) @ frame.T
    return GpointRun(
        **common,
        encoder=encoder,
        observed=observed,
        columns=columns,
        azimuth=GPOINT_AZIMUTH,
        observations=Observations(encoder, target, convention=GPOINT_AZIMUTH),
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
    raw = hadec_to_enu_numpy(encoder[:, 0], encoder[:, 1], lat)
    far = np.degrees(np.arccos(np.clip(np.sum(raw * target, axis=-1), -1.0, 1.0)))
    bad = [(int(line_numbers[k]), float(far[k])) for k in np.flatnonzero(far > FAR_DEG)]
    if bad:
        shown = ", ".join(f"line {ln}: {d:.1f} deg" for ln, d in bad[:5]) + (", ..." if len(bad) > 5 else "")
        warn_input(
            path,
            bad[0][0],
            f"{len(bad)} of {len(line_numbers)} {record}s have their real position more than {FAR_DEG:g} deg from "
            f"the mount's ({shown}): a pier flip written in the mount's RA/Dec (fields 4-5) but not both, or the "
            "wrong row order?",
            stacklevel=4,
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
        observations=Observations(encoder, target, convention="ha-dec"),
        mount="gem",
        flipped=flipped,
    )


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
    return parse_gpoint(read_text(path, GpointFormatError), path)


# ------------------------------------------------------------------ model files

_MODEL_KEYWORDS = {"RTS2_MODEL": "gem", "RTS2_GEM": "gem", "RTS2_ALTAZ": "altaz"}
_BASE_NAMES = {"altaz": GPOINT_ALTAZ_TERMS, "gem": GPOINT_GEM_TERMS}
_WRITTEN_KEYWORD = {"altaz": "RTS2_ALTAZ", "gem": "RTS2_GEM"}


def _gpoint_number(x) -> str:
    """gpoint's text of a value in radians: ``str(numpy.degrees(x) * 3600.0)`` (arcseconds)."""
    return str(np.degrees(np.float64(float(x))) * 3600.0)


def _model_of(source):
    from ..fitting.result import FitResult

    return source.model if isinstance(source, FitResult) else source


def format_gpoint_model(source) -> str:
    """The text ``gpoint -o`` writes for a model of gpoint's terms (see
    :mod:`pointax.io.gpoint`): ``RTS2_ALTAZ`` for an alt-az model (azimuth ``"S-W"``),
    ``RTS2_GEM`` for an equatorial one, then one line per extra term, values in
    arcseconds, no newline at the end. Base terms the model lacks are written as 0, as
    gpoint fits and writes all of them.

    Args:
        source: a :class:`pointax.Model` or :class:`pointax.FitResult` whose terms are
            all gpoint's terms of its mount (:mod:`pointax.terms.gpoint`).

    Raises:
        ValueError: naming the term gpoint's file cannot hold (a TPOINT term, a term of
            the other mount, a repeated term), a mount gpoint has no model for, an
            alt-az model whose azimuth is not counted from South through West, or a GEM
            term whose latitude is not the model's.
    """
    from ..mounts import AltAzMount, EquatorialMount

    model = _model_of(source)
    mount = model.mount
    if isinstance(mount, EquatorialMount):
        kind, base_class = "gem", GpointGemTerm
        latitude = float(np.asarray(mount.latitude))
    elif isinstance(mount, AltAzMount):
        kind, base_class, latitude = "altaz", GpointTerm, None
        if mount.azimuth != GPOINT_AZIMUTH:
            raise ValueError(
                f"gpoint's alt-az terms are defined on the azimuth counted from South through West; this model "
                f"counts it {mount.azimuth!r}: build it with pointax.AltAz(terms, azimuth='S-W')"
            )
    else:
        raise ValueError(
            f"gpoint's model files hold alt-az (RTS2_ALTAZ) and German-equatorial (RTS2_GEM) models; this model's "
            f"mount is {type(mount).__name__}"
        )
    base_names = _BASE_NAMES[kind]
    values: dict[str, float] = {}
    extras: list[GpointExtra] = []
    seen: set[str] = set()
    for term in model.terms:
        ok = isinstance(term, base_class) or (isinstance(term, GpointExtra) and term.gpoint_mount == kind)
        if not ok:
            raise ValueError(
                f"term {term.name} ({type(term).__name__}) cannot be written to a gpoint model file: it holds only "
                f"gpoint's {kind} terms ({' '.join(base_names)} and {'ha/dec' if kind == 'gem' else 'az/el'} extras)"
            )
        if term.name in seen:
            raise ValueError(f"term {term.name} appears twice in the model; gpoint's model file holds it once")
        seen.add(term.name)
        if kind == "gem" and getattr(term, "uses_latitude", False) and term.latitude is not None:
            if abs(float(term.latitude) - latitude) > 1e-12:
                raise ValueError(
                    f"term {term.name} was built for latitude {math.degrees(term.latitude):.9g} deg, the model's "
                    f"mount is at {math.degrees(latitude):.9g} deg"
                )
        if isinstance(term, GpointExtra):
            extras.append(term)
        else:
            values[term.name] = term.coef
    out = _WRITTEN_KEYWORD[kind] + " " + '" '.join(_gpoint_number(values.get(n, 0.0)) for n in base_names) + '"'
    for e in extras:
        # gpoint: '\n{0}\t{1}"\t{2}'.format(e.axis.upper(), value, e) with
        # str(e) = '{function}\t{params ;-joined}\t{consts ;-joined}' and consts floats.
        out += '\n{0}\t{1}"\t{2}\t{3}\t{4}'.format(
            e.axis.upper(),
            _gpoint_number(e.coef),
            e.function,
            ";".join(e.variables),
            ";".join(str(float(m)) for m in e.multipliers),
        )
    return out


def write_gpoint_model(path: str | os.PathLike, source) -> None:
    """Write the model file ``gpoint -o`` writes (:func:`format_gpoint_model`) to ``path``.

    Nothing is written when the model cannot be (ValueError, see
    :func:`format_gpoint_model`)."""
    text = format_gpoint_model(source)
    Path(os.fspath(path)).write_text(text, encoding="utf-8")


@dataclasses.dataclass(frozen=True)
class GpointModelFile:
    """A gpoint model file as read (:func:`read_gpoint_model`).

    Values are radians, as gpoint holds them after ``GPoint.load``. The file has no
    latitude: give it to :meth:`terms` / :meth:`model` for a GEM model.
    """

    path: str
    keyword: str
    """``"RTS2_ALTAZ"``, ``"RTS2_GEM"`` or ``"RTS2_MODEL"`` (gpoint reads the last two alike)."""
    mount: str
    """``"altaz"`` or ``"gem"``."""
    values: dict
    """Base terms by gpoint name, in the file's order, radians."""
    extras: tuple
    """``(spec, value)`` per extra line, in the file's order: the canonical spec
    (``ha:sin:dec:2``) and the value in radians."""
    lines: dict
    """Line number of each parameter, by name."""

    @property
    def names(self) -> list[str]:
        """Parameter names: the base terms, then the extras' specs."""
        return list(self.values) + [spec for spec, _ in self.extras]

    def terms(self, latitude: float | None = None) -> tuple:
        """The model's terms with the file's values (:mod:`pointax.terms.gpoint`);
        ``latitude`` (radians) is required for a GEM model."""
        if self.mount == "gem" and latitude is None:
            raise ValueError(f"{self.path}: a GEM model file holds no latitude; give latitude= (radians)")
        values = dict(self.values)
        values.update(dict(self.extras))
        return gpoint_model_terms(self.names, self.mount, latitude=latitude, values=values)

    def model(self, latitude: float | None = None):
        """A :class:`pointax.Model`: ``pointax.AltAz(terms, azimuth="S-W")`` or
        ``pointax.Equatorial(terms, latitude=latitude)``."""
        from ..mount_models import AltAz, Equatorial

        terms = self.terms(latitude)
        if self.mount == "altaz":
            return AltAz(terms, azimuth=GPOINT_AZIMUTH)
        return Equatorial(terms, latitude=latitude)


def _model_value(path: str, lineno: int, token: str, what: str) -> float:
    """gpoint's ``_str_to_rad``: a number in radians, or in degrees (``d``), arcminutes
    (``'``, ``m``) or arcseconds (``"``, ``s``) by its last character."""
    scale = {"d": math.pi / 180.0, "'": math.pi / 10800.0, "m": math.pi / 10800.0, '"': None, "s": None}
    body, unit = (token[:-1], token[-1]) if token and token[-1] in scale else (token, "")
    try:
        number = float(body)
    except ValueError:
        raise GpointFormatError(path, lineno, f"{what} is {token!r}, not a number (radians, or with d ' m \" s)") from None
    if not math.isfinite(number):
        raise GpointFormatError(path, lineno, f"{what} is {token!r}, not finite")
    if unit in ('"', "s"):
        return float(np.radians(number / 3600.0))  # as gpoint: np.radians(float(s[:-1]) / 3600.0)
    if unit in ("'", "m"):
        return float(np.radians(number / 60.0))
    if unit == "d":
        return float(np.radians(number))
    return number


def parse_gpoint_model(text: str, path: str = "<string>") -> GpointModelFile:
    """Parse the text of a gpoint model file (see :func:`read_gpoint_model`)."""
    keyword = mount = None
    values: dict[str, float] = {}
    lines: dict[str, int] = {}
    extras: list[tuple[str, float, int, str]] = []
    for lineno, line in enumerate(text.splitlines(), 1):
        if line.startswith("#") or not line.strip():
            continue  # gpoint skips '#' lines (and would stop at a blank one)
        tokens = line.split()
        if tokens[0] in _MODEL_KEYWORDS:
            kind = _MODEL_KEYWORDS[tokens[0]]
            names = _BASE_NAMES[kind]
            if keyword is not None:
                raise GpointFormatError(path, lineno, f"a second model line ({tokens[0]}; the first is {keyword})")
            if len(tokens) != len(names) + 1:
                raise GpointFormatError(
                    path,
                    lineno,
                    f"{tokens[0]} line has {len(tokens) - 1} values; gpoint's has {len(names)}: {' '.join(names)}",
                )
            keyword, mount = tokens[0], kind
            for k, (name, token) in enumerate(zip(names, tokens[1:])):
                values[name] = _model_value(path, lineno, token, f"{tokens[0]} line: field {k + 2} ({name})")
                lines[name] = lineno
        elif len(tokens) == 5:
            axis, multi, function, params, consts = tokens
            spec = f"{axis}:{function}:{params}:{consts}"
            try:
                parsed = _parse_extra(spec)
            except ValueError as err:
                raise GpointFormatError(path, lineno, f"extra line: {err}") from None
            name = GpointExtra(axis=parsed[0], function=parsed[1], variables=parsed[2], multipliers=parsed[3]).name
            value = _model_value(path, lineno, multi, f"extra line: field 2 (value of {name})")
            extras.append((name, value, lineno, parsed[0]))
        else:
            raise GpointFormatError(
                path,
                lineno,
                f"not a gpoint model line: expected RTS2_ALTAZ (7 values), RTS2_GEM or RTS2_MODEL (9 values), or an "
                f"extra term 'AXIS VALUE FUNCTION VARIABLES MULTIPLIERS' (5 fields), got {len(tokens)} field(s) "
                f"starting {tokens[0]!r}",
            )
    if keyword is None:
        raise GpointFormatError(path, None, "no model line (RTS2_ALTAZ, RTS2_GEM or RTS2_MODEL)")
    seen: dict[str, int] = {}
    for spec, _, lineno, axis in extras:
        if spec in seen:
            raise GpointFormatError(path, lineno, f"extra term {spec} is given twice (first on line {seen[spec]}); gpoint refuses it")
        seen[spec] = lineno
        own = ("az", "el") if mount == "altaz" else ("ha", "dec")
        if axis not in own:
            raise GpointFormatError(
                path, lineno, f"extra term {spec} corrects {axis}, which a {keyword} model does not have (gpoint "
                f"would ignore it): its extras correct {' or '.join(own)}"
            )
        lines[spec] = lineno
    return GpointModelFile(
        path=path,
        keyword=keyword,
        mount=mount,
        values=values,
        extras=tuple((spec, value) for spec, value, _, _ in extras),
        lines=lines,
    )


def read_gpoint_model(path: str | os.PathLike) -> GpointModelFile:
    """Read a gpoint model file (``RTS2_ALTAZ`` / ``RTS2_GEM`` / ``RTS2_MODEL`` line and
    extra-term lines), as gpoint's ``GPoint.load`` reads it.

    Values written by :func:`write_gpoint_model` read back as the arcsecond values
    written, exactly (the shortest text of each double); converted back to radians
    (``np.radians(arcsec / 3600)``, as gpoint does) they come within 2 units in the last
    place of the values written (relative 4.4e-16).

    Raises:
        GpointFormatError: naming file, line and field of the first malformed line.
    """
    path = os.fspath(path)
    return parse_gpoint_model(read_text(path, GpointFormatError), path)

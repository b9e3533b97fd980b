"""PAINT heliostat calibration data (DLR solar tower Juelich): JSON readers.

A PAINT heliostat folder (e.g. ``AA39/``) holds::

    heliostat-properties.json              position, size, initial orientation, two
                                           linear actuators, joint/concentrator offsets
    <id>-calibration-properties.json       one calibration sample each: motor positions,
                                           sun azimuth/elevation, focal-spot centroids
                                           (methods "HeliOS" and/or "UTIS"), target name

and ``tower-measurements.json`` (target planes of the tower, WGS84) sits in the folder
or its parent. :func:`read_paint` reads a whole folder into a :class:`PaintRun` with
the per-sample arrays a kinematics fit needs (motor increments, sun directions and
measured mirror normals in East-North-Up).

Conventions of the files, converted here where data enters pointax:

* Positions are WGS84 ``[latitude deg, longitude deg, height m]``; :func:`wgs84_to_enu`
  turns them into metres East, North, Up of a local origin (the heliostat).
* Sun azimuth is counted from **South = 0, East positive** (West negative), degrees.
  pointax counts azimuth from North through East, so ``A_NE = 180 deg - A_paint``
  and the ENU sun direction is ``(sin A_paint cos E, -cos A_paint cos E, sin E)``
  (:func:`sun_enu_from_paint`).
* The measured mirror normal of a sample is the unit bisector of the direction to the
  sun and the direction from the heliostat to the focal spot.

Every malformed file raises :class:`PaintFormatError`, whose message names the file,
the field as a JSON path (``kinematics_properties.actuators[1].increment``) and the
line of that field (or, for a missing field, of the object that lacks it).

This is an edge module: numpy and astropy only, no JAX.
"""

from __future__ import annotations

import bisect
import dataclasses
import json
import math
import os
import re
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from ..observations import Observations
from .errors import FileFormatError

__all__ = [
    "FOCAL_SPOT_METHODS",
    "CalibrationSample",
    "HeliostatProperties",
    "LinearActuator",
    "PaintFormatError",
    "PaintRun",
    "TargetPlane",
    "Tower",
    "paint_azimuth_to_north_east",
    "read_calibration",
    "read_heliostat",
    "read_paint",
    "read_tower",
    "sun_enu_from_paint",
    "wgs84_to_enu",
]

FOCAL_SPOT_METHODS = ("HeliOS", "UTIS")
"""The focal-spot centroid methods of PAINT, in fall-back order."""
HELIOSTAT_FILE = "heliostat-properties.json"
CALIBRATION_SUFFIX = "-calibration-properties.json"
TOWER_FILE = "tower-measurements.json"
POWER_PLANT_KEY = "power_plant_properties"


class PaintFormatError(FileFormatError):
    """A PAINT JSON file could not be read.

    Attributes:
        path: the file (or folder).
        field: JSON path of the offending field, e.g.
            ``kinematics_properties.actuators[1].increment`` (``None`` for whole-file
            problems such as malformed JSON).
        line: line in the file of that field (of the enclosing object when the field
            is missing; of the syntax error for malformed JSON), or ``None``.
        message: what is wrong.
    """

    def __init__(self, path: str, field: str | None, message: str, line: int | None = None):
        self.field, self.message = field, message
        super().__init__(path, line, message, f"field {field}" if field else None)


# --------------------------------------------------------------------------- JSON access


def _kind(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"the boolean {json.dumps(value)}"
    if isinstance(value, str):
        return f"the string {value!r}"
    if isinstance(value, dict):
        return "an object"
    if isinstance(value, list):
        return f"an array of {len(value)}"
    return repr(value)


_LAST_PART = re.compile(r"(\.[^.\[]*|\[\d+\])$")


def _value_lines(text: str) -> dict[str, int]:
    """Line number (1-based) of every value in a valid JSON text, keyed by JSON path
    (root ``""``, then ``a.b[2].c``)."""
    newlines = [m.start() for m in re.finditer("\n", text)]
    decoder = json.JSONDecoder()
    lines: dict[str, int] = {}
    space = " \t\n\r"

    def skip(i: int) -> int:
        while i < len(text) and text[i] in space:
            i += 1
        return i

    def walk(i: int, path: str) -> int:
        i = skip(i)
        lines[path] = bisect.bisect_left(newlines, i) + 1
        if text[i] == "{":
            i = skip(i + 1)
            if text[i] == "}":
                return i + 1
            while True:
                key, i = json.decoder.scanstring(text, i + 1)
                i = skip(i) + 1  # past ':'
                i = skip(walk(i, f"{path}.{key}" if path else key))
                if text[i] == "}":
                    return i + 1
                i = skip(i + 1)  # past ','
        if text[i] == "[":
            i = skip(i + 1)
            if text[i] == "]":
                return i + 1
            k = 0
            while True:
                i = skip(walk(i, f"{path}[{k}]"))
                if text[i] == "]":
                    return i + 1
                i, k = i + 1, k + 1
        return decoder.raw_decode(text, i)[1]

    walk(0, "")
    return lines


class _Json:
    """One parsed JSON file plus typed accessors that raise :class:`PaintFormatError`."""

    def __init__(self, path: str | os.PathLike):
        self.path = os.fspath(path)
        try:
            self.text = Path(self.path).read_text(encoding="utf-8-sig")
        except UnicodeDecodeError as err:
            raise PaintFormatError(self.path, None, f"not a UTF-8 text file ({err})") from None
        try:
            self.data = json.loads(self.text)
        except json.JSONDecodeError as err:
            raise PaintFormatError(
                self.path, None, f"malformed JSON: {err.msg} (column {err.colno})", line=err.lineno
            ) from None
        self._lines: dict[str, int] | None = None

    def line_of(self, field: str) -> int | None:
        if self._lines is None:
            try:
                self._lines = _value_lines(self.text)
            except (ValueError, IndexError, RecursionError):  # not expected: the JSON parsed
                self._lines = {}
        while field not in self._lines:  # a missing field: the line of its parent
            if not field:
                return None
            parent = _LAST_PART.sub("", field)
            field = "" if parent == field else parent
        return self._lines[field]

    def fail(self, field: str, message: str) -> NoReturn:
        raise PaintFormatError(self.path, field, message, self.line_of(field))

    @staticmethod
    def join(prefix: str, key: str | int) -> str:
        if isinstance(key, int):
            return f"{prefix}[{key}]"
        return f"{prefix}.{key}" if prefix else key

    def obj(self, value: Any, field: str) -> dict:
        if not isinstance(value, dict):
            self.fail(field, f"is {_kind(value)}, expected a JSON object")
        return value

    def get(self, parent: dict, key: str, prefix: str = "") -> tuple[Any, str]:
        field = self.join(prefix, key)
        if key not in parent:
            self.fail(field, "is missing")
        return parent[key], field

    def as_number(self, value: Any, field: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(field, f"is {_kind(value)}, expected a number")
        if not math.isfinite(value):
            self.fail(field, f"is {value}, expected a finite number")
        return float(value)

    def number(self, parent: dict, key: str, prefix: str = "", *, positive: bool = False) -> float:
        value, field = self.get(parent, key, prefix)
        x = self.as_number(value, field)
        if positive and not x > 0:
            self.fail(field, f"is {x}, expected a positive number")
        return x

    def string(self, parent: dict, key: str, prefix: str = "") -> str:
        value, field = self.get(parent, key, prefix)
        if not isinstance(value, str):
            self.fail(field, f"is {_kind(value)}, expected a string")
        return value

    def as_vector(self, value: Any, field: str, n: int = 3) -> np.ndarray:
        if not isinstance(value, list) or len(value) != n:
            self.fail(field, f"is {_kind(value)}, expected an array of {n} numbers")
        return _frozen(np.array([self.as_number(v, self.join(field, k)) for k, v in enumerate(value)]))

    def vector(self, parent: dict, key: str, prefix: str = "", n: int = 3) -> np.ndarray:
        value, field = self.get(parent, key, prefix)
        return self.as_vector(value, field, n)

    def geodetic(self, value: Any, field: str) -> np.ndarray:
        """A WGS84 ``[lat deg, lon deg, height m]`` triple."""
        v = self.as_vector(value, field, 3)
        if not -90.0 <= v[0] <= 90.0:
            self.fail(self.join(field, 0), f"latitude {v[0]} is outside -90..90 deg")
        if not -360.0 <= v[1] <= 360.0:
            self.fail(self.join(field, 1), f"longitude {v[1]} is outside -360..360 deg")
        return v


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, np.float64)
    a.flags.writeable = False
    return a


# --------------------------------------------------------------------------- heliostat


@dataclasses.dataclass(frozen=True, eq=False)
class LinearActuator:
    """One linear actuator of a PAINT heliostat axis (see DESIGN, "Heliostat kinematics").

    Stroke ``s = motor / increment + initial_stroke_length``; the actuator angle is
    ``phi(s) = arccos((offset^2 + pivot_radius^2 - s^2) / (2 offset pivot_radius))``;
    the joint angle is ``initial_angle +/- (phi(s0) - phi(s))`` (``+`` when
    ``clockwise``), ``s0`` the stroke at motor position 0.
    """

    increment: float
    """Motor increments per metre of stroke (1/m)."""
    initial_stroke_length: float
    """Stroke at motor position 0 (m)."""
    offset: float
    """Distance from the axis to the actuator's fixed end (m)."""
    pivot_radius: float
    """Distance from the axis to the actuator's moving end (m)."""
    initial_angle: float
    """Joint angle at motor position 0 (rad)."""
    clockwise: bool
    """The file's ``clockwise_axis_movement`` (0/1)."""
    min_increment: float
    """Lowest allowed motor position (increments)."""
    max_increment: float
    """Highest allowed motor position (increments)."""
    min_movement_angle: float
    """Lower joint-angle limit (rad)."""
    max_movement_angle: float
    """Upper joint-angle limit (rad)."""
    offset_shift: float = 0.0
    """Kept as given (m); 0 in the PAINT files seen."""
    radius_shift: float = 0.0
    """Kept as given (m); 0 in the PAINT files seen."""


@dataclasses.dataclass(frozen=True, eq=False)
class HeliostatProperties:
    """A PAINT ``heliostat-properties.json``."""

    path: str
    position: np.ndarray
    """``(3,)`` WGS84 latitude (deg), longitude (deg), height (m) of the heliostat."""
    width: float
    """Mirror width (m)."""
    height: float
    """Mirror height (m)."""
    initial_orientation: np.ndarray
    """``(3,)`` mirror normal at zero joint angles, ENU (PAINT: ``(0, -1, 0)``)."""
    actuators: tuple[LinearActuator, LinearActuator]
    """Axis 1 and axis 2 actuators."""
    joint_translations: np.ndarray
    """``(2, 3)`` ENU translations (m) of joints 1 and 2 (``joint_translation_{e,n,u}_{1,2}``)."""
    concentrator_translation: np.ndarray
    """``(3,)`` ENU translation (m) of the mirror centre after both joints
    (``concentrator_translation_{e,n,u}``); it turns with the mirror."""
    renovation: str | None = None
    """Date of the last renovation as written (e.g. ``"2021-04-15"``), if given."""

    @property
    def lat_deg(self) -> float:
        return float(self.position[0])

    @property
    def lon_deg(self) -> float:
        return float(self.position[1])

    @property
    def height_m(self) -> float:
        return float(self.position[2])


_ACTUATOR_NUMBERS = (
    "increment",
    "initial_stroke_length",
    "offset",
    "pivot_radius",
    "initial_angle",
    "min_increment",
    "max_increment",
    "min_movement_angle",
    "max_movement_angle",
)
_POSITIVE = {"increment", "offset", "pivot_radius"}


def _actuator(doc: _Json, value: Any, field: str) -> LinearActuator:
    a = doc.obj(value, field)
    kind = doc.string(a, "type_axis", field)
    if kind != "linear":
        doc.fail(doc.join(field, "type_axis"), f"is {kind!r}: only linear actuators are supported")
    v = {k: doc.number(a, k, field, positive=k in _POSITIVE) for k in _ACTUATOR_NUMBERS}
    cw, cw_field = doc.get(a, "clockwise_axis_movement", field)
    if isinstance(cw, bool):
        clockwise = cw
    elif isinstance(cw, (int, float)) and cw in (0, 1):
        clockwise = bool(cw)
    else:
        doc.fail(cw_field, f"is {_kind(cw)}, expected 0, 1, true or false")
    if v["min_increment"] > v["max_increment"]:
        doc.fail(doc.join(field, "max_increment"), f"{v['max_increment']} is below min_increment {v['min_increment']}")
    if v["min_movement_angle"] > v["max_movement_angle"]:
        doc.fail(
            doc.join(field, "max_movement_angle"),
            f"{v['max_movement_angle']} is below min_movement_angle {v['min_movement_angle']}",
        )
    shifts = {k: doc.number(a, k, field) if k in a else 0.0 for k in ("offset_shift", "radius_shift")}
    return LinearActuator(clockwise=clockwise, **v, **shifts)


def read_heliostat(path: str | os.PathLike) -> HeliostatProperties:
    """Read a PAINT ``heliostat-properties.json``.

    Checks types and finiteness of every field used, that there are exactly two
    actuators, both ``"linear"``, with positive ``increment``, ``offset`` and
    ``pivot_radius``. Facet properties are not read.

    Raises:
        FileNotFoundError: no such file.
        PaintFormatError: naming file, field and line of the first bad field.
    """
    doc = _Json(path)
    root = doc.obj(doc.data, "")
    value, field = doc.get(root, "heliostat_position")
    position = doc.geodetic(value, field)
    width = doc.number(root, "width", positive=True)
    height = doc.number(root, "height", positive=True)
    orientation = doc.vector(root, "initial_orientation")
    if not np.linalg.norm(orientation) > 0:
        doc.fail("initial_orientation", "is the zero vector")
    value, kin_field = doc.get(root, "kinematics_properties")
    kin = doc.obj(value, kin_field)
    value, field = doc.get(kin, "actuators", kin_field)
    if not isinstance(value, list) or len(value) != 2:
        doc.fail(field, f"is {_kind(value)}, expected an array of exactly 2 actuators (axis 1, axis 2)")
    actuators = tuple(_actuator(doc, a, doc.join(field, k)) for k, a in enumerate(value))
    joints = _frozen(
        [[doc.number(kin, f"joint_translation_{c}_{j}", kin_field) for c in "enu"] for j in (1, 2)]
    )
    concentrator = _frozen([doc.number(kin, f"concentrator_translation_{c}", kin_field) for c in "enu"])
    renovation = doc.string(root, "renovation") if "renovation" in root else None
    return HeliostatProperties(
        path=doc.path,
        position=position,
        width=width,
        height=height,
        initial_orientation=orientation,
        actuators=actuators,
        joint_translations=joints,
        concentrator_translation=concentrator,
        renovation=renovation,
    )


# --------------------------------------------------------------------------- calibration samples


@dataclasses.dataclass(frozen=True, eq=False)
class CalibrationSample:
    """A PAINT ``<id>-calibration-properties.json``."""

    path: str
    sample_id: str
    """The file name before ``-calibration-properties.json``."""
    motor: np.ndarray
    """``(2,)`` axis-1 and axis-2 motor positions (actuator increments)."""
    sun_azimuth_deg: float
    """Sun azimuth as stored: degrees, South = 0, East positive."""
    sun_elevation_deg: float
    """Sun elevation, degrees."""
    focal_spot: dict[str, np.ndarray]
    """Method (``"HeliOS"``, ``"UTIS"``) -> ``(3,)`` WGS84 lat (deg), lon (deg), height (m)
    of the measured focal-spot centroid, for the methods present (not null)."""
    target_name: str
    """The target plane hit (a key of :func:`read_tower`)."""

    @property
    def sun_enu(self) -> np.ndarray:
        """``(3,)`` unit vector towards the sun, ENU."""
        return sun_enu_from_paint(self.sun_azimuth_deg, self.sun_elevation_deg)


def read_calibration(path: str | os.PathLike) -> CalibrationSample:
    """Read one PAINT ``<id>-calibration-properties.json``.

    ``focal_spot`` must hold at least one of the methods in :data:`FOCAL_SPOT_METHODS`
    (a method given as ``null`` counts as absent; other methods are kept as read).

    Raises:
        FileNotFoundError: no such file.
        PaintFormatError: naming file, field and line of the first bad field.
    """
    doc = _Json(path)
    name = Path(doc.path).name
    sample_id = name[: -len(CALIBRATION_SUFFIX)] if name.endswith(CALIBRATION_SUFFIX) else Path(doc.path).stem
    root = doc.obj(doc.data, "")
    value, mp_field = doc.get(root, "motor_position")
    mp = doc.obj(value, mp_field)
    motor = _frozen([doc.number(mp, f"axis_{k}_motor_position", mp_field) for k in (1, 2)])
    azimuth = doc.number(root, "sun_azimuth")
    elevation = doc.number(root, "sun_elevation")
    if not -90.0 <= elevation <= 90.0:
        doc.fail("sun_elevation", f"is {elevation}, outside -90..90 deg")
    value, fs_field = doc.get(root, "focal_spot")
    spots = doc.obj(value, fs_field)
    focal_spot = {k: doc.geodetic(v, doc.join(fs_field, k)) for k, v in spots.items() if v is not None}
    if not any(m in focal_spot for m in FOCAL_SPOT_METHODS):
        doc.fail(fs_field, f"has none of the methods {', '.join(FOCAL_SPOT_METHODS)}")
    target = doc.string(root, "target_name")
    return CalibrationSample(
        path=doc.path,
        sample_id=sample_id,
        motor=motor,
        sun_azimuth_deg=azimuth,
        sun_elevation_deg=elevation,
        focal_spot=focal_spot,
        target_name=target,
    )


# --------------------------------------------------------------------------- tower


@dataclasses.dataclass(frozen=True, eq=False)
class TargetPlane:
    """A target area of the tower (``type`` "planar", or e.g. the "convex_cylinder"
    receiver); positions are WGS84 ``(3,)`` lat (deg), lon (deg), height (m)."""

    name: str
    type: str
    center: np.ndarray
    """``(3,)`` centre of the area, WGS84."""
    corners: dict[str, np.ndarray]
    """The other named points of ``coordinates`` (``upper_left``, ...), WGS84."""
    normal_vector: np.ndarray
    """``(3,)`` normal of the area, ENU (as written; not normalised)."""
    extra: dict[str, Any] = dataclasses.field(default_factory=dict)
    """Other properties as written (e.g. ``radius``, ``opening_angle`` of a receiver)."""


@dataclasses.dataclass(frozen=True, eq=False)
class Tower(Mapping):
    """A PAINT ``tower-measurements.json``: a read-only mapping name -> :class:`TargetPlane`,
    plus the power plant's properties."""

    path: str
    plant_id: str
    """``power_plant_properties.ID``."""
    plant_position: np.ndarray
    """``(3,)`` ``power_plant_properties.coordinates``: WGS84 lat (deg), lon (deg), height (m)."""
    targets: dict[str, TargetPlane]

    def __getitem__(self, name: str) -> TargetPlane:
        return self.targets[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self.targets)

    def __len__(self) -> int:
        return len(self.targets)


def read_tower(path: str | os.PathLike) -> Tower:
    """Read a PAINT ``tower-measurements.json``.

    Every top-level key other than ``power_plant_properties`` is a target area with
    ``type``, ``normal_vector`` and ``coordinates`` (which must hold ``center``).

    Returns:
        A :class:`Tower`: use it as ``dict[str, TargetPlane]``; ``plant_id`` and
        ``plant_position`` keep ``power_plant_properties``.

    Raises:
        FileNotFoundError: no such file.
        PaintFormatError: naming file, field and line of the first bad field.
    """
    doc = _Json(path)
    root = doc.obj(doc.data, "")
    value, pp_field = doc.get(root, POWER_PLANT_KEY)
    pp = doc.obj(value, pp_field)
    plant_id = doc.string(pp, "ID", pp_field)
    value, field = doc.get(pp, "coordinates", pp_field)
    plant_position = doc.geodetic(value, field)
    targets = {}
    for name, value in root.items():
        if name == POWER_PLANT_KEY:
            continue
        t = doc.obj(value, name)
        kind = doc.string(t, "type", name)
        normal = doc.vector(t, "normal_vector", name)
        if not np.linalg.norm(normal) > 0:
            doc.fail(doc.join(name, "normal_vector"), "is the zero vector")
        value, c_field = doc.get(t, "coordinates", name)
        coords = doc.obj(value, c_field)
        center, field = doc.get(coords, "center", c_field)
        center = doc.geodetic(center, field)
        corners = {k: doc.geodetic(v, doc.join(c_field, k)) for k, v in coords.items() if k != "center"}
        extra = {k: v for k, v in t.items() if k not in ("type", "normal_vector", "coordinates")}
        targets[name] = TargetPlane(name, kind, center, corners, normal, extra)
    if not targets:
        raise PaintFormatError(doc.path, None, "no target areas (only power_plant_properties)")
    return Tower(doc.path, plant_id, plant_position, targets)


# --------------------------------------------------------------------------- geometry


def wgs84_to_enu(
    lat_deg: Any, lon_deg: Any, height_m: Any, origin: Sequence[float] | np.ndarray
) -> np.ndarray:
    """WGS84 geodetic positions -> local East-North-Up coordinates (m) at ``origin``.

    The points and the origin go to geocentric (ECEF) x, y, z through astropy's
    ``EarthLocation.from_geodetic`` (WGS84 ellipsoid); the difference is turned into
    the ENU frame of the origin (East along increasing longitude, Up along the
    ellipsoid normal at the origin's geodetic latitude).

    Args:
        lat_deg, lon_deg, height_m: geodetic latitude (deg), longitude (deg) and
            ellipsoidal height (m); any broadcastable shapes ``(...)``.
        origin: ``(3,)`` latitude (deg), longitude (deg), height (m) of the frame origin.

    Returns:
        ``(..., 3)`` East, North, Up in metres.
    """
    import astropy.units as u
    from astropy.coordinates import EarthLocation

    lat, lon, h = np.broadcast_arrays(*(np.asarray(x, np.float64) for x in (lat_deg, lon_deg, height_m)))
    lat0, lon0, h0 = (float(x) for x in np.asarray(origin, np.float64).reshape(3))

    def ecef(la, lo, hh):
        loc = EarthLocation.from_geodetic(lo * u.deg, la * u.deg, hh * u.m, ellipsoid="WGS84")
        return np.stack([loc.x.to_value(u.m), loc.y.to_value(u.m), loc.z.to_value(u.m)], axis=-1)

    d = ecef(lat, lon, h) - ecef(lat0, lon0, h0)
    sp, cp = math.sin(math.radians(lat0)), math.cos(math.radians(lat0))
    sl, cl = math.sin(math.radians(lon0)), math.cos(math.radians(lon0))
    rotation = np.array(
        [
            [-sl, cl, 0.0],  # East
            [-sp * cl, -sp * sl, cp],  # North
            [cp * cl, cp * sl, sp],  # Up
        ]
    )
    return d @ rotation.T


def paint_azimuth_to_north_east(azimuth_deg: Any) -> np.ndarray:
    """PAINT azimuth (South = 0, East positive, deg) -> azimuth from North through East,
    degrees in [0, 360): ``A_NE = (180 - A_paint) mod 360``."""
    return np.mod(180.0 - np.asarray(azimuth_deg, np.float64), 360.0)


def sun_enu_from_paint(azimuth_deg: Any, elevation_deg: Any) -> np.ndarray:
    """Unit sun direction in ENU from PAINT's azimuth and elevation.

    PAINT counts azimuth from South = 0, East positive (West negative), so with
    ``A = azimuth_deg``, ``E = elevation_deg`` (radians inside)::

        ENU = (sin A cos E, -cos A cos E, sin E)

    which equals pointax's ``azel_to_enu(180 deg - A, E)``. E.g. A = +45 (South-East)
    gives East > 0, North < 0.

    Args:
        azimuth_deg, elevation_deg: broadcastable shapes ``(...)``, degrees.

    Returns:
        ``(..., 3)`` unit vectors.
    """
    a = np.radians(np.asarray(azimuth_deg, np.float64))
    e = np.radians(np.asarray(elevation_deg, np.float64))
    a, e = np.broadcast_arrays(a, e)
    return np.stack([np.sin(a) * np.cos(e), -np.cos(a) * np.cos(e), np.sin(e)], axis=-1)


# --------------------------------------------------------------------------- a whole folder


@dataclasses.dataclass(frozen=True, eq=False)
class PaintRun:
    """All calibration samples of one PAINT heliostat, in file order.

    "File order" is the plain lexicographic order of the sample file names
    (so ``"151375" < "86520" < "field1"``), the order of every per-sample array.
    Positions are metres East, North, Up from the heliostat position
    (``heliostat.position``); directions are ENU unit vectors.
    """

    directory: str
    heliostat: HeliostatProperties
    samples: tuple[CalibrationSample, ...]
    targets: Tower
    """The tower's target areas (name -> :class:`TargetPlane`)."""
    focal_spot: str
    """The focal-spot method asked for."""
    focal_spot_method: tuple[str, ...]
    """Per sample, the method actually used: ``focal_spot``, or the other method of
    :data:`FOCAL_SPOT_METHODS` where the sample lacks it (fall-back)."""
    motor: np.ndarray
    """``(n, 2)`` axis-1, axis-2 motor positions (increments)."""
    sun: np.ndarray
    """``(n, 3)`` unit vectors towards the sun, ENU."""
    focal_spot_enu: np.ndarray
    """``(n, 3)`` focal-spot centroids (of ``focal_spot_method``), m, ENU from the heliostat."""
    measured_normal: np.ndarray
    """``(n, 3)`` unit bisector of ``sun`` and the unit heliostat-to-focal-spot direction."""
    mirror_offset: bool = False
    """Whether the heliostat-to-focal-spot direction starts at the offset mirror centre
    (see :func:`read_paint`) rather than at the heliostat position."""

    @property
    def sample_ids(self) -> list[str]:
        return [s.sample_id for s in self.samples]

    @property
    def target_names(self) -> list[str]:
        return [s.target_name for s in self.samples]

    @property
    def reflected(self) -> np.ndarray:
        """``(n, 3)`` unit directions from the mirror to the focal spot, ENU."""
        return 2.0 * np.sum(self.sun * self.measured_normal, axis=-1, keepdims=True) * self.measured_normal - self.sun

    @property
    def observations(self) -> Observations:
        """The samples as :class:`pointax.Observations` of a
        :class:`pointax.HeliostatMount`: motor increments and measured normals."""
        return Observations(self.motor, self.measured_normal, convention="heliostat")

    def __len__(self) -> int:
        return len(self.samples)


def _find_tower(directory: Path) -> Path:
    candidates = [directory / TOWER_FILE, directory.parent / TOWER_FILE]
    for c in candidates:
        if c.is_file():
            return c
    raise FileNotFoundError(
        f"no {TOWER_FILE} in {directory} or its parent; pass tower=<path> (looked for: "
        + ", ".join(str(c) for c in candidates)
        + ")"
    )


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def read_paint(
    directory: str | os.PathLike,
    focal_spot: str = "HeliOS",
    tower: str | os.PathLike | None = None,
    mirror_offset: bool = False,
) -> PaintRun:
    """Read a PAINT heliostat folder: ``heliostat-properties.json`` and every
    ``*-calibration-properties.json`` in it, in file order (plain lexicographic order
    of the file names).

    Args:
        directory: the heliostat's folder (e.g. ``.../paint/AA39``).
        focal_spot: focal-spot method to use, ``"HeliOS"`` or ``"UTIS"``. A sample that
            lacks it falls back to the other method; ``PaintRun.focal_spot_method``
            records which one each sample used.
        tower: path of ``tower-measurements.json``; by default the one in ``directory``,
            else in its parent.
        mirror_offset: start the reflected ray at the mirror centre instead of the
            heliostat position. As in DLR's ARTIST kinematics, the concentrator
            translation is applied after both joint rotations, so it turns with the
            mirror; this is computed only where that is defined by the normal alone
            (zero joint translations, concentrator translation parallel to
            ``initial_orientation``): centre = position + (t . o) n, solved for the
            normal n by fixed-point iteration. Default False (DESIGN's definition:
            from the heliostat position).

    Measured on AA39 (17.5 cm concentrator translation, focal spots 45-65 m away): the
    mirror offset turns the measured normals by 0.3-1.0 mrad (about 0.6 mrad RMS),
    comparable to the 0.8 mrad RMS between the HeliOS and UTIS centroids, so it is
    not negligible at the fit's accuracy; it is a smooth, mostly systematic effect.

    Raises:
        FileNotFoundError: the folder, ``heliostat-properties.json`` or the tower file
            is missing.
        PaintFormatError: a malformed file (naming file, field and line), no
            calibration samples, or a sample whose ``target_name`` the tower lacks.
        ValueError: an unknown ``focal_spot`` method, or ``mirror_offset`` where it is
            not defined.
    """
    if focal_spot not in FOCAL_SPOT_METHODS:
        raise ValueError(f"unknown focal_spot method {focal_spot!r}; expected one of {FOCAL_SPOT_METHODS}")
    folder = Path(directory)
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: no such directory")
    heliostat_file = folder / HELIOSTAT_FILE
    if not heliostat_file.is_file():
        raise FileNotFoundError(f"{heliostat_file}: no such file (every PAINT heliostat folder has one)")
    heliostat = read_heliostat(heliostat_file)
    files = sorted((p for p in folder.iterdir() if p.name.endswith(CALIBRATION_SUFFIX)), key=lambda p: p.name)
    if not files:
        raise PaintFormatError(str(folder), None, f"no *{CALIBRATION_SUFFIX} files in this folder")
    samples = tuple(read_calibration(p) for p in files)
    targets = read_tower(Path(tower) if tower is not None else _find_tower(folder))
    for s in samples:
        if s.target_name not in targets:
            doc = _Json(s.path)
            doc.fail("target_name", f"{s.target_name!r} is not a target of {targets.path} ({', '.join(targets)})")

    order = (focal_spot,) + tuple(m for m in FOCAL_SPOT_METHODS if m != focal_spot)
    methods = tuple(next(m for m in order if m in s.focal_spot) for s in samples)
    spots = np.array([s.focal_spot[m] for s, m in zip(samples, methods)])
    focal_enu = wgs84_to_enu(spots[:, 0], spots[:, 1], spots[:, 2], heliostat.position)
    motor = np.array([s.motor for s in samples])
    sun = sun_enu_from_paint([s.sun_azimuth_deg for s in samples], [s.sun_elevation_deg for s in samples])

    normal = _bisector(samples, sun, focal_enu)
    if mirror_offset:
        along = _mirror_offset_along_normal(heliostat)
        for _ in range(4):  # the offset changes the normal by ~1e-3: converges to 1e-12 in 4 steps
            normal = _bisector(samples, sun, focal_enu - along * normal)
    return PaintRun(
        directory=str(folder),
        heliostat=heliostat,
        samples=samples,
        targets=targets,
        focal_spot=focal_spot,
        focal_spot_method=methods,
        motor=_frozen(motor),
        sun=_frozen(sun),
        focal_spot_enu=_frozen(focal_enu),
        measured_normal=_frozen(normal),
        mirror_offset=mirror_offset,
    )


def _bisector(samples, sun: np.ndarray, to_spot: np.ndarray) -> np.ndarray:
    b = sun + _unit(to_spot)
    norm = np.linalg.norm(b, axis=-1)
    for s, nb in zip(samples, norm):
        if not nb > 1e-9:
            raise PaintFormatError(s.path, "focal_spot", "the focal spot lies opposite the sun: no mirror normal")
    return b / norm[:, None]


def _mirror_offset_along_normal(heliostat: HeliostatProperties) -> float:
    """Signed distance (m) of the mirror centre from the heliostat position along the
    mirror normal, where the concentrator translation is parallel to the initial
    orientation and the joints are not translated."""
    t = heliostat.concentrator_translation
    o = _unit(heliostat.initial_orientation)
    along = float(t @ o)
    if np.any(heliostat.joint_translations != 0) or np.linalg.norm(t - along * o) > 1e-9:
        raise ValueError(
            f"{heliostat.path}: mirror_offset needs zero joint translations and a concentrator translation "
            f"parallel to initial_orientation (got {t.tolist()} and {heliostat.initial_orientation.tolist()}); "
            "otherwise the mirror centre depends on the full kinematic chain"
        )
    return along

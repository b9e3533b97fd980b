"""The three kinds of PAINT JSON file: heliostat properties (:func:`read_heliostat`), one
calibration sample (:func:`read_calibration`) and the tower's target planes
(:func:`read_tower`). See :mod:`pointax.io.paint`."""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import file_errors
from .document import (
    CALIBRATION_SUFFIX,
    FOCAL_SPOT_METHODS,
    KINEMATICS_KEYS,
    LAYOUT_CURRENT,
    LAYOUT_SCHEMA1,
    POWER_PLANT_KEY,
    JsonDocument,
    PaintFormatError,
    describe_value,
    frozen_array,
)
from .geometry import sun_enu_from_paint

__all__ = [
    "IDEAL_LAW",
    "LinearActuator",
    "HeliostatProperties",
    "read_heliostat",
    "CalibrationSample",
    "read_calibration",
    "TargetPlane",
    "Tower",
    "read_tower",
]

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
    type_axis: str = "linear"
    """``type_axis`` as written: ``"linear"`` or ``"ideal"``."""
    law: str = "linear"
    """How motor positions become joint angles: ``"linear"`` (the law of cosines above)
    or ``"ideal"`` (:data:`IDEAL_LAW`: the motor position *is* the joint angle in
    radians, DLR ARTIST's ``IdealActuators``; ``min_increment`` and ``max_increment``
    are then angles too, and the linear parameters, NaN where the file leaves them out,
    are not used). ``"ideal"`` for an actuator typed ``"ideal"`` in the current layout;
    schema-1 files type every actuator ``"ideal"`` but carry linear-actuator parameters
    and motor positions in increments, which the linear law fits (AC43), so theirs are
    read with the linear law."""

    @property
    def ideal(self) -> bool:
        """Whether the motor position is the joint angle (``law == "ideal"``)."""
        return self.law == "ideal"


@dataclasses.dataclass(frozen=True, eq=False)
class HeliostatProperties:
    """A PAINT ``heliostat-properties.json``, in either layout (``layout``).

    Everything here is described in the current layout's terms, the kinematic chain of
    DESIGN.md (``n = Re(theta1 - pi/2) Ru(theta2) initial_orientation``); what a
    schema-1 file wrote differently is kept beside it (``file_orientation``,
    ``LinearActuator.type_axis``).
    """

    path: str
    position: np.ndarray
    """``(3,)`` WGS84 latitude (deg), longitude (deg), height (m) of the heliostat."""
    width: float
    """Mirror width (m)."""
    height: float
    """Mirror height (m)."""
    initial_orientation: np.ndarray
    """``(3,)`` the vector the chain ``Re(theta1 - pi/2) Ru(theta2)`` turns into the
    mirror normal, ENU (current PAINT files: ``(0, -1, 0)``, as written). A schema-1
    file describes the same chain as ``Re(theta1) Rn(theta2)`` acting on its
    ``(0, 0, 1)``; since ``Re(theta1 - pi/2) Ru(theta2) Re(pi/2) = Re(theta1) Rn(theta2)``,
    its orientation is read as ``Re(pi/2) o_file`` (so ``(0, 0, 1)`` -> ``(0, -1, 0)``)."""
    actuators: tuple[LinearActuator, LinearActuator]
    """Axis 1 and axis 2 actuators."""
    joint_translations: np.ndarray
    """``(2, 3)`` ENU translations (m) of joints 1 and 2 (``joint_translation_{e,n,u}_{1,2}``)."""
    concentrator_translation: np.ndarray
    """``(3,)`` ENU translation (m) of the mirror centre after both joints
    (``concentrator_translation_{e,n,u}``); it turns with the mirror."""
    renovation: str | None = None
    """Date of the last renovation as written (e.g. ``"2021-04-15"``), if given."""
    layout: str = LAYOUT_CURRENT
    """Which layout the file has: :data:`~pointax.io.paint.LAYOUT_CURRENT`
    (``"kinematics_properties (current)"``) or :data:`~pointax.io.paint.LAYOUT_SCHEMA1`
    (``"kinematic_properties (schema 1)"``)."""
    file_orientation: np.ndarray | None = None
    """``(3,)`` ``initial_orientation`` exactly as written in the file (``None``: the
    same as ``initial_orientation``)."""

    @property
    def kinematics_key(self) -> str:
        """The name of the file's kinematics block (``kinematics_properties`` or
        ``kinematic_properties``)."""
        return KINEMATICS_KEYS[self.layout]

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


IDEAL_LAW = "joint angle = motor position (rad)"
"""An ideal actuator's law, as DLR's ARTIST has it (``IdealActuators.motor_positions_to_angles``
returns the motor positions): no stroke, no lever, no zero offset, no turning sign."""

_IDEAL_REQUIRED = ("min_increment", "max_increment")
"""The numbers an ideal actuator needs (its motor range, in radians); the others are
read when present."""


def _actuator(doc: JsonDocument, value: Any, field: str, layout: str = LAYOUT_CURRENT) -> LinearActuator:
    a = doc.obj(value, field)
    kind = doc.string(a, "type_axis", field)
    if kind not in ("linear", "ideal"):
        doc.fail(doc.join(field, "type_axis"), f"is {kind!r}: only 'linear' and 'ideal' actuators are supported")
    law = "ideal" if kind == "ideal" and layout == LAYOUT_CURRENT else "linear"
    v = {
        k: doc.number(a, k, field, positive=k in _POSITIVE)
        if law == "linear" or k in _IDEAL_REQUIRED or k in a
        else math.nan
        for k in _ACTUATOR_NUMBERS
    }
    cw, cw_field = doc.get(a, "clockwise_axis_movement", field)
    if isinstance(cw, bool):
        clockwise = cw
    elif isinstance(cw, (int, float)) and cw in (0, 1):
        clockwise = bool(cw)
    else:
        doc.fail(cw_field, f"is {describe_value(cw)}, expected 0, 1, true or false")
    if v["min_increment"] > v["max_increment"]:
        doc.fail(doc.join(field, "max_increment"), f"{v['max_increment']} is below min_increment {v['min_increment']}")
    if law == "ideal" and not (-2 * math.pi <= v["min_increment"] and v["max_increment"] <= 2 * math.pi):
        doc.fail(
            doc.join(field, "max_increment" if v["max_increment"] > 2 * math.pi else "min_increment"),
            f"range {v['min_increment']:g}..{v['max_increment']:g} is no range of joint angles: an 'ideal' actuator's "
            f"motor position is its joint angle in radians ({IDEAL_LAW}); a range in increments belongs to a "
            "'linear' actuator",
        )
    if v["min_movement_angle"] > v["max_movement_angle"]:
        doc.fail(
            doc.join(field, "max_movement_angle"),
            f"{v['max_movement_angle']} is below min_movement_angle {v['min_movement_angle']}",
        )
    shifts = {k: doc.number(a, k, field) if k in a else 0.0 for k in ("offset_shift", "radius_shift")}
    return LinearActuator(clockwise=clockwise, **v, **shifts, type_axis=kind, law=law)


def _re_half_pi(v: np.ndarray) -> np.ndarray:
    """``Re(pi/2) v``: a right-handed quarter turn about East, (0, 0, 1) -> (0, -1, 0)."""
    return np.array([v[0], -v[2], v[1]], np.float64)


@file_errors(PaintFormatError.in_file)
def read_heliostat(path: str | os.PathLike) -> HeliostatProperties:
    """Read a PAINT ``heliostat-properties.json``, in either layout.

    Two layouts occur in PAINT releases (``HeliostatProperties.layout`` says which
    was read):

    * current (``"kinematics_properties (current)"``): a ``kinematics_properties``
      block, ``initial_orientation`` (0, -1, 0), actuators ``"linear"``;
    * schema 1 (``"kinematic_properties (schema 1)"``): a ``kinematic_properties``
      block, ``initial_orientation`` (0, 0, 1), actuators typed ``"ideal"`` with the
      linear-actuator parameters, nonzero joint translations. It describes the same
      kinematic chain (checked on AC43: the nominal errors are those of the current
      layout's heliostats); its orientation is turned into the current layout's
      description (see ``HeliostatProperties.initial_orientation``), its actuators
      are read with the linear law, and its translations are kept as written (in the
      chain's frames, as DLR's ARTIST applies them).

    An actuator typed ``"ideal"`` in the current layout is DLR ARTIST's ideal actuator:
    its motor position is the joint angle in radians (``LinearActuator.law``); it needs
    only ``clockwise_axis_movement`` and its motor range ``min_increment`` ..
    ``max_increment`` (radians, within +-2 pi), the other numbers are read if present.

    Checks types and finiteness of every field used, that there are exactly two
    actuators, each ``"linear"`` (positive ``increment``, ``offset`` and
    ``pivot_radius``) or ``"ideal"``. Facet properties are not read.

    Raises:
        FileNotFoundError: no such file.
        PaintFormatError: naming file, field and line of the first bad field.
    """
    doc = JsonDocument(path)
    with doc.named_errors():
        root = doc.obj(doc.data, "")
        value, field = doc.get(root, "heliostat_position")
        position = doc.geodetic(value, field)
        width = doc.number(root, "width", positive=True)
        height = doc.number(root, "height", positive=True)
        layout = _layout(doc, root)
        written = doc.vector(root, "initial_orientation")
        if not np.linalg.norm(written) > 0:
            doc.fail("initial_orientation", "is the zero vector")
        orientation = frozen_array(_re_half_pi(written)) if layout == LAYOUT_SCHEMA1 else written
        value, kin_field = doc.get(root, KINEMATICS_KEYS[layout])
        kin = doc.obj(value, kin_field)
        value, field = doc.get(kin, "actuators", kin_field)
        if not isinstance(value, list) or len(value) != 2:
            doc.fail(field, f"is {describe_value(value)}, expected an array of exactly 2 actuators (axis 1, axis 2)")
        actuators = tuple(_actuator(doc, a, doc.join(field, k), layout) for k, a in enumerate(value))
        joints = frozen_array(
            [[doc.number(kin, f"joint_translation_{c}_{j}", kin_field) for c in "enu"] for j in (1, 2)]
        )
        concentrator = frozen_array([doc.number(kin, f"concentrator_translation_{c}", kin_field) for c in "enu"])
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
            layout=layout,
            file_orientation=written,
        )


def _layout(doc: JsonDocument, root: dict) -> str:
    """The layout of a heliostat-properties file, from the name of its kinematics block."""
    current, schema1 = (KINEMATICS_KEYS[k] in root for k in (LAYOUT_CURRENT, LAYOUT_SCHEMA1))
    if current and schema1:
        doc.fail(
            KINEMATICS_KEYS[LAYOUT_SCHEMA1],
            f"is present beside {KINEMATICS_KEYS[LAYOUT_CURRENT]}: a file has one layout or the other "
            "(current: kinematics_properties; schema 1: kinematic_properties), not both",
        )
    if schema1:
        return LAYOUT_SCHEMA1
    if not current:
        doc.fail(
            KINEMATICS_KEYS[LAYOUT_CURRENT],
            "is missing (the earlier PAINT layout's kinematic_properties is missing too): "
            "no kinematics block in this file",
        )
    return LAYOUT_CURRENT


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
    time_mjd: float | None = None
    """The calibration's time, MJD (UTC days), when a file gives it (:data:`TIME_FIELDS`
    of the properties file, else ``properties.datetime`` of the sample's STAC item
    ``<id>-calibration-item-stac.json`` beside it); None otherwise. As stored: PAINT's
    clock may be off the UTC of its sun position (use the sun position for geometry)."""

    @property
    def sun_enu(self) -> np.ndarray:
        """``(3,)`` unit vector towards the sun, ENU."""
        return sun_enu_from_paint(self.sun_azimuth_deg, self.sun_elevation_deg)


@file_errors(PaintFormatError.in_file)
def read_calibration(path: str | os.PathLike) -> CalibrationSample:
    """Read one PAINT ``<id>-calibration-properties.json``.

    ``focal_spot`` must hold at least one of the methods in :data:`FOCAL_SPOT_METHODS`
    (a method given as ``null`` counts as absent; other methods are kept as read).

    Raises:
        FileNotFoundError: no such file.
        PaintFormatError: naming file, field and line of the first bad field.
    """
    doc = JsonDocument(path)
    with doc.named_errors():
        name = Path(doc.path).name
        sample_id = name[: -len(CALIBRATION_SUFFIX)] if name.endswith(CALIBRATION_SUFFIX) else Path(doc.path).stem
        root = doc.obj(doc.data, "")
        value, mp_field = doc.get(root, "motor_position")
        mp = doc.obj(value, mp_field)
        motor = frozen_array([doc.number(mp, f"axis_{k}_motor_position", mp_field) for k in (1, 2)])
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
        time_mjd = _time_of(doc, root, Path(doc.path).parent / f"{sample_id}{STAC_ITEM_SUFFIX}")
        return CalibrationSample(
            path=doc.path,
            sample_id=sample_id,
            motor=motor,
            sun_azimuth_deg=azimuth,
            sun_elevation_deg=elevation,
            focal_spot=focal_spot,
            target_name=target,
            time_mjd=time_mjd,
        )


TIME_FIELDS = ("datetime", "timestamp", "DateTime", "time")
"""Fields of a calibration-properties file that may hold the calibration's time (ISO 8601)."""
STAC_ITEM_SUFFIX = "-calibration-item-stac.json"
"""A sample's STAC item (PAINT's metadata, ``properties.datetime``), beside its properties file."""


def _time_of(doc: JsonDocument, root: dict, stac: Path) -> float | None:
    """The calibration's MJD from ``root``'s :data:`TIME_FIELDS`, else the STAC item's
    ``properties.datetime``; None when neither gives one. A time that is not ISO 8601
    text fails naming the file and field."""
    from ..run_readings import mjd_from_iso

    for key in TIME_FIELDS:
        if key in root and root[key] is not None:
            return _iso(doc, root[key], key, mjd_from_iso)
    if stac.is_file():
        item = JsonDocument(stac)
        with item.named_errors():
            properties = item.data.get("properties") if isinstance(item.data, dict) else None
            if isinstance(properties, dict) and properties.get("datetime") is not None:
                return _iso(item, properties["datetime"], "properties.datetime", mjd_from_iso)
    return None


def _iso(doc: JsonDocument, value: Any, field: str, parse) -> float:
    if not isinstance(value, str):
        doc.fail(field, f"is {value!r}: expected an ISO 8601 date and time (e.g. 2022-06-01T10:15:00Z)")
    try:
        return parse(value)
    except ValueError as e:
        doc.fail(field, str(e))


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


@file_errors(PaintFormatError.in_file)
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
    doc = JsonDocument(path)
    with doc.named_errors():
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


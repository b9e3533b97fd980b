"""A whole PAINT heliostat folder: :func:`read_paint` into a :class:`PaintRun` (motor
increments, sun directions, measured mirror normals). See :mod:`pointax.io.paint`."""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path

import numpy as np

from ...core.observations import Observations
from ..errors import file_errors, warn_input
from ..sanity import row_separations
from .document import (
    CALIBRATION_SUFFIX,
    FOCAL_SPOT_METHODS,
    HELIOSTAT_FILE,
    TOWER_FILE,
    JsonDocument,
    PaintFormatError,
    frozen_array,
)
from .files import (
    CalibrationSample,
    HeliostatProperties,
    Tower,
    read_calibration,
    read_heliostat,
    read_tower,
)
from .geometry import sun_enu_from_paint, wgs84_to_enu

__all__ = [
    "PaintRun",
    "mirror_centre",
    "nominal_normal",
    "read_paint",
    "AIM_SEPARATION_DEG",
]

AIM_SEPARATION_DEG = 10.0
"""A sample whose measured mirror normal lies more than this (degrees) from the nominal
normal of its motor positions, beyond the run's common offset, is named. Twice the 5 deg
of TPOINT and gpoint rows: a heliostat's nominal kinematics is coarser than a
telescope's encoders (AA39's real samples reach 4.9 deg), while a sun position of another
time or a mistyped motor position moves the normal by tens of degrees."""

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
    mirror_centre: np.ndarray | None = None
    """``(n, 3)`` the reflection point of each sample, m ENU from the heliostat position
    (:func:`mirror_centre`; zeros when ``mirror_offset`` is False)."""

    @property
    def layout(self) -> str:
        """The layout of the heliostat file: ``"kinematics_properties (current)"`` or
        ``"kinematic_properties (schema 1)"`` (:attr:`HeliostatProperties.layout`)."""
        return self.heliostat.layout

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
    def readings(self) -> dict[str, np.ndarray]:
        """Auxiliary readings per sample: ``sun_azimuth`` (radians, North through East,
        pointax's convention: ``180 deg - `` PAINT's South-based azimuth) and
        ``sun_elevation`` (radians) as stored, and ``time`` (MJD, UTC days) when the
        files give the calibrations' times (:attr:`CalibrationSample.time_mjd`; NaN for a
        sample without one)."""
        az = np.radians(np.mod(180.0 - np.array([s.sun_azimuth_deg for s in self.samples], np.float64), 360.0))
        out = {"sun_azimuth": az, "sun_elevation": np.radians([s.sun_elevation_deg for s in self.samples])}
        times = [s.time_mjd for s in self.samples]
        if any(t is not None for t in times):
            out["time"] = np.array([math.nan if t is None else t for t in times], np.float64)
        return out

    @property
    def observations(self) -> Observations:
        """The samples as :class:`pointax.Observations` of a
        :class:`pointax.HeliostatMount`: motor increments and measured normals, with
        :attr:`readings`."""
        return Observations(self.motor, self.measured_normal, convention="heliostat", readings=self.readings)

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


@file_errors(PaintFormatError.in_file)
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
        mirror_offset: start the reflected ray at the mirror centre (the reflection
            point) instead of the heliostat position: the joint and concentrator
            translations of the heliostat file are applied in the kinematic chain as
            DLR's ARTIST applies them (:func:`mirror_centre`), for either layout, and
            the normal, on which the centre depends, is found by fixed-point
            iteration. ``PaintRun.mirror_centre`` holds the centres used. Default
            False (DESIGN's definition: from the heliostat position).

    Measured on AA39 (17.5 cm concentrator translation, focal spots 45-65 m away): the
    mirror offset turns the measured normals by 0.3-1.0 mrad (about 0.6 mrad RMS),
    comparable to the 0.8 mrad RMS between the HeliOS and UTIS centroids, so it is
    not negligible at the fit's accuracy; it is a smooth, mostly systematic effect.
    On AC43 (schema 1: 31.5 cm joint-2 and 44 cm concentrator translations) it turns
    them by about 1.0 mrad.

    Both layouts of ``heliostat-properties.json`` are read (:func:`read_heliostat`);
    ``PaintRun.layout`` says which.

    A sample whose measured normal (from its sun position and focal spot) lies more
    than 10 deg (:data:`AIM_SEPARATION_DEG`) from the normal its motor
    positions give through the file's nominal kinematics (:func:`nominal_normal`), once
    the run's common offset is taken out, gives an :class:`~pointax.io.InputWarning`
    naming its file and both normals: its sun position, focal spot and motor positions
    contradict each other (a sun position of another time, a mistyped field). On AA39
    the samples lie 0.1-4.9 deg from the nominal normals (two above 4 deg).

    Raises:
        FileNotFoundError: the folder, ``heliostat-properties.json`` or the tower file
            is missing.
        PaintFormatError: a malformed file (naming file, field and line), no
            calibration samples, a sample whose ``target_name`` the tower lacks, or
            one whose motor position lies outside its actuator's range.
        ValueError: an unknown ``focal_spot`` method.
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
            doc = JsonDocument(s.path)
            doc.fail("target_name", f"{s.target_name!r} is not a target of {targets.path} ({', '.join(targets)})")

    for s in samples:
        _check_motor_range(s, heliostat)

    order = (focal_spot,) + tuple(m for m in FOCAL_SPOT_METHODS if m != focal_spot)
    methods = tuple(next(m for m in order if m in s.focal_spot) for s in samples)
    spots = np.array([s.focal_spot[m] for s, m in zip(samples, methods)])
    focal_enu = wgs84_to_enu(spots[:, 0], spots[:, 1], spots[:, 2], heliostat.position)
    motor = np.array([s.motor for s in samples])
    sun = sun_enu_from_paint([s.sun_azimuth_deg for s in samples], [s.sun_elevation_deg for s in samples])

    normal = _bisector(samples, sun, focal_enu)
    _check_aims(samples, heliostat, motor, normal)
    centre = np.zeros_like(focal_enu)
    if mirror_offset:
        # The centre moves by ~0.2 m with the normal's ~1e-3 change: 6 steps converge to 1e-12.
        for _ in range(6):
            centre = mirror_centre(heliostat, normal)
            normal = _bisector(samples, sun, focal_enu - centre)
    return PaintRun(
        directory=str(folder),
        heliostat=heliostat,
        samples=samples,
        targets=targets,
        focal_spot=focal_spot,
        focal_spot_method=methods,
        motor=frozen_array(motor),
        sun=frozen_array(sun),
        focal_spot_enu=frozen_array(focal_enu),
        measured_normal=frozen_array(normal),
        mirror_offset=mirror_offset,
        mirror_centre=frozen_array(centre),
    )


def _check_motor_range(sample, heliostat: HeliostatProperties) -> None:
    """Refuse a sample whose motor position lies outside its actuator's range
    (``min_increment``..``max_increment`` of ``heliostat-properties.json``): the
    actuator cannot reach it, so the file is wrong, not the kinematics."""
    for k, (motor, actuator) in enumerate(zip(sample.motor, heliostat.actuators), 1):
        if not actuator.min_increment <= motor <= actuator.max_increment:
            JsonDocument(sample.path).fail(
                f"motor_position.axis_{k}_motor_position",
                f"{motor:g} is outside the range of actuator {k} ({actuator.min_increment:g}..{actuator.max_increment:g} "
                f"{'rad, an ideal actuator' if actuator.ideal else 'increments'} in {Path(heliostat.path).name}); "
                "remove the sample or correct the file",
            )


def nominal_normal(heliostat: HeliostatProperties, motor: np.ndarray) -> np.ndarray:
    """``(n, 3)`` the mirror normals (ENU) that motor positions ``motor`` (``(n, 2)``)
    give through the nominal kinematics of ``heliostat``, no error terms: each actuator's
    law (:class:`LinearActuator`, ideal or linear) turns its motor position into a joint
    angle, and ``n = Re(theta1 - pi/2) Ru(theta2) initial_orientation`` (DESIGN's chain,
    :class:`pointax.HeliostatMount`'s forward model in numpy)."""
    motor = np.asarray(motor, np.float64).reshape(-1, 2)
    angles = []
    for k, a in enumerate(heliostat.actuators):
        if a.ideal:
            angles.append(motor[:, k])
            continue
        offset, radius = a.offset + a.offset_shift, a.pivot_radius + a.radius_shift

        def phi(stroke):
            return np.arccos(np.clip((offset**2 + radius**2 - stroke**2) / (2 * offset * radius), -1.0, 1.0))

        s0 = a.initial_stroke_length
        sign = 1.0 if a.clockwise else -1.0
        angles.append(a.initial_angle + sign * (phi(s0) - phi(motor[:, k] / a.increment + s0)))
    r1, r2 = _rot_e(angles[0] - np.pi / 2), _rot_u(angles[1])
    return np.einsum("nij,njk,k->ni", r1, r2, np.asarray(heliostat.initial_orientation, np.float64))


def _azimuth_elevation(v: np.ndarray) -> np.ndarray:
    """``(n, 2)`` azimuth (North through East) and elevation, radians, of ENU vectors."""
    return np.stack([np.arctan2(v[:, 0], v[:, 1]), np.arcsin(np.clip(v[:, 2], -1.0, 1.0))], -1)


def _check_aims(samples, heliostat: HeliostatProperties, motor: np.ndarray, measured: np.ndarray) -> None:
    """Warn of the samples whose measured normal lies more than :data:`AIM_SEPARATION_DEG`
    from the nominal normal of their motor positions beyond the run's common offset (the
    check TPOINT and gpoint runs get, :func:`pointax.io.sanity.row_separations`), naming
    each sample's file and both normals."""
    observed, nominal = _azimuth_elevation(measured), _azimuth_elevation(nominal_normal(heliostat, motor))
    apart = row_separations(observed, nominal)
    far = np.flatnonzero(apart > AIM_SEPARATION_DEG)
    if far.size == 0:
        return
    a, b = np.degrees(observed), np.degrees(nominal)
    shown = ", ".join(
        f"{Path(samples[k].path).name}: {apart[k]:.1f} deg (measured az {a[k, 0] % 360:.2f} el {a[k, 1]:.2f}, "
        f"nominal az {b[k, 0] % 360:.2f} el {b[k, 1]:.2f} deg)"
        for k in far[:5]
    ) + (", ..." if far.size > 5 else "")
    warn_input(
        samples[far[0]].path,
        None,
        f"{far.size} of {len(samples)} samples have their measured mirror normal (the bisector of the sun and the "
        f"focal spot) and the normal of their motor positions (nominal kinematics of {HELIOSTAT_FILE}) more than "
        f"{AIM_SEPARATION_DEG:g} deg apart beyond the run's common offset ({shown}): a sun position of another "
        "time, a focal spot of another sample or a mistyped motor position? Such a sample is fitted as it "
        "stands; correct it or remove it",
        stacklevel=5,  # the caller of read_paint
    )


def _bisector(samples, sun: np.ndarray, to_spot: np.ndarray) -> np.ndarray:
    b = sun + _unit(to_spot)
    norm = np.linalg.norm(b, axis=-1)
    for s, nb in zip(samples, norm):
        if not nb > 1e-9:
            raise PaintFormatError(s.path, "focal_spot", "the focal spot lies opposite the sun: no mirror normal")
    return b / norm[:, None]


def _rot_e(angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2)


def _rot_u(angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def mirror_centre(heliostat: HeliostatProperties, normal: np.ndarray) -> np.ndarray:
    """The mirror centre (the reflection point), m ENU from the heliostat position, of a
    mirror whose normal is ``normal`` (``(..., 3)``), by the translations of the
    heliostat file applied in the kinematic chain as DLR's ARTIST applies them::

        c = T1 + R1 (T2 + R2 Tc),   R1 = Re(theta1 - pi/2),  R2 = Ru(theta2)

    ``T1``, ``T2`` the joint translations, ``Tc`` the concentrator translation (each in
    the frame of the joint before it), ``theta1, theta2`` the joint angles that turn
    ``(0, -1, 0)`` into ``normal`` in the chain of DESIGN.md
    (``theta1 = atan2(-n_N, n_U)`` the mirror's zenith angle, ``theta2 = asin n_E``),
    axis tilts taken as zero (they move the centre by well under a millimetre). For
    AA39's ``Tc = (0, 0.175, 0)`` and no joint translation this is ``c = -0.175 n``.

    The same chain is used for both layouts (see :func:`read_heliostat`).
    """
    n = np.asarray(normal, np.float64)
    theta1 = np.arctan2(-n[..., 1], n[..., 2])
    theta2 = np.arctan2(n[..., 0], np.hypot(n[..., 1], n[..., 2]))
    r1, r2 = _rot_e(theta1 - np.pi / 2), _rot_u(theta2)
    t1, t2 = heliostat.joint_translations
    tc = heliostat.concentrator_translation
    inner = t2 + np.einsum("...ij,j->...i", r2, tc)
    return t1 + np.einsum("...ij,...j->...i", r1, inner)

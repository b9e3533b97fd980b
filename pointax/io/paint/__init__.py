"""PAINT heliostat calibration data (DLR solar tower Juelich): JSON readers.

A PAINT heliostat folder (e.g. ``AA39/``) holds::

    heliostat-properties.json              position, size, initial orientation, two
                                           actuators (linear, or 'ideal': motor position =
                                           joint angle), joint/concentrator offsets
    <id>-calibration-properties.json       one calibration sample each: motor positions,
                                           sun azimuth/elevation, focal-spot centroids
                                           (methods "HeliOS" and/or "UTIS"), target name

and ``tower-measurements.json`` (target planes of the tower, WGS84) sits in the folder
or its parent. :func:`read_paint` reads a whole folder into a :class:`PaintRun` with
the per-sample arrays a kinematics fit needs (motor increments, sun directions and
measured mirror normals in East-North-Up).

``heliostat-properties.json`` comes in two layouts, both read (``layout`` of the
result says which): the current one (``kinematics_properties``, initial orientation
(0, -1, 0)) and PAINT's first schema (``kinematic_properties``, initial orientation
(0, 0, 1), actuators typed "ideal", nonzero joint translations), which describes the
same kinematic chain (:func:`read_heliostat`).

Conventions of the files, converted here where data enters pointax:

* Positions are WGS84 ``[latitude deg, longitude deg, height m]``; :func:`wgs84_to_enu`
  turns them into metres East, North, Up of a local origin (the heliostat).
* Sun azimuth is counted from **South = 0, East positive** (West negative), degrees.
  pointax counts azimuth from North through East, so ``A_NE = 180 deg - A_paint``
  and the ENU sun direction is ``(sin A_paint cos E, -cos A_paint cos E, sin E)``
  (:func:`sun_enu_from_paint`).
* The measured mirror normal of a sample is the unit bisector of the direction to the
  sun and the direction from the heliostat to the focal spot.
* Auxiliary readings (``run.readings``, ``run.observations.readings``): ``sun_azimuth``
  (radians, North through East) and ``sun_elevation`` (radians) of every sample, and
  ``time`` (MJD, UTC) where a sample's time is given (an ISO 8601 ``datetime`` or
  ``timestamp`` field of its properties file, or ``properties.datetime`` of its STAC item
  ``<id>-calibration-item-stac.json`` beside it; NaN for a sample without one).

Every malformed file raises :class:`PaintFormatError`, whose message names the file,
the field as a JSON path (``kinematics_properties.actuators[1].increment``) and the
line of that field (or, for a missing field, of the object that lacks it). Any other
error raised while a file is read (an unexpected ``TypeError``, ...) leaves the reader
as a :class:`PaintFormatError` too, naming the file and the field last read
(:meth:`JsonDocument.named_errors <pointax.io.paint.document.JsonDocument.named_errors>`;
:func:`read_paint`: the folder, :func:`pointax.io.errors.file_errors`). A sample whose
measured normal contradicts its motor positions is named in a warning
(:func:`read_paint`).

This is an edge module: numpy and astropy only, no JAX. One module per job:
:mod:`~pointax.io.paint.document` (file names, errors, JSON access),
:mod:`~pointax.io.paint.files` (the three kinds of file), :mod:`~pointax.io.paint.geometry`
(PAINT's conventions to pointax's), :mod:`~pointax.io.paint.run` (a whole folder).
"""

from __future__ import annotations

from .document import (  # noqa: F401  (the file names: importable from here, as before the split)
    CALIBRATION_SUFFIX,
    FOCAL_SPOT_METHODS,
    HELIOSTAT_FILE,
    KINEMATICS_KEYS,
    LAYOUT_CURRENT,
    LAYOUT_SCHEMA1,
    POWER_PLANT_KEY,
    TOWER_FILE,
    PaintFormatError,
)
from .document import value_lines as _value_lines  # noqa: F401  (tests/test_io_paint.py)
from .files import (
    IDEAL_LAW,
    CalibrationSample,
    HeliostatProperties,
    LinearActuator,
    TargetPlane,
    Tower,
    read_calibration,
    read_heliostat,
    read_tower,
)
from .geometry import paint_azimuth_to_north_east, sun_enu_from_paint, wgs84_to_enu
from .run import AIM_SEPARATION_DEG, PaintRun, mirror_centre, nominal_normal, read_paint

__all__ = [
    "AIM_SEPARATION_DEG",
    "FOCAL_SPOT_METHODS",
    "IDEAL_LAW",
    "CalibrationSample",
    "HeliostatProperties",
    "LAYOUT_CURRENT",
    "LAYOUT_SCHEMA1",
    "LinearActuator",
    "PaintFormatError",
    "PaintRun",
    "TargetPlane",
    "Tower",
    "mirror_centre",
    "nominal_normal",
    "paint_azimuth_to_north_east",
    "read_calibration",
    "read_heliostat",
    "read_paint",
    "read_tower",
    "sun_enu_from_paint",
    "wgs84_to_enu",
]

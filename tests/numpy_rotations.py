"""Right-handed rotation matrices in plain NumPy: the tests' independent reference for
pointax's rotations (``R @ v`` turns ``v`` by ``t`` radians about the axis)."""

from __future__ import annotations

import numpy as np


def Rx(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def Ry(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def Rz(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def angle_between(a, b):
    """Angle (radians) between unit vectors ``a`` and ``b`` (``(..., 3)``), by atan2 of
    the cross and dot products (accurate near 0 and pi)."""
    a, b = np.asarray(a), np.asarray(b)
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))

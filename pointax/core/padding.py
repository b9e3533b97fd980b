"""Padded shapes: one compiled program serves a bucket of sizes (a new size would
compile again, padding costs microseconds).

    power_of_two(83, least=16)   # 128: the rows a fit of 83 stars compiles for
    pad_rows(x, 128)             # x's rows, then copies of its first row up to 128
"""

from __future__ import annotations

import numpy as np

__all__ = ["power_of_two", "pad_rows"]


def power_of_two(n: int, least: int = 1) -> int:
    """The smallest power of two that is at least ``n`` (and 1), and at least ``least``."""
    return max(int(least), 1 << (max(int(n), 1) - 1).bit_length())


def pad_rows(x: np.ndarray, size: int) -> np.ndarray:
    """Rows of ``x`` (NumPy, ``(n, ...)``, n >= 1) padded to ``size`` with copies of its first row."""
    x = np.asarray(x)
    if x.shape[0] >= size:
        return x
    return np.concatenate([x, np.broadcast_to(x[:1], (size - x.shape[0],) + x.shape[1:])])

"""Observing order: a short path through the chosen targets (an open travelling-
salesman path: greedy nearest neighbour, then 2-opt until no reversal shortens it).

The cost of a slew is what the mount does: with both axes driven at once, the larger
of the two axis moves (:func:`slew_matrix`, readings in radians; the readings put each
target on its cable-wrap branch, so a long way round costs what it costs). Mounts whose
readings are not angles (actuator counts) use the angle on the sky instead.
"""

from __future__ import annotations

import numpy as np
from jaxtyping import Float, Int

__all__ = ["slew_matrix", "sky_angle_matrix", "order_path", "path_length"]


def slew_matrix(readings: Float[np.ndarray, "n 2"]) -> Float[np.ndarray, "n n"]:
    """``(n, n)`` slew costs between readings: the larger axis move (radians)."""
    r = np.asarray(readings, np.float64)
    return np.max(np.abs(r[:, None, :] - r[None, :, :]), axis=-1)


def sky_angle_matrix(directions: Float[np.ndarray, "n 3"]) -> Float[np.ndarray, "n n"]:
    """``(n, n)`` great-circle angles (radians) between unit vectors."""
    d = np.asarray(directions, np.float64)
    cross = np.linalg.norm(np.cross(d[:, None, :], d[None, :, :]), axis=-1)
    return np.arctan2(cross, d @ d.T)


def path_length(cost: np.ndarray, order) -> float:
    """Total cost of visiting ``order`` in turn."""
    order = np.asarray(order)
    return float(np.sum(cost[order[:-1], order[1:]])) if order.size > 1 else 0.0


def order_path(cost: Float[np.ndarray, "n n"], start: int | None = None, *, max_passes: int = 50) -> Int[np.ndarray, " n"]:
    """A short open path through every node of a symmetric ``cost`` matrix.

    Nearest neighbour from ``start`` (default: each node in turn, the shortest
    result kept), then 2-opt: reversing a stretch ``order[i:j+1]`` whenever that
    shortens the path (the first node stays first when ``start`` is given), until no
    reversal helps or ``max_passes`` passes.
    """
    cost = np.asarray(cost, np.float64)
    n = cost.shape[0]
    if n <= 2:
        return np.arange(n) if start is None or n < 2 else np.array([start, 1 - start])
    starts = range(n) if start is None else (int(start),)
    best = None
    for s in starts:
        order = _nearest_neighbour(cost, s)
        length = path_length(cost, order)
        if best is None or length < best[0]:
            best = (length, order)
    order = best[1]
    first = 1 if start is not None else 0
    for _ in range(max_passes):
        improved = False
        for i in range(first, n - 1):
            # Reverse order[i..j]: edges (i-1, i) and (j, j+1) become (i-1, j), (i, j+1).
            a = order[i - 1] if i > 0 else None
            b = order[i]
            js = np.arange(i + 1, n)
            c = order[js]
            d = np.where(js + 1 < n, order[np.minimum(js + 1, n - 1)], -1)
            old = (cost[a, b] if a is not None else 0.0) + np.where(d >= 0, cost[c, np.maximum(d, 0)], 0.0)
            new = (cost[a, c] if a is not None else 0.0) + np.where(d >= 0, cost[b, np.maximum(d, 0)], 0.0)
            gain = old - new
            k = int(np.argmax(gain))
            if gain[k] > 1e-12:
                j = int(js[k])
                order[i : j + 1] = order[i : j + 1][::-1].copy()
                improved = True
        if not improved:
            break
    return order


def _nearest_neighbour(cost: np.ndarray, start: int) -> np.ndarray:
    n = cost.shape[0]
    seen = np.zeros(n, bool)
    order = np.empty(n, int)
    order[0] = start
    seen[start] = True
    for k in range(1, n):
        row = np.where(seen, np.inf, cost[order[k - 1]])
        order[k] = int(np.argmin(row))
        seen[order[k]] = True
    return order

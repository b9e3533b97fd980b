"""Sun centroids in sun-sensor frames, batched with torch and kornia.

Every frame passes the same steps, batched over frames, and gets a status and a reason
(a frame's result does not depend on the other frames in its batch):

1. **Checks** (per frame, before batching): a 2-D array of numbers (a leading or
   trailing singleton channel is accepted), at least 32 x 32 pixels, the expected
   shape if one is given, finite values. Otherwise ``bad_input``.
2. **Background and detection** on the whole frame (float32): 4 x 4 block means; the
   median of 8 x 8 blocks is the background, their scatter (MAD) and that of
   neighbouring-pixel differences the noise. A 2 x 2 erosion of the block means drops
   hot pixels; the brightest block must stand ``detect_sigma`` noise sigmas above the
   background (else ``no_sun``), and the bright blocks around it give a rough centre and
   radius. A frame with most blocks at the saturation level is ``saturated``.
3. **Region of interest** (float64) around the rough centre; pixels beyond the frame
   edge are marked invalid, so a clipped sun is handled like any other. Hot pixels
   (above all 8 neighbours by far) are replaced by their neighbours' median. The
   local background is a plane fitted (4-sigma clipped) to the pixels around the disk,
   which a threshold on the smoothed signal (``kornia.filters.gaussian_blur2d``) finds
   and a 9 x 9 dilation grows.
4. **Intensity centroid**: the background-subtracted intensity weighted over a window:
   the smoothed signal thresholded at ``threshold`` of the peak, grown by 3 pixels
   (a square dilation; ``torch.nn.functional.max_pool2d`` is 6x faster here than
   ``kornia.morphology.dilation``). Pixels are not thresholded one by one, which would
   bias the result with the pixel phase: the window only decides which pixels count.
5. **Limb fit**: rays from the centre, the image sampled along each
   (``torch.nn.functional.grid_sample``, bicubic) and the outermost crossing of the edge
   level located to a fraction of a pixel; rays whose samples leave the frame are
   dropped. The edge level is ``edge_level`` of the peak, or half the saturation level
   above the background for a saturated disk. A circle (in coordinates scaled by
   ``1 / aspect`` along y, so the camera's ``fy / fx`` may differ from 1) is fitted to
   the edge points, batched: algebraic (Kasa) start, geometric Gauss-Newton, outliers
   rejected, refit. Two passes: 90 rays from the intensity centroid, then 180 from the
   first fit's centre.
6. **Status**: ``clipped`` if less than ``min_limb_fraction`` of the fitted limb lies
   inside the frame; ``faint`` if the peak is below ``min_snr`` noise sigmas; ``cloud``
   if the aureole around the disk (1.3-2 radii) is brighter than ``max_aureole`` of the
   disk's peak; ``inconsistent`` if the frame holds more than one sun (a second bright
   disk outside the first, at least :data:`SECOND_SUN` as bright: a reflection or a
   second source), too few limb points were found, the radius is more
   than 25 % off an expected ``radius``, or the intensity centroid and the limb fit of
   an unclipped disk disagree by more than ``max_disagreement`` pixels. Only ``ok``
   frames get a centre.

``method="auto"`` takes the intensity centroid for a disk wholly inside the frame
(saturated or not: a saturated disk is still symmetric, and benchmarks/centroid.py
measures it at least as accurate as the limb fit there) and the limb fit for a clipped
one. The intensity centroid of a clipped disk is biased towards the frame's interior,
so ``method="intensity"`` on a clipped frame gives the status ``clipped``, never a
biased centre.

Accuracy on the synthetic frames of :mod:`pointax.sunsensor.frames` (the paper's
camera, realistic noise; ``benchmarks/centroid.py``): about 0.006 px RMS unclipped,
0.02 px with the disk saturated at 3x full scale, 0.01-0.02 px clipped with 60-100 % of
the limb inside the frame, 0.02-0.04 px at 40-60 %.

Pixel coordinates: origin at the centre of the top-left pixel, x to the right (column),
y down (row): kornia's convention.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
import torch

from .measure import measure

__all__ = ["STATUSES", "METHODS", "Centroids", "centroid", "check_frame"]

SECOND_SUN = 0.3
"""A frame with a second bright disk (outside the first) at least this fraction as bright
as the first is ``inconsistent`` ("more than one sun")."""

STATUSES = ("ok", "bad_input", "no_sun", "saturated", "clipped", "cloud", "faint", "inconsistent")
"""Every status a frame can get; only ``ok`` frames have a centre."""

METHODS = ("auto", "intensity", "limb")
"""Values of ``centroid(..., method=...)``."""

_MIN_SIZE = 32
_CHUNK = 32  # frames processed together (bounds memory)


@dataclasses.dataclass(frozen=True)
class Centroids:
    """Sun centres found in a set of frames (one entry per frame, in input order).

    Attributes:
        x, y: ``(n,)`` centre, pixels (origin at the centre of the top-left pixel, x right,
            y down); NaN where the status is not ``ok``.
        radius: ``(n,)`` disk radius along x from the limb fit, pixels (NaN if none):
            the radius of the ``edge_level`` contour, within ~0.15 px of a sharp limb.
        method: per frame, ``"intensity"`` or ``"limb"`` for ``ok`` frames, else ``""``.
        status: per frame, one of :data:`STATUSES`.
        reason: per frame, why the status is not ``ok``, in words ('' when ok).
        intensity: ``(n, 2)`` the intensity centroid whatever the method (NaN if none).
        limb: ``(n, 2)`` the limb-fit centre whatever the method (NaN if none).
        limb_fraction: ``(n,)`` fraction of the fitted limb inside the frame.
        peak: ``(n,)`` disk peak above the background, frame units.
        background: ``(n,)`` global background level, frame units.
        noise: ``(n,)`` pixel noise of the background, frame units.
        names: optional per-frame names (file names), for messages.
    """

    x: np.ndarray
    y: np.ndarray
    radius: np.ndarray
    method: tuple[str, ...]
    status: tuple[str, ...]
    reason: tuple[str, ...]
    intensity: np.ndarray
    limb: np.ndarray
    limb_fraction: np.ndarray
    peak: np.ndarray
    background: np.ndarray
    noise: np.ndarray
    names: tuple[str, ...] | None = None

    def __len__(self) -> int:
        return len(self.status)

    @property
    def ok(self) -> np.ndarray:
        """``(n,)`` bool: frames with a centre."""
        return np.array([s == "ok" for s in self.status], bool)

    @property
    def xy(self) -> np.ndarray:
        """``(n, 2)`` centres ``(x, y)``, pixels (NaN where not ok)."""
        return np.stack([self.x, self.y], axis=-1)

    def to_dicts(self) -> list[dict]:
        """One dict per frame: ``x``, ``y``, ``radius`` (None where undefined),
        ``method``, ``status``, ``reason`` (and ``frame`` if names were given)."""
        out = []
        for i in range(len(self)):
            row = {}
            if self.names is not None:
                row["frame"] = self.names[i]

            def num(v):
                return None if not np.isfinite(v) else float(v)

            row.update(
                x=num(self.x[i]),
                y=num(self.y[i]),
                radius=num(self.radius[i]),
                method=self.method[i],
                status=self.status[i],
                reason=self.reason[i],
            )
            out.append(row)
        return out

    def summary(self) -> str:
        """A table: one line per frame."""
        lines = [f"{'frame':<24s} {'x':>10s} {'y':>10s} {'radius':>7s} {'method':>9s}  status"]
        for i, row in enumerate(self.to_dicts()):
            name = row.get("frame", str(i))
            fmt = lambda v, w, p: f"{v:{w}.{p}f}" if v is not None else f"{'-':>{w}s}"  # noqa: E731
            tail = row["status"] + (f": {row['reason']}" if row["reason"] else "")
            lines.append(
                f"{name[-24:]:<24s} {fmt(row['x'], 10, 3)} {fmt(row['y'], 10, 3)} {fmt(row['radius'], 7, 2)} "
                f"{row['method'] or '-':>9s}  {tail}"
            )
        return "\n".join(lines)


# --------------------------------------------------------------------------- checks


def check_frame(frame, shape: tuple[int, int] | None = None) -> tuple[np.ndarray | None, str]:
    """Check one frame; return ``(2-D array in its own dtype, '')`` or ``(None, reason)``."""
    try:
        if isinstance(frame, torch.Tensor):
            frame = frame.detach().cpu().numpy()
        array = np.asarray(frame)
    except Exception as err:  # noqa: BLE001 - anything that is not an array
        return None, f"not an array ({type(frame).__name__}: {err})"
    kind = array.dtype.kind
    if kind not in "uif":
        return None, f"dtype {array.dtype} is not a number type (expected unsigned or signed integers or floats)"
    if array.ndim == 3 and 1 in (array.shape[0], array.shape[-1]):
        array = array.reshape(array.shape[1:] if array.shape[0] == 1 else array.shape[:-1])
    if array.ndim != 2:
        extra = " (colour? a sun sensor frame has one channel)" if array.ndim == 3 and array.shape[-1] in (3, 4) else ""
        return None, f"shape {array.shape}: expected a 2-D frame (height, width){extra}"
    if min(array.shape) < _MIN_SIZE:
        return None, f"shape {array.shape}: smaller than {_MIN_SIZE} x {_MIN_SIZE} pixels"
    if shape is not None and tuple(array.shape) != tuple(shape):
        return None, f"shape {array.shape} does not match the camera's {tuple(shape)} (height, width)"
    if kind == "f" and not np.all(np.isfinite(array)):
        bad = int(np.sum(~np.isfinite(array)))
        return None, f"{bad} pixel(s) are NaN or infinite"
    return array, ""


def _default_saturation(dtype: np.dtype) -> float:
    return float(np.iinfo(dtype).max) if dtype.kind in "ui" else math.inf


# ------------------------------------------------------------------- public API


def centroid(
    frames,
    *,
    method: str = "auto",
    radius: float | None = None,
    aspect: float = 1.0,
    saturation: float | None = None,
    shape: tuple[int, int] | None = None,
    names: Sequence[str] | None = None,
    threshold: float = 0.1,
    edge_level: float = 0.3,
    detect_sigma: float = 10.0,
    min_limb_fraction: float = 0.4,
    max_aureole: float = 0.1,
    min_snr: float = 20.0,
    max_disagreement: float = 1.0,
    max_saturated_fraction: float = 0.5,
) -> Centroids:
    """Find the sun's centre in each frame (batched; see the module docstring).

    Args:
        frames: a ``(B, H, W)`` or ``(H, W)`` array or tensor, or a sequence of 2-D
            frames (NumPy or torch; integer or float; shapes may differ).
        method: 'auto' (intensity centroid unless the disk is clipped, then the limb
            fit), 'intensity' or 'limb'.
        radius: expected disk radius along x, pixels (e.g. from the camera:
            :meth:`pointax.sunsensor.camera.Camera.sun_radius_px`); None measures it.
        aspect: ``fy / fx`` of the camera: the disk's radius along y over that along x.
        saturation: saturation level in frame units; None takes the dtype's maximum
            for integer frames (255, 65535, ...) and none for float frames. A 12-bit
            camera writing 16-bit files needs ``saturation=4095``.
        shape: expected ``(height, width)``; other shapes are ``bad_input``.
        names: per-frame names (file names) for the result and messages.
        threshold: window threshold of the intensity centroid, fraction of the peak.
        edge_level: limb-crossing level, fraction of the peak (a saturated disk's edge
            is taken at half the saturation level above the background).
        detect_sigma: detection threshold in noise sigmas of the 4 x 4 block means.
        min_limb_fraction: below this fraction of the limb inside the frame the
            frame is ``clipped`` (past usefulness).
        max_aureole: above this ratio of aureole to disk peak the frame is ``cloud``.
        min_snr: below this disk peak over pixel noise the frame is ``faint``.
        max_disagreement: pixels by which the intensity centroid and the limb fit of
            an unclipped disk may differ before the frame is ``inconsistent``.
        max_saturated_fraction: above this fraction of saturated pixels the whole
            frame is ``saturated``.

    Returns:
        :class:`Centroids`, one entry per frame in input order.
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; expected one of {METHODS}")
    if aspect <= 0 or not math.isfinite(aspect):
        raise ValueError(f"aspect must be positive, got {aspect!r}")
    if radius is not None and not (math.isfinite(radius) and radius > 1.0):
        raise ValueError(f"radius must be a number of pixels > 1, got {radius!r}")
    if isinstance(frames, torch.Tensor):
        frames = frames.detach().cpu().numpy()
    if isinstance(frames, np.ndarray) and frames.dtype.kind in "uif" and frames.ndim in (2, 3):
        frame_list = [frames] if frames.ndim == 2 else list(frames)
    else:
        frame_list = list(frames)
    n = len(frame_list)
    if names is not None:
        names = tuple(str(s) for s in names)
        if len(names) != n:
            raise ValueError(f"got {len(names)} names for {n} frames")

    nan = np.full(n, np.nan)
    out = {
        key: nan.copy()
        for key in ("x", "y", "radius", "ix", "iy", "lx", "ly", "limb_fraction", "peak", "background", "noise")
    }
    status, reason, used = ["bad_input"] * n, [""] * n, [""] * n
    groups: dict[tuple, list[int]] = {}
    checked: dict[int, np.ndarray] = {}
    for i, frame in enumerate(frame_list):
        array, why = check_frame(frame, shape)
        if array is None:
            reason[i] = why
            continue
        checked[i] = array
        groups.setdefault((array.shape, array.dtype.str), []).append(i)

    for (_, _), members in groups.items():
        for start in range(0, len(members), _CHUNK):
            idx = members[start : start + _CHUNK]
            arrays = [checked[i] for i in idx]
            level = saturation if saturation is not None else _default_saturation(arrays[0].dtype)
            batch = torch.from_numpy(np.stack(arrays)).to(torch.float32)
            sat = torch.full((len(idx),), float(level), dtype=torch.float32)
            m = {k: v.numpy() for k, v in measure(batch, sat, radius, aspect, threshold, edge_level).items()}
            for k, i in enumerate(idx):
                s, why, chosen = _judge(m, k, method, radius, level, detect_sigma, min_limb_fraction, max_aureole, min_snr, max_disagreement, max_saturated_fraction)
                status[i], reason[i], used[i] = s, why, chosen
                out["ix"][i], out["iy"][i] = m["intensity_x"][k], m["intensity_y"][k]
                out["lx"][i], out["ly"][i] = m["limb_x"][k], m["limb_y"][k]
                out["limb_fraction"][i] = m["limb_fraction"][k]
                out["peak"][i], out["background"][i], out["noise"][i] = m["peak"][k], m["background"][k], m["noise"][k]
                if s == "ok":
                    key = "i" if chosen == "intensity" else "l"
                    out["x"][i], out["y"][i] = out[key + "x"][i], out[key + "y"][i]
                    out["radius"][i] = m["radius"][k]
    return Centroids(
        x=out["x"],
        y=out["y"],
        radius=out["radius"],
        method=tuple(used),
        status=tuple(status),
        reason=tuple(reason),
        intensity=np.stack([out["ix"], out["iy"]], axis=-1),
        limb=np.stack([out["lx"], out["ly"]], axis=-1),
        limb_fraction=out["limb_fraction"],
        peak=out["peak"],
        background=out["background"],
        noise=out["noise"],
        names=names,
    )


def _judge(m, k, method, radius, saturation, detect_sigma, min_limb_fraction, max_aureole, min_snr, max_disagreement, max_saturated_fraction):
    """Status, reason and method for frame ``k`` of a measured batch."""
    sat_frac = m["saturated_fraction"][k]
    if sat_frac > max_saturated_fraction:
        return "saturated", f"{100 * sat_frac:.0f}% of the pixels are at the saturation level {saturation:g}", ""
    detection = m["detection"][k] / m["block_noise"][k]
    if not detection >= detect_sigma:
        return "no_sun", f"no sun: the brightest spot is {detection:.1f} sigma above the background (< {detect_sigma:g})", ""
    second = m["second"][k]
    if second / m["block_noise"][k] >= detect_sigma and second >= SECOND_SUN * m["detection"][k]:
        return (
            "inconsistent",
            f"more than one sun: a second bright disk near ({m['second_x'][k]:.0f}, {m['second_y'][k]:.0f}) px, "
            f"{100 * second / m['detection'][k]:.0f}% as bright as the first: a reflection or a second source",
            "",
        )
    snr = m["peak"][k] / m["noise"][k]
    if not snr >= min_snr:
        return "faint", f"the sun is faint: peak {snr:.1f} sigma above the background (< {min_snr:g}): cloud or too dense a filter", ""
    finite_limb = np.isfinite(m["limb_x"][k]) and np.isfinite(m["limb_y"][k]) and np.isfinite(m["radius"][k])
    fraction = m["limb_fraction"][k] if finite_limb else 0.0
    if fraction < min_limb_fraction:
        return "clipped", f"clipped past usefulness: {100 * fraction:.0f}% of the limb inside the frame (< {100 * min_limb_fraction:.0f}%)", ""
    aureole = m["aureole"][k]
    if aureole > max_aureole:
        return "cloud", f"veiled by cloud: aureole at 1.3-2 radii is {100 * aureole:.0f}% of the disk peak (> {100 * max_aureole:.0f}%)", ""
    if m["n_edge"][k] < 12:
        return "inconsistent", f"only {int(m['n_edge'][k])} limb points found", ""
    if radius is not None and abs(m["radius"][k] / radius - 1) > 0.25:
        return "inconsistent", f"disk radius {m['radius'][k]:.1f} px, expected {radius:.1f} px: not a clean sun image", ""
    clipped = bool(m["window_clipped"][k]) or fraction < 1.0
    if not clipped:
        gap = math.hypot(m["intensity_x"][k] - m["limb_x"][k], m["intensity_y"][k] - m["limb_y"][k])
        if not gap <= max_disagreement:
            return "inconsistent", f"intensity centroid and limb fit differ by {gap:.2f} px (> {max_disagreement:g}): not a clean disk", ""
    if method == "intensity":
        if clipped:
            return "clipped", f"the disk is clipped by the frame edge ({100 * fraction:.0f}% of the limb inside): its intensity centroid would be biased; use method 'limb' or 'auto'", ""
        return "ok", "", "intensity"
    if method == "limb":
        return "ok", "", "limb"
    return "ok", "", "limb" if clipped else "intensity"

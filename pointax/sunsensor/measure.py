"""The measurement behind :func:`pointax.sunsensor.centroid`: detection of the sun in a
batch of same-shape frames, its region of interest, background plane, intensity
centroid and limb points, and the circle (ellipse, with ``aspect``) fitted to them, in
torch. :func:`measure` returns per-frame tensors; judging them (statuses) is
:mod:`pointax.sunsensor.centroids`'s.
"""

from __future__ import annotations

import math

import kornia
import torch
import torch.nn.functional as F

__all__ = ["measure", "BLOCK"]

BLOCK = 4
"""Block size (pixels) of the detection image."""

_RAYS = 180

def _weighted_plane(z, xs, ys, w):
    """Weighted least-squares plane ``a + b x + c y`` per frame; ``(B, 3)``."""
    a = torch.stack([torch.ones_like(xs), xs, ys], dim=-1)  # (B, N, 3)
    aw = a * w[..., None]
    normal = aw.transpose(1, 2) @ a + 1e-9 * torch.eye(3, dtype=z.dtype)
    rhs = (aw * z[..., None]).sum(dim=1)
    return torch.linalg.solve(normal, rhs)


def _circle_fit(px: torch.Tensor, py: torch.Tensor, w: torch.Tensor, iterations: int = 6):
    """Circle through weighted points, batched: Kasa start then geometric Gauss-Newton.

    Args:
        px, py: ``(B, N)`` points; w: ``(B, N)`` weights (0 drops a point).
    Returns:
        ``(cx, cy, r)`` each ``(B,)``.
    """
    dtype = px.dtype
    eye = torch.eye(3, dtype=dtype)
    # Kasa: x^2 + y^2 + D x + E y + F = 0, linear least squares (centred for conditioning).
    wsum = w.sum(dim=1).clamp(min=1e-12)
    mx, my = (w * px).sum(1) / wsum, (w * py).sum(1) / wsum
    x, y = px - mx[:, None], py - my[:, None]
    a = torch.stack([x, y, torch.ones_like(x)], dim=-1)
    aw = a * w[..., None]
    rhs = -(aw * (x**2 + y**2)[..., None]).sum(1)
    sol = torch.linalg.solve(aw.transpose(1, 2) @ a + 1e-12 * eye, rhs)
    cx, cy = -sol[:, 0] / 2, -sol[:, 1] / 2
    r = torch.sqrt(torch.clamp(cx**2 + cy**2 - sol[:, 2], min=1e-12))
    cx, cy = cx + mx, cy + my
    # Geometric fit: minimise sum w (|p - c| - r)^2.
    for _ in range(iterations):
        dx, dy = px - cx[:, None], py - cy[:, None]
        d = torch.sqrt(dx**2 + dy**2).clamp(min=1e-12)
        res = d - r[:, None]
        jac = torch.stack([-dx / d, -dy / d, -torch.ones_like(d)], dim=-1)
        jw = jac * w[..., None]
        step = torch.linalg.solve(jw.transpose(1, 2) @ jac + 1e-12 * eye, -(jw * res[..., None]).sum(1))
        cx, cy, r = cx + step[:, 0], cy + step[:, 1], r + step[:, 2]
    return cx, cy, r


# ------------------------------------------------------------------ measurement


def _window(image: torch.Tensor, row: torch.Tensor, col: torch.Tensor, half: int):
    """Square windows of side ``2 half + 1`` centred on integer ``(row, col)`` of each
    image ``(B, H, W)``; pixels beyond the image are marked invalid.

    Returns ``(window, valid, rows, cols)``: ``(B, S, S)``, ``(B, S, S)`` bool, and the
    image rows and columns of the window, ``(B, S)`` each.
    """
    b, h, w = image.shape
    offsets = torch.arange(-half, half + 1)
    rows = row[:, None] + offsets[None, :]
    cols = col[:, None] + offsets[None, :]
    valid = ((rows >= 0) & (rows < h))[:, :, None] & ((cols >= 0) & (cols < w))[:, None, :]
    index = rows.clamp(0, h - 1)[:, :, None] * w + cols.clamp(0, w - 1)[:, None, :]
    size = 2 * half + 1
    window = torch.gather(image.reshape(b, -1), 1, index.reshape(b, -1)).reshape(b, size, size)
    return window, valid, rows, cols


def _detect(img: torch.Tensor, saturation: torch.Tensor, radius_hint: float | None, aspect: float):
    """Whole-frame statistics and a rough position of the sun (float32 work).

    Returns a dict of ``(B,)`` tensors: background, pixel noise, block noise, detection
    (peak of the eroded block image above background), saturated fraction, rough
    centre and rough radius (pixels), and the brightest eroded block outside the first
    disk (``second``, above background, with its position ``second_x``, ``second_y``).
    """
    b, h, w = img.shape
    hb, wb = h // BLOCK, w // BLOCK
    blocks = F.avg_pool2d(img[:, None, : hb * BLOCK, : wb * BLOCK], BLOCK)[:, 0]  # (B, hb, wb)
    # Background and its block-level scatter from 8 x 8 blocks (cheaper; sun-free almost everywhere).
    coarse = F.avg_pool2d(blocks[:, None], 2).reshape(b, -1)
    background = coarse.median(dim=1).values
    coarse_noise = 1.4826 * (coarse - background[:, None]).abs().median(dim=1).values
    # Pixel noise from differences of horizontal neighbours on a sparse grid (robust to gradients).
    n_cols = (w - 1) // 4
    diffs = (img[:, ::8, 1::4][:, :, :n_cols] - img[:, ::8, 0::4][:, :, :n_cols]).reshape(b, -1)
    pixel_noise = (1.4826 * diffs.abs().median(dim=1).values / math.sqrt(2.0)).clamp(min=1e-3)
    block_noise = torch.maximum(2.0 * coarse_noise, pixel_noise / BLOCK)
    # Fraction of the blocks wholly at the saturation level.
    saturated_fraction = (blocks >= saturation[:, None, None]).float().mean(dim=(1, 2))
    # A 2 x 2 erosion of the block means drops isolated hot blocks; the sun (about
    # 7 x 8 blocks) survives.
    eroded = torch.minimum(
        torch.minimum(blocks[:, :-1, :-1], blocks[:, 1:, :-1]), torch.minimum(blocks[:, :-1, 1:], blocks[:, 1:, 1:])
    )
    detect = eroded - background[:, None, None]
    we = detect.shape[-1]
    best = detect.reshape(b, -1).max(dim=1)
    peak = best.values
    # Rough radius: the area of blocks above a third of the peak (a clipped part is missing).
    if radius_hint is not None:
        r_rough = torch.full((b,), float(radius_hint), dtype=torch.float64)
    else:
        area = (detect > peak[:, None, None] / 3).reshape(b, -1).sum(1).to(torch.float64) * BLOCK**2
        r_rough = torch.sqrt(area / (math.pi * aspect)).clamp(min=2.0)
    # Rough centre: the weighted centroid of the bright blocks near the brightest one
    # (a saturated disk has no single brightest block).
    k = int(math.ceil(1.5 * float(r_rough.max()) * max(1.0, aspect) / BLOCK)) + 2
    near, ok, rows, cols = _window(detect, best.indices // we, best.indices % we, k)
    weight = torch.where(ok, (near - peak[:, None, None] / 3).clamp(min=0), torch.zeros_like(near)).to(torch.float64)
    total = weight.sum(dim=(1, 2)).clamp(min=1e-12)
    # Eroded block (i, j) covers pixels 4i .. 4i + 7: its centre is at 4i + 3.5.
    rough_y = (weight * rows[:, :, None].to(torch.float64)).sum(dim=(1, 2)) / total * BLOCK + BLOCK - 0.5
    rough_x = (weight * cols[:, None, :].to(torch.float64)).sum(dim=(1, 2)) / total * BLOCK + BLOCK - 0.5
    # A second sun (a reflection, a second source): the brightest eroded block outside
    # the first disk (1.6 rough radii around the rough centre, in block units).
    by = torch.arange(detect.shape[-2], dtype=torch.float64)[None, :, None] * BLOCK + BLOCK - 0.5
    bx = torch.arange(detect.shape[-1], dtype=torch.float64)[None, None, :] * BLOCK + BLOCK - 0.5
    dist = torch.sqrt((bx - rough_x[:, None, None]) ** 2 + ((by - rough_y[:, None, None]) / aspect) ** 2)
    outside = dist > 1.6 * r_rough[:, None, None] + 2 * BLOCK
    second = torch.where(outside, detect.double(), torch.full_like(dist, -math.inf)).reshape(b, -1).max(dim=1)
    second_y = (second.indices // we).double() * BLOCK + BLOCK - 0.5
    second_x = (second.indices % we).double() * BLOCK + BLOCK - 0.5
    return {
        "second": second.values.clamp(min=0.0),
        "second_x": second_x,
        "second_y": second_y,
        "background": background.double(),
        "noise": pixel_noise.double(),
        "block_noise": block_noise.double(),
        "detection": peak.double(),
        "saturated_fraction": saturated_fraction.double(),
        "rough_x": rough_x,
        "rough_y": rough_y,
        "r_rough": r_rough,
    }


def _repair_hot(roi, valid, background, noise):
    """Replace hot pixels (far above all 8 neighbours) by their neighbours' median."""
    filled = torch.where(valid, roi, background[:, None, None])
    b, h, w = filled.shape
    patches = F.unfold(F.pad(filled[:, None], (1, 1, 1, 1), mode="replicate"), 3)  # (B, 9, H*W)
    ring = patches[:, [0, 1, 2, 3, 5, 6, 7, 8]]
    neighbours_max = ring.max(dim=1).values.view(b, h, w)
    excess = neighbours_max - background[:, None, None]
    hot = valid & (roi - neighbours_max > torch.maximum(8 * noise[:, None, None], 0.2 * excess))
    if bool(hot.any()):
        where = hot.view(b, -1)
        median = torch.zeros_like(filled).view(b, -1)
        bi, pi = torch.nonzero(where, as_tuple=True)
        median[bi, pi] = ring[bi, :, pi].median(dim=1).values
        roi = torch.where(hot, median.view(b, h, w), roi)
    return roi, hot


def _distance(xs, ys, cx, cy, aspect):
    """Distance of each pixel from ``(cx, cy)`` in x pixels (y scaled by 1 / aspect)."""
    return torch.sqrt((xs - cx[:, None, None]) ** 2 + ((ys - cy[:, None, None]) / aspect) ** 2)


def _background_plane(roi, use, xs, ys, cx, cy, noise, fallback):
    """Background plane fitted (4-sigma clipped) to the pixels ``use`` (the window less
    the grown disk, hot and saturated pixels); ``fallback`` (a constant) where fewer than
    24 remain. Returns the plane evaluated on the window, ``(B, S, S)``."""
    b = roi.shape[0]
    z = roi.reshape(b, -1)
    u = (xs - cx[:, None, None]).reshape(b, -1)
    v = (ys - cy[:, None, None]).reshape(b, -1)
    wts = use.reshape(b, -1).to(roi.dtype)
    plane = _weighted_plane(z, u, v, wts)
    resid = z - (plane[:, 0:1] + plane[:, 1:2] * u + plane[:, 2:3] * v)
    wts = wts * (resid.abs() <= 4 * noise[:, None])
    plane = _weighted_plane(z, u, v, wts)
    few = wts.sum(1) < 24
    flat = torch.stack([fallback, torch.zeros_like(fallback), torch.zeros_like(fallback)], 1)
    plane = torch.where(few[:, None], flat, plane)
    return (plane[:, 0:1] + plane[:, 1:2] * u + plane[:, 2:3] * v).view_as(roi)


def _ring_mean(roi, use, xs, ys, cx, cy, r, aspect):
    """Mean of the pixels ``use`` between 1.3 and 2 radii from ``(cx, cy)``."""
    dist = _distance(xs, ys, cx, cy, aspect)
    ring = use & (dist >= 1.3 * r[:, None, None]) & (dist <= 2.0 * r[:, None, None])
    return (roi * ring).sum(dim=(1, 2)) / ring.sum(dim=(1, 2)).clamp(min=1)


def _intensity_centroid(signal, valid, xs, ys, near, peak, noise, threshold):
    """Intensity-weighted centroid over a window: the smoothed signal thresholded at
    ``threshold * peak`` and grown by 3 pixels. Returns ``(x, y, mask, clipped)``."""
    smooth = kornia.filters.gaussian_blur2d(signal[:, None], (5, 5), (1.0, 1.0), border_type="constant")[:, 0]
    cut = torch.maximum(threshold * peak, 2.5 * noise)  # the smoothed noise is about sigma / 2
    mask = (smooth > cut[:, None, None]) & valid & near
    window = (F.max_pool2d(mask.to(signal.dtype)[:, None], 7, stride=1, padding=3)[:, 0] > 0.5) & valid
    weight = torch.where(window, signal, torch.zeros_like(signal))
    total = weight.sum(dim=(1, 2))
    x = (weight * xs).sum(dim=(1, 2)) / total
    y = (weight * ys).sum(dim=(1, 2)) / total
    # A window that reaches invalid pixels (beyond the frame) or the frame's outer pixels
    # means a clipped disk, whose intensity centroid is biased.
    grown = F.max_pool2d(window.to(signal.dtype)[:, None], 3, stride=1, padding=1)[:, 0] > 0.5
    clipped = (grown & ~valid).flatten(1).any(1)
    return x, y, mask, clipped


def _crossings(grid_img, size, col_lo, row_lo, level, cx, cy, r0, span, samples, cos_t, sin_t, aspect):
    """Edge points: the outermost crossing of ``level`` along rays from ``(cx, cy)``,
    each sampled (bicubic) at ``samples`` radii from ``r0 - span`` to ``r0 + span``
    (per frame, ``(B,)`` each). Returns ``(ex, ey, good)``, each ``(B, rays)``."""
    f64 = grid_img.dtype
    step = 2 * span / (samples - 1)  # (B,)
    radii = r0[:, None] + span[:, None] * torch.linspace(-1.0, 1.0, samples, dtype=f64)[None, :]  # (B, K)
    px = cx[:, None, None] + radii[:, None, :] * cos_t[None, :, None]  # (B, R, K)
    py = cy[:, None, None] + radii[:, None, :] * aspect * sin_t[None, :, None]
    gx = (px - col_lo[:, None, None]) / (size - 1) * 2 - 1
    gy = (py - row_lo[:, None, None]) / (size - 1) * 2 - 1
    grid = torch.stack([gx, gy], dim=-1)
    prof = F.grid_sample(grid_img[:, :1], grid, mode="bicubic", padding_mode="zeros", align_corners=True)[:, 0]
    # Bicubic reads 4 x 4 pixels: all of them are valid where the bilinear sample of the
    # validity mask eroded by one pixel is 1.
    ok = F.grid_sample(grid_img[:, 1:], grid, mode="bilinear", padding_mode="zeros", align_corners=True)[:, 0] > 0.999
    above = prof >= level[:, None, None]
    trans = above[..., :-1] & ~above[..., 1:]
    k = trans.shape[-1]
    idx = torch.where(trans, torch.arange(k)[None, None, :], torch.full_like(trans, -1, dtype=torch.long)).max(-1).values
    j = idx.clamp(min=0)
    p0 = prof.gather(-1, j[..., None])[..., 0]
    p1 = prof.gather(-1, (j + 1)[..., None])[..., 0]
    frac = ((p0 - level[:, None]) / (p0 - p1).clamp(min=1e-12)).clamp(0, 1)
    rho = radii[:, None, :].expand_as(prof).gather(-1, j[..., None])[..., 0] + frac * step[:, None]
    # Every sample from two pixels inside the crossing to one pixel outside must be valid.
    inner = torch.ceil(2 / step).long()[:, None, None]
    outer = torch.ceil(1 / step).long()[:, None, None]
    pos = torch.arange(k + 1)[None, None, :]
    needed = (pos >= j[..., None] - inner) & (pos <= j[..., None] + outer + 1)
    good = (idx >= 0) & (ok | ~needed).all(-1) & (j + outer[..., 0] + 1 <= k)
    ex = cx[:, None] + rho * cos_t[None, :]
    ey = cy[:, None] + rho * aspect * sin_t[None, :]
    return ex, ey, good


def _fit_limb_points(ex, ey, good, aspect):
    """Circle fit to edge points (y scaled by 1 / aspect), one round of outlier rejection
    (> 4 robust sigmas, at least 0.05 px, at most 1 px). Returns ``(cx, cy, r, kept)``."""
    f64 = ex.dtype
    fx, fy, fr = _circle_fit(ex, ey / aspect, good.to(f64))
    res = torch.sqrt((ex - fx[:, None]) ** 2 + (ey / aspect - fy[:, None]) ** 2) - fr[:, None]
    mad = torch.where(good, res.abs(), torch.full_like(res, math.nan)).nanmedian(dim=1).values * 1.4826
    keep = good & (res.abs() <= torch.clamp(4 * mad, min=0.05, max=1.0)[:, None])
    fx, fy, fr = _circle_fit(ex, ey / aspect, keep.to(f64))
    return fx, fy * aspect, fr, keep


def measure(
    img: torch.Tensor,
    saturation: torch.Tensor,
    radius_hint: float | None,
    aspect: float,
    threshold: float,
    edge_level: float,
) -> dict[str, torch.Tensor]:
    """Measure a batch of same-shape frames ``(B, H, W)`` float32; per-frame tensors out."""
    b, h, w = img.shape
    f64 = torch.float64
    found = _detect(img, saturation, radius_hint, aspect)
    background, noise, r_rough = found["background"], found["noise"], found["r_rough"]
    rough_x, rough_y = found["rough_x"], found["rough_y"]

    # --- region of interest (float64); pixels beyond the frame are invalid
    r_max = float(r_rough.max()) * max(1.0, aspect)
    half = int(math.ceil(1.3 * r_max + 14))
    size = 2 * half + 1
    roi, valid, rows, cols = _window(img, torch.round(rough_y).long(), torch.round(rough_x).long(), half)
    roi = roi.to(f64)
    xs = cols.to(f64)[:, None, :].expand(b, size, size)
    ys = rows.to(f64)[:, :, None].expand(b, size, size)
    sat_mask = (roi >= saturation.to(f64)[:, None, None]) & valid
    roi, hot = _repair_hot(roi, valid, background, noise)
    use = valid & ~hot & ~sat_mask

    # --- background plane (fitted around the disk, which a threshold on the signal above
    # the global background finds), peak, intensity centroid
    near = _distance(xs, ys, rough_x, rough_y, aspect) <= 1.3 * r_rough[:, None, None] + 4

    def smoothed(signal):
        return kornia.filters.gaussian_blur2d(signal[:, None], (3, 3), (0.7, 0.7), border_type="constant")[:, 0]

    def peak_of(smooth):
        # The mean of the 8 brightest smoothed pixels (a single maximum is noisy).
        return torch.where(valid & near, smooth, torch.full_like(smooth, -math.inf)).flatten(1).topk(8, dim=1).values.mean(1)

    disk_saturated = sat_mask.flatten(1).sum(1) >= 5
    first = smoothed(torch.where(valid, roi - background[:, None, None], torch.zeros_like(roi)))
    disk = first > torch.maximum(0.05 * peak_of(first), 5 * noise)[:, None, None]
    grown = F.max_pool2d(disk.to(f64)[:, None], 9, stride=1, padding=4)[:, 0] > 0.5
    # Background pixels: outside the grown disk, within a per-frame distance (so that
    # a frame's result does not depend on the window size its batch needed).
    around = _distance(xs, ys, rough_x, rough_y, aspect) <= 1.3 * r_rough[:, None, None] + 12
    bg_plane = _background_plane(roi, use & ~grown & around, xs, ys, rough_x, rough_y, noise, background)
    signal = torch.where(valid, roi - bg_plane, torch.zeros_like(roi))
    peak = peak_of(smoothed(signal))
    peak = torch.where(disk_saturated, saturation.to(f64) - background, peak).clamp(min=1e-9)
    ix, iy, mask, window_clipped = _intensity_centroid(signal, valid, xs, ys, near, peak, noise, threshold)
    if radius_hint is None:
        r_start = torch.sqrt(mask.flatten(1).sum(1).to(f64) / (math.pi * aspect)).clamp(min=2.0)
        r_start = torch.where(window_clipped, torch.maximum(r_start, r_rough), r_start)
    else:
        r_start = r_rough

    # --- limb fit: a coarse pass from the intensity centroid, a fine one from its fit
    # Crossing level: ``edge_level`` of the peak; half the saturation level above the
    # background for a saturated disk (whose edge pixels jump straight to saturation).
    level = torch.where(disk_saturated, 0.5 * peak, edge_level * peak)
    eroded = -F.max_pool2d(-valid.to(f64)[:, None], 3, stride=1, padding=1)[:, 0]
    grid_img = torch.stack([signal, eroded], dim=1)  # (B, 2, S, S): signal, eroded validity
    col_lo, row_lo = cols[:, 0].to(f64), rows[:, 0].to(f64)
    geometry = (grid_img, size, col_lo, row_lo, level)
    theta = torch.arange(_RAYS // 2, dtype=f64) * (4 * math.pi / _RAYS)
    span = 0.6 * r_start + 4
    ex, ey, good = _crossings(*geometry, ix, iy, r_start, span, 81, torch.cos(theta), torch.sin(theta), aspect)
    lx, ly, lr, _ = _fit_limb_points(ex, ey, good, aspect)
    lx = torch.where(torch.isfinite(lx), lx, ix)
    ly = torch.where(torch.isfinite(ly), ly, iy)
    lr = torch.where(torch.isfinite(lr) & (lr > 1), lr, r_start)
    theta = torch.arange(_RAYS, dtype=f64) * (2 * math.pi / _RAYS)
    ex, ey, good = _crossings(*geometry, lx, ly, lr, torch.full_like(lr, 3.0), 61, torch.cos(theta), torch.sin(theta), aspect)
    lx, ly, lr, keep = _fit_limb_points(ex, ey, good, aspect)

    # --- fraction of the fitted limb inside the frame (between the outermost pixel centres)
    t = torch.linspace(0, 2 * math.pi, 721, dtype=f64)[:-1]
    bx = lx[:, None] + lr[:, None] * torch.cos(t)[None, :]
    by = ly[:, None] + lr[:, None] * aspect * torch.sin(t)[None, :]
    inside = (bx >= 0.0) & (bx <= w - 1.0) & (by >= 0.0) & (by <= h - 1.0)
    limb_fraction = torch.where(torch.isfinite(lr), inside.to(f64).mean(1), torch.zeros_like(lr))

    # --- aureole: mean excess over the global background at 1.3-2 radii
    cx = torch.where(torch.isfinite(lx), lx, rough_x)
    cy = torch.where(torch.isfinite(ly), ly, rough_y)
    cr = torch.where(torch.isfinite(lr), lr, r_rough)
    aureole = (_ring_mean(roi, use, xs, ys, cx, cy, cr, aspect) - background) / peak

    return {
        **found,
        "peak": peak,
        "disk_saturated": disk_saturated,
        "intensity_x": ix,
        "intensity_y": iy,
        "window_clipped": window_clipped,
        "limb_x": lx,
        "limb_y": ly,
        "radius": lr,
        "n_edge": keep.sum(1),
        "limb_fraction": limb_fraction,
        "aureole": aureole,
    }

"""Synthetic sun-sensor frames with a known centre, for tests, examples and benchmarks.

The scene is the sun imaged by a camera like the sun-vector paper's (1280 x 1024
pixels, field of view 23 x 17 deg, see :func:`pointax.sunsensor.camera.paper_camera`)
through a neutral-density filter:

* **The disk.** A limb-darkened disk of radius ``radius`` pixels along x and
  ``radius * aspect`` along y (``aspect = fy / fx``: the paper's lens has 0.018 deg
  pixels across and 0.0166 deg pixels down, so the sun is a slightly tall ellipse).
  Limb darkening follows the quadratic law::

      I(mu) / I(1) = 1 - u1 (1 - mu) - u2 (1 - mu)^2,     mu = sqrt(1 - rho^2)

  with ``rho`` the normalised distance from the centre; the default ``limb=(0.6, 0.0)``
  is the linear law with u = 0.6, about the sun's in the visible.
* **Exact pixels.** Each pixel holds the integral of the intensity over its square
  (pixel ``(i, j)`` spans ``[j - 0.5, j + 0.5] x [i - 0.5, i + 0.5]``: the origin is the
  centre of the top-left pixel, x to the right, y down). The integral along x is
  done in closed form (``int sqrt(c^2 - t^2) dt``), the one along y by the midpoint rule
  on ``subrows`` sub-rows per pixel (128 by default). The true centre ``(x, y)`` is
  exact by construction; the rendering's error moves the frame's first moment by less
  than 2e-5 px (tests/test_sunsensor_frames.py checks pixel values against scipy
  quadrature, fluxes against closed forms, moments against a 1024 sub-row rendering).
  What remains between the noise-free first moment and the centre, < 3e-4 px, is the
  pixelisation of a sharp disk (pixel-centre moments of a pixel-integrated edge), a
  property of the image, not an error of the truth. Pixels beyond the frame edge are
  simply not there: a sun near the edge is clipped.
* **Signal and detector.** ``level`` is the signal at the disk centre as a fraction of
  the detector's full scale: the neutral-density filter (and exposure) sets it; above 1
  the disk saturates. The detector counts electrons with shot noise (the Poisson
  distribution's normal limit: variance = mean, every pixel holds >= ~20 electrons), adds
  Gaussian read noise, converts with ``gain`` electrons per ADU onto a ``bias`` and
  clips at the ADC's full scale ``2**bits - 1`` (saturation). ``hot_pixels`` random
  pixels get a large random excess. ``sky`` is a uniform background (electrons).
* **Thin cloud.** ``cloud`` is an optical depth tau: the disk is dimmed by
  ``exp(-tau)`` and the scattered light, a fraction ``0.5 (1 - exp(-tau))`` of the
  unattenuated disk's flux, forms an aureole ``(1 + (d / 2R)^2)^(-3/2)`` around the sun
  (d the distance from the centre, R the radius) plus a uniform sky brightening.
  Thin cloud (tau ~ 0.2) leaves a usable disk; thick cloud veils it.

Everything is rendered in torch float64 and batched over frames; the frames come back
as integer NumPy arrays (``uint16`` for ``bits > 8``), as a camera delivers them.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import torch

__all__ = [
    "PAPER_SUN_RADIUS_PX",
    "PAPER_ASPECT",
    "SUN_ANGULAR_RADIUS",
    "Detector",
    "SyntheticFrames",
    "render_disk",
    "disk_flux",
    "synthetic_frames",
]

SUN_ANGULAR_RADIUS = math.radians(0.53 / 2)
"""The sun's angular radius, radians (0.53 deg diameter; it varies by +-1.7 % over a year)."""

PAPER_SUN_RADIUS_PX = (1280 / 2) / math.tan(math.radians(23.0 / 2)) * math.tan(SUN_ANGULAR_RADIUS)
"""Radius of the sun in pixels along x for the paper's camera (about 14.5 px)."""

PAPER_ASPECT = (math.tan(math.radians(23.0 / 2)) / 1280) / (math.tan(math.radians(17.0 / 2)) / 1024)
"""``fy / fx`` of the paper's camera (1280 x 1024 pixels over 23 x 17 deg): about 1.09."""


@dataclasses.dataclass(frozen=True)
class Detector:
    """The sun sensor's detector (defaults: a 1.3 Mpixel CMOS sensor like the paper's).

    Attributes:
        width, height: frame size, pixels.
        bits: ADC resolution; full scale is ``2**bits - 1`` ADU (the saturation level).
        gain: electrons per ADU.
        read_noise: read noise, electrons RMS.
        bias: offset added to every pixel, ADU.
    """

    width: int = 1280
    height: int = 1024
    bits: int = 12
    gain: float = 2.0
    read_noise: float = 8.0
    bias: float = 32.0

    @property
    def full_scale(self) -> int:
        """Saturation level, ADU."""
        return 2**self.bits - 1

    @property
    def dtype(self) -> np.dtype:
        """NumPy dtype of the frames: uint8 up to 8 bits, else uint16."""
        return np.dtype(np.uint8 if self.bits <= 8 else np.uint16)


def _limb_coefficients(limb) -> tuple[float, float, float]:
    """``(A0, A1, A2)`` with ``I = A0 + A1 mu + A2 mu^2`` for the quadratic law."""
    u1, u2 = (float(limb), 0.0) if np.ndim(limb) == 0 else (float(limb[0]), float(limb[1]))
    return 1.0 - u1 - u2, u1 + 2.0 * u2, -u2


def disk_flux(radius: float, aspect: float = 1.0, limb=(0.6, 0.0)) -> float:
    """Total flux (pixel units, centre intensity 1) of the whole limb-darkened disk:
    ``pi R^2 aspect (A0 + 2 A1 / 3 + A2 / 2)`` (closed form)."""
    a0, a1, a2 = _limb_coefficients(limb)
    return math.pi * radius**2 * aspect * (a0 + 2.0 * a1 / 3.0 + a2 / 2.0)


def render_disk(
    x: torch.Tensor,
    y: torch.Tensor,
    radius: torch.Tensor,
    aspect: float = 1.0,
    limb=(0.6, 0.0),
    *,
    size: int,
    subrows: int = 128,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Pixel-integrated limb-darkened disks on small windows (torch float64, batched).

    Args:
        x, y: ``(B,)`` disk centres, pixels (origin at the centre of the top-left pixel).
        radius: ``(B,)`` radius along x, pixels; along y it is ``radius * aspect``.
        aspect: ``fy / fx`` of the camera.
        limb: limb darkening ``(u1, u2)`` of the quadratic law (or one number: linear).
        size: window side, pixels (must hold the disk: ``>= 2 radius max(1, aspect) + 3``).
        subrows: midpoint sub-rows per pixel for the integral along y.

    Returns:
        ``(window, col0, row0)``: ``(B, size, size)`` the integral of the intensity
        (centre intensity 1) over each pixel, and the frame column and row of each
        window's top-left pixel, ``(B,)`` int64.
    """
    a0, a1, a2 = _limb_coefficients(limb)
    x = torch.as_tensor(x, dtype=torch.float64)
    y = torch.as_tensor(y, dtype=torch.float64)
    radius = torch.as_tensor(radius, dtype=torch.float64).expand_as(x)
    half = size // 2
    col0 = torch.round(x).to(torch.int64) - half
    row0 = torch.round(y).to(torch.int64) - half
    offsets = torch.arange(size, dtype=torch.float64)
    # Column edges relative to the centre: (B, size) left and right.
    left = (col0[:, None] + offsets[None, :]).to(torch.float64) - 0.5 - x[:, None]
    right = left + 1.0
    # Sub-row positions relative to the centre: (B, size, subrows).
    sub = (torch.arange(subrows, dtype=torch.float64) + 0.5) / subrows - 0.5
    dy = (row0[:, None, None] + offsets[None, :, None]).to(torch.float64) + sub[None, None, :] - y[:, None, None]
    r = radius[:, None, None]
    c2 = r**2 - (dy / aspect) ** 2  # squared half-chord of each sub-row
    inside = c2 > 0
    c = torch.sqrt(torch.where(inside, c2, torch.ones_like(c2)))
    # Integrate along x over [left, right] clipped to the chord [-c, c]: (B, size, subrows, size).
    cc = c[..., None]
    lo = torch.minimum(torch.maximum(left[:, None, None, :], -cc), cc)
    hi = torch.minimum(torch.maximum(right[:, None, None, :], -cc), cc)

    def primitive(t):
        # A0 t + A1 int sqrt(c^2 - t^2) dt / R + A2 int (c^2 - t^2) dt / R^2
        root = torch.sqrt(torch.clamp(cc**2 - t**2, min=0.0))
        arc = torch.asin(torch.clamp(t / cc, -1.0, 1.0))
        rr = r[..., None]
        return a0 * t + a1 * 0.5 * (t * root + cc**2 * arc) / rr + a2 * (cc**2 * t - t**3 / 3.0) / rr**2

    strip = torch.where(inside[..., None], primitive(hi) - primitive(lo), torch.zeros_like(lo))
    window = strip.mean(dim=2)  # (B, size rows, size cols)
    return window, col0, row0


def _aureole(shape, x, y, radius, aspect) -> torch.Tensor:
    """Aureole profile ``(1 + (d / 2R)^2)^(-3/2)`` (``d`` scaled by the aspect), normalised
    to unit flux over the infinite plane, sampled at the pixel centres: ``(B, H, W)``."""
    height, width = shape
    cols = torch.arange(width, dtype=torch.float64)
    rows = torch.arange(height, dtype=torch.float64)
    scale = 2.0 * radius[:, None, None]
    d2 = ((cols[None, None, :] - x[:, None, None]) ** 2 + ((rows[None, :, None] - y[:, None, None]) / aspect) ** 2) / scale**2
    # int over the plane of (1 + s^2)^(-3/2) = 2 pi (in units of scale^2, times aspect).
    return (1.0 + d2) ** -1.5 / (2.0 * math.pi * scale**2 * aspect)


@dataclasses.dataclass(frozen=True)
class SyntheticFrames:
    """Synthetic frames and their truth.

    Attributes:
        images: ``(B, H, W)`` integer frames (ADU), as the detector delivers them.
        x, y: ``(B,)`` true disk centres, pixels (origin at the centre of the top-left
            pixel, x right, y down). Exact by construction.
        radius: ``(B,)`` true radius along x, pixels.
        aspect: ``fy / fx`` used (the radius along y is ``radius * aspect``).
        visible: ``(B,)`` fraction of the disk's limb (by angle) that lies inside the frame.
        expected: ``(B, H, W)`` float64 noise-free expectation (ADU, before saturation
            and quantisation) when asked for with ``keep_expected=True``, else None.
        detector: the :class:`Detector`.
    """

    images: np.ndarray
    x: np.ndarray
    y: np.ndarray
    radius: np.ndarray
    aspect: float
    visible: np.ndarray
    detector: Detector
    expected: np.ndarray | None = None

    def __len__(self) -> int:
        return self.images.shape[0]


def _visible_limb(x, y, radius, aspect, width, height, n=720) -> np.ndarray:
    """Fraction of the limb (by position angle) inside the frame's pixel area."""
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    lx = x[:, None] + radius[:, None] * np.cos(t)
    ly = y[:, None] + radius[:, None] * aspect * np.sin(t)
    inside = (lx >= -0.5) & (lx <= width - 0.5) & (ly >= -0.5) & (ly <= height - 0.5)
    return inside.mean(axis=1)


def synthetic_frames(
    x,
    y,
    *,
    radius=PAPER_SUN_RADIUS_PX,
    aspect: float = PAPER_ASPECT,
    limb=(0.6, 0.0),
    level=0.7,
    cloud=0.0,
    sky: float = 20.0,
    hot_pixels: int = 0,
    noise: bool = True,
    detector: Detector = Detector(),
    seed: int | None = 0,
    keep_expected: bool = False,
    subrows: int = 128,
) -> SyntheticFrames:
    """Render a batch of sun-sensor frames (see the module docstring for the model).

    Args:
        x, y: disk centres, pixels; scalars or ``(B,)`` arrays (broadcast together).
            A centre near or beyond the frame edge gives a clipped sun.
        radius: disk radius along x, pixels (default: the sun in the paper's camera).
        aspect: ``fy / fx`` (the disk's radius along y is ``radius * aspect``).
        limb: quadratic limb-darkening ``(u1, u2)``, or one number for the linear law.
        level: signal at the disk centre as a fraction of the detector's full scale (the
            neutral-density filter level); scalar or ``(B,)``. Above 1 the disk saturates.
        cloud: optical depth of thin cloud in front of the sun, scalar or ``(B,)``.
        sky: uniform sky background, electrons per pixel.
        hot_pixels: number of hot pixels per frame (random places, excess 300 ADU up to
            full scale).
        noise: False for the noise-free expectation (rounded to integers, still clipped).
        detector: the :class:`Detector`.
        seed: random seed (shot noise, read noise, hot pixels).
        keep_expected: also return the float noise-free expectation.
        subrows: sub-rows per pixel in the integral along y (128: the frame's moments
            are within 2e-5 px of the converged integral; 32 is ample where noise
            dominates).

    Returns:
        :class:`SyntheticFrames`.
    """
    x, y, level, cloud = np.broadcast_arrays(
        np.atleast_1d(np.asarray(x, np.float64)),
        np.atleast_1d(np.asarray(y, np.float64)),
        np.asarray(level, np.float64),
        np.asarray(cloud, np.float64),
    )
    radius = np.broadcast_to(np.asarray(radius, np.float64), x.shape).copy()
    if x.ndim != 1:
        raise ValueError(f"x and y must be scalars or 1-D arrays, got shape {x.shape}")
    if np.any(radius <= 0) or not np.all(np.isfinite(radius)):
        raise ValueError("radius must be positive and finite")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError("x and y must be finite")
    batch = x.shape[0]
    height, width = detector.height, detector.width
    generator = torch.Generator().manual_seed(0 if seed is None else int(seed))

    tx, ty, tr = (torch.as_tensor(a.copy()) for a in (x, y, radius))
    size = 2 * int(math.ceil(float(radius.max()) * max(1.0, aspect))) + 5
    # float64 where the exact expectation is wanted; float32 (ample for integer ADU)
    # for fast noisy frames.
    dtype = torch.float64 if (keep_expected or not noise) else torch.float32
    full_e = (detector.full_scale - detector.bias) * detector.gain  # electrons at full scale
    peak_e = torch.as_tensor(level * full_e)
    transmission = torch.as_tensor(np.exp(-cloud))
    electrons = torch.full((batch, height, width), float(sky), dtype=dtype)
    chunk = 16  # frames rendered at a time (bounds the memory of the sub-row integrals)
    for start in range(0, batch, chunk):
        part = slice(start, min(start + chunk, batch))
        window, col0, row0 = render_disk(tx[part], ty[part], tr[part], aspect, limb, size=size, subrows=subrows)
        # Paste each window into its frame (scatter-add), dropping what falls outside:
        # a sun near the edge comes out clipped.
        rows = row0[:, None, None] + torch.arange(size)[None, :, None]
        cols = col0[:, None, None] + torch.arange(size)[None, None, :]
        inside = (rows >= 0) & (rows < height) & (cols >= 0) & (cols < width)
        index = torch.where(inside, rows * width + cols, torch.zeros_like(rows)).reshape(window.shape[0], -1)
        signal = torch.where(inside, window, torch.zeros_like(window)) * (peak_e[part] * transmission[part])[:, None, None]
        electrons[part].view(window.shape[0], -1).scatter_add_(1, index, signal.reshape(window.shape[0], -1).to(dtype))
    if np.any(cloud > 0):
        # Scattered light: half of what the cloud takes from the disk, in the aureole.
        scattered = 0.5 * (1.0 - transmission) * peak_e * torch.as_tensor(disk_flux(1.0, 1.0, limb) * radius**2 * aspect)
        aureole = _aureole((height, width), tx, ty, tr, aspect)
        haze = 0.02 * (1.0 - transmission) * peak_e  # uniform brightening of the sky
        electrons += (scattered[:, None, None] * aureole + haze[:, None, None]).to(dtype)

    expected = detector.bias + electrons / detector.gain
    if noise:
        # Shot noise as the Poisson distribution's normal limit (variance = mean; every
        # pixel holds >= ~20 electrons) plus Gaussian read noise.
        sigma = torch.sqrt(electrons + detector.read_noise**2)
        adu = expected + torch.randn(electrons.shape, generator=generator, dtype=dtype) * sigma / detector.gain
    else:
        adu = expected.clone()
    if hot_pixels:
        flat = adu.view(batch, -1)
        where = torch.randint(0, height * width, (batch, hot_pixels), generator=generator)
        excess = 300.0 + torch.rand((batch, hot_pixels), generator=generator, dtype=dtype) * detector.full_scale
        flat.scatter_add_(1, where, excess)
    adu = torch.clamp(torch.round(adu), 0, detector.full_scale)
    images = adu.numpy().astype(detector.dtype)
    visible = _visible_limb(x, y, radius, aspect, width, height)
    return SyntheticFrames(
        images=images,
        x=x.copy(),
        y=y.copy(),
        radius=radius,
        aspect=float(aspect),
        visible=visible,
        detector=detector,
        expected=expected.double().numpy() if keep_expected else None,
    )

"""Camera geometry of the sun sensor: intrinsics, radial distortion, pixels <-> rays.

The camera frame is OpenCV's and kornia's: ``x`` to the right in the image, ``y`` down,
``z`` along the optical axis (out of the lens). Pixel coordinates have their origin at
the centre of the top-left pixel (kornia's convention: integer pixel centres), ``u``
(x, column) to the right and ``v`` (y, row) down. A pixel ``(u, v)`` maps to the unit
direction (ray) of the light that lands there::

    (x_d, y_d) = ((u - cx) / fx, (v - cy) / fy)                   distorted, normalised
    (x_d, y_d) = distort(x, y)                                       solved for (x, y)
    ray = (x, y, 1) / |(x, y, 1)|

with OpenCV's distortion ``distort(x, y) = (x, y) (1 + k1 r^2 + k2 r^4 + k3 r^6) +
tangential(p1, p2)``, ``r^2 = x^2 + y^2``. :meth:`Camera.pixel_to_ray` goes through
``kornia.geometry.calibration.undistort_points`` and
``kornia.geometry.camera.perspective.unproject_points``; :meth:`Camera.ray_to_pixel`
through ``kornia.geometry.camera.perspective.project_points`` and
``kornia.geometry.calibration.distort_points``. tests/test_sunsensor_camera.py checks
both against an independent NumPy pinhole and distortion computation.

The camera turns pixels into rays once, in torch; the rays cross into JAX (as NumPy
float64) once, before any fit (see :mod:`pointax.sunsensor.pipeline`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import torch
from kornia.geometry.calibration import distort_points, undistort_points
from kornia.geometry.camera import PinholeCamera
from kornia.geometry.camera.perspective import project_points, unproject_points

from .frames import SUN_ANGULAR_RADIUS

__all__ = ["Camera", "paper_camera"]

_UNDISTORT_ITERATIONS = 30


@dataclasses.dataclass(frozen=True)
class Camera:
    """A pinhole camera with OpenCV radial (and tangential) distortion.

    Attributes:
        width, height: image size, pixels.
        fx, fy: focal lengths, pixels.
        cx, cy: principal point, pixels (origin at the centre of the top-left pixel).
        dist: distortion ``(k1, k2, p1, p2, k3)`` (OpenCV's order; zeros: none).
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    dist: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)

    def __post_init__(self):
        if not (self.width > 0 and self.height > 0):
            raise ValueError(f"image size must be positive, got {self.width} x {self.height}")
        if not (self.fx > 0 and self.fy > 0 and math.isfinite(self.fx) and math.isfinite(self.fy)):
            raise ValueError(f"focal lengths must be positive, got fx={self.fx}, fy={self.fy}")
        if len(self.dist) != 5:
            raise ValueError(f"dist must hold 5 coefficients (k1, k2, p1, p2, k3), got {len(self.dist)}")
        object.__setattr__(self, "dist", tuple(float(d) for d in self.dist))

    @classmethod
    def from_fov(
        cls,
        width: int = 1280,
        height: int = 1024,
        fov_x_deg: float = 23.0,
        fov_y_deg: float = 17.0,
        cx: float | None = None,
        cy: float | None = None,
        dist=(0.0, 0.0, 0.0, 0.0, 0.0),
    ) -> "Camera":
        """A camera whose undistorted field of view spans ``fov_x_deg`` by ``fov_y_deg``
        across the full image (pixel edges ``-0.5`` to ``width - 0.5``), principal point
        at the image centre ``((width - 1) / 2, (height - 1) / 2)`` unless given."""
        fx = (width / 2) / math.tan(math.radians(fov_x_deg) / 2)
        fy = (height / 2) / math.tan(math.radians(fov_y_deg) / 2)
        cx = (width - 1) / 2 if cx is None else cx
        cy = (height - 1) / 2 if cy is None else cy
        return cls(width, height, fx, fy, cx, cy, tuple(dist))

    # -------------------------------------------------------------- properties

    @property
    def shape(self) -> tuple[int, int]:
        """``(height, width)`` of the frames."""
        return (self.height, self.width)

    @property
    def aspect(self) -> float:
        """``fy / fx``: an object's height in pixels over its width."""
        return self.fy / self.fx

    @property
    def K(self) -> torch.Tensor:
        """The ``(3, 3)`` intrinsic matrix, float64."""
        return torch.tensor([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]], dtype=torch.float64)

    @property
    def pixel_scale_deg(self) -> tuple[float, float]:
        """Angle of one pixel at the principal point, degrees, ``(along x, along y)``."""
        return math.degrees(math.atan(1.0 / self.fx)), math.degrees(math.atan(1.0 / self.fy))

    def sun_radius_px(self, angular_radius: float = SUN_ANGULAR_RADIUS) -> float:
        """The sun's radius along x in pixels near the principal point
        (``fx tan(angular radius)``; along y it is ``aspect`` times that)."""
        return self.fx * math.tan(angular_radius)

    def pinhole(self) -> PinholeCamera:
        """This camera as a ``kornia.geometry.camera.PinholeCamera`` (batch of one,
        identity extrinsics: world = camera frame)."""
        intrinsics = torch.eye(4, dtype=torch.float64)
        intrinsics[:3, :3] = self.K
        return PinholeCamera(
            intrinsics[None],
            torch.eye(4, dtype=torch.float64)[None],
            torch.tensor([float(self.height)], dtype=torch.float64),
            torch.tensor([float(self.width)], dtype=torch.float64),
        )

    # -------------------------------------------------------------- mappings

    def _dist(self) -> torch.Tensor:
        return torch.tensor(self.dist, dtype=torch.float64)

    def pixel_to_ray(self, pixels) -> np.ndarray:
        """Unit directions in the camera frame of pixel positions.

        Args:
            pixels: ``(..., 2)`` pixel coordinates ``(u, v)`` (NumPy or torch).

        Returns:
            ``(..., 3)`` float64 NumPy unit vectors (x right, y down, z along the axis);
            NaN where the pixel is NaN.
        """
        pts = torch.as_tensor(np.asarray(pixels, np.float64))
        shape = pts.shape
        if shape[-1] != 2:
            raise ValueError(f"pixels must have shape (..., 2), got {tuple(shape)}")
        flat = pts.reshape(1, -1, 2)
        k = self.K[None]
        if any(self.dist):
            # Undistorted pixels of the same camera; kornia's fixed-point inverse,
            # iterated to float64 convergence.
            flat = undistort_points(flat, k, self._dist()[None], num_iters=_UNDISTORT_ITERATIONS)
        depth = torch.ones(flat.shape[:-1] + (1,), dtype=torch.float64)
        rays = unproject_points(flat, depth, k[:, None], normalize=True)
        return rays.reshape(shape[:-1] + (3,)).numpy()

    def ray_to_pixel(self, rays) -> np.ndarray:
        """Pixel positions of directions in the camera frame (the inverse of
        :meth:`pixel_to_ray`).

        Args:
            rays: ``(..., 3)`` directions (need not be unit; ``z > 0``).

        Returns:
            ``(..., 2)`` float64 NumPy pixel coordinates ``(u, v)``.
        """
        v = torch.as_tensor(np.asarray(rays, np.float64))
        shape = v.shape
        if shape[-1] != 3:
            raise ValueError(f"rays must have shape (..., 3), got {tuple(shape)}")
        flat = v.reshape(1, -1, 3)
        k = self.K[None]
        pix = project_points(flat, k[:, None])
        if any(self.dist):
            pix = distort_points(pix, k, self._dist()[None])
        return pix.reshape(shape[:-1] + (2,)).numpy()


def paper_camera(dist=(0.0, 0.0, 0.0, 0.0, 0.0)) -> Camera:
    """A sun-sensor camera like the sun-vector paper's: 1280 x 1024 pixels over a field
    of view of 23 x 17 deg (0.0182 deg per pixel across, 0.0167 down at the centre),
    principal point at the image centre."""
    return Camera.from_fov(1280, 1024, 23.0, 17.0, dist=dist)

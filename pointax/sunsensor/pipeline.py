"""Frames, encoder readings and sun directions -> observations for a pointing fit.

::

    frames  --centroid (torch, kornia)-->  pixels  --camera (kornia)-->  rays (NumPy)
    rays + sun directions  --camera_axis_target (JAX)-->  targets of the camera axis
    encoder readings + targets  -->  pointax.Observations  -->  pointax.fit

Arrays cross from torch to JAX once, as NumPy float64 rays, before any fit. Each frame
keeps its centroid status and reason; a frame that is not ``ok`` (or whose encoder
reading or sun direction is not finite) is left out of the observations, said so in
:meth:`SensorObservations.report`, and the others go on.

The observations are of the camera's optical axis: fit them with a model whose
boresight is the camera axis, i.e. the mount model plus
:class:`pointax.terms.camera.CameraMounting` (see that module for the reasoning and for
what is degenerate), or with the mount model alone to fold the camera's mounting into
the mount's terms.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..core.precision import float64
from ..core.observations import Observations
from ..terms.camera import camera_axis_target, camera_frame
from .camera import Camera
from .centroids import Centroids, centroid
from .frames import Detector, SyntheticFrames, synthetic_frames

__all__ = ["SensorObservations", "sensor_observations", "refine_targets", "camera_frames", "simulate_frames"]


@dataclasses.dataclass(frozen=True)
class SensorObservations:
    """Observations made from sun-sensor frames.

    Attributes:
        observations: :class:`pointax.Observations` of the camera axis, one per usable
            frame (``pointax.fit`` accepts this object directly).
        centroids: :class:`pointax.sunsensor.centroids.Centroids` of every frame.
        status, reason: per frame: the centroid's status, or ``bad_encoder`` /
            ``bad_sun`` for a non-finite reading or sun direction.
        used: ``(n,)`` bool: frames that became observations.
        index: ``(m,)`` frame index of each observation.
        encoder: ``(n, 2)`` raw readings, radians; sun: ``(n, 3)`` ENU sun directions.
        rays: ``(n, 3)`` the sun's direction in the camera frame (NaN where unusable).
    """

    observations: Observations
    centroids: Centroids
    status: tuple[str, ...]
    reason: tuple[str, ...]
    used: np.ndarray
    index: np.ndarray
    encoder: np.ndarray
    sun: np.ndarray
    rays: np.ndarray

    def __len__(self) -> int:
        return len(self.observations)

    def skipped(self) -> list[tuple[int, str, str]]:
        """``(frame index, status, reason)`` of every frame left out."""
        return [(i, s, r) for i, (s, r) in enumerate(zip(self.status, self.reason)) if s != "ok"]

    def report(self) -> str:
        """How many frames were used, and why each other one was not."""
        n = len(self.status)
        lines = [f"{int(self.used.sum())} of {n} frames used"]
        names = self.centroids.names
        for i, s, r in self.skipped():
            label = names[i] if names is not None else f"frame {i}"
            lines.append(f"  {label}: {s}: {r}")
        return "\n".join(lines)


def _check(array, shape_tail: tuple[int, ...], name: str, n: int | None) -> np.ndarray:
    array = np.asarray(array, np.float64)
    if array.ndim != 1 + len(shape_tail) or array.shape[1:] != shape_tail:
        raise ValueError(f"{name} must have shape (n, {', '.join(map(str, shape_tail))}), got {array.shape}")
    if n is not None and array.shape[0] != n:
        raise ValueError(f"{name} has {array.shape[0]} rows for {n} frames")
    return array


@float64
def sensor_observations(
    frames,
    encoder,
    sun,
    camera: Camera,
    *,
    convention: str | None = "turntable",
    names=None,
    frame=None,
    **centroid_options,
) -> SensorObservations:
    """Turn sun-sensor frames with their encoder readings and sun directions into
    observations of the camera axis.

    Args:
        frames: the frames (anything :func:`pointax.sunsensor.centroids.centroid` takes).
        encoder: ``(n, 2)`` raw readings at each frame, radians, in the mount's convention.
        sun: ``(n, 3)`` the sun's direction at each frame (East-North-Up unit vectors,
            e.g. :func:`pointax.sky.sun_direction`).
        camera: the sun sensor's :class:`~pointax.sunsensor.camera.Camera`.
        convention: the encoder convention of the observations ('turntable' default).
        names: optional frame names (file names) for messages.
        frame: optional ``(n, 3, 3)`` camera attitudes to place the offsets with
            (:func:`camera_frames` of a fitted model); default the nominal attitude.
        **centroid_options: passed to :func:`~pointax.sunsensor.centroids.centroid`
            (``method``, ``saturation``, thresholds); ``radius``, ``aspect`` and
            ``shape`` default to the camera's.

    Returns:
        :class:`SensorObservations`.
    """
    centroid_options.setdefault("radius", camera.sun_radius_px())
    centroid_options.setdefault("aspect", camera.aspect)
    centroid_options.setdefault("shape", camera.shape)
    found = centroid(frames, names=names, **centroid_options)
    n = len(found)
    encoder = _check(encoder, (2,), "encoder", n)
    sun = _check(sun, (3,), "sun", n)
    status, reason = list(found.status), list(found.reason)
    for i in range(n):
        if status[i] != "ok":
            continue
        if not np.all(np.isfinite(encoder[i])):
            status[i], reason[i] = "bad_encoder", f"encoder reading {encoder[i].tolist()} is not finite"
        elif not (np.all(np.isfinite(sun[i])) and abs(np.linalg.norm(sun[i]) - 1.0) < 1e-6):
            status[i], reason[i] = "bad_sun", f"sun direction {sun[i].tolist()} is not a finite unit vector"
    used = np.array([s == "ok" for s in status], bool)
    rays = np.full((n, 3), np.nan)
    if used.any():
        rays[used] = camera.pixel_to_ray(found.xy[used])  # torch (kornia) -> NumPy, once
    index = np.flatnonzero(used)
    if frame is None:
        target = camera_axis_target(jnp.asarray(sun[used]), jnp.asarray(rays[used]))
    else:
        frame = _check(frame, (3, 3), "frame", n)
        target = camera_axis_target(jnp.asarray(sun[used]), jnp.asarray(rays[used]), jnp.asarray(frame[used]))
    obs = Observations(encoder[used], np.asarray(target), convention=convention)
    return SensorObservations(obs, found, tuple(status), tuple(reason), used, index, encoder, sun, rays)


@eqx.filter_jit
def _camera_frames(model, encoder):
    return jax.vmap(lambda e: camera_frame(model, e))(encoder)


@float64
def camera_frames(model, encoder) -> np.ndarray:
    """``(n, 3, 3)`` camera attitudes (columns: image x, image y, axis in ENU) of
    ``model`` at raw readings ``encoder`` ``(n, 2)``
    (:func:`pointax.terms.camera.camera_frame`, batched, compiled)."""
    encoder = jnp.asarray(_check(encoder, (2,), "encoder", None))
    return np.asarray(_camera_frames(model, encoder))


@float64
def refine_targets(data: SensorObservations, model) -> SensorObservations:
    """The same observations with targets placed by ``model``'s camera attitude at
    each reading instead of the nominal one (removes the second-order roll error; see
    :mod:`pointax.terms.camera`). Typically: fit, refine with the fitted model, refit."""
    frames = camera_frames(model, data.encoder[data.used])
    target = camera_axis_target(
        jnp.asarray(data.sun[data.used]), jnp.asarray(data.rays[data.used]), jnp.asarray(frames)
    )
    obs = Observations(data.observations.encoder, np.asarray(target), data.observations.weight, data.observations.convention)
    return dataclasses.replace(data, observations=obs)


def simulate_frames(model, camera: Camera, encoder, sun, **frame_options) -> SyntheticFrames:
    """Synthetic frames of the sun seen by a camera on a mount: where ``model`` (the
    truth, with its :class:`~pointax.terms.camera.CameraMounting`) and ``camera`` put
    the sun at each raw reading.

    Args:
        model: the true :class:`pointax.Model` of the camera axis.
        camera: the true :class:`~pointax.sunsensor.camera.Camera`.
        encoder: ``(n, 2)`` true raw readings, radians.
        sun: ``(n, 3)`` true sun directions (ENU).
        **frame_options: passed to :func:`~pointax.sunsensor.frames.synthetic_frames`
            (``level``, ``cloud``, ``hot_pixels``, ``seed`` ...; ``radius`` and
            ``aspect`` default to the camera's).

    Returns:
        :class:`~pointax.sunsensor.frames.SyntheticFrames` with the true sun centres.
    """
    sun = _check(sun, (3,), "sun", None)
    attitude = camera_frames(model, encoder)
    rays = np.einsum("nji,nj->ni", attitude, sun)  # A^T S
    pixels = camera.ray_to_pixel(rays)
    frame_options.setdefault("radius", camera.sun_radius_px())
    frame_options.setdefault("aspect", camera.aspect)
    frame_options.setdefault("detector", Detector(width=camera.width, height=camera.height))
    return synthetic_frames(pixels[:, 0], pixels[:, 1], **frame_options)

"""Sun-sensor images: synthetic frames, centroids, camera geometry, observations.

An edge of pointax built on torch and kornia (the JAX core never imports it):

* :mod:`~pointax.sunsensor.frames`: synthetic frames of the limb-darkened sun with an
  exact centre (a camera like the sun-vector paper's, noise, saturation, hot pixels,
  clipping, thin cloud).
* :mod:`~pointax.sunsensor.centroids`: batched intensity centroids and limb fits with a
  status and reason per frame.
* :mod:`~pointax.sunsensor.camera`: intrinsics and radial distortion through kornia,
  pixels <-> unit rays in the camera frame.
* :mod:`~pointax.sunsensor.pipeline`: frames + encoder readings + sun directions ->
  :class:`pointax.Observations` of the camera axis (see
  :mod:`pointax.terms.camera` for the camera's mounting term).
* :mod:`~pointax.sunsensor.imageio`, :mod:`pointax.cli.centroid`: PNG / FITS / .npy
  frames and ``pointax centroid``.

    from pointax.sunsensor import paper_camera, centroid, sensor_observations
    cam = paper_camera()
    found = centroid(frames, radius=cam.sun_radius_px(), aspect=cam.aspect, saturation=4095)
    data = sensor_observations(frames, readings, sun_enu, cam, saturation=4095)
    result = px.fit(model_with_camera_term, data)
"""

from ..core.lazy import lazy_namespace

# Names -> submodule. Loaded on first use (PEP 562), so that importing
# pointax.cli.centroid (for the ``pointax`` command's parser) does not import torch.
_EXPORTS = {
    "Camera": "camera",
    "paper_camera": "camera",
    "METHODS": "centroids",
    "STATUSES": "centroids",
    "Centroids": "centroids",
    "centroid": "centroids",
    "check_frame": "centroids",
    "PAPER_ASPECT": "frames",
    "PAPER_SUN_RADIUS_PX": "frames",
    "SUN_ANGULAR_RADIUS": "frames",
    "Detector": "frames",
    "SyntheticFrames": "frames",
    "disk_flux": "frames",
    "render_disk": "frames",
    "synthetic_frames": "frames",
    "FrameReadError": "imageio",
    "read_frame": "imageio",
    "SensorObservations": "pipeline",
    "camera_frames": "pipeline",
    "refine_targets": "pipeline",
    "sensor_observations": "pipeline",
    "simulate_frames": "pipeline",
}

__all__ = sorted(_EXPORTS)

VISION_INSTALL = "pip install 'pointax[vision]'"
"""The install line of the optional extra this package needs (torch, kornia, pillow)."""


def require_vision() -> None:
    """Import torch and kornia, or raise ImportError saying how to install them
    (:data:`VISION_INSTALL`), as :func:`pointax.plots._mpl.require_matplotlib` does for
    matplotlib."""
    missing = []
    for name in ("torch", "kornia"):
        try:
            __import__(name)
        except ImportError:
            missing.append(name)
    if missing:
        raise ImportError(
            f"pointax's sun-sensor images need {' and '.join(missing)}, part of an optional extra: {VISION_INSTALL}"
        )


__getattr__, __dir__ = lazy_namespace(__name__, _EXPORTS)

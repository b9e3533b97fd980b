"""Frames + encoder readings + sun directions -> observations of the camera axis:
targets against the true camera axis, bad frames skipped with reasons, a fit that
recovers the truth."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("kornia")

import pointax as px  # noqa: E402
from pointax.sunsensor import (  # noqa: E402
    Camera,
    camera_frames,
    refine_targets,
    sensor_observations,
    simulate_frames,
)
from pointax.terms.camera import CameraMounting, camera_frame  # noqa: E402

PAPER = {"mu0": 0.0751, "nu0": 0.0145, "omega0": -0.0947, "alpha0": 60.5425, "beta0": 165.8931}
CAMERA = Camera.from_fov(1280, 1024, 23.0, 17.0, cx=611.3, cy=530.8, dist=(-0.08, 0.01, 0.0, 0.0, 0.0))
ARCSEC = math.pi / 180 / 3600


def truth_model(cross=0.04, up=0.03, roll=0.3):
    terms = list(px.terms.turntable("full")) + [CameraMounting(px.deg(cross), px.deg(up), px.deg(roll))]
    return px.Turntable(terms).set(**{k: px.deg(v) for k, v in PAPER.items()})


def scene(n, seed=0, max_offset_deg=1.0):
    """Readings over a day-like spread, and the sun at a random offset (up to
    ``max_offset_deg``) from the true camera axis at each."""
    rng = np.random.default_rng(seed)
    truth = truth_model()
    alpha = np.radians(PAPER["alpha0"]) + np.radians(rng.uniform(100, 260, n))
    beta = np.radians(PAPER["beta0"]) + np.radians(rng.uniform(15, 75, n))
    reading = np.column_stack([alpha, beta])
    attitude = camera_frames(truth, reading)
    offset = np.tan(np.radians(rng.uniform(-max_offset_deg, max_offset_deg, (n, 2))))
    ray = np.column_stack([offset, np.ones(n)])
    ray /= np.linalg.norm(ray, axis=1, keepdims=True)
    sun = np.einsum("nij,nj->ni", attitude, ray)
    return truth, reading, sun


def angle(a, b):
    return np.arccos(np.clip(np.sum(np.asarray(a) * np.asarray(b), axis=-1), -1.0, 1.0))


def test_targets_are_where_the_true_camera_axis_points():
    truth, reading, sun = scene(10, seed=1)
    frames = simulate_frames(truth, CAMERA, reading, sun, seed=2)
    data = sensor_observations(frames.images, reading, sun, CAMERA, saturation=4095)
    assert data.used.all() and len(data) == 10
    np.testing.assert_allclose(data.centroids.xy, np.column_stack([frames.x, frames.y]), atol=0.02)
    axis = np.asarray(truth(reading))
    # Nominal attitude: centroid noise (~0.006 px = 0.4") plus the roll of the camera
    # (0.3 deg + the tilts) times the offset (<= 1.4 deg): a few arcsec.
    assert angle(data.observations.target, axis).max() < 30 * ARCSEC
    # With the true attitude only the centroid noise is left.
    refined = refine_targets(data, truth)
    assert angle(refined.observations.target, axis).max() < 1 * ARCSEC
    np.testing.assert_array_equal(refined.observations.encoder, reading)
    assert isinstance(data.rays, np.ndarray) and data.rays.dtype == np.float64


def test_bad_frames_are_skipped_with_reasons_and_the_rest_go_on():
    truth, reading, sun = scene(6, seed=3, max_offset_deg=0.5)
    images = list(simulate_frames(truth, CAMERA, reading, sun, seed=4).images)
    images[1] = np.zeros((1024, 1280), np.uint16) + 40  # no sun
    images[2] = images[2][:, :640]  # wrong shape
    reading[3] = [np.nan, 1.0]  # no encoder reading
    sun[4] = [0.0, 0.0, 2.0]  # not a unit vector
    data = sensor_observations(images, reading, sun, CAMERA, saturation=4095, names=[f"f{i}.png" for i in range(6)])
    assert data.status == ("ok", "no_sun", "bad_input", "bad_encoder", "bad_sun", "ok")
    np.testing.assert_array_equal(data.index, [0, 5])
    assert len(data.observations) == 2
    np.testing.assert_array_equal(data.observations.encoder, reading[[0, 5]])
    report = data.report()
    assert report.startswith("2 of 6 frames used")
    for name, word in [("f1.png", "no_sun"), ("f2.png", "bad_input"), ("f3.png", "bad_encoder"), ("f4.png", "bad_sun")]:
        assert f"{name}: {word}" in report
    assert np.isnan(data.rays[1]).all() and np.isfinite(data.rays[[0, 5]]).all()


def test_fit_of_the_observations_recovers_the_camera_axis_model():
    truth, reading, sun = scene(24, seed=5)
    data = sensor_observations(simulate_frames(truth, CAMERA, reading, sun, seed=6).images, reading, sun, CAMERA, saturation=4095)
    model = px.Turntable(list(px.terms.turntable("full")) + [CameraMounting()], fixed=["camera.up"], start=data.observations)
    result = px.fit(model, refine_targets(data, truth))
    assert result.converged
    # camera.up is absorbed by beta0 exactly; the rest comes back.
    assert result.value("beta0", "deg") == pytest.approx(PAPER["beta0"] - 0.03, abs=2e-4)
    for name in ("mu0", "nu0", "omega0", "alpha0"):
        assert result.value(name, "deg") == pytest.approx(PAPER[name], abs=max(3 * result.sigma(name, "deg"), 2e-4))
    assert result.value("camera.cross", "deg") == pytest.approx(0.04, abs=max(3 * result.sigma("camera.cross", "deg"), 2e-4))
    assert float(result.sky_rms) < 2 * ARCSEC
    # The fitted camera attitude: the truth's, up to the unobservable up/beta0 trade.
    fitted = np.asarray(jax.vmap(lambda e: camera_frame(result.model, e))(jnp.asarray(reading)))
    assert angle(fitted[:, :, 2], np.asarray(truth(reading))).max() < 5 * ARCSEC


def test_bad_arguments_name_the_field():
    truth, reading, sun = scene(2, seed=7)
    images = simulate_frames(truth, CAMERA, reading, sun, seed=8).images
    with pytest.raises(ValueError, match="encoder"):
        sensor_observations(images, reading[:, :1], sun, CAMERA)
    with pytest.raises(ValueError, match="sun has 1 rows for 2 frames"):
        sensor_observations(images, reading, sun[:1], CAMERA)

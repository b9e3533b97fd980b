"""Camera geometry against an independent NumPy pinhole with radial distortion, and
the camera's mounting term against the paper's rotation chain written out in NumPy."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from numpy_rotations import Rx, Ry, Rz
from scipy.optimize import least_squares

import pointax as px
from pointax.terms.camera import (
    CameraMounting,
    camera_axes,
    camera_axis_target,
    camera_frame,
    rotation_between,
)

DIST = (-0.21, 0.08, 4e-4, -3e-4, -0.02)  # k1 k2 p1 p2 k3: a strongly distorting lens


# ----------------------------------------------------------- independent NumPy camera


def np_distort(x, y, dist):
    """OpenCV's distortion of normalised coordinates, written out."""
    k1, k2, p1, p2, k3 = dist
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    return x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x), y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y


def np_project(ray, fx, fy, cx, cy, dist):
    x, y = ray[..., 0] / ray[..., 2], ray[..., 1] / ray[..., 2]
    xd, yd = np_distort(x, y, dist)
    return np.stack([fx * xd + cx, fy * yd + cy], axis=-1)


def np_unproject(pixel, fx, fy, cx, cy, dist):
    """Pixel -> unit ray by solving the distortion with scipy (not kornia's iteration)."""
    out = []
    for u, v in np.atleast_2d(pixel):
        xd, yd = (u - cx) / fx, (v - cy) / fy
        sol = least_squares(lambda p: np.subtract(np_distort(p[0], p[1], dist), (xd, yd)), [xd, yd], xtol=1e-15, ftol=1e-15, gtol=1e-15)
        ray = np.array([sol.x[0], sol.x[1], 1.0])
        out.append(ray / np.linalg.norm(ray))
    return np.array(out)


@pytest.fixture(scope="module")
def sensor():
    pytest.importorskip("torch")
    pytest.importorskip("kornia")
    from pointax.sunsensor.camera import Camera, paper_camera

    return Camera, paper_camera


def test_paper_camera_field_of_view_and_pixel_scale(sensor):
    _, paper_camera = sensor
    cam = paper_camera()
    assert cam.shape == (1024, 1280)
    # The rays through the outer edges of the outer pixels span 23 x 17 deg.
    left, right = cam.pixel_to_ray([[-0.5, cam.cy], [1279.5, cam.cy]])
    top, bottom = cam.pixel_to_ray([[cam.cx, -0.5], [cam.cx, 1023.5]])
    assert math.degrees(math.acos(left @ right)) == pytest.approx(23.0, abs=1e-9)
    assert math.degrees(math.acos(top @ bottom)) == pytest.approx(17.0, abs=1e-9)
    # The paper's angular resolution: 0.018 deg across, 0.016-0.017 deg down.
    sx, sy = cam.pixel_scale_deg
    assert sx == pytest.approx(0.018, abs=3e-4) and sy == pytest.approx(0.0167, abs=3e-4)
    assert 2 * cam.sun_radius_px() == pytest.approx(0.53 / sx, rel=1e-3)


def test_pixel_to_ray_and_back_against_numpy(sensor):
    Camera, _ = sensor
    cam = Camera(1280, 1024, fx=3100.0, fy=3350.0, cx=631.7, cy=519.2, dist=DIST)
    rng = np.random.default_rng(0)
    pixels = np.column_stack([rng.uniform(-0.5, 1279.5, 40), rng.uniform(-0.5, 1023.5, 40)])
    rays = cam.pixel_to_ray(pixels)
    want = np_unproject(pixels, cam.fx, cam.fy, cam.cx, cam.cy, DIST)
    np.testing.assert_allclose(rays, want, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(rays, axis=1), 1.0, atol=1e-14)
    # Forward: kornia's projection and distortion against the NumPy formula.
    np.testing.assert_allclose(cam.ray_to_pixel(rays), np_project(rays, cam.fx, cam.fy, cam.cx, cam.cy, DIST), atol=1e-9)
    np.testing.assert_allclose(cam.ray_to_pixel(rays), pixels, atol=1e-8)
    # Shapes: any leading dimensions; the principal point is the optical axis.
    assert cam.pixel_to_ray(pixels.reshape(4, 10, 2)).shape == (4, 10, 3)
    np.testing.assert_allclose(cam.pixel_to_ray([cam.cx, cam.cy]), [0, 0, 1], atol=1e-15)


def test_kornia_pinhole_camera_is_the_same_camera(sensor):
    import torch

    Camera, _ = sensor
    cam = Camera(1280, 1024, fx=3100.0, fy=3350.0, cx=631.7, cy=519.2)
    points = np.array([[0.1, -0.05, 1.0], [-0.02, 0.07, 2.0]])
    got = cam.pinhole().project(torch.as_tensor(points)).numpy()
    np.testing.assert_allclose(got, np_project(points, cam.fx, cam.fy, cam.cx, cam.cy, (0, 0, 0, 0, 0)), atol=1e-9)


def test_camera_rejects_bad_parameters(sensor):
    Camera, _ = sensor
    with pytest.raises(ValueError, match="focal"):
        Camera(10, 10, fx=-1.0, fy=1.0, cx=0.0, cy=0.0)
    with pytest.raises(ValueError, match="5 coefficients"):
        Camera(10, 10, fx=1.0, fy=1.0, cx=0.0, cy=0.0, dist=(0.1,))


# ----------------------------------------------------------- the mounting term (pure JAX)


# Camera axes in the turntable's frame at zero: x East, y down (-Up), z North.
M = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])
PAPER = dict(mu0=0.0751, nu0=0.0145, omega0=-0.0947, alpha0=60.5425, beta0=165.8931)


def np_attitude(p, cross, up, roll, alpha, beta):
    """Camera-to-ENU: the paper's chain Rx(mu0) Ry(nu0) Rz'(alpha0 - alpha) Ry(omega0)
    Rx(beta - beta0) followed by the mounting Rz(-cross) Rx(up) Ry(roll) and M."""
    mu0, nu0, omega0, alpha0, beta0 = (math.radians(p[k]) for k in ("mu0", "nu0", "omega0", "alpha0", "beta0"))
    chain = Rx(mu0) @ Ry(nu0) @ Rz(alpha - alpha0) @ Ry(omega0) @ Rx(beta - beta0)
    return chain @ Rz(-cross) @ Rx(up) @ Ry(roll) @ M


def model_with_camera(cross, up, roll=0.0):
    terms = list(px.terms.turntable("full")) + [CameraMounting(cross=cross, up=up, roll=roll)]
    return px.Turntable(terms).set(**{k: px.deg(v) for k, v in PAPER.items()})


def test_camera_frame_is_the_paper_chain_with_the_mounting():
    cross, up, roll = 1e-3, -7e-4, 0.02
    model = model_with_camera(cross, up, roll)
    readings = jnp.array([(4.9, 3.8), (4.7, 3.6), (3.4, 3.7)])
    got = np.asarray(jax.jit(jax.vmap(lambda e: camera_frame(model, e)))(readings))
    # The model's direction (its boresight) is the camera axis: the third column.
    axis = np.asarray(model(readings))
    for k, (alpha, beta) in enumerate(np.asarray(readings)):
        np.testing.assert_allclose(got[k], np_attitude(PAPER, cross, up, roll, alpha, beta), atol=1e-14)
        np.testing.assert_allclose(axis[k], got[k][:, 2], atol=1e-14)
    np.testing.assert_allclose(np.asarray(camera_axes(jnp.array([0.0, 1.0, 0.0]))), M, atol=0)


def test_camera_up_tilt_is_exactly_a_pitch_zero():
    readings = jnp.array([[4.9, 3.8], [4.7, 3.6], [3.4, 3.7]])
    with_up = model_with_camera(0.0, px.deg(0.03))
    shifted = model_with_camera(0.0, 0.0).set(beta0=px.deg(PAPER["beta0"] - 0.03))
    np.testing.assert_allclose(np.asarray(with_up(readings)), np.asarray(shifted(readings)), atol=1e-15)
    assert with_up.parameter_names[-2:] == ["camera.cross", "camera.up"]


def sun_at(attitude, offset_px):
    """The sun direction that a camera with this attitude sees at a given offset from
    its axis (normalised image coordinates)."""
    ray = np.array([offset_px[0], offset_px[1], 1.0])
    ray /= np.linalg.norm(ray)
    return attitude @ ray, ray


def test_camera_axis_target_nominal_is_exact_for_a_level_unrolled_camera():
    rng = np.random.default_rng(1)
    level = dict(mu0=0.0, nu0=0.0, omega0=0.0, alpha0=60.5425, beta0=165.8931)
    suns, rays, axes = [], [], []
    for _ in range(20):
        alpha, beta = rng.uniform(0, 2 * np.pi), math.radians(165.8931) + rng.uniform(0.1, 1.4)
        attitude = np_attitude(level, 0.0, 0.0, 0.0, alpha, beta)
        s, r = sun_at(attitude, rng.uniform(-0.15, 0.15, 2))  # up to 8.5 deg off the axis
        suns.append(s), rays.append(r), axes.append(attitude[:, 2])
    target = np.asarray(camera_axis_target(np.array(suns), np.array(rays)))
    np.testing.assert_allclose(target, np.array(axes), atol=1e-13)


def test_camera_axis_target_with_the_attitude_is_exact_and_nominal_errs_to_second_order():
    rng = np.random.default_rng(2)
    cross, up, roll = px.deg(0.05), px.deg(0.03), px.deg(0.5)
    model = model_with_camera(cross, up, roll)
    readings = np.column_stack([rng.uniform(3.2, 5.2, 12), math.radians(165.8931) + rng.uniform(0.3, 1.2, 12)])
    frames = np.stack([np_attitude(PAPER, cross, up, roll, a, b) for a, b in readings])
    for size in (0.002, 0.02):
        suns, rays = zip(*(sun_at(f, rng.uniform(-size, size, 2)) for f in frames))
        suns, rays = np.array(suns), np.array(rays)
        exact = np.asarray(camera_axis_target(suns, rays, frames))
        np.testing.assert_allclose(exact, frames[:, :, 2], atol=1e-13)
        model_frames = np.asarray(jax.vmap(lambda e: camera_frame(model, e))(jnp.asarray(readings)))
        np.testing.assert_allclose(np.asarray(camera_axis_target(suns, rays, model_frames)), frames[:, :, 2], atol=1e-13)
        # Nominal attitude: wrong by (roll error ~0.5 deg) x (offset), second order.
        nominal = np.asarray(camera_axis_target(suns, rays))
        err = np.arccos(np.clip(np.sum(nominal * frames[:, :, 2], axis=1), -1, 1))
        assert err.max() < 0.02 * size * math.sqrt(2), (size, err.max())


def test_camera_axis_target_is_differentiable():
    sun = jnp.array([[0.3, -0.5, 0.81]]) / jnp.linalg.norm(jnp.array([0.3, -0.5, 0.81]))

    def f(offset):
        ray = jnp.array([offset, 0.01, 1.0])
        return camera_axis_target(sun, (ray / jnp.linalg.norm(ray))[None])[0, 0]

    grad = jax.jit(jax.grad(f))(0.02)
    h = 1e-6
    value = jax.jit(f)
    assert float(grad) == pytest.approx((float(value(0.02 + h)) - float(value(0.02 - h))) / (2 * h), rel=1e-6)


def test_rotation_between():
    a = np.array([0.3, 0.4, np.sqrt(0.75)])
    b = np.array([0.0, 0.6, 0.8])
    r = np.asarray(rotation_between(a, b))
    np.testing.assert_allclose(r @ a, b, atol=1e-15)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(np.asarray(rotation_between(a, a)), np.eye(3), atol=1e-15)


def test_camera_frame_refuses_sky_offset_terms():
    model = px.AltAz(px.terms.tpoint("IA IE CA", form="linear"))
    with pytest.raises(ValueError, match="sky offsets"):
        camera_frame(model, jnp.array([0.1, 0.5]))
    # The same terms in the rigorous form (the default) are rotations: they have an attitude.
    rigorous = px.AltAz(px.terms.tpoint("IA IE CA", values={"IA": 1e-3, "IE": -2e-3, "CA": 5e-4}))
    reading = jnp.array([0.1, 0.5])
    frame = np.asarray(camera_frame(rigorous, reading))
    np.testing.assert_allclose(frame[:, 2], np.asarray(rigorous(reading[None]))[0], atol=1e-14)

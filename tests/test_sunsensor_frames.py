"""Synthetic sun-sensor frames: pixel integrals against scipy, fluxes and moments
against closed forms, the detector model against its definition."""

from __future__ import annotations

import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("kornia")

from scipy.integrate import quad  # noqa: E402

from pointax.sunsensor.frames import (  # noqa: E402
    PAPER_ASPECT,
    PAPER_SUN_RADIUS_PX,
    Detector,
    disk_flux,
    render_disk,
    synthetic_frames,
)


def intensity(x, y, x0, y0, radius, aspect, u1, u2):
    """Quadratic limb darkening, centre intensity 1 (independent of the renderer)."""
    rho2 = ((x - x0) ** 2 + ((y - y0) / aspect) ** 2) / radius**2
    if rho2 >= 1.0:
        return 0.0
    mu = math.sqrt(1.0 - rho2)
    return 1.0 - u1 * (1.0 - mu) - u2 * (1.0 - mu) ** 2


def pixel_integral(i, j, x0, y0, radius, aspect, u1, u2):
    """The intensity integrated over pixel (row i, column j) with nested scipy quad."""

    def row(y):
        dy = (y - y0) / aspect
        if abs(dy) >= radius:
            return 0.0
        c = math.sqrt(radius**2 - dy**2)
        a, b = max(j - 0.5, x0 - c), min(j + 0.5, x0 + c)
        if a >= b:
            return 0.0
        return quad(lambda x: intensity(x, y, x0, y0, radius, aspect, u1, u2), a, b, epsabs=1e-13, epsrel=1e-13)[0]

    return quad(row, i - 0.5, i + 0.5, epsabs=1e-12, epsrel=1e-12, limit=200)[0]


def test_pixel_integrals_match_scipy_quadrature():
    x0, y0, radius, aspect, u1, u2 = 0.37, -0.21, 9.3, 1.2, 0.6, 0.1
    window, col0, row0 = render_disk(
        torch.tensor([x0]), torch.tensor([y0]), torch.tensor([radius]), aspect, (u1, u2), size=29, subrows=128
    )
    # Interior, limb and near-limb pixels on every side.
    for i, j in [(0, 0), (-10, 0), (0, 9), (0, -9), (7, 6), (-7, -6), (9, 3), (5, -8), (-3, 8)]:
        want = pixel_integral(i, j, x0, y0, radius, aspect, u1, u2)
        got = float(window[0, i - int(row0[0]), j - int(col0[0])])
        assert abs(got - want) < 1e-6, (i, j, got, want)
    # The pixels holding the top and bottom tips of the disk (a sqrt singularity in y)
    # are the least exact: still within 2e-4 of a pixel's full flux.
    for i, j in [(11, 0), (-11, 2)]:
        want = pixel_integral(i, j, x0, y0, radius, aspect, u1, u2)
        got = float(window[0, i - int(row0[0]), j - int(col0[0])])
        assert abs(got - want) < 2e-4, (i, j, got, want)


@pytest.mark.parametrize("limb", [0.0, (0.6, 0.0), (0.4, 0.2)])
def test_total_flux_is_the_closed_form(limb):
    # pi R^2 aspect (A0 + 2 A1 / 3 + A2 / 2) for I = A0 + A1 mu + A2 mu^2.
    u1, u2 = (limb, 0.0) if np.ndim(limb) == 0 else limb
    closed = math.pi * 14.2**2 * 1.09 * ((1 - u1 - u2) + 2 * (u1 + 2 * u2) / 3 - u2 / 2)
    assert disk_flux(14.2, 1.09, limb) == pytest.approx(closed, rel=1e-14)
    window, _, _ = render_disk(torch.tensor([3.3, -0.71]), torch.tensor([0.45, 2.0]), torch.tensor([14.2]), 1.09, limb, size=37)
    np.testing.assert_allclose(window.sum(dim=(1, 2)).numpy(), closed, rtol=2e-6)


def test_clipped_uniform_disk_flux_is_the_circular_segment():
    # A uniform disk centred x0 from the frame's left edge (x = -0.5): the visible area
    # is aspect (R^2 acos(d / R) - d sqrt(R^2 - d^2)), d = -0.5 - x0.
    radius, aspect = 14.5, 1.09
    for x0 in (3.3, -2.7, 8.1):
        f = synthetic_frames([x0], [500.4], radius=radius, aspect=aspect, limb=0.0, noise=False, keep_expected=True, sky=0.0)
        flux = (f.expected[0] - f.detector.bias).sum() / (0.7 * f.detector.full_scale - 0.7 * f.detector.bias)
        d = -0.5 - x0
        area = aspect * (radius**2 * math.acos(d / radius) - d * math.sqrt(radius**2 - d**2))
        assert flux == pytest.approx(area, rel=2e-6)
        assert f.visible[0] < 1.0


def moments(image):
    h, w = image.shape
    total = image.sum()
    return (image * np.arange(w)[None, :]).sum() / total, (image * np.arange(h)[:, None]).sum() / total


def test_ground_truth_centre_to_1e4_px():
    """The noise-free disk's first moment is the true centre up to the pixelisation of
    a sharp disk (< 3e-4 px, a property of pixel-centre moments), and the rendering's
    own error on the moments is < 2e-5 px (128 sub-rows against 1024)."""
    rng = np.random.default_rng(4)
    x = torch.as_tensor(rng.uniform(300, 900, 3))
    y = torch.as_tensor(rng.uniform(300, 700, 3))
    r = torch.tensor([PAPER_SUN_RADIUS_PX])
    coarse, col0, row0 = render_disk(x, y, r, PAPER_ASPECT, size=39, subrows=128)
    fine, _, _ = render_disk(x, y, r, PAPER_ASPECT, size=39, subrows=1024)
    for k in range(3):
        mc = moments(coarse[k].numpy())
        mf = moments(fine[k].numpy())
        assert abs(mc[0] - mf[0]) < 2e-5 and abs(mc[1] - mf[1]) < 2e-5
        assert abs(mc[0] + int(col0[k]) - float(x[k])) < 3e-4
        assert abs(mc[1] + int(row0[k]) - float(y[k])) < 3e-4
    # The frame holds the same disk: its moment (background removed) is the window's.
    f = synthetic_frames(x.numpy()[:1], y.numpy()[:1], noise=False, keep_expected=True, sky=0.0)
    mx, my = moments(f.expected[0] - f.detector.bias)
    assert abs(mx - float(x[0])) < 3e-4 and abs(my - float(y[0])) < 3e-4


def test_paper_camera_sun_size():
    # 0.53 deg across a 23 deg, 1280 px field: about 29.1 px across (14.5 px radius).
    assert PAPER_SUN_RADIUS_PX == pytest.approx(640 / math.tan(math.radians(11.5)) * math.tan(math.radians(0.265)))
    assert 2 * PAPER_SUN_RADIUS_PX == pytest.approx(29.1, abs=0.1)
    assert PAPER_ASPECT == pytest.approx((math.tan(math.radians(11.5)) / 640) / (math.tan(math.radians(8.5)) / 512))


def test_detector_noise_levels_and_saturation():
    det = Detector()
    f = synthetic_frames([640.0], [512.0], level=0.7, sky=20.0, seed=3)
    img = f.images[0].astype(float)
    assert f.images.dtype == np.uint16 and f.images.shape == (1, 1024, 1280)
    background = img[:400, :400]
    # Mean: bias + sky / gain; noise: sqrt(sky + read^2) / gain (and +1/12 ADU^2 rounding).
    assert background.mean() == pytest.approx(det.bias + 20.0 / det.gain, abs=0.05)
    assert background.std() == pytest.approx(math.sqrt((20.0 + det.read_noise**2) / det.gain**2 + 1 / 12), rel=0.02)
    # The disk centre: level of full scale above the bias (limb darkening is 1 there).
    centre = img[510:515, 638:643].mean()
    want = det.bias + (0.7 * (det.full_scale - det.bias) * det.gain + 20.0) / det.gain
    assert centre == pytest.approx(want, rel=0.01)
    sat = synthetic_frames([640.0], [512.0], level=3.0, seed=3)
    assert sat.images.max() == det.full_scale
    assert (sat.images[0] == det.full_scale).sum() > 500


def test_hot_pixels_and_eight_bit_frames():
    f = synthetic_frames([640.0], [512.0], hot_pixels=30, seed=5)
    clean = synthetic_frames([640.0], [512.0], hot_pixels=0, seed=5)
    assert np.sum(f.images[0].astype(int) - clean.images[0].astype(int) >= 250) >= 28
    eight = synthetic_frames([100.0], [100.0], detector=Detector(bits=8, gain=40.0, read_noise=8.0, bias=2.0))
    assert eight.images.dtype == np.uint8 and eight.images.max() <= 255


def test_thin_cloud_dims_the_disk_and_adds_an_aureole():
    clear = synthetic_frames([640.0], [512.0], noise=False, keep_expected=True)
    cloudy = synthetic_frames([640.0], [512.0], cloud=1.0, noise=False, keep_expected=True)
    bias_sky = clear.detector.bias + 20.0 / clear.detector.gain
    disk_clear = clear.expected[0, 512, 640] - bias_sky
    ring = cloudy.expected[0, 512, 640 + 25] - bias_sky  # outside the disk: aureole + haze
    assert ring > 0.01 * disk_clear
    # The disk centre: exp(-1) of the clear disk, plus the aureole's and haze's share.
    disk_cloudy = cloudy.expected[0, 512, 640] - bias_sky
    assert math.exp(-1) * disk_clear < disk_cloudy < (math.exp(-1) + 0.1) * disk_clear


def test_clipped_sun_and_visible_fraction():
    f = synthetic_frames([-0.5, 640.0], [512.0, -0.5], noise=False)
    # A centre on the edge: half the limb inside the frame.
    np.testing.assert_allclose(f.visible, [0.5, 0.5], atol=0.01)
    assert f.images[0, 512, :3].min() > 1000 and f.images[1, :3, 640].min() > 1000


def test_bad_arguments_raise():
    with pytest.raises(ValueError, match="radius"):
        synthetic_frames([1.0], [1.0], radius=-1.0)
    with pytest.raises(ValueError, match="finite"):
        synthetic_frames([np.nan], [1.0])

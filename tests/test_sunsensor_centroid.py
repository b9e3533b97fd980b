"""Sun centroids: accuracy against the frames' known truth, an independent NumPy
moment, and a status with a reason for every kind of bad frame."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("kornia")

from pointax.sunsensor.centroids import STATUSES, centroid  # noqa: E402
from pointax.sunsensor.frames import PAPER_ASPECT, PAPER_SUN_RADIUS_PX, synthetic_frames  # noqa: E402

R = PAPER_SUN_RADIUS_PX
OPTIONS = dict(aspect=PAPER_ASPECT, saturation=4095)


def rms(found, frames):
    err = found - np.stack([frames.x, frames.y], axis=1)
    return float(np.sqrt(np.mean(np.sum(err**2, axis=1))))


@pytest.fixture(scope="module")
def realistic():
    """Unclipped frames at realistic noise, a few hot pixels each, sun anywhere."""
    rng = np.random.default_rng(11)
    x, y = rng.uniform(60, 1220, 24), rng.uniform(60, 964, 24)
    frames = synthetic_frames(x, y, hot_pixels=20, seed=12)
    return frames, centroid(frames.images, **OPTIONS)


def test_unclipped_frames_within_the_required_0_05_px(realistic):
    frames, found = realistic
    assert found.status == ("ok",) * len(frames)
    assert found.method == ("intensity",) * len(frames)
    # The issue asks for <= 0.05 px RMS; the noise limit here is about 0.006 px.
    assert rms(found.xy, frames) < 0.02
    assert rms(found.limb, frames) < 0.02
    # The radius is that of the edge-level contour: within 0.15 px of the limb.
    np.testing.assert_allclose(found.radius, R, atol=0.15)


def test_intensity_centroid_equals_an_independent_numpy_moment():
    # Noise-free frames: the background is exactly bias + sky / gain = 42 ADU, so the
    # plain first moment of (frame - 42) over the whole frame is the reference.
    frames = synthetic_frames([321.37, 877.81], [200.52, 765.09], noise=False)
    found = centroid(frames.images, **OPTIONS)
    for k in range(2):
        img = frames.images[k].astype(float) - 42.0
        h, w = img.shape
        ref = ((img * np.arange(w)).sum() / img.sum(), (img * np.arange(h)[:, None]).sum() / img.sum())
        np.testing.assert_allclose(found.intensity[k], ref, atol=1e-6)
        # ... and both are the truth up to the sharp disk's pixelisation (< 3e-4 px).
        np.testing.assert_allclose(found.intensity[k], [frames.x[k], frames.y[k]], atol=3e-4)


def test_clipped_frames_use_the_limb_fit():
    rng = np.random.default_rng(3)
    # Centres 0.3 R to 0.8 R inside the left edge: 60-80 % of the limb in the frame.
    frames = synthetic_frames(rng.uniform(-0.5 + 0.3 * R, -0.5 + 0.8 * R, 16), rng.uniform(100, 900, 16), seed=4)
    found = centroid(frames.images, **OPTIONS)
    assert found.status == ("ok",) * 16 and found.method == ("limb",) * 16
    assert rms(found.xy, frames) < 0.05
    # The intensity centroid of a clipped disk is biased towards the frame's interior.
    assert np.all(found.intensity[:, 0] > frames.x + 0.5)
    # Forcing the intensity centroid on a clipped disk is refused, not answered wrongly.
    forced = centroid(frames.images[:2], method="intensity", **OPTIONS)
    assert forced.status == ("clipped", "clipped") and np.all(np.isnan(forced.x))
    assert "intensity centroid would be biased" in forced.reason[0]


def test_saturated_disks():
    rng = np.random.default_rng(8)
    frames = synthetic_frames(rng.uniform(100, 1100, 12), rng.uniform(100, 900, 12), level=3.0, seed=9)
    found = centroid(frames.images, **OPTIONS)
    assert found.status == ("ok",) * 12
    assert rms(found.intensity, frames) < 0.05 and rms(found.limb, frames) < 0.05


def test_thin_cloud_and_eight_bit_and_aspect_one():
    rng = np.random.default_rng(5)
    x, y = rng.uniform(100, 1100, 4), rng.uniform(100, 900, 4)
    thin = synthetic_frames(x, y, cloud=0.3, seed=6)
    assert rms(centroid(thin.images, **OPTIONS).xy, thin) < 0.05
    round_sun = synthetic_frames(x, y, aspect=1.0, seed=6)
    assert rms(centroid(round_sun.images, saturation=4095).xy, round_sun) < 0.05


def test_batches_and_single_frames_agree_and_inputs_may_be_tensors():
    frames = synthetic_frames([400.2, 900.7, 12.0], [300.3, 700.1, 500.0], seed=2)
    batch = centroid(frames.images, **OPTIONS)
    for k in range(3):
        one = centroid(frames.images[k], **OPTIONS)
        np.testing.assert_allclose(one.xy[0], batch.xy[k], atol=1e-8)
    tensors = centroid([torch.from_numpy(f.astype(np.int32)) for f in frames.images], **OPTIONS)
    np.testing.assert_allclose(tensors.xy, batch.xy, atol=1e-9)


def test_every_bad_frame_gets_a_status_and_the_good_ones_go_on():
    rng = np.random.default_rng(1)
    good = synthetic_frames([500.3, 700.8], [400.1, 600.6], seed=1).images
    empty = synthetic_frames([-300.0], [500.0], seed=2).images[0]  # the sun far outside
    sliver = synthetic_frames([-0.5 - 0.55 * R], [500.0], seed=3).images[0]  # ~20 % of the limb inside
    thick_cloud = synthetic_frames([640.0], [512.0], cloud=3.0, seed=4).images[0]
    faint = synthetic_frames([640.0], [512.0], level=0.004, seed=5).images[0]
    all_saturated = np.full((1024, 1280), 4095, np.uint16)
    colour = np.zeros((1024, 1280, 3), np.uint8)
    frames = [
        good[0],
        empty,
        sliver,
        thick_cloud,
        faint,
        all_saturated,
        colour,
        np.zeros((16, 16), np.uint16),  # too small
        np.zeros((1024, 1280), bool),  # not a number type
        np.full((1024, 1280), np.nan),  # NaN
        "frame.png",  # not an array at all
        good[1],
    ]
    found = centroid(frames, **OPTIONS)
    want = ["ok", "no_sun", "clipped", "cloud", "faint", "saturated"] + ["bad_input"] * 5 + ["ok"]
    assert list(found.status) == want, list(zip(found.status, found.reason))
    assert set(found.status) <= set(STATUSES)
    for s, r, x in zip(found.status, found.reason, found.x):
        assert (s == "ok") == (r == "") == np.isfinite(x)
    assert "no sun" in found.reason[1]
    assert "clipped past usefulness" in found.reason[2]
    assert "cloud" in found.reason[3]
    assert "faint" in found.reason[4]
    assert "saturation" in found.reason[5]
    assert "channel" in found.reason[6] and "smaller than" in found.reason[7]
    assert "not a number type" in found.reason[8] and "NaN" in found.reason[9]
    # The good frames are measured as if alone.
    alone = centroid(good, **OPTIONS)
    np.testing.assert_allclose(found.xy[[0, 11]], alone.xy, atol=1e-9)
    # A frame of the wrong shape for the camera, and a radius far from the expected one.
    other = centroid([good[0], good[0][:512, :640]], shape=(1024, 1280), **OPTIONS)
    assert other.status == ("ok", "bad_input") and "does not match" in other.reason[1]
    wrong_radius = centroid(good[:1], radius=2 * R, **OPTIONS)
    assert wrong_radius.status == ("inconsistent",) and "expected" in wrong_radius.reason[0]
    del rng


def test_results_as_dicts_and_table():
    frames = synthetic_frames([500.3], [400.1], seed=1)
    found = centroid([frames.images[0], np.zeros((8, 8))], names=["a.png", "b.npy"], **OPTIONS)
    rows = found.to_dicts()
    assert rows[0]["frame"] == "a.png" and rows[0]["status"] == "ok" and rows[0]["method"] == "intensity"
    assert rows[1] == dict(frame="b.npy", x=None, y=None, radius=None, method="", status="bad_input", reason=rows[1]["reason"])
    assert "a.png" in found.summary() and "bad_input" in found.summary()


def test_bad_options_raise():
    with pytest.raises(ValueError, match="method"):
        centroid(np.zeros((64, 64)), method="psf")
    with pytest.raises(ValueError, match="names"):
        centroid([np.zeros((64, 64))], names=["a", "b"])

"""The sun-vector paper's calibration, end to end, from sun-sensor images.

The paper (Acta Optica Sinica 39(11) 1128001) aligns a mirror turntable with the sun
through a camera fixed parallel to the mirror normal, fits its five-parameter model,
then checks the calibration by comparing sun-image centroids: where the sun sits in the
image when the servo aligns the mirror with the sun ("before"), and where it sits when
the calibrated model drives the turntable open loop to the same sun position
("after"). It reports differences of about 2 pixels, 0.036 deg.

Here every step runs on synthetic data:

1. **Track the sun** over a calibration day (every 12 minutes above 15 deg). A servo
   centres the sun in the camera to within about a pixel; the 14-bit encoders (0.022
   deg steps, repeatability +-2 counts, as in the paper) are read. The truth is the
   paper's geometry plus a camera mounted 0.02 deg (across) and 0.03 deg (up) off the
   mirror normal, on a lens with mild barrel distortion.
2. **Take frames** (1280 x 1024, 23 x 17 deg, the sun 29 px across, noise, hot pixels)
   at each reading; a few are bad (thick cloud, the sun clipped past use, a truncated
   frame) and are flagged and skipped.
3. **Centroid** them (torch/kornia, batched), turn pixels into rays through the
   camera model, and the rays plus the sun's ephemeris into observations of the camera
   axis (:mod:`pointax.sunsensor.pipeline`).
4. **Calibrate**: fit the paper's five parameters plus the camera's mounting
   (``camera.cross``; ``camera.up`` is exactly degenerate with ``beta0`` and stays
   fixed), then place the offsets once more with the fitted camera attitude and refit.
5. **Compare centroids** on the next afternoon: servo-aligned frames against frames
   taken where the calibrated model commands the turntable, in pixels and degrees,
   next to the paper's figures.

Run:  python examples/sun_sensor_calibration.py        (about 25 s on 2 idle cores)
"""

from __future__ import annotations

import time

import astropy.units as u
import jax.numpy as jnp
import numpy as np
from astropy.time import Time

import pointax as px
from pointax.sunsensor import (
    Camera,
    refine_targets,
    sensor_observations,
    simulate_frames,
    synthetic_frames,
)
from pointax.terms.camera import CameraMounting

SITE = px.sky.site(40.13, 94.34, 1140.0)  # about the Dunhuang radiometric calibration site
WEATHER = {"pressure_hpa": 885.0, "temperature_c": 20.0}
TRUTH = {"mu0": 0.0751, "nu0": 0.0145, "omega0": -0.0947, "alpha0": 60.5425, "beta0": 165.8931}  # deg
MOUNTING = {"cross": 0.02, "up": 0.03}  # deg: the camera axis relative to the mirror normal
ENCODER_STEP = 2 * np.pi / 2**14  # 14-bit absolute encoders: 0.022 deg
REPEATABILITY = 2  # counts
SERVO_PX = 1.0  # RMS per axis of the servo's centring, pixels
LIMITS = ((0.0, 2 * np.pi), None)
CAMERA = Camera.from_fov(1280, 1024, 23.0, 17.0, dist=(-0.05, 0.0, 0.0, 0.0, 0.0))
PAPER_PX, PAPER_DEG = 2.0, 0.036  # the paper's centroid comparison


def sun_track(start: str, minutes: float, hours: float = 24.0) -> np.ndarray:
    """Sun directions (ENU) every ``minutes`` while the sun is above 15 deg."""
    t = Time(start) + np.arange(0.0, hours * 60.0, minutes) * u.min
    sun = px.sky.sun_direction(t, SITE, **WEATHER)
    return sun[sun[:, 2] > np.sin(np.radians(15.0))]


def servo_readings(model: px.Model, sun: np.ndarray, rng) -> np.ndarray:
    """True readings of a servo that centres the sun in the camera to ~SERVO_PX."""
    scale = np.radians(CAMERA.pixel_scale_deg[0])
    aim = px.rotations.offset_direction(jnp.asarray(sun), jnp.asarray(rng.normal(size=(len(sun), 2)) * SERVO_PX * scale))
    return np.asarray(px.command(model, aim, limits=LIMITS).reading)


def encoder_reads(true_reading: np.ndarray, rng) -> np.ndarray:
    """What the encoders report at a true position: 14-bit steps, +-2 counts repeatability."""
    counts = np.round(true_reading / ENCODER_STEP) + rng.integers(-REPEATABILITY, REPEATABILITY + 1, true_reading.shape)
    return counts * ENCODER_STEP


def drive_to(reading: np.ndarray, rng) -> np.ndarray:
    """Where the turntable really stops when told to go to ``reading``: the encoder
    feedback is good to +-2 counts."""
    return reading + rng.integers(-REPEATABILITY, REPEATABILITY + 1, reading.shape) * ENCODER_STEP


def main(seed: int = 0, verbose: bool = True) -> dict:
    start = time.perf_counter()
    rng = np.random.default_rng(seed)
    truth = px.Turntable(list(px.terms.turntable("full")) + [CameraMounting(**{k: px.deg(v) for k, v in MOUNTING.items()})])
    truth = truth.set(**{k: px.deg(v) for k, v in TRUTH.items()})

    # 1-2. Calibration day: servo-aligned readings, encoder values, frames.
    sun = sun_track("2026-06-21T00:00", minutes=12.0)
    n = len(sun)
    true_reading = servo_readings(truth, sun, rng)
    frames = simulate_frames(truth, CAMERA, true_reading, sun, hot_pixels=10, seed=seed, subrows=32)
    images = list(frames.images)
    bad = {3: "thick cloud", 10: "sun clipped past use", 17: "truncated frame"}
    images[3] = simulate_frames(truth, CAMERA, true_reading[3:4], sun[3:4], cloud=3.0, seed=seed + 1, subrows=32).images[0]
    # The servo lost the sun: most of it has left the top of the frame.
    r = CAMERA.sun_radius_px()
    images[10] = synthetic_frames([frames.x[10]], [-0.5 - 0.6 * r * CAMERA.aspect], radius=r, aspect=CAMERA.aspect, seed=seed + 2, subrows=32).images[0]
    images[17] = images[17][:512]
    reading = encoder_reads(true_reading, rng)

    # 3. Centroids -> rays -> observations of the camera axis.
    data = sensor_observations(images, reading, sun, CAMERA, saturation=frames.detector.full_scale)
    ok = data.centroids.ok
    pixel_error = data.centroids.xy[ok] - np.stack([frames.x, frames.y], axis=1)[ok]

    # 4. Calibrate; place the offsets with the fitted attitude; refit.
    model = px.Turntable(
        list(px.terms.turntable("full")) + [CameraMounting()], fixed=["camera.up"], start=data.observations
    )
    first = px.fit(model, data)
    data = refine_targets(data, first.model)
    result = px.fit(first.model, data)

    # 5. Validation on the next afternoon (12:30-16:30 local, as the paper's Fig. 6).
    sun_check = sun_track("2026-06-22T06:30", minutes=20.0, hours=4.0)
    aligned = servo_readings(truth, sun_check, rng)  # the sun observer aligns the mirror
    commanded = px.command(result.model.free(), sun_check, limits=LIMITS)  # (free: same compiled command)
    if not bool(np.all(commanded.ok)):
        raise RuntimeError(f"commands failed: {commanded.reasons()}")
    after_reading = drive_to(np.asarray(commanded.reading), rng)
    m = len(sun_check)
    check = simulate_frames(truth, CAMERA, np.concatenate([aligned, after_reading]), np.concatenate([sun_check, sun_check]), seed=seed + 5, subrows=32)
    found = sensor_observations(check.images, np.concatenate([aligned, after_reading]), np.concatenate([sun_check, sun_check]), CAMERA, saturation=check.detector.full_scale)
    before_px, after_px = found.centroids.xy[:m], found.centroids.xy[m:]
    diff_px = after_px - before_px
    diff_deg = np.degrees(np.arccos(np.clip(np.sum(found.rays[:m] * found.rays[m:], axis=1), -1, 1)))
    # The fitted mirror-normal model (the camera term removed) against the true normal.
    true_normal = np.asarray(truth.without_terms("camera")(aligned))
    fitted_normal = np.asarray(result.model.without_terms("camera")(aligned))
    normal_err = np.degrees(np.arccos(np.clip(np.sum(true_normal * fitted_normal, axis=1), -1, 1)))

    out = {
        "frames": n,
        "used": int(data.used.sum()),
        "skipped": {i: s for i, s, _ in data.skipped()},
        "centroid_rms_px": float(np.sqrt(np.mean(np.sum(pixel_error**2, axis=1)))),
        "converged": bool(result.converged),
        "values_deg": {name: result.value(name, "deg") for name in list(TRUTH) + ["camera.cross"]},
        "sky_rms_deg": float(result.sky_rms) * 180 / np.pi,
        "diff_px_rms": float(np.sqrt(np.mean(np.sum(diff_px**2, axis=1)))),
        "diff_px_max": float(np.max(np.hypot(*diff_px.T))),
        "diff_deg_rms": float(np.sqrt(np.mean(diff_deg**2))),
        "normal_err_deg_rms": float(np.sqrt(np.mean(normal_err**2))),
        "seconds": time.perf_counter() - start,
    }
    if verbose:
        print(f"Calibration day: {n} frames of the sun above 15 deg (every 12 min)")
        print(data.report())
        print(f"  (planted: {', '.join(f'frame {i}: {why}' for i, why in bad.items())})")
        print(f"Centroid error on the good frames: {out['centroid_rms_px']:.4f} px RMS (truth known)\n")
        print(result.report())
        print("\n  parameter        fitted (deg)    truth (deg)")
        for name, want in list(TRUTH.items()) + [("camera.cross", MOUNTING["cross"])]:
            note = "  (+ camera.up, fixed at 0: beta0 absorbs it)" if name == "beta0" else ""
            truth_value = want - MOUNTING["up"] if name == "beta0" else want
            print(f"  {name:<14s} {result.value(name, 'deg'):+14.4f} {truth_value:+14.4f}{note}")
        names = list(result.names)
        r_cross = float(np.asarray(result.correlation)[names.index("omega0"), names.index("camera.cross")])
        print(
            f"\ncamera.cross is separable from omega0 and alpha0 only through sec(el) against tan(el)\n"
            f"over the day's elevations: r(omega0, camera.cross) = {r_cross:+.3f}, sigma "
            f"{result.sigma('camera.cross', 'deg'):.3f} deg with these encoders."
        )
        print(f"\nCentroid comparison, {m} sun positions on the next afternoon:")
        print("  before: the servo aligns the mirror with the sun; after: the calibrated model drives it")
        print(f"  {'':<26s} {'pixels':>8s} {'degrees':>9s}")
        print(f"  {'this simulation, RMS':<26s} {out['diff_px_rms']:8.2f} {out['diff_deg_rms']:9.4f}")
        print(f"  {'this simulation, largest':<26s} {out['diff_px_max']:8.2f} {np.max(diff_deg):9.4f}")
        print(f"  {'the paper (about)':<26s} {PAPER_PX:8.2f} {PAPER_DEG:9.4f}")
        print(f"  x {' '.join(f'{d:+5.1f}' for d in diff_px[:, 0])}")
        print(f"  y {' '.join(f'{d:+5.1f}' for d in diff_px[:, 1])}")
        print(
            f"\nThe differences come from the encoders (0.022 deg steps, +-2 counts) at\n"
            f"command time; the camera's up-tilt ({MOUNTING['up']} deg) cannot be told from beta0 with\n"
            f"the sun alone: the fitted mirror-normal model (without the camera term) is\n"
            f"{out['normal_err_deg_rms']:.4f} deg RMS from the true normal."
        )
        print(f"\n({out['seconds']:.1f} s)")
    return out


if __name__ == "__main__":
    main()

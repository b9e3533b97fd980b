"""
Finding the sun in sun-sensor frames
====================================

A small part of ``examples/sun_sensor_calibration.py`` (which runs the sun-vector
paper's whole calibration from images, about a minute; ``tests/test_examples_sunsensor.py``
runs it): synthetic frames with known sun centres, one of them clipped at the edge,
one under thick cloud, centroided in one batch (:func:`pointax.sunsensor.centroid`).
The found centres are compared with the true ones.
"""

# example: examples/sun_sensor_calibration.py
import matplotlib.pyplot as plt
import numpy as np

from pointax.sunsensor import centroid, synthetic_frames

x = np.array([640.0, 300.0, 1000.0, 1270.0, 640.0])  # true centres, pixels
y = np.array([512.0, 200.0, 800.0, 512.0, 512.0])
frames = synthetic_frames(x, y, cloud=np.array([0, 0, 0, 0, 3.0]), hot_pixels=5, seed=0)
found = centroid(frames.images, saturation=frames.detector.full_scale)
for k in range(len(x)):
    dx, dy = found.x[k] - x[k], found.y[k] - y[k]
    print(f"frame {k}: {found.status[k]:<12s} {found.method[k]:<9s} error ({dx:+.3f}, {dy:+.3f}) px  {found.reason[k]}")

fig, axes = plt.subplots(1, len(x), figsize=(12, 2.6))
for k, ax in enumerate(axes):
    ax.imshow(np.asarray(frames.images[k]), cmap="gray")
    ax.plot(x[k], y[k], "c+", ms=12, label="true")
    if found.status[k] == "ok":
        ax.plot(found.x[k], found.y[k], "rx", ms=8, label="found")
    ax.set_title(f"{k}: {found.status[k]}", fontsize=9)
    ax.set_xticks([])
    ax.set_yticks([])
axes[0].legend(fontsize=7, loc="lower left")
plt.show()

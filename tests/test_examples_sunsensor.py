"""examples/sun_sensor_calibration.py runs end to end and prints the paper's comparison."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest
from conftest import EXAMPLES, REPO

pytest.importorskip("torch")
pytest.importorskip("kornia")

pytestmark = pytest.mark.slow  # the example end to end, about 30 s


def test_sun_sensor_calibration_example():
    proc = subprocess.run(
        [sys.executable, str(EXAMPLES / "sun_sensor_calibration.py")],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = proc.stdout
    # The planted bad frames are flagged and skipped; the rest are used.
    assert "57 of 60 frames used" in out
    assert "frame 3: cloud" in out and "frame 10: clipped" in out and "frame 17: bad_input" in out
    centroid_rms = float(re.search(r"Centroid error on the good frames: ([\d.]+) px RMS", out).group(1))
    assert centroid_rms < 0.05
    assert "converged in" in out
    # The before/after comparison, next to the paper's figures.
    px_rms, deg_rms = map(float, re.search(r"this simulation, RMS\s+([\d.]+)\s+([\d.]+)", out).groups())
    assert "the paper (about)" in out and "2.00" in out and "0.0360" in out
    assert 0.5 < px_rms < 5.0 and 0.01 < deg_rms < 0.09

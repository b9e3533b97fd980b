"""
Calibrating a sun-tracking turntable
====================================

``examples/turntable_sun_calibration.py`` simulates the sun-vector paper's turntable
(five parameters: two axis tilts, an axis non-orthogonality and two encoder zeros)
following the sun, fits it and draws up the error budget. At build time it runs one
noise realisation (``realisations=1``); the script's default is 4.

.. literalinclude:: ../../examples/turntable_sun_calibration.py
   :language: python
"""

# example: examples/turntable_sun_calibration.py
import sys
from pathlib import Path

sys.path.insert(0, str(Path.cwd()))  # sphinx-gallery runs a script in its folder
from _load import QUICK, example  # noqa: E402

out = example("turntable_sun_calibration").main(realisations=1 if QUICK else 4, seed=0)

"""
Comparing model families
========================

``examples/compare_model_families.py`` reproduces the shape of Table 3 of the
level-mount paper: four model families fitted to 68 simulated X-Y stars and judged on
78 others (:func:`pointax.compare`). At build time it skips the further noise draws
that give the spread (``draws=0``; the script's default is 8).

.. literalinclude:: ../../examples/compare_model_families.py
   :language: python
"""

# example: examples/compare_model_families.py
import sys
from pathlib import Path

sys.path.insert(0, str(Path.cwd()))  # sphinx-gallery runs a script in its folder
from _load import QUICK, example  # noqa: E402

out = example("compare_model_families").main(seed=1, draws=0 if QUICK else 8)

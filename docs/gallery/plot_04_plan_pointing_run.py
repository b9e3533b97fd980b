"""
Planning a pointing run
=======================

``examples/plan_pointing_run.py`` chooses 40 bright stars for TPOINT's eight basic
terms at Mt Hopkins (:func:`pointax.plan_run`), prints them in observing order with
the predicted accuracy, and draws the predicted-accuracy sky map, shown below.

.. literalinclude:: ../../examples/plan_pointing_run.py
   :language: python
"""

# example: examples/plan_pointing_run.py
import sys
import tempfile
from pathlib import Path

import matplotlib.image as mpimg
import matplotlib.pyplot as plt

sys.path.insert(0, str(Path.cwd()))  # sphinx-gallery runs a script in its folder
from _load import example  # noqa: E402

skymap = example("plan_pointing_run").main(skymap=Path(tempfile.mkdtemp()) / "plan_skymap.png")

# The sky map the example wrote:
fig, ax = plt.subplots(figsize=(7, 6))
ax.imshow(mpimg.imread(skymap))
ax.axis("off")
plt.show()

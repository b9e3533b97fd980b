"""
A thermal flexure term from auxiliary readings
==============================================

``examples/thermal_flexure.py`` prototypes a tube flexure that follows the temperature:
a new :class:`pointax.Term` that reads the ``temperature`` reading by name
(``self.reading("temperature")``), fitted with the physical terms to four simulated runs
at different temperatures; ``px.terms.thermal("TF")`` is the same term, ready-made, and
the inverse takes the temperature at the time of the command. The guide
:doc:`/guides/pointing_over_time` explains readings and run history. The whole example:

.. literalinclude:: ../../examples/thermal_flexure.py
   :language: python

Running it prints the fitted coefficients next to the truth; the thermal coefficient
comes back within its sigma.
"""

# example: examples/thermal_flexure.py
import sys
from pathlib import Path

sys.path.insert(0, str(Path.cwd()))  # sphinx-gallery runs a script in its folder
from _load import example  # noqa: E402

out = example("thermal_flexure").main(seed=0)

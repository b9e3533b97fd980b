"""
A new error term in a few lines of JAX
======================================

``examples/new_error_term.py`` defines an azimuth-axis wobble as a new
:class:`pointax.Term` (it overrides ``base_rotation``), simulates a run with it and
fits it next to TPOINT's basic terms: no derivative is written, JAX differentiates the
term. The guide :doc:`/guides/new_error_term` explains the hooks. The whole example:

.. literalinclude:: ../../examples/new_error_term.py
   :language: python

Running it prints the fit; the wobble's amplitude and phase come back within their
sigmas.
"""

# example: examples/new_error_term.py
import sys
from pathlib import Path

sys.path.insert(0, str(Path.cwd()))  # sphinx-gallery runs a script in its folder
from _load import example  # noqa: E402

out = example("new_error_term").main(seed=0)

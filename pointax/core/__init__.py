"""The numerical core: the forward model of a pointing mount, pure JAX in float64.

* :mod:`~pointax.core.rotations`: rotation matrices, unit vectors, tangent-plane offsets.
* :mod:`~pointax.core.trig`: float64 sine, cosine and arctangent as vectorised polynomials.
* :mod:`~pointax.core.mounts`: two-axis mount kinematics as chains of rotations.
* :mod:`~pointax.core.term`: the interface of an error term (:class:`Term`, :func:`param`).
* :mod:`~pointax.core.model`: :class:`Model`, a mount with its terms and named parameters.
* :mod:`~pointax.core.observations`: :class:`Observations`, raw encoder angles and observed directions.
* :mod:`~pointax.core.inverse`: encoder commands for wanted directions (the model's inverse).
* :mod:`~pointax.core.simulate`: simulated observations from a true model.
* :mod:`~pointax.core.units`: angle units and plausibility checks.
* :mod:`~pointax.core.errors`: the error and warning every reader raises for bad input.
* :mod:`~pointax.core.precision`: float64 without changing the user's JAX settings.
* :mod:`~pointax.core.compiled`: functions of a model compiled once per structure when called op by op.
* :mod:`~pointax.core.xla_options`: XLA options that shorten the compilation of the larger programs.
* :mod:`~pointax.core.lazy`: lazy package namespaces (``import pointax`` loads no numerical library).

The core imports no particular term, no file format, no plotting, no command line and
no astropy (``tests/test_import_rules.py``). Its public names are re-exported from
:mod:`pointax`.
"""

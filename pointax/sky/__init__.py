"""The astropy edge: where the sun and the stars are.

* :mod:`~pointax.sky.sun`: topocentric sun directions for a site and times, refraction,
  sites and times (re-exported here: ``px.sky.sun_direction``).
* :mod:`~pointax.sky.stars`: a bright-star catalogue, apparent places, a run planner and a
  run simulator (``px.stars``).

Importing this package imports astropy; the core never does.
"""

from .sun import *  # noqa: F403
from .sun import __all__

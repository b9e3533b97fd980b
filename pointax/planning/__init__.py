"""Plan the next pointing run, and predict a model's accuracy before the first star.

pointax has the Jacobian of any model (library and user terms alike) by autodiff, so it
can predict, from the parameters' covariance, how well a fitted model will point in
every direction, and choose the observations that pin the model down best.

* :mod:`~pointax.planning.jacobian`: readings for directions (a fast inverse) and the
  pointing Jacobian ``d offset / d parameters``.
* :mod:`~pointax.planning.accuracy`: :func:`predicted_accuracy`, the
  :class:`PredictedAccuracy` over directions, its sky summary and sky map; :func:`sky_grid`.
* :mod:`~pointax.planning.design`: greedy I-/D-optimal selection (rank-two updates,
  one compiled call), and the bound no selection of n can beat (:func:`design_bound`).
* :mod:`~pointax.planning.candidates`: stars at a site and time (away from the Sun and
  the Moon), placed again at their scheduled times; sun positions over days; grids.
* :mod:`~pointax.planning.ordering`: a short observing order (nearest neighbour + 2-opt).
* :mod:`~pointax.planning.plan`: :func:`plan_run` and :class:`Plan` (stars scheduled at
  a cadence; sun plans judged over the sun's path).
"""

from .accuracy import PredictedAccuracy, information_matrix, predicted_accuracy, sky_average, sky_grid
from .candidates import (
    Candidates,
    StarRules,
    grid_candidates,
    moon_direction,
    place_stars,
    star_candidates,
    sun_candidates,
)
from .design import CRITERIA, STARTS, design_bound, greedy_design
from .jacobian import pointing_jacobian, readings_for
from .ordering import order_path
from .plan import SKY_CHOICES, Plan, plan_run

__all__ = [
    "CRITERIA",
    "SKY_CHOICES",
    "STARTS",
    "Candidates",
    "Plan",
    "PredictedAccuracy",
    "StarRules",
    "design_bound",
    "greedy_design",
    "grid_candidates",
    "information_matrix",
    "moon_direction",
    "order_path",
    "place_stars",
    "plan_run",
    "pointing_jacobian",
    "predicted_accuracy",
    "readings_for",
    "sky_average",
    "sky_grid",
    "star_candidates",
    "sun_candidates",
]

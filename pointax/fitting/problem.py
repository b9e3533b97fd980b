"""One problem definition for every fit: what one site's observations fix, prepared
once, and one residual function of the model's parameters.

Every fit evaluates its residuals on the structured evaluation of :mod:`pointax.fitting.fast_evaluation`
(nominal axis angles and their sines and cosines, the targets in the mount frame,
TPOINT's unit sky offsets: computed once per fit, not once per step): the solo fit
(:func:`pointax.fit`, leave-one-out, the comparison folds, TPOINT's FIT, model
building) through this module's :class:`Problem`; the batched fit
(:func:`pointax.fit_batch`) and the shared-parameter fit (:func:`pointax.fit_shared`)
on the same site data with a leading site axis, and their full loop is the solo fit. :meth:`pointax.Model.mount_direction` and :func:`pointax.residuals` stay the
plain forward model, the oracle these residuals are tested against
(``tests/test_site.py``).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from ..core.model import Model
from ..core.observations import Observations
from .fast_evaluation import SiteData, site_data, site_residuals, without_pinned_singularities

__all__ = ["Problem", "define_problem"]


class Problem(eqx.Module):
    """One site's least-squares problem (a pytree: ``vmap`` it over sites).

    Attributes:
        data: what the observations fix (:class:`pointax.fitting.fast_evaluation.SiteData`), for the
            model structure the problem was defined with; the parameter values are not
            part of it.
    """

    data: SiteData

    def residuals(self, model: Model) -> Float[Array, "n 2"]:
        """Observed minus model, ``(n, 2)`` (cross-elevation, elevation) radians, in the
        model's residual form, unweighted; 0 for observations with weight 0. Equal to
        :func:`pointax.residuals` of the same model and observations (to rounding).
        ``model`` must have the structure the problem was defined with (any values)."""
        rx, ry = site_residuals(model, self.data, weighted=False)
        return jnp.stack([rx, ry], axis=-1)


def define_problem(model: Model, data: Observations | Problem, free: Bool[Array, " m"] | None = None) -> Problem:
    """The :class:`Problem` of fitting ``model`` (its structure) to the observations
    ``data`` (pure JAX); a :class:`Problem` is returned as it is. ``free``: ``(M,)``
    which of ``model.parameters`` the fit adjusts, if known: the others that are 0 then
    add exactly nothing, even where their term is singular
    (:func:`pointax.fitting.fast_evaluation.without_pinned_singularities`)."""
    if isinstance(data, Problem):
        return data
    # One site's fit: the smaller program of XLA's own sines and cosines (SiteData.library_trig).
    site = site_data(model, data, library_trig=True)
    if free is not None:
        site = without_pinned_singularities(model, site, jnp.asarray(free, bool))
    return Problem(site)

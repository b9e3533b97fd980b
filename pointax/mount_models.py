"""Model factories for X-Y and equatorial mounts, and the level-mount paper's families.

``XY("basic")`` is the paper's basic physical model on an :class:`pointax.XYMount`;
``xy_family(name)`` gives the terms of each family (:mod:`pointax.terms.xy`);
``Equatorial(terms, latitude)`` is an :class:`pointax.EquatorialMount` with terms.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import numpy as np
from jaxtyping import ArrayLike, Float

from .model import Model
from .mounts import EquatorialMount, XYMount
from .terms.base import Term
from .terms.xy import FAMILIES

__all__ = ["XY", "Equatorial", "xy_family", "XY_FAMILIES"]

XY_FAMILIES: tuple[str, ...] = tuple(FAMILIES)
"""Names of the level-mount paper's model families: 'harmonic' (eqs 1-2, 13 + 13
terms), 'basic' (eqs 3-4, 10 terms), 'rotation' (eqs 9-17, rigorous, 10 parameters),
'linearised' (eqs 18-19, 16 + 10 terms)."""


def xy_family(name: str, values: Mapping[str, float] | None = None) -> tuple[Term, ...]:
    """The terms of one of the level-mount paper's model families for an X-Y mount.

    Args:
        name: 'harmonic', 'basic', 'rotation' or 'linearised' (:data:`XY_FAMILIES`;
            'linearized' is accepted too). See :mod:`pointax.terms.xy` for each
            family's terms, symbols and equations.
        values: optional parameter values by name (radians), e.g.
            ``pointax.terms.xy.rotation_values(v=px.arcsec(100), Lv=px.deg(-60))``;
            the others start at 0.

    Raises:
        ValueError: for an unknown family name.
        KeyError: for a value whose name is not a parameter of the family.
    """
    key = "linearised" if name == "linearized" else name
    if key not in FAMILIES:
        raise ValueError(f"unknown X-Y model family {name!r}; expected one of {', '.join(XY_FAMILIES)}")
    terms = FAMILIES[key]()
    if values:
        # Python numbers as float64 arrays: jit then traces them instead of baking them in.
        values = {k: np.float64(v) if isinstance(v, (int, float)) else v for k, v in values.items()}
        terms = Model(XYMount(), terms).set(**values).terms
    return terms


def _terms(terms: str | Iterable[Term]) -> tuple[Term, ...]:
    if isinstance(terms, str):
        return xy_family(terms)
    return tuple(terms)


def XY(
    terms: str | Sequence[Term] | Iterable[Term] = (), fixed: Iterable[str] = (), residual_form: str = "sky"
) -> Model:
    """An X-Y mount model: :class:`pointax.XYMount` with ``terms``.

    Encoder readings are ``(L, B)`` in radians (observations with convention 'xy');
    ``pointing = (sin L cos B, sin B, cos L cos B)`` in East-North-Up, and fit
    residuals are ``(dL cos B, dB)``.

    Args:
        terms: a family name (:func:`xy_family`: 'harmonic', 'basic', 'rotation',
            'linearised') or a sequence of terms (:mod:`pointax.terms.xy`, or your own
            :class:`pointax.Term` written in the X-Y mount's frame).
        fixed: names of parameters held fixed in fits.
        residual_form: 'sky' (exact, default) or 'tpoint' (angle residuals with sky
            offsets at the observed position: see :class:`pointax.Model`).
    """
    return Model(XYMount(), _terms(terms), fixed, residual_form=residual_form)


def Equatorial(
    terms: Sequence[Term] | Iterable[Term] = (),
    latitude: Float[ArrayLike, ""] = None,
    fixed: Iterable[str] = (),
    residual_form: str = "sky",
) -> Model:
    """An equatorial mount model: :class:`pointax.EquatorialMount` at ``latitude`` with
    ``terms``.

    Encoder readings are ``(hour angle, declination)`` in radians, hour angle positive
    West (observations with convention 'ha-dec'); both pier sides are readings of the
    same model (``(H + pi, pi - dec)`` is the flipped side). Fit residuals are ``(dH cos
    dec, d dec)``.

    Args:
        terms: error terms acting in the mount's frame (+x West, +y the equator on the
            meridian, +z the celestial pole), e.g. the rigorous rotations of
            :mod:`pointax.terms.rigorous`, which there mean: ``IA`` hour-angle zero
            point (``H = reading - IA``), ``IE`` declination zero point, ``CA``
            collimation, ``NPAE`` polar / declination axis non-perpendicularity, ``AN``
            and ``AW`` tilts of the polar axis.
        latitude: the site's latitude, radians (North positive), required.
        fixed: names of parameters held fixed in fits.
        residual_form: 'sky' (exact, default) or 'tpoint' (angle residuals with sky
            offsets at the observed position: see :class:`pointax.Model`).
    """
    if latitude is None:
        raise ValueError("Equatorial: give the site's latitude in radians, e.g. latitude=pointax.deg(31.7)")
    return Model(EquatorialMount(latitude), tuple(terms), fixed, residual_form=residual_form)

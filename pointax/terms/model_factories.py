"""Model factories: a mount with its terms, for each kind of mount.

``AltAz(terms, azimuth)`` is an :class:`pointax.AltAzMount` with terms;
``Turntable("full")`` the sun-vector paper's mirror turntable;
``XY("basic")`` the level-mount paper's basic physical model on an :class:`pointax.XYMount`,
``xy_family(name)`` the terms of each of its families (:mod:`pointax.terms.xy`);
``Equatorial(terms, latitude)`` an :class:`pointax.EquatorialMount` with terms. (A PAINT
heliostat's model comes with its file: :func:`pointax.heliostat_model`.) The core
(:mod:`pointax.core.model`) knows no particular term; these do.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import numpy as np
from jaxtyping import ArrayLike, Float

from ..core.model import Model
from ..core.mounts import AltAzMount, EquatorialMount, TurntableMount, XYMount
from ..core.observations import Observations
from . import turntable as turntable_terms
from ..core.term import Term

__all__ = ["AltAz", "Turntable", "XY", "Equatorial", "xy_family", "XY_FAMILIES"]

XY_FAMILIES: tuple[str, ...] = ("harmonic", "basic", "rotation", "linearised")
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
    from .xy import FAMILIES  # on first use: an alt-az fit never creates the X-Y classes

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

    TPOINT's equatorial terms by name: ``pointax.terms.tpoint(spec, mount="equatorial",
    latitude=latitude, form="linear" | "rigorous")`` (:mod:`pointax.terms.equatorial`);
    a run read by :func:`pointax.io.read_tpoint` builds its model with ``run.model(terms)``.

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


def AltAz(
    terms: Sequence[Term] | Iterable[Term] = (),
    azimuth: str = "N-E",
    fixed: Iterable[str] = (),
    residual_form: str = "sky",
) -> Model:
    """An alt-az telescope model: :class:`AltAzMount` with ``terms``.

    Args:
        terms: error terms, e.g. ``pointax.terms.tpoint("IA IE NPAE CA AN AW TF TX")``.
        azimuth: how the encoders count azimuth ('N-E', 'S-E' or 'S-W'; see
            :class:`pointax.AltAzMount`). Use the convention of your data
            (``run.azimuth`` for a run read by :func:`pointax.io.read_tpoint`).
        fixed: names of parameters held fixed in fits.
        residual_form: 'sky' (exact, default) or 'tpoint' (TPOINT's own residuals:
            see :class:`Model`).
    """
    return Model(AltAzMount(azimuth=azimuth), terms, fixed, residual_form=residual_form)



def Turntable(
    terms: str | Sequence[str] | Sequence[Term] = "full",
    fixed: Iterable[str] = (),
    start: Observations | None = None,
) -> Model:
    """A sun-tracking mirror turntable model: :class:`TurntableMount` with ``terms``.

    Args:
        terms: 'full' (the paper's five parameters), 'simple' (alpha0, beta0), names
            (see :func:`pointax.terms.turntable`) or a sequence of :class:`Term`.
        fixed: names of parameters held fixed in fits.
        start: observations to take starting values of the encoder zeros from
            (:func:`pointax.terms.sun_vector.estimate_zeros`); the zeros may be far from
            0 and a least-squares fit needs a start within a few degrees.
    """
    terms = terms if isinstance(terms, str) else tuple(terms)
    if isinstance(terms, str) or all(isinstance(t, str) for t in terms):
        terms = turntable_terms(terms)
    model = Model(TurntableMount(), terms, fixed)
    if start is not None:
        use = np.asarray(start.weight) > 0  # rows with weight 0 may hold NaN
        from .sun_vector import estimate_zeros

        alpha0, beta0 = estimate_zeros(np.asarray(start.encoder)[use], np.asarray(start.target)[use])
        names = set(model.parameter_names)
        zeros = {k: v for k, v in (("alpha0", alpha0), ("beta0", beta0)) if k in names}
        model = model.set(**zeros)
    return model

"""RTS2 gpoint's alt-az terms (``ia ie tn te npae npoa tf``), exactly as gpoint defines
them: :class:`GpointTerm` and its seven subclasses, and :data:`GPOINT_TERMS` (name ->
class). Transcribed from gpoint's ``GPoint.model_az_hadec`` and ``GPoint.model_el_hadec``
(:data:`pointax.terms.gpoint.GPOINT_SOURCE`); build them by name with
:func:`pointax.terms.gpoint.gpoint_term` or :func:`pointax.terms.gpoint_terms`.

**gpoint's model.** With ``A, E`` the mount's (raw) azimuth and elevation, gpoint fits
``true = raw + model(raw)`` (``fit_model_az`` returns ``a_az - r_az + model_az(a_az,
a_el)``, ``a`` the mount position and ``r`` the real one, and minimises the angular
separation of ``raw + model`` from ``true``). So each term is an offset in radians
added to the encoder angle and evaluated at the *raw* encoder position: in pointax an
:meth:`~pointax.Term.encoder_offset`, which reproduces gpoint's prediction exactly::

    model_az = - ia + tn sin A tan E - te cos A tan E - npae tan E + npoa / cos E + extras(az)
    model_el = - ie + tn cos A + te sin A + tf cos E + extras(el)

**Azimuth.** gpoint counts azimuth as RTS2 and libnova do, from South through West
(its ``hrz_to_equ`` takes ``ha = atan2(sin A, ...)`` with ``A = 0`` South, and its sky
plot puts ``A = 0`` at S and ``A = 90`` at W). gpoint terms therefore see the azimuth
in the ``"S-W"`` convention: build the model with ``pointax.AltAz(terms,
azimuth="S-W")`` (``run.azimuth`` of :func:`pointax.io.read_gpoint`).

**TPOINT equivalents** (same azimuth numbers; exact for the constants, to first order
for the rest, since gpoint evaluates at the raw position and TPOINT at the sky one):

=======  ===========================================  ==============================
gpoint   offset added (radians)                       TPOINT
=======  ===========================================  ==============================
ia       dA = -ia                                     IA = +ia (identical)
ie       dE = -ie                                     IE = -ie (identical)
tn       dA = +tn sin A tan E,  dE = +tn cos A        AN = -tn (tilt towards North)
te       dA = -te cos A tan E,  dE = +te sin A        AW = +te (tilt towards East)
npae     dA = -npae tan E                             NPAE = +npae
npoa     dA = +npoa / cos E                           CA = -npoa
tf       dE = +tf cos E                               TF = -tf (= ECEC)
=======  ===========================================  ==============================
"""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp

from ..core.term import Term, angle_pair, param

__all__ = [
    "GpointTerm",
    "GpointIA",
    "GpointIE",
    "GpointTN",
    "GpointTE",
    "GpointNPAE",
    "GpointNPOA",
    "GpointTF",
    "GPOINT_TERMS",
]


class GpointTerm(Term):
    """One of gpoint's alt-az terms: ``coef * offset(A, E)`` added to the encoder angles,
    evaluated at the raw encoder reading (azimuth from South through West).

    Attributes:
        coef: the coefficient, radians (reported in arcseconds).
    """

    coef: float = param(0.0)
    gpoint_name: ClassVar[str] = ""
    gpoint_mount: ClassVar[str] = "altaz"

    @property
    def name(self) -> str:
        return self.gpoint_name

    def offset(self, az, el) -> tuple:
        """(dA, dE) added per radian of coefficient: gpoint's formula."""
        raise NotImplementedError

    def encoder_offset(self, encoder):
        return self.coef * angle_pair(*self.offset(encoder[0], encoder[1]))


class GpointIA(GpointTerm):
    """gpoint ``ia``, zero point in azimuth: ``dA = -ia``. TPOINT: IA = +ia."""

    gpoint_name: ClassVar[str] = "ia"

    def offset(self, az, el):
        return -1.0, 0.0


class GpointIE(GpointTerm):
    """gpoint ``ie``, zero point in elevation: ``dE = -ie``. TPOINT: IE = -ie (the
    opposite sign)."""

    gpoint_name: ClassVar[str] = "ie"

    def offset(self, az, el):
        return 0.0, -1.0


class GpointTN(GpointTerm):
    """gpoint ``tn``, tilt of the azimuth axis towards North: ``dA = +tn sin A tan E``,
    ``dE = +tn cos A`` (A from South through West). TPOINT on the same azimuth: AN = -tn."""

    gpoint_name: ClassVar[str] = "tn"

    def offset(self, az, el):
        return jnp.sin(az) * jnp.tan(el), jnp.cos(az)


class GpointTE(GpointTerm):
    """gpoint ``te``, tilt of the azimuth axis towards East: ``dA = -te cos A tan E``,
    ``dE = +te sin A`` (A from South through West). TPOINT on the same azimuth: AW = +te."""

    gpoint_name: ClassVar[str] = "te"

    def offset(self, az, el):
        return -jnp.cos(az) * jnp.tan(el), jnp.sin(az)


class GpointNPAE(GpointTerm):
    """gpoint ``npae``, non-perpendicularity of the elevation and azimuth axes:
    ``dA = -npae tan E``. TPOINT: NPAE = +npae."""

    gpoint_name: ClassVar[str] = "npae"

    def offset(self, az, el):
        return -jnp.tan(el), 0.0


class GpointNPOA(GpointTerm):
    """gpoint ``npoa``, non-perpendicularity of the optical and elevation axes
    (collimation): ``dA = +npoa / cos E``. TPOINT: CA = -npoa."""

    gpoint_name: ClassVar[str] = "npoa"

    def offset(self, az, el):
        return 1.0 / jnp.cos(el), 0.0


class GpointTF(GpointTerm):
    """gpoint ``tf``, tube flexure: ``dE = +tf cos E``. TPOINT: TF = -tf (ECEC = +tf)."""

    gpoint_name: ClassVar[str] = "tf"

    def offset(self, az, el):
        return 0.0, jnp.cos(el)


GPOINT_TERMS: dict[str, type[GpointTerm]] = {
    cls.gpoint_name: cls for cls in (GpointIA, GpointTN, GpointTE, GpointNPAE, GpointNPOA, GpointIE, GpointTF)
}
"""gpoint alt-az name -> term class."""

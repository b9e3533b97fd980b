"""The model families of the level-mount (X-Y) telescope paper.

Source: Li Mengmeng, Li Zhenwei, Liu Chengzhi, "Modeling and correction of static
pointing error of level mounting telescope", Laser & Infrared 47(5) 624-629 (2017).
Despite its title the telescope is an X-Y mount (:class:`pointax.XYMount`)::

    pointing = (sin L cos B, sin B, cos L cos B)        East-North-Up      (eq 5)

with ``L`` about the horizontal North-South primary axis and ``B`` about the secondary
axis. Every term here is for that mount only (the rotations are written in its
frame).

**Sign.** As the paper's eq 20, ``Delta = encoder - sky``: ``DL = L - L0`` with ``L`` the
encoder reading and ``L0`` where the star is. A term with coefficient ``c`` and function
``f`` contributes ``Delta = c f``: the axis angles are the reading minus ``c f``. Small
angles are in radians inside and arcseconds in reports.

Four families (:func:`pointax.xy_family` builds each by name):

``"harmonic"`` (eqs 1-2, 13 + 13 terms, :class:`SphericalHarmonic`)
    ``DL cos B = sum_k a_k g_k`` and ``DB = sum_k b_k g_k`` with the 13 functions ``g``
    below. In the direction's components ``(E, N, U) = (sin L cos B, sin B, cos L
    cos B)`` they are ``1, N, U, E, N^2, UN, EN, N^3, UN^2, EN^2, N^4, UN^3, EN^3``.
    Terms ``SHL_<g>`` (the paper's ``a_k``) and ``SHB_<g>`` (``b_k``).

``"basic"`` (eqs 3-4, 10 terms, :class:`Basic`)
    The paper's basic physical model, with the elevation tilt term as it must read for
    a rigid tilt (the printed eq 4 has ``+ theta sin L``)::

        DL = eps sin L tan B + theta cos L tan B + phi tan B + C sec B
             + a1 sin L + a2 cos L + mu
        DB = eps cos L - theta sin L + a1' sin B + a2' cos B + u

``"rotation"`` (eqs 9-17, 10 parameters, rigorous)
    The paper's rotation-matrix model ``pointing = Mv ML Mphi MB MC (0, 0, 1)`` (eq 15)
    as exact rotations in the mount's chain, plus encoder zero points (eq 16) and
    eccentricities (eq 17) as encoder corrections:

    ==================  ===========  ==========================================  ======
    term (parameter)    symbol       meaning                                     eq
    ==================  ===========  ==========================================  ======
    ``tilt_rot.up``     v cos Lv     ``Mv``: primary axis turned by ``v`` about  9, 10
    ``tilt_rot.west``   v sin Lv     ``(cos Lv, 0, sin Lv)``; ``up``: its North
                                     end raised, ``west``: turned West
    ``nonperp_rot``     phi          ``Mphi = Rz(phi)`` between the axes         12
    ``collim_rot``      C            ``MC = Ry(C)`` before the boresight         14
    ``L_zero``          a'0          ``L`` encoder reading at the zenith         16
    ``B_zero``          b'0          ``B`` encoder reading at the zenith         16
    ``L_ecc_sin``       e1 cos L0    ``DL = e1 sin(L - L0)`` (``e1 = eps1 / r``)   17
    ``L_ecc_cos``       -e1 sin L0
    ``B_ecc_sin``       e2 cos B0    ``DB = e2 sin(B - B0)``                      17
    ``B_ecc_cos``       -e2 sin B0
    ==================  ===========  ==========================================  ======

    The tilt and the eccentricities are fitted as Cartesian components (the polar
    ``v, Lv`` and ``e, L0`` cannot be fitted from zero, where the angle is undefined);
    :func:`rotation_values` converts from the paper's polar form.

``"linearised"`` (eqs 18-19, 16 + 10 terms, :class:`Linearised`)
    The rotation model expanded as the paper does: ``DX, DY`` from ``M`` (eq 15) put
    into eqs 6-7, ``DL = DX / (cos L cos B) + tan L tan B DY / cos B`` and ``DB = DY /
    cos B``, regrouped by functions of ``(L, B)`` with free coefficients. The printed
    eq 18 is damaged (``a12, a13`` three times); the terms are derived here:

    =====  =========================  =====  ====================
    paper  ``dL_`` term               paper  ``dB_`` term
    =====  =========================  =====  ====================
    a0     ``1``                      b0     ``1``
    a1     ``secL_secB``              b1     ``secB``
    a2     ``secB``                   b2     ``sinL_secB``
    a3     ``tanL_secB``              b3     ``cosL_secB``
    a4     ``secL_tanB``              b4     ``sinL_tanB``
    a5     ``tanL_tanB_secB``         b5     ``cosL_tanB``
    a6     ``tanL_tanB``              b6     ``sinL``
    a7     ``tanB``                   b7     ``cosL``
    a8     ``sinL_tanL_tanB_secB``    b8     ``sinB``
    a9     ``sinL_tanB_secB``         b9     ``cosB``
    a10    ``sinL_tanL_tanB^2``
    a11    ``sinL_tanB^2``
    a12    ``sinL_tanL_tanB``
    a13    ``sinL_tanB``
    a14    ``sinL``
    a15    ``cosL``
    =====  =========================  =====  ====================

    (``secL_tanB`` is ``tan B / cos L``, ``sinL_tanB^2`` is ``sin L tan^2 B``.) Three
    functions of the exact expansion have coefficients of second order only (``cos v
    cos phi cos C - 1`` and the like) and are left out, as the paper does: ``tan L``
    and ``tan L tan^2 B`` in ``DL``, ``tan B`` in ``DB``. With the coefficients of
    :func:`linearised_from_rotation` the family equals the rotation model to second
    order in the small parameters (a test checks the t^2 scaling).

The basic family's parameters mean, to first order, what the rotation family's of the
same physics mean: ``tilt_up = v cos Lv``, ``tilt_west = v sin Lv``, ``nonperp =
phi``, but ``collim = -C`` (the paper's ``MC`` turns the boresight the other way from
its eq 3's ``C``); :func:`basic_from_rotation` does the conversion.

**Where the functions are evaluated.** At the raw reading ``(L, B)``: every
``Delta`` term is an encoder correction (:meth:`pointax.Term.encoder_offset`), so the
model is explicit, ``pointing = d(reading - Delta(reading))`` (for the rotation family
the rotations follow). The paper does not say whether its functions take the reading
or the star's position; the two differ at second order (``Delta`` times its slope,
about (150")^2 / 1 rad = 0.1" for the paper's errors). TPOINT-style sky offsets,
evaluated at the corrected position, would need the model's fixed-point iteration,
which multiplies the compile time of a fit of 26 such terms many times over.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ..core.precision import float64
from ..core.rotations import rot_y, rot_z
from ..core.term import Term, angle_pair, param

__all__ = [
    "SphericalHarmonic",
    "Basic",
    "Linearised",
    "PrimaryAxisTilt",
    "AxesNonPerpendicularity",
    "Collimation",
    "HARMONIC_FUNCTIONS",
    "HARMONIC_NAMES",
    "BASIC_NAMES",
    "LINEARISED_NAMES",
    "ROTATION_NAMES",
    "FAMILIES",
    "harmonic_terms",
    "basic_terms",
    "rotation_terms",
    "linearised_terms",
    "rotation_values",
    "basic_from_rotation",
    "linearised_from_rotation",
    "primary_axis_rotation",
]

# A function of the axis angles (L, B), radians -> (DL, DB) per unit coefficient.
OffsetFunction = Callable[[Array, Array], tuple]


# ------------------------------------------------------------------ the X-Y mount frame

# The X-Y mount frame is (East, Up, North) (pointax.core.mounts.XY_FRAME, a permutation P with
# P = P^T = P^-1): a rotation R written in East-North-Up acts as P R P there. P is a
# mirror, so a rotation about a coordinate axis changes sense: P Rz(t) P = Ry(-t) (Up is
# the mount frame's y) and P Ry(t) P = Rz(-t) (North is its z).


def _in_mount_frame(r: Float[Array, "3 3"]) -> Float[Array, "3 3"]:
    """``P R P``: an East-North-Up rotation as it acts in the X-Y mount frame (rows
    and columns 1 and 2 swapped; static slices, no gather)."""
    rows = jnp.stack([r[0], r[2], r[1]])
    return jnp.stack([rows[:, 0], rows[:, 2], rows[:, 1]], axis=1)


def primary_axis_rotation(up: Float[ArrayLike, ""], west: Float[ArrayLike, ""]) -> Float[Array, "3 3"]:
    """The paper's ``Mv`` (eq 9) in East-North-Up: the right-handed rotation by ``v =
    hypot(up, west)`` about ``(cos Lv, 0, sin Lv)`` with ``(up, west) = v (cos Lv, sin
    Lv)``, i.e. the rotation vector ``(up, 0, west)`` (radians). Smooth at ``v = 0``
    (Rodrigues with the small-angle series there), so it can be fitted from zero."""
    up, west = jnp.asarray(up, float), jnp.asarray(west, float)
    zero = jnp.zeros_like(up)
    theta2 = up * up + west * west
    small = theta2 < 1e-12
    safe2 = jnp.where(small, 1.0, theta2)
    theta = jnp.sqrt(safe2)
    # sin t / t and (1 - cos t) / t^2 = 2 sin^2(t/2) / t^2, with their series near 0.
    a = jnp.where(small, 1.0 - theta2 / 6.0, jnp.sin(theta) / theta)
    b = jnp.where(small, 0.5 - theta2 / 24.0, 2.0 * jnp.sin(theta / 2) ** 2 / safe2)
    k = jnp.stack(
        [
            jnp.stack([zero, -west, zero]),
            jnp.stack([west, zero, -up]),
            jnp.stack([zero, up, zero]),
        ]
    )
    return jnp.eye(3) + a * k + b * (k @ k)


# ------------------------------------------------------------------ table-driven terms


class _TableTerm(Term):
    """``Delta = coef * f(L, B)`` for one function ``f`` of a table, evaluated at the raw
    reading: the axis angles are the reading minus ``coef f``. Subclasses set ``TABLE``
    (name -> function) and ``FAMILY``."""

    label: str = eqx.field(static=True)
    coef: float = param(0.0)
    TABLE: ClassVar[Mapping[str, OffsetFunction]] = {}
    FAMILY: ClassVar[str] = ""

    def __check_init__(self):
        if self.label not in self.TABLE:
            raise ValueError(
                f"unknown {self.FAMILY} term {self.label!r}; expected one of {' '.join(self.TABLE)}"
            )

    @property
    def name(self) -> str:
        return self.label

    def function(self, angles: Float[Array, "2"]) -> Float[Array, "2"]:
        """``(DL, DB)`` per unit coefficient at axis angles ``(L, B)`` (radians)."""
        return angle_pair(*self.TABLE[self.label](angles[0], angles[1]))

    def encoder_offset(self, encoder):
        return -self.coef * self.function(encoder)


def _trig(L, B):
    return jnp.sin(L), jnp.cos(L), jnp.sin(B), jnp.cos(B)


# The 13 functions of the spherical-harmonic model (eqs 1-2), in the paper's order.
HARMONIC_FUNCTIONS: dict[str, Callable[[Array, Array], Array]] = {
    "1": lambda sL, cL, sB, cB: jnp.ones_like(sB),
    "sinB": lambda sL, cL, sB, cB: sB,
    "cosL_cosB": lambda sL, cL, sB, cB: cL * cB,
    "sinL_cosB": lambda sL, cL, sB, cB: sL * cB,
    "sinB^2": lambda sL, cL, sB, cB: sB**2,
    "cosL_sinB_cosB": lambda sL, cL, sB, cB: cL * sB * cB,
    "sinL_sinB_cosB": lambda sL, cL, sB, cB: sL * sB * cB,
    "sinB^3": lambda sL, cL, sB, cB: sB**3,
    "cosL_sinB^2_cosB": lambda sL, cL, sB, cB: cL * sB**2 * cB,
    "sinL_sinB^2_cosB": lambda sL, cL, sB, cB: sL * sB**2 * cB,
    "sinB^4": lambda sL, cL, sB, cB: sB**4,
    "cosL_sinB^3_cosB": lambda sL, cL, sB, cB: cL * sB**3 * cB,
    "sinL_sinB^3_cosB": lambda sL, cL, sB, cB: sL * sB**3 * cB,
}
"""Function name -> ``g(sin L, cos L, sin B, cos B)``, the paper's ``g_0 .. g_12``."""


def _harmonic_table() -> dict[str, OffsetFunction]:
    table = {}
    for key, g in HARMONIC_FUNCTIONS.items():

        def on_l(L, B, g=g):
            sL, cL, sB, cB = _trig(L, B)
            return g(sL, cL, sB, cB) / cB, 0.0

        def on_b(L, B, g=g):
            return 0.0, g(*_trig(L, B))

        table["SHL_" + key] = on_l
        table["SHB_" + key] = on_b
    # The paper's order: a_0 .. a_12, then b_0 .. b_12.
    return {k: table[k] for k in [*(f"SHL_{g}" for g in HARMONIC_FUNCTIONS), *(f"SHB_{g}" for g in HARMONIC_FUNCTIONS)]}


class SphericalHarmonic(_TableTerm):
    """One term of the paper's spherical-harmonic model (eqs 1-2): ``SHL_<g>`` adds
    ``coef g / cos B`` to ``DL`` (``DL cos B = a_k g_k``), ``SHB_<g>`` adds ``coef g`` to
    ``DB``, with ``g`` one of :data:`HARMONIC_FUNCTIONS`, e.g.
    ``SphericalHarmonic("SHL_cosL_cosB")`` is the paper's ``a_2``."""

    TABLE: ClassVar[Mapping[str, OffsetFunction]] = _harmonic_table()
    FAMILY: ClassVar[str] = "spherical-harmonic"


HARMONIC_NAMES: tuple[str, ...] = tuple(SphericalHarmonic.TABLE)
"""The harmonic family's 26 term names: ``a_0 .. a_12`` then ``b_0 .. b_12``."""


def _basic(fn):
    def f(L, B):
        return fn(*_trig(L, B))

    return f


class Basic(_TableTerm):
    """One term of the paper's basic physical model (eqs 3-4, with ``DB = eps cos L -
    theta sin L`` for a rigid tilt):

    ===============  ========  ===================  ==============  ====
    term             symbol    DL                   DB              eq
    ===============  ========  ===================  ==============  ====
    ``tilt_up``      eps       ``sin L tan B``      ``cos L``       3, 4
    ``tilt_west``    theta     ``cos L tan B``      ``-sin L``      3, 4
    ``nonperp``      phi       ``tan B``                            3
    ``collim``       C         ``sec B``                            3
    ``L_ecc_sin``    a1        ``sin L``                            3
    ``L_ecc_cos``    a2        ``cos L``                            3
    ``L_zero``       mu        ``1``                                3
    ``B_ecc_sin``    a1'                            ``sin B``       4
    ``B_ecc_cos``    a2'                            ``cos B``       4
    ``B_zero``       u                              ``1``           4
    ===============  ========  ===================  ==============  ====

    ``eps`` raises the primary axis's North end, ``theta`` turns it West (rotations of
    the mount about East and about Up); ``phi`` is the axes' non-perpendicularity,
    ``C`` the collimation error, ``a, a'`` encoder eccentricities, ``mu, u`` encoder
    zero points (the readings at the zenith).
    """

    TABLE: ClassVar[Mapping[str, OffsetFunction]] = {
        "tilt_up": _basic(lambda sL, cL, sB, cB: (sL * sB / cB, cL)),
        "tilt_west": _basic(lambda sL, cL, sB, cB: (cL * sB / cB, -sL)),
        "nonperp": _basic(lambda sL, cL, sB, cB: (sB / cB, 0.0)),
        "collim": _basic(lambda sL, cL, sB, cB: (1.0 / cB, 0.0)),
        "L_ecc_sin": _basic(lambda sL, cL, sB, cB: (sL, 0.0)),
        "L_ecc_cos": _basic(lambda sL, cL, sB, cB: (cL, 0.0)),
        "L_zero": _basic(lambda sL, cL, sB, cB: (1.0, 0.0)),
        "B_ecc_sin": _basic(lambda sL, cL, sB, cB: (0.0, sB)),
        "B_ecc_cos": _basic(lambda sL, cL, sB, cB: (0.0, cB)),
        "B_zero": _basic(lambda sL, cL, sB, cB: (0.0, 1.0)),
    }
    FAMILY: ClassVar[str] = "basic"


BASIC_NAMES: tuple[str, ...] = tuple(Basic.TABLE)
"""The basic family's 10 term names, in the order of eqs 3-4."""


class Linearised(_TableTerm):
    """One term of the paper's linearised rotation model (eqs 18-19, derived afresh):
    ``dL_<f>`` adds ``coef f`` to ``DL``, ``dB_<f>`` to ``DB``; see the table in
    :mod:`pointax.terms.xy` for the paper's ``a_0 .. a_15, b_0 .. b_9``. Single terms
    also serve as errors outside the other families, e.g. ``Linearised("dL_tanL_secB",
    px.arcsec(24))`` is ``DL = 24" tan L / cos B``."""

    TABLE: ClassVar[Mapping[str, OffsetFunction]] = {
        "dL_1": _basic(lambda sL, cL, sB, cB: (jnp.ones_like(sB), 0.0)),
        "dL_secL_secB": _basic(lambda sL, cL, sB, cB: (1.0 / (cL * cB), 0.0)),
        "dL_secB": _basic(lambda sL, cL, sB, cB: (1.0 / cB, 0.0)),
        "dL_tanL_secB": _basic(lambda sL, cL, sB, cB: (sL / (cL * cB), 0.0)),
        "dL_secL_tanB": _basic(lambda sL, cL, sB, cB: (sB / (cL * cB), 0.0)),
        "dL_tanL_tanB_secB": _basic(lambda sL, cL, sB, cB: (sL * sB / (cL * cB * cB), 0.0)),
        "dL_tanL_tanB": _basic(lambda sL, cL, sB, cB: (sL * sB / (cL * cB), 0.0)),
        "dL_tanB": _basic(lambda sL, cL, sB, cB: (sB / cB, 0.0)),
        "dL_sinL_tanL_tanB_secB": _basic(lambda sL, cL, sB, cB: (sL * sL * sB / (cL * cB * cB), 0.0)),
        "dL_sinL_tanB_secB": _basic(lambda sL, cL, sB, cB: (sL * sB / (cB * cB), 0.0)),
        "dL_sinL_tanL_tanB^2": _basic(lambda sL, cL, sB, cB: (sL * sL * sB * sB / (cL * cB * cB), 0.0)),
        "dL_sinL_tanB^2": _basic(lambda sL, cL, sB, cB: (sL * sB * sB / (cB * cB), 0.0)),
        "dL_sinL_tanL_tanB": _basic(lambda sL, cL, sB, cB: (sL * sL * sB / (cL * cB), 0.0)),
        "dL_sinL_tanB": _basic(lambda sL, cL, sB, cB: (sL * sB / cB, 0.0)),
        "dL_sinL": _basic(lambda sL, cL, sB, cB: (sL, 0.0)),
        "dL_cosL": _basic(lambda sL, cL, sB, cB: (cL, 0.0)),
        "dB_1": _basic(lambda sL, cL, sB, cB: (0.0, jnp.ones_like(sB))),
        "dB_secB": _basic(lambda sL, cL, sB, cB: (0.0, 1.0 / cB)),
        "dB_sinL_secB": _basic(lambda sL, cL, sB, cB: (0.0, sL / cB)),
        "dB_cosL_secB": _basic(lambda sL, cL, sB, cB: (0.0, cL / cB)),
        "dB_sinL_tanB": _basic(lambda sL, cL, sB, cB: (0.0, sL * sB / cB)),
        "dB_cosL_tanB": _basic(lambda sL, cL, sB, cB: (0.0, cL * sB / cB)),
        "dB_sinL": _basic(lambda sL, cL, sB, cB: (0.0, sL)),
        "dB_cosL": _basic(lambda sL, cL, sB, cB: (0.0, cL)),
        "dB_sinB": _basic(lambda sL, cL, sB, cB: (0.0, sB)),
        "dB_cosB": _basic(lambda sL, cL, sB, cB: (0.0, cB)),
    }
    FAMILY: ClassVar[str] = "linearised"


LINEARISED_NAMES: tuple[str, ...] = tuple(Linearised.TABLE)
"""The linearised family's 26 term names: ``a_0 .. a_15`` then ``b_0 .. b_9``."""


# ------------------------------------------------------------------ the rotation family


class PrimaryAxisTilt(Term):
    """The paper's ``Mv`` (eqs 9-10): the primary axis turned by ``v`` about the
    horizontal axis ``(cos Lv, 0, sin Lv)`` (East-North-Up), an exact rotation before
    axis 1. Fitted as the rotation vector's components ``up = v cos Lv`` (the North end
    of the primary axis raised) and ``west = v sin Lv`` (turned towards West), radians."""

    up: float = param(0.0)
    west: float = param(0.0)

    @property
    def name(self) -> str:
        return "tilt_rot"

    def base_rotation(self, angles):
        return _in_mount_frame(primary_axis_rotation(self.up, self.west))


class AxesNonPerpendicularity(Term):
    """The paper's ``Mphi = Rz(phi)`` (eq 12): the secondary axis is not perpendicular
    to the primary one, an exact rotation between the axes (about Up at ``L = 0``)."""

    phi: float = param(0.0)

    @property
    def name(self) -> str:
        return "nonperp_rot"

    def axes_rotation(self, angles):
        return rot_y(-self.phi)  # P Rz(phi) P


class Collimation(Term):
    """The paper's ``MC = Ry(C)`` (eq 14): the boresight is not perpendicular to the
    secondary axis, an exact rotation before the boresight. To first order ``DL = -C
    sec B`` (the basic model's ``collim`` is ``-C``)."""

    C: float = param(0.0)

    @property
    def name(self) -> str:
        return "collim_rot"

    def boresight_rotation(self, angles):
        return rot_z(-self.C)  # P Ry(C) P


ROTATION_NAMES: tuple[str, ...] = (
    "tilt_rot.up",
    "tilt_rot.west",
    "nonperp_rot",
    "collim_rot",
    "L_zero",
    "B_zero",
    "L_ecc_sin",
    "L_ecc_cos",
    "B_ecc_sin",
    "B_ecc_cos",
)
"""The rotation family's 10 parameter names."""


# ------------------------------------------------------------------ families


def harmonic_terms() -> tuple[Term, ...]:
    """The spherical-harmonic family (eqs 1-2), 26 terms at zero."""
    return tuple(SphericalHarmonic(n) for n in HARMONIC_NAMES)


def basic_terms() -> tuple[Term, ...]:
    """The basic physical family (eqs 3-4), 10 terms at zero."""
    return tuple(Basic(n) for n in BASIC_NAMES)


def rotation_terms() -> tuple[Term, ...]:
    """The rotation-matrix family (eqs 9-17): ``Mv``, ``Mphi``, ``MC`` as exact
    rotations and the six encoder terms (eqs 16-17, the same functions as the basic
    family's: :class:`Basic`), 10 parameters at zero."""
    encoder = ("L_zero", "B_zero", "L_ecc_sin", "L_ecc_cos", "B_ecc_sin", "B_ecc_cos")
    return (PrimaryAxisTilt(), AxesNonPerpendicularity(), Collimation(), *(Basic(n) for n in encoder))


def linearised_terms() -> tuple[Term, ...]:
    """The linearised rotation family (eqs 18-19), 16 + 10 terms at zero."""
    return tuple(Linearised(n) for n in LINEARISED_NAMES)


FAMILIES: dict[str, Callable[[], tuple[Term, ...]]] = {
    "harmonic": harmonic_terms,
    "basic": basic_terms,
    "rotation": rotation_terms,
    "linearised": linearised_terms,
}
"""Family name -> builder of its terms (at zero)."""


# ------------------------------------------------------------------ conversions


def rotation_values(
    v: float = 0.0,
    Lv: float = 0.0,
    phi: float = 0.0,
    C: float = 0.0,
    L_zero: float = 0.0,
    B_zero: float = 0.0,
    L_ecc: float = 0.0,
    L_ecc_phase: float = 0.0,
    B_ecc: float = 0.0,
    B_ecc_phase: float = 0.0,
) -> dict[str, np.float64]:
    """The rotation family's parameter values (radians, by name) from the paper's
    symbols (radians): tilt ``v`` about ``(cos Lv, 0, sin Lv)`` (eq 9),
    non-perpendicularity ``phi``, collimation ``C``, zero points ``a'0, b'0`` and
    eccentricities ``DL = L_ecc sin(L - L_ecc_phase)``, ``DB = B_ecc sin(B -
    B_ecc_phase)`` (eq 17's ``eps1 / r``, ``L0``, ``eps2 / r``, ``B0``)."""
    values = {
        "tilt_rot.up": v * np.cos(Lv),
        "tilt_rot.west": v * np.sin(Lv),
        "nonperp_rot": phi,
        "collim_rot": C,
        "L_zero": L_zero,
        "B_zero": B_zero,
        "L_ecc_sin": L_ecc * np.cos(L_ecc_phase),
        "L_ecc_cos": -L_ecc * np.sin(L_ecc_phase),
        "B_ecc_sin": B_ecc * np.cos(B_ecc_phase),
        "B_ecc_cos": -B_ecc * np.sin(B_ecc_phase),
    }
    return {k: np.float64(x) for k, x in values.items()}


def _rotation_params(values: Mapping[str, ArrayLike]) -> dict[str, Array]:
    unknown = sorted(set(values) - set(ROTATION_NAMES))
    if unknown:
        raise ValueError(f"not rotation-family parameters: {unknown}; expected names from {list(ROTATION_NAMES)}")
    return {n: jnp.asarray(values.get(n, 0.0), float) for n in ROTATION_NAMES}


@float64
def basic_from_rotation(values: Mapping[str, ArrayLike]) -> dict[str, Array]:
    """The basic family's values that equal the rotation family's ``values`` (by
    parameter name, radians; missing ones are 0) to first order: the tilt components,
    ``phi``, ``-C``, and the encoder terms as they are."""
    p = _rotation_params(values)
    return {
        "tilt_up": p["tilt_rot.up"],
        "tilt_west": p["tilt_rot.west"],
        "nonperp": p["nonperp_rot"],
        "collim": -p["collim_rot"],
        "L_ecc_sin": p["L_ecc_sin"],
        "L_ecc_cos": p["L_ecc_cos"],
        "L_zero": p["L_zero"],
        "B_ecc_sin": p["B_ecc_sin"],
        "B_ecc_cos": p["B_ecc_cos"],
        "B_zero": p["B_zero"],
    }


@float64
def linearised_from_rotation(values: Mapping[str, ArrayLike]) -> dict[str, Array]:
    """The linearised family's 26 coefficients for the rotation family's ``values``
    (by parameter name, radians; missing ones are 0): the exact trigonometric
    coefficients of the expansion (the paper's list under eq 19, re-derived), with
    ``m = Mv`` (:func:`primary_axis_rotation`)::

        DX / R = X(M) - sin L cos B,   DY / R = Y(M) - sin B
        DL = DX / (cos L cos B) + tan L tan B DY / cos B,   DB = DY / cos B     (eqs 6-7)

    negated (those are sky minus encoder), plus the encoder terms. Equal to the
    rotation model to second order in its parameters."""
    p = _rotation_params(values)
    m = primary_axis_rotation(p["tilt_rot.up"], p["tilt_rot.west"])
    cp, sp = jnp.cos(p["nonperp_rot"]), jnp.sin(p["nonperp_rot"])
    cc, sc = jnp.cos(p["collim_rot"]), jnp.sin(p["collim_rot"])
    m11, m12, m13 = m[0, 0], m[0, 1], m[0, 2]
    m21, m22, m23 = m[1, 0], m[1, 1], m[1, 2]
    # Sky minus encoder, by function (see the module docstring for the derivation).
    sky_minus_encoder = {
        "dL_1": m13 * cc,
        "dL_secL_secB": m12 * sp * sc,
        "dL_secB": m11 * cp * sc,
        "dL_tanL_secB": -m13 * cp * sc,
        "dL_secL_tanB": m12 * cp * cc,
        "dL_tanL_tanB_secB": m22 * sp * sc,
        "dL_tanL_tanB": m13 * sp * cc,
        "dL_tanB": -m11 * sp * cc,
        "dL_sinL_tanL_tanB_secB": -m23 * cp * sc,
        "dL_sinL_tanB_secB": m21 * cp * sc,
        "dL_sinL_tanL_tanB^2": m23 * sp * cc,
        "dL_sinL_tanB^2": -m21 * sp * cc,
        "dL_sinL_tanL_tanB": m21 * cc,
        "dL_sinL_tanB": m23 * cc,
        "dB_secB": m22 * sp * sc,
        "dB_sinL_secB": -m23 * cp * sc,
        "dB_cosL_secB": m21 * cp * sc,
        "dB_sinL_tanB": m23 * sp * cc,
        "dB_cosL_tanB": -m21 * sp * cc,
        "dB_sinL": m21 * cc,
        "dB_cosL": m23 * cc,
    }
    out = {n: -sky_minus_encoder.get(n, jnp.asarray(0.0)) for n in LINEARISED_NAMES}
    out["dL_1"] = out["dL_1"] + p["L_zero"]
    out["dL_sinL"] = p["L_ecc_sin"]
    out["dL_cosL"] = p["L_ecc_cos"]
    out["dB_1"] = p["B_zero"]
    out["dB_sinB"] = p["B_ecc_sin"]
    out["dB_cosB"] = p["B_ecc_cos"]
    return out

"""TPOINT's harmonic terms, generated from their names.

A harmonic term's name says what it is::

    H  R  F1 V1 [m1]  [F2 V2 [m2]]

* ``H``: a harmonic term.
* ``R``: what it corrects: ``A`` azimuth, ``E`` elevation, ``S`` cross-elevation
  (a sideways offset on the sky, ``dA cos E``), ``Z`` zenith distance (``dE = -dZ``).
* ``F``: ``S`` sine or ``C`` cosine; ``V``: its argument, ``A`` azimuth, ``E``
  elevation or ``Z`` zenith distance (``90 deg - E``); ``m``: an optional integer
  multiplier >= 1 (1 when left out).
* An optional second factor of the same kind multiplies the first.

This is the grammar of P. T. Wallace's TPOINT routine for generic terms (``tptPtermg``),
whose formats are ``HRFC``, ``HRFCI`` (to three digits, ``HRFCII``, ``HRFCIII``),
``HRFCFC``, ``HRFCIFC``, ``HRFCFCI``, ``HRFCIFCI``, ``HRFCIIFC`` and ``HRFCFCII``: pointax
reads any multipliers, a superset. TPOINT also takes, on any mount, the other mount's
corrections and arguments (``HXCA`` on an alt-az mount, ``HASH`` on an equatorial one)
and the parallactic angle ``Q`` as an argument; those need the site's latitude and
raise :class:`pointax.terms.NotYetInPointax`. TPOINT's polynomial terms, the
same idea with powers, are :mod:`pointax.terms.polynomial`.

Examples: ``HACA2`` (``dA`` proportional to ``cos 2A'``), ``HESE5`` (``dE`` proportional
to ``sin 5E``), ``HZSZ2`` (zenith distance proportional to ``sin 2z``), ``HESACE``
(``dE`` proportional to ``sin A' cos E``), ``HSCA5CE8`` (cross-elevation proportional
to ``cos 5A' cos 8E``). Names are case-insensitive and kept upper-case; the multiplier
is kept as written (``HACA`` and ``HACA1`` are the same function under two names, so
use one of them).

TPOINT's conventions (``DESIGN.md``, checked there against a published 22-term TPOINT
fit of a real alt-az run, where every coefficient came back within 0.4 sigma):

* **Azimuth argument.** Inside the functions the azimuth is ``A' = 180 deg - A``, with
  ``A`` the azimuth *as the data count it*: the mount's ``azimuth`` convention, i.e. the
  numbers in the TPOINT file. What ``A'`` is on the sky therefore depends on that
  convention (``A_NE`` = azimuth from North through East):

  ==============  =======================  =============================================
  convention      A (as written)           A' = 180 deg - A
  ==============  =======================  =============================================
  ``"N-E"``       ``A_NE``                 ``180 deg - A_NE`` (from South through East)
  ``"S-E"``       ``180 deg - A_NE``       ``A_NE`` (from North through East)
  ``"S-W"``       ``A_NE - 180 deg``       ``-A_NE`` (from North through West)
  ==============  =======================  =============================================

  So the coefficients of a harmonic fit, like TPOINT's, belong to the way the file
  counts azimuth: a model and its data must use the same convention (they do when the
  model is built with ``azimuth=run.azimuth``). Cosines of even multiples do not
  notice: ``cos 2(180 deg - A) = cos 2A``.
* **Sign.** As IA and IE: observed minus raw is ``dA = -coef f`` for ``A`` terms,
  ``dE = +coef f`` for ``E`` terms and ``dA cos E = -coef f`` for ``S`` terms.

Hence TPOINT's identities ACEC = HACA1, ACES = HASA1, ECEC = HECE1, ECES = HESE1 with
the centring terms of :mod:`pointax.terms.tpoint_terms` (a test checks all four, in both
forms).

**Equatorial harmonic terms** (``mount="equatorial"``, for
:class:`pointax.EquatorialMount`): the same grammar with ``R`` one of ``H`` hour angle,
``D`` declination, ``X`` east-west (cross-declination, ``dh cos dec``) and the
arguments ``H`` (hour angle, positive West, as the mount reads it: no ``180 deg -``
turn) and ``D`` (declination): ``HHSH``, ``HHCH2``, ``HDSD``, ``HDCD``, ``HXSH2CD``.
TPOINT users' models hold such names (e.g. ``HHSH HHCH HDSH HDCH`` in the HATS
model, github.com/guigue/CRAAM-Instruments/wiki/HATS-Pointing-Model). The sign follows
IH, ID and CH of :mod:`pointax.terms.equatorial` (observed minus raw ``dh = +coef f``,
``ddec = +coef f``, ``dh cos dec = +coef f``): **by analogy** with the alt-az rule
(which was checked on TPOINT output), not checked against TPOINT output for
equatorial terms. With it TPOINT's identities HCES = HHSH1, HCEC = HHCH1,
DCES = HDSD1, DCEC = HDCD1 hold (a test checks them). Like the named equatorial terms
the functions are of the mechanical angles, so on a German mount's flipped side
(``h + 180 deg``, ``180 deg - dec``) they take the values there.

Two forms, like the named terms:

* ``form="linear"`` (:class:`Harmonic`): TPOINT's own definition, an offset of the
  pointing evaluated at the corrected (sky) position. ``S`` terms have a pole at the
  zenith (``dA = -coef f / cos E``), as TPOINT's.
* ``form="rigorous"`` (:class:`RigorousHarmonic`): ``A`` and ``E`` terms are encoder
  errors, ``coef f`` added to the encoder angle and evaluated at the raw encoder
  reading (where a periodic encoder error lives: this is what the rigorous ACEC,
  ACES, ECEC, ECES already are); ``S`` terms turn the boresight sideways by
  ``-coef f`` about the tube's axis perpendicular to the elevation axis (the rigorous
  CA with a coefficient that varies with position), an exact cross-elevation offset
  with no pole at the zenith. To first order in the coefficient both forms agree.
"""

from __future__ import annotations

import dataclasses
import re

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from ..core.rotations import rot_z
from ..core.term import Term, angle_pair, param
from .linear import LinearTerm, NotYetInPointax

__all__ = [
    "HarmonicSpec",
    "GeneratedTerm",
    "RigorousGeneratedTerm",
    "TPOINT_RESULTS",
    "TPOINT_ARGUMENTS",
    "not_yet_letter",
    "describe_offset",
    "Harmonic",
    "RigorousHarmonic",
    "parse_harmonic",
    "is_harmonic_name",
    "harmonic_term",
    "harmonic_function",
    "RESULTS",
    "EQUATORIAL_RESULTS",
]

RESULTS = {"A": "azimuth", "E": "elevation", "S": "cross-elevation (dA cos E)", "Z": "zenith distance"}
"""Letter after ``H`` -> what the term corrects (alt-az)."""
EQUATORIAL_RESULTS = {"H": "hour angle", "D": "declination", "X": "east-west (dh cos dec)"}
"""Letter after ``H`` -> what the term corrects (equatorial)."""
_FUNCTIONS = {"S": "sine", "C": "cosine"}
_ARGUMENTS = {"A": "azimuth", "E": "elevation", "Z": "zenith distance"}
_EQUATORIAL_ARGUMENTS = {"H": "hour angle", "D": "declination"}
_MOUNTS = ("altaz", "equatorial")
_MAX_FACTORS = 2

# Every letter TPOINT's generic terms accept (Wallace's tptPtermg and tptPtappl): what a
# term corrects and the coordinates of its functions, on any mount. Those a mount here
# does not take need the site's latitude (or, Q, the parallactic angle) to convert.
TPOINT_RESULTS = {**RESULTS, **EQUATORIAL_RESULTS}
"""Every letter TPOINT accepts for what a generated (harmonic, polynomial) term corrects."""
TPOINT_ARGUMENTS = {**_ARGUMENTS, **_EQUATORIAL_ARGUMENTS, "Q": "parallactic angle"}
"""Every coordinate TPOINT's generated terms take."""

# result letter -> (axis corrected, sign of observed minus raw, cross-axis: divided by
# cos of axis 2). Alt-az A, E, S: checked on TPOINT output; Z: Wallace's tptPtappl (a
# zenith-distance change, the sign of TF); equatorial: by analogy with IH ID CH.
_RESULT_RULES = {
    "A": (0, -1.0, False),
    "E": (1, 1.0, False),
    "S": (0, -1.0, True),
    "Z": (1, -1.0, False),
    "H": (0, 1.0, False),
    "D": (1, 1.0, False),
    "X": (0, 1.0, True),
}


def describe_offset(result: str, f: str) -> str:
    """``coef * f`` as the offset a generated term with result letter ``result`` adds."""
    return {
        "A": f"dA = -coef {f}",
        "E": f"dE = +coef {f}",
        "S": f"dA cos E = -coef {f}",
        "Z": f"dE = -coef {f}",
        "H": f"dh = +coef {f}",
        "D": f"ddec = +coef {f}",
        "X": f"dh cos dec = +coef {f}",
    }[result]


def not_yet_letter(kind: str, name: str, pos: int, letter: str, mount: str) -> NotYetInPointax:
    """The error for a letter TPOINT's generated term names accept but pointax's mount
    ``mount`` does not take (yet): ``kind`` is 'harmonic' or 'polynomial'."""
    meaning = TPOINT_RESULTS.get(letter) if pos == 1 else TPOINT_ARGUMENTS.get(letter)
    need = (
        "the site's latitude to compute"
        if letter == "Q"
        else "a conversion between the alt-az and equatorial frames, which needs the site's latitude"
    )
    return NotYetInPointax(
        f"{kind} term {name!r}: character {pos + 1} is {letter!r} ({meaning}); TPOINT accepts it on "
        f"{'an alt-az' if mount == 'altaz' else 'an equatorial'} mount, but it needs {need}: "
        "TPOINT's, not yet in pointax"
    )


@dataclasses.dataclass(frozen=True)
class HarmonicSpec:
    """A parsed harmonic-term name.

    Attributes:
        name: the name, upper-case, as written (e.g. ``"HSCA5CE8"``).
        result: ``"A"``, ``"E"``, ``"S"`` or ``"Z"`` (alt-az), ``"H"``, ``"D"`` or
            ``"X"`` (equatorial): what the term corrects.
        factors: ``((function, argument, multiplier), ...)``, one or two factors, with
            function ``"S"``/``"C"``, argument ``"A"``/``"E"``/``"Z"`` (or ``"H"``/``"D"``)
            and an integer multiplier.
    """

    name: str
    result: str
    factors: tuple[tuple[str, str, int], ...]

    @property
    def mount(self) -> str:
        """``"altaz"`` or ``"equatorial"``: the mount the name is a term of."""
        return "equatorial" if self.result in EQUATORIAL_RESULTS else "altaz"

    def describe(self) -> str:
        """The formula in words, e.g. ``dA = -coef cos(2 A')``, ``dh = +coef sin(h)``."""
        parts = []
        for func, arg, mult in self.factors:
            x = {"A": "A'", "E": "E", "Z": "z", "H": "h", "D": "dec"}[arg]
            multiplier = "" if mult == 1 else f"{mult} "
            parts.append(f"{'sin' if func == 'S' else 'cos'}({multiplier}{x})")
        return describe_offset(self.result, " ".join(parts))


def is_harmonic_name(name: str) -> bool:
    """Whether ``name`` is meant as a harmonic term (starts with ``H``, case-insensitive).

    Every TPOINT alt-az term pointax knows by a fixed name starts with another letter.
    """
    return isinstance(name, str) and name.strip().upper().startswith("H")


def parse_harmonic(name: str, mount: str = "altaz") -> HarmonicSpec:
    """Parse a TPOINT harmonic-term name such as ``HACA2``, ``HESACE`` or ``HSCA5CE8``
    (``mount="altaz"``), or ``HHSH``, ``HDCD2``, ``HXSH2CD`` (``mount="equatorial"``).

    Raises:
        NotYetInPointax: (a ``ValueError``) for a letter TPOINT accepts there but pointax
            does not take on this mount yet: a correction or coordinate of the other
            mount (``HXCA`` alt-az, ``HASH`` equatorial) or the parallactic angle ``Q``,
            which need the site's latitude.
        ValueError: naming the character that does not fit the grammar
            ``H {A|E|S|Z} {S|C}{A|E|Z}[m] [{S|C}{A|E|Z}[m]]`` (alt-az) or
            ``H {H|D|X} {S|C}{H|D}[m] [{S|C}{H|D}[m]]`` (equatorial), or for an unknown mount.
    """
    if mount not in _MOUNTS:
        raise ValueError(f"unknown mount {mount!r} for harmonic terms; expected one of {list(_MOUNTS)}")
    text = name.strip().upper()
    equatorial = mount == "equatorial"
    results = EQUATORIAL_RESULTS if equatorial else RESULTS
    arguments = _EQUATORIAL_ARGUMENTS if equatorial else _ARGUMENTS

    def bad(pos: int, what: str):
        got = repr(text[pos]) if pos < len(text) else "the end of the name"
        if equatorial:
            grammar = (
                "(equatorial harmonic names read H, then H/D/X for what is corrected, then one or two "
                "factors S or C, H or D, optional multiplier; e.g. HHSH, HDCD2, HXSH2CD)"
            )
        else:
            grammar = (
                "(harmonic names read H, then A/E/S for what is corrected, then one or two factors "
                "S or C, A or E, optional multiplier; e.g. HACA2, HESE5, HESACE, HSCA5CE8)"
            )
        return ValueError(f"harmonic term {name!r}: character {pos + 1} is {got}, expected {what} {grammar}")

    if not text.startswith("H"):
        raise bad(0, "'H'")
    if len(text) >= 2 and text[1] not in results and text[1] in TPOINT_RESULTS:
        raise not_yet_letter("harmonic", name, 1, text[1], mount)
    if len(text) < 2 or text[1] not in results:
        raise bad(
            1,
            "H (hour angle), D (declination) or X (east-west)"
            if equatorial
            else "A (azimuth), E (elevation) or S (cross-elevation), or Z (zenith distance)",
        )
    pos, factors = 2, []
    while pos < len(text) or not factors:
        if len(factors) == _MAX_FACTORS:
            raise ValueError(
                f"harmonic term {name!r}: at most {_MAX_FACTORS} factors are supported; "
                f"{text[pos:]!r} follows the second"
            )
        if pos >= len(text) or text[pos] not in _FUNCTIONS:
            raise bad(pos, "S (sine) or C (cosine)")
        if pos + 1 < len(text) and text[pos + 1] not in arguments and text[pos + 1] in TPOINT_ARGUMENTS:
            raise not_yet_letter("harmonic", name, pos + 1, text[pos + 1], mount)
        if pos + 1 >= len(text) or text[pos + 1] not in arguments:
            raise bad(
                pos + 1,
                "H (hour angle) or D (declination) as the argument"
                if equatorial
                else "A (azimuth) or E (elevation) as the argument, or Z (zenith distance)",
            )
        digits = re.match(r"\d*", text[pos + 2 :]).group(0)
        if digits.startswith("0"):
            raise ValueError(
                f"harmonic term {name!r}: multiplier {digits!r} must be an integer >= 1 without leading zeros"
            )
        factors.append((text[pos], text[pos + 1], int(digits) if digits else 1))
        pos += 2 + len(digits)
    return HarmonicSpec(text, text[1], tuple(factors))


def harmonic_function(
    factors: tuple[tuple[str, str, int], ...], az: Float[Array, ""], el: Float[Array, ""]
) -> Float[Array, ""]:
    """The product of the factors at the mount's angles ``(az, el)`` (radians): azimuth
    (as the data count it) and elevation, or hour angle and declination. The azimuth
    argument is ``A' = pi - az`` (TPOINT's convention); the hour angle ``H`` is ``az``
    itself, ``D`` and ``E`` are ``el``, ``Z`` is ``pi/2 - el``."""
    out = jnp.ones_like(jnp.asarray(az, float))
    for func, arg, mult in factors:
        x = {"A": jnp.pi - az, "H": az, "Z": jnp.pi / 2 - el}.get(arg, el)
        out = out * (jnp.sin(mult * x) if func == "S" else jnp.cos(mult * x))
    return out


class GeneratedTerm(LinearTerm):
    """A term TPOINT generates from its name (a harmonic or polynomial term), linear
    form: ``coef * f`` added as ``_RESULT_RULES`` says for its ``result`` letter, ``f``
    given by :meth:`function` at the sky position."""

    coef: float = param(0.0)
    label: str = eqx.field(static=True, default="HACA1")
    result: str = eqx.field(static=True, default="A")
    factors: tuple[tuple[str, str, int], ...] = eqx.field(static=True, default=(("C", "A", 1),))

    @property
    def name(self) -> str:
        return self.label

    def function(self, az, el):
        """The term's function of the mount's angles (radians)."""
        raise NotImplementedError

    def basis(self, p):
        f = self.function(p.az, p.el)
        axis, sign, cross = _RESULT_RULES[self.result]
        if axis == 1:
            return 0.0, sign * f
        return (sign * f / p.cos_el if cross else sign * f), 0.0


class RigorousGeneratedTerm(Term):
    """A generated term in rigorous form: an encoder correction at the raw reading
    (axis-angle results) or a turn of the boresight (cross-axis results ``S``, ``X``)."""

    coef: float = param(0.0)
    neutral_at_zero = True  # 0 adds exactly nothing: carried switched off, never probed
    label: str = eqx.field(static=True, default="HACA1")
    result: str = eqx.field(static=True, default="A")
    factors: tuple[tuple[str, str, int], ...] = eqx.field(static=True, default=(("C", "A", 1),))

    @property
    def name(self) -> str:
        return self.label

    def function(self, az, el):
        raise NotImplementedError

    def encoder_offset(self, encoder):
        axis, sign, cross = _RESULT_RULES[self.result]
        if cross:
            return None
        f = sign * self.coef * self.function(encoder[0], encoder[1])
        return angle_pair(f, 0.0) if axis == 0 else angle_pair(0.0, f)

    def boresight_rotation(self, angles):
        axis, sign, cross = _RESULT_RULES[self.result]
        if not cross:
            return None
        # rot_z(t) turns the boresight so that axis 1 changes by -t sec(axis 2).
        return rot_z(-sign * self.coef * self.function(angles[0], angles[1]))


class Harmonic(GeneratedTerm):
    """A TPOINT harmonic term in TPOINT's linear form (see :mod:`pointax.terms.harmonic`).

    ``dA = -coef f`` (``A`` terms), ``dE = +coef f`` (``E`` terms),
    ``dA cos E = -coef f`` (``S`` terms) or ``dE = -coef f`` (``Z`` terms, a change of
    zenith distance), with ``f`` the product of the named sines and cosines of
    ``A' = 180 deg - A``, ``E`` and ``z = 90 deg - E``, evaluated at the sky position.
    Build one with :func:`harmonic_term` or :func:`pointax.terms.tpoint`.

    Attributes:
        coef: the coefficient, radians (reported in arcseconds).
        label: the term's name, e.g. ``"HACA2"`` (static).
        result: ``"A"``, ``"E"``, ``"S"`` or ``"Z"`` (``"H"``, ``"D"``, ``"X"``
            equatorial) (static).
        factors: ``((function, argument, multiplier), ...)`` (static).
    """

    def function(self, az, el):
        return harmonic_function(self.factors, az, el)


class RigorousHarmonic(RigorousGeneratedTerm):
    """A TPOINT harmonic term in rigorous form (see :mod:`pointax.terms.harmonic`).

    ``A``, ``E`` and ``Z`` terms: ``-coef f`` added to the azimuth encoder angle,
    ``+coef f`` (``Z``: ``-coef f``) to the elevation encoder angle, ``f`` evaluated at
    the raw encoder reading. ``S`` terms: the boresight turned by ``-coef f`` towards
    increasing azimuth (``rot_z(coef f)`` before the boresight, as the rigorous CA),
    ``f`` evaluated at the corrected axis angles: a cross-elevation offset of exactly
    ``-coef f``.

    Attributes: as :class:`Harmonic`.
    """

    def function(self, az, el):
        return harmonic_function(self.factors, az, el)


def harmonic_term(
    name: str, coef: float = 0.0, form: str = "rigorous", mount: str = "altaz"
) -> Harmonic | RigorousHarmonic:
    """The harmonic term called ``name`` (e.g. ``"HACA2"``; ``"HHSH"`` with
    ``mount="equatorial"``) with coefficient ``coef`` (radians), in the
    ``"rigorous"`` form (the default, as TPOINT applies it) or TPOINT's ``"linear"`` form.

    Raises:
        ValueError: for a name that is not a harmonic term of ``mount`` (the message
            says which character is wrong), an unknown form or an unknown mount.
    """
    spec = parse_harmonic(name, mount=mount)
    forms = {"linear": Harmonic, "rigorous": RigorousHarmonic}
    if form not in forms:
        raise ValueError(f"unknown term form {form!r}; expected one of {sorted(forms)}")
    return forms[form](coef=coef, label=spec.name, result=spec.result, factors=spec.factors)

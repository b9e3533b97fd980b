"""TPOINT's generic polynomial terms, generated from their names (``PAA1``, ``PEE2``,
``PSZ2``, ``PAA1E2``, ``PHD2`` ...).

A polynomial term's name says what it is (Wallace's ``tptPtermg``, TPOINT's routine for
its generic terms, formats ``PRC``, ``PRCI``, ``PRCIC``, ``PRCICI``)::

    P  R  C1 [n1]  [C2 [n2]]

* ``R``: what it corrects, as for harmonic terms (:mod:`pointax.terms.harmonic`):
  alt-az ``A`` azimuth, ``E`` elevation, ``S`` cross-elevation (``dA cos E``), ``Z``
  zenith distance; equatorial ``H`` hour angle, ``D`` declination, ``X`` east-west
  (``dh cos dec``).
* ``C``: a coordinate, ``n`` its power, one digit 0-9 (1 when left out). Alt-az: ``A``
  (TPOINT's azimuth ``A_T``, below), ``E`` elevation, ``Z`` zenith distance;
  equatorial: ``H`` hour angle, ``D`` declination. A second coordinate may follow only
  a first that has its power written (``PAA1E``, ``PAA2E3``; ``PAAE`` is not a TPOINT
  name).

The function is ``C1**n1 * C2**n2``, the coordinates in radians, evaluated at the sky
position, and the term adds ``coef`` times it with the signs of the harmonic terms
(observed - raw ``dA = -coef f``, ``dE = +coef f``, ``dA cos E = -coef f``,
``dE = -coef f`` for ``Z``; ``dh = +coef f``, ``ddec = +coef f``,
``dh cos dec = +coef f``).

**The azimuth of a polynomial** is TPOINT's internal one, ``A_T = 180 deg - A`` with
``A`` as the data count it, reduced to (-180, 180] deg
(:func:`pointax.terms.tpoint_terms.tpoint_azimuth`), as Wallace's ``tptPtpre`` computes it with
``atan2``: unlike a harmonic, a polynomial notices the branch, and TPOINT's is this one.
The hour angle is reduced to (-180, 180] deg likewise. On a German mount's flipped side
TPOINT uses the mechanical hour angle ``h + 180 deg`` without reducing it, so a
polynomial in ``H`` fitted across the pier may differ from TPOINT's by that branch.

TPOINT also accepts the parallactic angle ``Q`` and the coordinates and corrections of
the other mount (``PAH1`` on an alt-az mount): those need the site's latitude and
raise :class:`pointax.terms.NotYetInPointax`.

**Checked against:** Wallace's definition, written out independently in
``tests/test_tpoint_repertoire.py``; not against TPOINT output (no public run with a
published TPOINT fit holds a polynomial term).

Forms: ``"linear"`` (:class:`Polynomial`, TPOINT's) and ``"rigorous"``
(:class:`RigorousPolynomial`: azimuth, elevation, zenith-distance, hour-angle and
declination terms correct the encoder angle at the raw reading; cross-axis terms turn
the boresight, as :class:`pointax.terms.harmonic.RigorousHarmonic`).
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp

from .harmonic import (
    EQUATORIAL_RESULTS,
    RESULTS,
    TPOINT_ARGUMENTS,
    TPOINT_RESULTS,
    GeneratedTerm,
    RigorousGeneratedTerm,
    describe_offset,
    not_yet_letter,
)
from .linear import tpoint_azimuth

__all__ = [
    "PolynomialSpec",
    "Polynomial",
    "RigorousPolynomial",
    "parse_polynomial",
    "is_polynomial_name",
    "polynomial_term",
    "polynomial_function",
]

_ALTAZ_COORDINATES = {"A": "TPOINT's azimuth A_T", "E": "elevation", "Z": "zenith distance"}
_EQUATORIAL_COORDINATES = {"H": "hour angle", "D": "declination"}
_MOUNTS = ("altaz", "equatorial")


@dataclasses.dataclass(frozen=True)
class PolynomialSpec:
    """A parsed polynomial-term name.

    Attributes:
        name: the name, upper-case (e.g. ``"PAA1E2"``).
        result: what the term corrects (as :class:`pointax.terms.harmonic.HarmonicSpec`).
        factors: ``(("P", coordinate, power), ...)``, one or two.
    """

    name: str
    result: str
    factors: tuple[tuple[str, str, int], ...]

    def describe(self) -> str:
        """The formula in words, e.g. ``dA = -coef A_T^2 E``."""
        symbol = {"A": "A_T", "E": "E", "Z": "z", "H": "h", "D": "dec"}
        f = " ".join(symbol[c] + ("" if n == 1 else f"^{n}") for _, c, n in self.factors)
        return describe_offset(self.result, f)


def is_polynomial_name(name: str) -> bool:
    """Whether ``name`` is meant as a polynomial term (``P`` then a letter TPOINT takes
    for what a term corrects, case-insensitive)."""
    text = name.strip().upper() if isinstance(name, str) else ""
    return len(text) >= 2 and text[0] == "P" and text[1] in TPOINT_RESULTS


def parse_polynomial(name: str, mount: str = "altaz") -> PolynomialSpec:
    """Parse a TPOINT polynomial-term name (``PAA1``, ``PEE2``, ``PSZ2``, ``PAA1E2``;
    ``PHH1``, ``PDD2``, ``PXD1H`` with ``mount="equatorial"``).

    Raises:
        NotYetInPointax: (a ``ValueError``) for a letter TPOINT accepts but this mount
            does not take here (the other mount's, or the parallactic angle ``Q``).
        ValueError: naming the character that does not fit TPOINT's formats, or for an
            unknown mount.
    """
    if mount not in _MOUNTS:
        raise ValueError(f"unknown mount {mount!r} for polynomial terms; expected one of {list(_MOUNTS)}")
    text = name.strip().upper()
    equatorial = mount == "equatorial"
    results = EQUATORIAL_RESULTS if equatorial else RESULTS
    coordinates = _EQUATORIAL_COORDINATES if equatorial else _ALTAZ_COORDINATES

    def bad(pos: int, what: str):
        got = repr(text[pos]) if pos < len(text) else "the end of the name"
        example = "PHH1, PDD2, PXD1H" if equatorial else "PAA1, PEE2, PSZ2, PAA1E2"
        return ValueError(
            f"polynomial term {name!r}: character {pos + 1} is {got}, expected {what} (polynomial names read P, "
            f"then what is corrected ({'/'.join(results)}), then a coordinate ({'/'.join(coordinates)}) with "
            f"an optional one-digit power, then optionally a second coordinate, after a written power; e.g. {example})"
        )

    if not text.startswith("P"):
        raise bad(0, "'P'")
    if len(text) >= 2 and text[1] not in results and text[1] in TPOINT_RESULTS:
        raise not_yet_letter("polynomial", name, 1, text[1], mount)
    if len(text) < 2 or text[1] not in results:
        raise bad(1, " or ".join(f"{k} ({v})" for k, v in results.items()))
    pos, factors = 2, []
    while pos < len(text) or not factors:
        if len(factors) == 2:
            raise bad(pos, "the end of the name (at most two coordinates)")
        if factors and factors[0][3] is False:
            raise bad(pos, "a one-digit power after the first coordinate (TPOINT's formats PRC, PRCI, PRCIC, PRCICI)")
        if pos < len(text) and text[pos] not in coordinates and text[pos] in TPOINT_ARGUMENTS:
            raise not_yet_letter("polynomial", name, pos, text[pos], mount)
        if pos >= len(text) or text[pos] not in coordinates:
            raise bad(pos, " or ".join(f"{k} ({v})" for k, v in coordinates.items()))
        written = pos + 1 < len(text) and text[pos + 1].isdigit()
        factors.append(("P", text[pos], int(text[pos + 1]) if written else 1, written))
        pos += 2 if written else 1
    return PolynomialSpec(text, text[1], tuple(f[:3] for f in factors))


def _coordinate(letter: str, az, el):
    if letter == "A":
        return tpoint_azimuth(jnp.sin(az), jnp.cos(az))
    if letter == "H":
        return jnp.arctan2(jnp.sin(az), jnp.cos(az))
    if letter == "Z":
        return jnp.pi / 2 - el
    return el  # E, D


def polynomial_function(factors: tuple[tuple[str, str, int], ...], az, el):
    """The product ``C1**n1 * C2**n2`` at the mount's angles ``(az, el)`` (radians):
    azimuth as the data count it and elevation, or hour angle and declination."""
    out = jnp.ones_like(jnp.asarray(az, float))
    for _, letter, power in factors:
        out = out * _coordinate(letter, az, el) ** power
    return out


class Polynomial(GeneratedTerm):
    """A TPOINT polynomial term in TPOINT's linear form (:mod:`pointax.terms.polynomial`).

    Attributes:
        coef: the coefficient, radians (reported in arcseconds).
        label: the term's name, e.g. ``"PAA1E2"`` (static).
        result: what it corrects (static).
        factors: ``(("P", coordinate, power), ...)`` (static).
    """

    def function(self, az, el):
        return polynomial_function(self.factors, az, el)


class RigorousPolynomial(RigorousGeneratedTerm):
    """A TPOINT polynomial term in rigorous form: an encoder correction at the raw
    reading, or (``S``, ``X``) a turn of the boresight. Attributes: as :class:`Polynomial`."""

    def function(self, az, el):
        return polynomial_function(self.factors, az, el)


def polynomial_term(name: str, coef: float = 0.0, form: str = "rigorous", mount: str = "altaz"):
    """The polynomial term called ``name`` with coefficient ``coef`` (radians), in the
    ``"rigorous"`` (default) or ``"linear"`` form.

    Raises:
        ValueError: for a name that is not a polynomial term of ``mount``, an unknown
            form or mount (:class:`pointax.terms.NotYetInPointax` for one TPOINT
            takes but pointax does not yet).
    """
    spec = parse_polynomial(name, mount=mount)
    forms = {"linear": Polynomial, "rigorous": RigorousPolynomial}
    if form not in forms:
        raise ValueError(f"unknown term form {form!r}; expected one of {sorted(forms)}")
    return forms[form](coef=coef, label=spec.name, result=spec.result, factors=spec.factors)

"""TPOINT's auxiliary-reading terms: a coefficient times an auxiliary reading (a value
recorded with each observation: a temperature, a rotator angle, a dome position ...),
applied as one of TPOINT's corrections.

**Source.** P. T. Wallace's TPOINT term routines, public C source under his copyright,
found in a public code index: ``tptPterms`` (standard terms, last revision 14 November
2006; its argument ``auxil[3]`` holds "auxiliary readings if any") and ``tptPtermg``
(generic terms, last revision 14 March 2001). Their definitions:

* ``AUX1H``, ``AUX1X``, ``AUX1D``, ``AUX1A``, ``AUX1S``, ``AUX1E`` (``tptPterms`` cases
  40-45) and ``AUX2H`` ... ``AUX2E`` (cases 46-51): "change in HA / EW on the sky / Dec /
  Az / LR on the sky / El equal to coefficient AUXnR multiplied by the first (second)
  auxiliary reading", e.g. ``dHA = +AUX1H*AUX1``, ``dAz = +AUX1S*AUX1/cos(El)``.
* ``ZH``, the AAT's hour-angle Z-gear effect (case 3): ``dHA = +ZH*AUX1`` (the same
  function as ``AUX1H``); ``ZE``, its Z-gear effect in polar-axis elevation (case 7):
  "rotation about EW axis equal to coefficient ZE multiplied by first auxiliary
  reading", ``dHA = +ZE*AUX1*sin(HA)*tan(DEC)``, ``dDec = +ZE*AUX1*cos(HA)``: ME's
  function times ``AUX1``.
* generic terms ``A{n}{R}`` (``tptPtermg``, format ``A``): ``n`` = 1, 2 or 3 picks
  ``auxil[n-1]``, ``R`` is the correction it is applied as, any of TPOINT's ``H X D A S
  E Z`` (Z: zenith distance), e.g. ``A3Z``.

**Signs in pointax.** TPOINT applies a type-``R`` correction ``coef * f`` exactly as it
applies its basic terms of that type (``tptPtappl``), so with ``f`` the reading each
term is ``reading`` times the function of the checked basic term of its letter
(observed minus raw, as everywhere in pointax; ``A``, ``E`` as the data count them):

=====  ==============================  =============================  ==================
R      pointax offset                  basic term with f = 1           checked against
=====  ==============================  =============================  ==================
A      ``dA = -coef r``                IA                              TPOINT output
E      ``dE = +coef r``                IE                              TPOINT output
S      ``dA cos E = -coef r``          CA                              TPOINT output
Z      ``dE = -coef r``                FLOP                            Wallace's code
H      ``dh = +coef r``                IH                              Wallace's fit
D      ``ddec = +coef r``              ID                              Wallace's fit
X      ``dh cos dec = +coef r``        CH                              Wallace's fit
ZE     ``dh = +coef r sin h tan dec``, ME                              Wallace's fit
       ``ddec = +coef r cos h``
=====  ==============================  =============================  ==================

(``r`` the reading; the same rules as :mod:`pointax.terms.harmonic`'s generated terms).
No public TPOINT fit with auxiliary terms was found, so beyond these identities (a test
checks each, and a fit of simulated runs recovers the coefficients) they are not
checked against TPOINT output. The reading is used as recorded, in its own unit (a
coefficient is radians per unit of the reading): TPOINT multiplies the auxiliary
reading as it stands.

**Readings.** By default ``AUX1x``, ``ZH``, ``ZE`` and ``A1x`` read ``aux1``; ``AUX2x``,
``A2x`` read ``aux2``; ``A3x`` reads ``aux3``: the names under which
:func:`pointax.io.read_tpoint` keeps a record's auxiliary fields by position.
``reading="temperature"`` makes the term read another reading instead (the term is
then named ``AUX1E@temperature``). ``h``, ``dec`` terms are of an equatorial mount,
``A``, ``E``, ``S``, ``Z`` terms of an alt-az one; the other mount's letters (TPOINT
converts them with the site's latitude) raise :class:`NotYetInPointax`.
"""

from __future__ import annotations

import functools
import re
from typing import ClassVar

import equinox as eqx

from .harmonic import GeneratedTerm, describe_offset
from .linear import LinearTerm, NotYetInPointax

__all__ = [
    "AuxiliaryTerm",
    "Aux1Term",
    "Aux2Term",
    "Aux3Term",
    "ZE",
    "AUXILIARY_RESULTS",
    "STANDARD_AUXILIARY",
    "is_auxiliary_name",
    "parse_auxiliary",
    "auxiliary_term",
]

AUXILIARY_RESULTS = {
    "altaz": {"A": "azimuth", "E": "elevation", "S": "cross-elevation (dA cos E)", "Z": "zenith distance"},
    "equatorial": {"H": "hour angle", "D": "declination", "X": "east-west (dh cos dec)"},
}
"""Mount -> the correction letters its auxiliary terms take, and what each corrects."""

STANDARD_AUXILIARY = {
    **{f"AUX{n}{r}": (n, r) for n in (1, 2) for r in "HXDASE"},
    "ZH": (1, "H"),
    "ZE": (1, "U"),
}
"""TPOINT's standard auxiliary terms (``tptPterms``) -> (reading number, correction
letter); ``U`` is ZE's rotation about the east-west axis."""

_GENERIC = re.compile(r"^A([1-3])([HXDASEZ])$")


def is_auxiliary_name(name: str) -> bool:
    """Whether ``name`` is one of TPOINT's auxiliary terms (``AUX1H`` ... ``AUX2E``,
    ``ZH``, ``ZE``, generic ``A{1-3}{HXDASEZ}``), case-insensitive."""
    if not isinstance(name, str):
        return False
    text = name.strip().upper()
    return text in STANDARD_AUXILIARY or bool(_GENERIC.match(text))


def parse_auxiliary(name: str, mount: str = "altaz") -> tuple[str, int, str]:
    """``(name upper-case, reading number 1-3, correction letter)`` of an auxiliary
    term's name on ``mount``.

    Raises:
        NotYetInPointax: for a letter of the other mount (TPOINT converts it with the
            site's latitude; pointax does not yet).
        ValueError: for a name that is not an auxiliary term, or an unknown mount.
    """
    if mount not in AUXILIARY_RESULTS:
        raise ValueError(f"unknown mount {mount!r}; expected one of {list(AUXILIARY_RESULTS)}")
    text = name.strip().upper() if isinstance(name, str) else name
    if not is_auxiliary_name(text):
        raise ValueError(
            f"{name!r} is not a TPOINT auxiliary term: expected AUX1H ... AUX2E (AUX{{1|2}}{{H|X|D|A|S|E}}), ZH, ZE "
            "or a generic A{1|2|3}{H|X|D|A|S|E|Z}"
        )
    if text in STANDARD_AUXILIARY:
        number, letter = STANDARD_AUXILIARY[text]
    else:
        m = _GENERIC.match(text)
        number, letter = int(m.group(1)), m.group(2)
    own = "equatorial" if letter in AUXILIARY_RESULTS["equatorial"] or letter == "U" else "altaz"
    if own != mount:
        raise NotYetInPointax(
            f"TPOINT term {text!r} is TPOINT's but not yet in pointax on {'an alt-az' if mount == 'altaz' else 'an equatorial'} "
            f"mount: it corrects the {'equatorial' if own == 'equatorial' else 'alt-az'} coordinates, which TPOINT "
            f"converts with the site's latitude, pointax does not yet (use it with mount={own!r})"
        )
    return text, number, letter


class AuxiliaryTerm(GeneratedTerm):
    """TPOINT's auxiliary term in TPOINT's linear form: ``coef * r`` (``r`` the reading
    this class reads, :attr:`readings`) applied as the correction ``result`` (see
    :mod:`pointax.terms.tpoint_auxiliary` for the table). Build one with
    :func:`auxiliary_term` (or :func:`pointax.terms.tpoint`).

    Attributes:
        coef: radians per unit of the reading (reported in arcseconds).
        label: the term's name, e.g. ``"AUX1E"`` (static).
        result: the correction letter (static).
    """

    readings: ClassVar[tuple[str, ...]] = ("aux1",)
    factors: tuple = eqx.field(static=True, default=())

    def function(self, az, el):
        return self.reading(self.readings[0]) + 0.0 * az

    def describe(self) -> str:
        """The formula in words, e.g. ``dE = +coef aux1``."""
        return describe_offset(self.result, self.readings[0])


class Aux1Term(AuxiliaryTerm):
    """An auxiliary term reading ``aux1`` (TPOINT's first auxiliary reading)."""

    readings: ClassVar[tuple[str, ...]] = ("aux1",)


class Aux2Term(AuxiliaryTerm):
    """An auxiliary term reading ``aux2`` (TPOINT's second auxiliary reading)."""

    readings: ClassVar[tuple[str, ...]] = ("aux2",)


class Aux3Term(AuxiliaryTerm):
    """An auxiliary term reading ``aux3`` (TPOINT's third auxiliary reading)."""

    readings: ClassVar[tuple[str, ...]] = ("aux3",)


class ZE(LinearTerm):
    """The AAT's hour-angle Z-gear effect in polar-axis elevation (Wallace's
    ``tptPterms``, case 7): a rotation about the east-west axis of ``ZE * aux1``, i.e.
    ME's function times the first auxiliary reading: ``dh = +ZE aux1 sin h tan dec``,
    ``ddec = +ZE aux1 cos h`` (equatorial). Not checked against TPOINT output."""

    readings: ClassVar[tuple[str, ...]] = ("aux1",)
    label: str = eqx.field(static=True, default="ZE")

    @property
    def name(self) -> str:
        return self.label

    def basis(self, p):
        r = self.reading(self.readings[0])
        return r * p.sin_az * p.tan_el, r * p.cos_az


_DEFAULT_CLASSES = {"aux1": Aux1Term, "aux2": Aux2Term, "aux3": Aux3Term}


@functools.cache
def _class_reading(base: type, reading: str) -> type:
    """``base`` reading ``reading`` instead (one class per pair, so that models built
    twice share their structure and a fit does not compile again)."""
    if base is ZE:
        if reading == "aux1":
            return ZE
        return type(f"ZE_{re.sub(r'[^0-9A-Za-z_]', '_', reading)}", (ZE,), {"readings": (reading,), "__module__": __name__})
    if reading in _DEFAULT_CLASSES:
        return _DEFAULT_CLASSES[reading]
    safe = re.sub(r"[^0-9A-Za-z_]", "_", reading)
    return type(f"AuxTerm_{safe}", (AuxiliaryTerm,), {"readings": (reading,), "__module__": __name__})


def auxiliary_term(name: str, coef: float = 0.0, mount: str = "altaz", reading: str | None = None):
    """TPOINT's auxiliary term ``name`` (``AUX1E``, ``A3Z``, ``ZH``, ``ZE`` ...) on
    ``mount``, with its starting coefficient ``coef`` (radians per unit of the reading).

    Args:
        name: the term's TPOINT name, case-insensitive.
        coef: starting value.
        mount: 'altaz' or 'equatorial'.
        reading: the reading it multiplies; default ``aux<n>`` (``n`` from the name),
            the names :func:`pointax.io.read_tpoint` gives a record's auxiliary fields.
            Another name (``"temperature"``) names the term ``<NAME>@<reading>``.

    Raises:
        NotYetInPointax: for a term of the other mount.
        ValueError: for a name that is not an auxiliary term, or an empty reading name.
    """
    text, number, letter = parse_auxiliary(name, mount)
    default = f"aux{number}"
    if reading is not None and (not isinstance(reading, str) or not reading.strip()):
        raise ValueError(f"auxiliary term {text}: reading must be a non-empty name, got {reading!r}")
    reading = default if reading is None else reading.strip()
    label = text if reading == default else f"{text}@{reading}"
    if letter == "U":
        return _class_reading(ZE, reading)(coef=coef, label=label)
    cls = _class_reading(AuxiliaryTerm, reading)
    return cls(coef=coef, label=label, result="H" if letter == "H" else letter)

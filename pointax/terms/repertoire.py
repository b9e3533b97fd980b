"""TPOINT's repertoire: which of its term names pointax builds, and why the others are
refused with :class:`pointax.terms.NotYetInPointax` (a ``ValueError`` whose
message says the term is TPOINT's but not yet in pointax) rather than as unknown names.

Built (:func:`pointax.terms.tpoint`):

* alt-az named terms: IA IE CA NPAE AN AW TF TX ACEC ACES ECEC ECES PAA1 PEE1
  (:mod:`pointax.terms.tpoint_terms`), NRX NRY CRX CRY FLOP TFP ANL AWL CAL NPAEL TXL
  (:mod:`pointax.terms.tpoint_special`);
* equatorial named terms: IH ID CH NP MA ME TF FO DAF HCES HCEC DCES DCEC
  (:mod:`pointax.terms.equatorial`), TX TFP FLOP DAB DNP HF HFX HFD X2HC HGES HGEC DGES
  DGEC CD4A CD4B CD5A CD5B CHL MAL MEL NPL (:mod:`pointax.terms.equatorial_special`);
* generated names: harmonics ``H...`` (:mod:`pointax.terms.harmonic`) and polynomials
  ``P...`` (:mod:`pointax.terms.polynomial`) in the coordinates of the mount;
* terms driven by auxiliary readings (AUX1H ... AUX2E, the AAT's ZH and ZE, generic
  auxiliary terms ``A{n}{R}``: :mod:`pointax.terms.tpoint_auxiliary`), on their mount.

Refused as TPOINT's but not yet in pointax (:data:`NOT_YET`, :func:`not_yet_reason`):

* a named term of the other mount (IH on an alt-az mount, IA on an equatorial one), and
  generated names with the other mount's coordinates or corrections or the parallactic
  angle ``Q``: TPOINT converts them with the site's latitude, pointax does not yet;
* names seen in public TPOINT model files whose definition is not public: TX10.

The definitions are P. T. Wallace's TPOINT routines ``tptPterms`` (standard terms) and
``tptPtermg`` (generic terms), public C source; each module names what it took.
"""

from __future__ import annotations

from .linear import NotYetInPointax

__all__ = ["NOT_YET", "not_yet_reason", "not_yet_error"]

NOT_YET: dict[str, str] = {
    "TX10": (
        "a term name found in public TPOINT model files, not among TPOINT's standard terms in P. T. Wallace's "
        "public term routine tptPterms (2006) nor in its generic-term grammar; no public definition of it was "
        "found (perhaps a locally implemented term)"
    ),
}
"""Named TPOINT terms pointax refuses, with the reason."""


def not_yet_reason(name: str, mount: str) -> str | None:
    """Why ``name`` (upper-case), a TPOINT name, is not built for ``mount``; None when it
    is not such a name (unknown, or built)."""
    from . import equatorial
    from .tpoint_terms import LINEAR_TERMS

    if name in NOT_YET:
        return NOT_YET[name]
    if mount == "altaz" and name in equatorial.EQUATORIAL_LINEAR_TERMS and name not in LINEAR_TERMS:
        return (
            f"TPOINT's equatorial term; TPOINT also applies it on an alt-az mount, converting it with the "
            f"site's latitude, which pointax does not yet (use it with mount='equatorial')"
        )
    if mount == "equatorial" and name in LINEAR_TERMS and name not in equatorial.EQUATORIAL_LINEAR_TERMS:
        return (
            "TPOINT's alt-az term; TPOINT also applies it on an equatorial mount, converting it with the "
            "site's latitude, which pointax does not yet (use it with mount='altaz')"
        )
    return None


def not_yet_error(name: str, reason: str) -> NotYetInPointax:
    """The error :func:`pointax.terms.tpoint` raises for such a name."""
    return NotYetInPointax(f"TPOINT term {name!r} is TPOINT's but not yet in pointax: {reason}")

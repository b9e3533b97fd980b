"""Model families named for a mount: the level-mount paper's X-Y families and TPOINT's
alt-az and equatorial sets, resolved from names to :class:`pointax.Model` objects
(:func:`family_model`).

For an X-Y mount the level-mount paper's families (``basic``, ``harmonic``,
``rotation``, ``linearised``) and term names of :mod:`pointax.terms.xy`; for an alt-az
mount ``basic`` (TPOINT's eight terms), ``harmonic`` (those plus
:data:`ALTAZ_HARMONICS`) and TPOINT term names; for an equatorial mount ``basic``
(TPOINT's six: IH ID CH NP MA ME), ``flexure`` (those and TF FO DAF), ``harmonic``
(those and :data:`EQUATORIAL_HARMONICS`) and TPOINT's equatorial term names.
"""

from __future__ import annotations

from collections.abc import Iterable

from .. import terms as term_library
from ..core.model import Model
from ..core.mounts import AZIMUTH_CONVENTIONS, AltAzMount, EquatorialMount, Mount, XYMount
from ..core.observations import Observations
from ..terms import xy as xy_terms
from ..core.term import Term

__all__ = ["ALTAZ_FAMILIES", "ALTAZ_HARMONICS", "EQUATORIAL_FAMILIES", "EQUATORIAL_HARMONICS", "family_model"]

ALTAZ_HARMONICS: tuple[str, ...] = ("HACA2", "HASA2", "HECA2", "HESA2", "HSCA2", "HSSA2")
"""The harmonic set the alt-az ``harmonic`` family adds to TPOINT's basic eight: the
second azimuth harmonics (cos 2A', sin 2A') of azimuth, elevation and cross-elevation
(TPOINT's names, :mod:`pointax.terms.harmonic`)."""

ALTAZ_FAMILIES: dict[str, tuple[str, ...]] = {
    "basic": term_library.BASIC_ALTAZ,
    "harmonic": term_library.BASIC_ALTAZ + ALTAZ_HARMONICS,
    "gpoint": tuple(term_library.gpoint_names(term_library.GPOINT_ALTAZ_TERMS)),
}
"""Alt-az family name -> term names: ``basic`` is TPOINT's eight basic terms,
``harmonic`` adds :data:`ALTAZ_HARMONICS`, ``gpoint`` is RTS2 gpoint's default seven
(only with ``naming="gpoint"``)."""


EQUATORIAL_HARMONICS: tuple[str, ...] = ("HHSH2", "HHCH2", "HDSH2", "HDCH2", "HXSH2", "HXCH2")
"""The harmonic set the equatorial ``harmonic`` family adds: the second hour-angle
harmonics (sin 2H, cos 2H) of hour angle, declination and cross-declination (TPOINT's
names, :mod:`pointax.terms.harmonic`)."""

EQUATORIAL_FAMILIES: dict[str, tuple[str, ...]] = {
    "basic": term_library.BASIC_EQUATORIAL,
    "flexure": term_library.BASIC_EQUATORIAL + ("TF", "FO", "DAF"),
    "harmonic": term_library.BASIC_EQUATORIAL + ("TF", "FO", "DAF") + EQUATORIAL_HARMONICS,
}
"""Equatorial family name -> term names: ``basic`` is TPOINT's six basic terms (IH ID CH
NP MA ME), ``flexure`` adds tube flexure TF, fork flexure FO and declination-axis
flexure DAF, ``harmonic`` adds :data:`EQUATORIAL_HARMONICS` to those."""


def _mount_of(obs: Observations) -> Mount:
    convention = obs.convention
    if convention == "xy":
        return XYMount()
    if convention in AZIMUTH_CONVENTIONS:
        return AltAzMount(azimuth=convention)
    if convention == "ha-dec":
        raise ValueError(
            "equatorial observations do not carry the site's latitude: name the families for a "
            "pointax.EquatorialMount(latitude), or pass the run (pointax.io.read_tpoint) instead of its observations"
        )
    raise ValueError(
        f"cannot build a model family by name for observations with convention {convention!r}: "
        "names are known for X-Y ('xy') and alt-az ('N-E', 'S-E', 'S-W') data; pass pointax.Model objects"
    )


def _tokens(spec: str | Iterable[str]) -> list[str]:
    if isinstance(spec, str):
        return spec.replace(",", " ").split()
    return [s.strip() for s in spec if s.strip()]


_XY_ROTATIONS = {
    "tilt_rot": xy_terms.PrimaryAxisTilt,
    "nonperp_rot": xy_terms.AxesNonPerpendicularity,
    "collim_rot": xy_terms.Collimation,
}


def _xy_terms(tokens: list[str]) -> tuple[Term, ...]:
    out: list[Term] = []
    for token in tokens:
        key = "linearised" if token == "linearized" else token
        if key in xy_terms.FAMILIES:
            out.extend(xy_terms.FAMILIES[key]())
        elif token in xy_terms.Basic.TABLE:
            out.append(xy_terms.Basic(token))
        elif token in xy_terms.Linearised.TABLE:
            out.append(xy_terms.Linearised(token))
        elif token in xy_terms.SphericalHarmonic.TABLE:
            out.append(xy_terms.SphericalHarmonic(token))
        elif token in _XY_ROTATIONS:
            out.append(_XY_ROTATIONS[token]())
        else:
            raise ValueError(
                f"unknown X-Y family or term {token!r}; families: {', '.join(xy_terms.FAMILIES)}; terms: the names of "
                "pointax.terms.xy (Basic, Linearised, SphericalHarmonic tables) and tilt_rot, nonperp_rot, collim_rot"
            )
    return tuple(out)


def _altaz_terms(tokens: list[str], naming: str, form: str) -> tuple[Term, ...]:
    names: list[str] = []
    for token in tokens:
        key = token.lower()
        if key in ALTAZ_FAMILIES and (key != "gpoint" or naming == "gpoint"):
            names.extend(ALTAZ_FAMILIES[key])
        else:
            names.append(token)
    if naming == "gpoint":
        return term_library.gpoint_terms(names, form=form)
    return term_library.tpoint(names, form=form)


def _equatorial_terms(tokens: list[str], form: str, latitude) -> tuple[Term, ...]:
    names: list[str] = []
    for token in tokens:
        names.extend(EQUATORIAL_FAMILIES.get(token.lower(), (token,)))
    return term_library.tpoint(names, form=form, mount="equatorial", latitude=latitude)


def family_model(
    spec: str | Iterable[str], mount: Mount | Observations, *, naming: str = "tpoint", form: str = "rigorous"
) -> Model:
    """A model named by a family or a list of terms, for the mount at hand.

    Args:
        spec: family names and term names separated by spaces or commas (a family name
            expands to its terms), e.g. ``"basic"``, ``"rotation dL_tanL_secB"``,
            ``"basic HACA2 HESE2"``, ``"IA IE CA NPAE AN AW"``.

            * X-Y mount: families ``basic``, ``harmonic``, ``rotation``, ``linearised``
              (:data:`pointax.XY_FAMILIES`); terms of :mod:`pointax.terms.xy` by name.
            * Alt-az mount: ``basic`` (TPOINT's eight), ``harmonic`` (those and
              :data:`ALTAZ_HARMONICS`), ``gpoint`` (gpoint's seven, with
              ``naming="gpoint"``); TPOINT term names (:func:`pointax.terms.tpoint`), or
              with ``naming="gpoint"`` gpoint's names too
              (:func:`pointax.terms.gpoint_terms`: lower-case ``ia``, extras).
            * Equatorial mount: ``basic``, ``flexure``, ``harmonic``
              (:data:`EQUATORIAL_FAMILIES`) and TPOINT's equatorial term names.
        mount: the mount, observations whose convention names it ('xy', or an
            azimuth convention for alt-az), or a TPOINT run (an equatorial one gives
            its latitude).
        naming: 'tpoint' or 'gpoint' (alt-az term names only).
        form: 'rigorous' (default) or 'linear' (TPOINT terms only).

    Raises:
        ValueError: an unknown name, a term named twice, or a mount without names.
    """
    if naming not in ("tpoint", "gpoint"):
        raise ValueError(f"naming must be 'tpoint' or 'gpoint', got {naming!r}")
    if getattr(mount, "mount", None) == "equatorial" and hasattr(mount, "latitude"):
        mount = EquatorialMount(mount.latitude)  # a TPOINT run
    elif hasattr(mount, "observations"):
        mount = mount.observations
    if isinstance(mount, Observations):
        mount = _mount_of(mount)
    tokens = _tokens(spec)
    if not tokens:
        raise ValueError("empty model family: give a family name or term names")
    if isinstance(mount, XYMount):
        return Model(mount, _xy_terms(tokens))
    if isinstance(mount, AltAzMount):
        return Model(mount, _altaz_terms(tokens, naming, form))
    if isinstance(mount, EquatorialMount):
        if naming != "tpoint":
            raise ValueError("equatorial families are named with TPOINT's names (naming='tpoint')")
        return Model(mount, _equatorial_terms(tokens, form, mount.latitude))
    raise ValueError(f"no named families for a {type(mount).__name__}; pass pointax.Model objects")

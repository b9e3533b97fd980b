"""TPOINT's term repertoire: the named terms beyond the basic ones, polynomial terms,
harmonic terms in zenith distance, and the names pointax refuses as TPOINT's but not yet
built.

References, outside the code under test: P. T. Wallace's TPOINT term routines
(``tptPterms``, ``tptPtermg``, ``tptPtappl``, ``tptPtpre``; public C source), whose
statements are written out here term by term as (kind, function) pairs in TPOINT's own
coordinates (azimuth ``A_T`` South = 0, East = +90 deg); the translation of those kinds
into pointax's observed-minus-raw offsets, which is checked first on the terms already
checked against real TPOINT output (IA ... TX, centring terms; IH ... TF); a finite
change of zenith distance done with spherical trigonometry for the equatorial ``Z``
kind; the geometry of a displaced rotator; central finite differences for Jacobians.
None of the new terms is checked against TPOINT output: no public run with a published
TPOINT fit holds them.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import MMT_DAT

import pointax as px
from pointax.io import ModelTerm, TpointFormatError, format_model, read_model
from pointax.terms import equatorial as eq
from pointax.core.term import SkyPoint, _linearity_error

# Terms are checked against their formulas with unit coefficients (1 rad): the formulas are
# linear in them, and pointax's warning of an implausible pointing term is expected.
pytestmark = pytest.mark.filterwarnings("ignore:.*most likely in degrees:pointax.core.errors.InputWarning")

ARCSEC = np.pi / 648000
s, c, t = np.sin, np.cos, np.tan
LAT = np.radians(-29.26)
RNG = np.random.default_rng(27)
# Alt-az positions away from A_T = +-180 deg (where TPOINT's azimuth wraps) and the zenith.
AZ = np.concatenate([RNG.uniform(0.2, 2 * np.pi - 0.2, 10), [-2.0, 5.5]])
ALTAZ = np.stack([AZ, RNG.uniform(0.15, 1.4, 12)], -1)
EQUAT = np.stack([RNG.uniform(-3.0, 3.0, 12), RNG.uniform(-1.2, 1.2, 12)], -1)


def a_t(A):
    """TPOINT's azimuth, South 0, East +90 deg, in (-pi, pi]: 180 deg - A reduced."""
    return np.mod(np.pi - A + np.pi, 2 * np.pi) - np.pi


# ----------------------------------------------------------------- alt-az: Wallace's statements

# name -> [(kind, f(A_T, E)), ...] as tptPterms (and tptPtermg for PAA1, PEE1) state them.
# 'N', 'W', 'V' kinds of the basic terms are written here in their linear (A, E) form,
# as Wallace's comments beside them give it.
WALLACE_ALTAZ = {
    "IA": [("A", lambda a, e: 1.0)],
    "IE": [("E", lambda a, e: 1.0)],
    "CA": [("S", lambda a, e: 1.0)],
    "NPAE": [("S", lambda a, e: s(e))],
    "AN": [("A", lambda a, e: s(a) * t(e)), ("E", lambda a, e: c(a))],
    "AW": [("A", lambda a, e: -c(a) * t(e)), ("E", lambda a, e: s(a))],
    "TF": [("Z", lambda a, e: c(e))],  # sin(ZD)
    "TX": [("Z", lambda a, e: 1 / t(e))],  # tan(ZD)
    "ACES": [("A", lambda a, e: s(a))],
    "ACEC": [("A", lambda a, e: c(a))],
    "ECES": [("E", lambda a, e: s(e))],
    "ECEC": [("E", lambda a, e: c(e))],
    "PAA1": [("A", lambda a, e: a)],
    "PEE1": [("E", lambda a, e: e)],
    "NRX": [("S", lambda a, e: c(e)), ("E", lambda a, e: -s(e))],
    "NRY": [("S", lambda a, e: s(e)), ("E", lambda a, e: c(e))],
    "CRX": [("S", lambda a, e: c(a + e)), ("E", lambda a, e: -s(a + e))],
    "CRY": [("S", lambda a, e: s(a + e)), ("E", lambda a, e: c(a + e))],
    "FLOP": [("Z", lambda a, e: 1.0)],
    "TFP": [("Z", lambda a, e: (np.pi / 2 - e) ** 4)],
    "ANL": [("A", lambda a, e: s(a) * s(e) / c(e)), ("E", lambda a, e: c(a))],
    "AWL": [("A", lambda a, e: -c(a) * s(e) / c(e)), ("E", lambda a, e: s(a))],
    "CAL": [("A", lambda a, e: 1 / c(e))],
    "NPAEL": [("A", lambda a, e: s(e) / c(e))],
    "TXL": [("E", lambda a, e: -c(e) / s(e))],
}
CHECKED_ON_TPOINT_OUTPUT = ("IA", "IE", "CA", "NPAE", "AN", "AW", "TF", "TX")


def wallace_altaz(name, A, E):
    """(dA, dE) observed - raw with A as the data count it: TPOINT's adjustments of
    A_T (dA = -dA_T), left-right S (dA = -dS / cos E), E and zenith distance Z."""
    dA = dE = 0.0
    for kind, f in WALLACE_ALTAZ[name]:
        v = f(a_t(A), E)
        if kind == "A":
            dA -= v
        elif kind == "S":
            dA -= v / c(E)
        elif kind == "E":
            dE += v
        else:
            dE -= v
    return np.broadcast_to(np.array([dA, dE], dtype=float), (2,))


def test_every_alt_az_named_term_is_stated():
    assert sorted(px.terms.LINEAR_TERMS) == sorted(WALLACE_ALTAZ)
    assert sorted(px.terms.rigorous.RIGOROUS_TERMS) == sorted(WALLACE_ALTAZ)


@pytest.mark.parametrize("name", sorted(WALLACE_ALTAZ))
def test_alt_az_terms_are_wallaces_statements(name):
    """The translation reproduces the terms checked on TPOINT output (IA ... TX) and the
    centring terms, so the same translation defines the others."""
    term = px.terms.LINEAR_TERMS[name](coef=1.0)
    for A, E in ALTAZ:
        got = np.asarray(term.sky_offset(jnp.array([A, E])))
        np.testing.assert_allclose(got, wallace_altaz(name, A, E), rtol=1e-12, atol=1e-13, err_msg=name)


def test_new_terms_say_where_they_come_from():
    from pointax.terms import equatorial_special, tpoint_special

    for module, table in ((tpoint_special, tpoint_special.SPECIAL_ALTAZ_TERMS),
                          (equatorial_special, equatorial_special.SPECIAL_EQUATORIAL_TERMS)):  # fmt: skip
        assert "tptPterms" in module.__doc__ and "None of the terms of this module has been checked" in module.__doc__
        for name, cls in table.items():
            assert "Not checked against TPOINT output" in " ".join(cls.__doc__.split()), name
    for name in ("PAA1", "PEE1"):
        assert "tptPtermg" in px.terms.LINEAR_TERMS[name].__doc__


def test_nasmyth_and_coude_offsets_are_a_fixed_vector_turned():
    """A displaced rotator axis gives an on-sky offset of constant length: NRX, NRY (turned
    by E) and CRX, CRY (turned by A_T + E)."""
    nrx, nry = 7.0 * ARCSEC, -4.0 * ARCSEC
    for x_name, y_name in (("NRX", "NRY"), ("CRX", "CRY")):
        terms = px.terms.tpoint([x_name, y_name], values={x_name: nrx, y_name: nry})
        for A, E in ALTAZ:
            off = sum(np.asarray(tm.sky_offset(jnp.array([A, E]))) for tm in terms)
            assert np.hypot(off[0] * c(E), off[1]) == pytest.approx(np.hypot(nrx, nry), rel=1e-12)


def test_linear_identities():
    """TPOINT's own definitions make NRX = IA - ECES and NRY = NPAE + ECEC (so neither can be
    fitted beside those), FLOP = -IE, and the approximate terms equal the exact ones in the
    linear form."""
    identities = {
        "NRX": {"IA": 1, "ECES": -1},
        "NRY": {"NPAE": 1, "ECEC": 1},
        "FLOP": {"IE": -1},
        "ANL": {"AN": 1},
        "AWL": {"AW": 1},
        "CAL": {"CA": 1},
        "NPAEL": {"NPAE": 1},
        "TXL": {"TX": 1},
    }
    for name, combination in identities.items():
        lhs = px.terms.LINEAR_TERMS[name](coef=1.0)
        for A, E in ALTAZ:
            p = jnp.array([A, E])
            rhs = sum(k * np.asarray(px.terms.LINEAR_TERMS[n](coef=1.0).sky_offset(p)) for n, k in combination.items())
            np.testing.assert_allclose(np.asarray(lhs.sky_offset(p)), rhs, atol=1e-13, err_msg=name)


def test_paa1_follows_tpoints_azimuth_branch():
    """PAA1's variable is A_T in (-180, 180] deg: on a file counting North through East the
    slope is +1 in A, and the wrap is at A = 0 (North)."""
    term = px.terms.PAA1(coef=1.0)
    offset = lambda A: float(term.sky_offset(jnp.array([A, 0.5]))[0])  # noqa: E731
    assert offset(1.0) == pytest.approx(1.0 - np.pi)  # -A_T = -(pi - A)
    assert offset(2 * np.pi - 0.1) == pytest.approx(np.pi - 0.1)
    assert offset(-0.1) == pytest.approx(np.pi - 0.1)  # the same direction, the same value
    assert offset(0.1) == pytest.approx(0.1 - np.pi)


# ----------------------------------------------------------------- equatorial


def hd_to_ae(h, d, phi):
    """(A_T, E): azimuth South 0, East +90 deg, from hour angle (West +) and declination."""
    x = s(phi) * c(h) * c(d) - c(phi) * s(d)
    y = -s(h) * c(d)
    z = c(phi) * c(h) * c(d) + s(phi) * s(d)
    return np.arctan2(y, x), np.arcsin(z)


def ae_to_hd(a, e, phi):
    x, y, z = c(a) * c(e), s(a) * c(e), s(e)
    xe = s(phi) * x + c(phi) * z
    ze = -c(phi) * x + s(phi) * z
    return np.arctan2(-y, xe), np.arcsin(ze)


def zenith_direction(h, d, phi, eps=1e-7):
    """(dh, ddec) per radian of zenith distance, by a finite move down the vertical."""
    a, e = hd_to_ae(h, d, phi)
    h2, d2 = ae_to_hd(a, e - eps, phi)
    h1, d1 = ae_to_hd(a, e + eps, phi)
    return (np.mod(h2 - h1 + np.pi, 2 * np.pi) - np.pi) / (2 * eps), (d2 - d1) / (2 * eps)


def cos_z(h, d, phi):
    return s(phi) * s(d) + c(phi) * c(d) * c(h)


def hfx(h, d):
    h2, h3, h5, d2 = 2 * h, 3 * h, 5 * h, 2 * d
    return (0.219 * s(h5) + 0.368 * c(h5 + h) + 0.195 * s(h5 + h5 + h5)
            + (1.279 * s(h2) - 1.718 * s(h2 + h2) + 1.202 * c(h5)) * s(d)
            - 1.928 * s(h3) * c(d) + (3.662 * s(h) + 0.381 * c(h3)) * s(d2)
            - 1.156 * s(h3) * c(d2) + (-0.633 * s(h2) + 0.723 * s(h)) * s(d2 + d2 + d))  # fmt: skip


def hfd(h, d):
    h2, h3, h5, d2, d3 = 2 * h, 3 * h, 5 * h, 2 * d, 3 * d
    h12, d6 = h5 + h5 + h2, d3 + d3
    return (-2.529 * s(h2) + 3.964 * s(h3) + 3.008 * c(h3) - 2.428 * s(h3 + h) - 0.921 * c(h5)
            - 0.233 * c(h12) + 0.163 * s(d6) - 0.147 * c(d6 + d3 + d2) - 0.244 * c(h12 + h3) * s(d)
            + (-4.330 * c(h) - 2.958 * c(h2) - 1.805 * s(h)) * c(d) + 1.666 * c(h) * c(d2))  # fmt: skip


# name -> [(kind, f(h, dec, phi)), ...]: H hour angle, X east-west (dh cos dec), P
# east-west times sin dec, D declination, Z zenith distance; MA, ME as Wallace's comments
# give their linear form.
WALLACE_EQUATORIAL = {
    "IH": [("H", lambda h, d, p: 1.0)],
    "ID": [("D", lambda h, d, p: 1.0)],
    "CH": [("X", lambda h, d, p: 1.0)],
    "NP": [("P", lambda h, d, p: 1.0)],
    "MA": [("H", lambda h, d, p: -c(h) * t(d)), ("D", lambda h, d, p: s(h))],
    "ME": [("H", lambda h, d, p: s(h) * t(d)), ("D", lambda h, d, p: c(h))],
    "TF": [("Z", lambda h, d, p: np.sqrt(1 - cos_z(h, d, p) ** 2))],
    "FO": [("D", lambda h, d, p: c(h))],
    "DAF": [("X", lambda h, d, p: -cos_z(h, d, p))],
    "HCES": [("H", lambda h, d, p: s(h))],
    "HCEC": [("H", lambda h, d, p: c(h))],
    "DCES": [("D", lambda h, d, p: s(d))],
    "DCEC": [("D", lambda h, d, p: c(d))],
    "TX": [("Z", lambda h, d, p: np.sqrt(1 - cos_z(h, d, p) ** 2) / cos_z(h, d, p))],
    "TFP": [("Z", lambda h, d, p: np.arccos(cos_z(h, d, p)) ** 4)],
    "FLOP": [("Z", lambda h, d, p: 1.0)],
    "DAB": [("X", lambda h, d, p: -np.sqrt((s(h) * s(p)) ** 2 + c(h) ** 2) * cos_z(h, d, p))],
    "DNP": [("P", lambda h, d, p: s(h))],
    "HF": [("X", lambda h, d, p: s(h))],
    "HFX": [("X", lambda h, d, p: hfx(h, d))],
    "HFD": [("D", lambda h, d, p: hfd(h, d))],
    "X2HC": [("X", lambda h, d, p: c(2 * h))],
    "HGES": [("H", lambda h, d, p: s(40 * h))],
    "HGEC": [("H", lambda h, d, p: c(40 * h))],
    "DGES": [("D", lambda h, d, p: s(40 * d))],
    "DGEC": [("D", lambda h, d, p: c(40 * d))],
    "CD4A": [("H", lambda h, d, p: 1.0), ("D", lambda h, d, p: s(d))],
    "CD4B": [("X", lambda h, d, p: -s(d)), ("D", lambda h, d, p: c(d))],
    "CD5A": [("X", lambda h, d, p: -s(h + d)), ("D", lambda h, d, p: c(h + d))],
    "CD5B": [("X", lambda h, d, p: c(h + d)), ("D", lambda h, d, p: s(h + d))],
    "CHL": [("H", lambda h, d, p: 1 / c(d))],
    "MAL": [("H", lambda h, d, p: -c(h) * s(d) / c(d)), ("D", lambda h, d, p: s(h))],
    "MEL": [("H", lambda h, d, p: s(h) * s(d) / c(d)), ("D", lambda h, d, p: c(h))],
    "NPL": [("H", lambda h, d, p: s(d) / c(d))],
}
CHECKED_EQUATORIAL = ("IH", "ID", "CH", "NP", "MA", "ME", "TF")


def wallace_equatorial(name, h, d, phi):
    dh = dd = 0.0
    for kind, f in WALLACE_EQUATORIAL[name]:
        v = f(h, d, phi)
        if kind == "H":
            dh += v
        elif kind == "X":
            dh += v / c(d)
        elif kind == "P":
            dh += v * s(d) / c(d)
        elif kind == "D":
            dd += v
        else:
            zh, zd = zenith_direction(h, d, phi)
            dh, dd = dh + v * zh, dd + v * zd
    return np.array([dh, dd], dtype=float)


def test_every_equatorial_named_term_is_stated():
    assert sorted(eq.EQUATORIAL_LINEAR_TERMS) == sorted(WALLACE_EQUATORIAL)
    assert sorted(eq.EQUATORIAL_RIGOROUS_TERMS) == sorted(WALLACE_EQUATORIAL)
    assert eq.NEEDS_LATITUDE == {"TF", "DAF", "TX", "TFP", "FLOP", "DAB"}


@pytest.mark.parametrize("name", sorted(WALLACE_EQUATORIAL))
def test_equatorial_terms_are_wallaces_statements(name):
    """IH ... TF are checked on Wallace's own fit (test_equatorial_terms.py); the same
    translation, and a finite zenith-distance move for the Z kind, give the others.
    Wallace's statements are of the linear form (offsets at the sky position)."""
    term = px.terms.tpoint([name], values={name: 1.0}, mount="equatorial", latitude=LAT, form="linear")[0]
    for h, d in EQUAT:
        got = np.asarray(term.sky_offset(jnp.array([h, d])))
        np.testing.assert_allclose(got, wallace_equatorial(name, h, d, LAT), rtol=1e-6, atol=1e-7, err_msg=name)


def test_equatorial_tx_is_wallaces_closed_form():
    term = px.terms.tpoint("TX", values={"TX": 1.0}, mount="equatorial", latitude=LAT)[0]
    for h, d in EQUAT:
        cz = cos_z(h, d, LAT)
        want = [c(LAT) * s(h) / (cz * c(d)), (c(LAT) * c(h) * s(d) - s(LAT) * c(d)) / cz]
        np.testing.assert_allclose(np.asarray(term.sky_offset(jnp.array([h, d]))), want, rtol=1e-12)


def test_equatorial_terms_that_need_the_latitude_say_so():
    for name in ("TX", "TFP", "FLOP", "DAB"):
        with pytest.raises(ValueError, match="needs the site's latitude"):
            px.terms.tpoint(name, mount="equatorial")
    assert px.terms.tpoint("TX")[0].__class__ is px.terms.TX  # the alt-az TX keeps its name


# ----------------------------------------------------------------- polynomials


POLY_ALTAZ = {
    "PAA1": ("A", lambda A, E: a_t(A)),
    "PAA": ("A", lambda A, E: a_t(A)),
    "PEE2": ("E", lambda A, E: E**2),
    "PSZ2": ("S", lambda A, E: (np.pi / 2 - E) ** 2),
    "PAA1E2": ("A", lambda A, E: a_t(A) * E**2),
    "PEA2E": ("E", lambda A, E: a_t(A) ** 2 * E),
    "PZE3": ("Z", lambda A, E: E**3),
}


@pytest.mark.parametrize("name", sorted(POLY_ALTAZ))
def test_polynomial_terms_are_tptptermg(name):
    result, f = POLY_ALTAZ[name]
    term = px.terms.tpoint([name], values={name: 1.0}, form="linear")[0]
    for A, E in ALTAZ:
        v = f(A, E)
        want = {"A": (-v, 0.0), "E": (0.0, v), "S": (-v / c(E), 0.0), "Z": (0.0, -v)}[result]
        np.testing.assert_allclose(np.asarray(term.sky_offset(jnp.array([A, E]))), want, rtol=1e-12, atol=1e-14)


def test_named_and_generated_polynomials_agree():
    for named, generated in (("PAA1", "PAA"), ("PEE1", "PEE")):
        a = px.terms.tpoint([named], values={named: 1.0}, form="linear")[0]
        b = px.terms.polynomial_term(generated, coef=1.0, form="linear")
        assert b.name == generated
        for p in ALTAZ:
            np.testing.assert_allclose(np.asarray(a.sky_offset(jnp.array(p))), np.asarray(b.sky_offset(jnp.array(p))))


def test_equatorial_polynomials():
    term = px.terms.tpoint("PXD1H2", values={"PXD1H2": 1.0}, mount="equatorial", form="linear")[0]
    for h, d in EQUAT:
        np.testing.assert_allclose(np.asarray(term.sky_offset(jnp.array([h, d]))), [d * h**2 / c(d), 0.0], rtol=1e-12)
    wrapped = px.terms.tpoint("PHH1", values={"PHH1": 1.0}, mount="equatorial", form="linear")[0]
    assert float(wrapped.sky_offset(jnp.array([2 * np.pi - 0.5, 0.2]))[0]) == pytest.approx(-0.5)


@pytest.mark.parametrize(
    "name, message",
    [
        ("PAAE", r"character 4 is 'E', expected a one-digit power after the first coordinate"),
        ("PBA1", r"unknown TPOINT term 'PBA1'.*polynomial terms named P\{A\|E\|S\|Z\}"),
        ("PAX1", r"character 3 is 'X', expected A \(TPOINT's azimuth A_T\)"),
        ("PAA1E2Z", r"character 7 is 'Z', expected the end of the name"),
        ("PA", r"character 3 is the end of the name"),
    ],
)
def test_bad_polynomial_names(name, message):
    with pytest.raises(ValueError, match=message) as info:
        px.terms.tpoint(name)
    assert not isinstance(info.value, px.terms.NotYetInPointax)


def test_polynomial_describe():
    assert px.terms.parse_polynomial("PAA1E2").describe() == "dA = -coef A_T E^2"
    assert px.terms.parse_polynomial("PXD1H", mount="equatorial").describe() == "dh cos dec = +coef dec h"


# ----------------------------------------------------------------- harmonics in zenith distance


def test_harmonics_in_zenith_distance():
    """Z as what is corrected (a zenith-distance change, the sign of TF) and as a
    coordinate (z = 90 deg - E): TPOINT's TF is HZSZ, ECES is HECZ."""
    pairs = {"TF": "HZSZ", "ECES": "HECZ", "ECEC": "HESZ", "TX": "HZSZ"}
    for named, harmonic in pairs.items():
        if named == "TX":
            continue
        a = px.terms.LINEAR_TERMS[named](coef=1.0)
        b = px.terms.harmonic_term(harmonic, coef=1.0, form="linear")
        for p in ALTAZ:
            np.testing.assert_allclose(np.asarray(a.sky_offset(jnp.array(p))), np.asarray(b.sky_offset(jnp.array(p))),
                                       atol=1e-14)  # fmt: skip
    spec = px.terms.parse_harmonic("HZSZ2CA")
    assert (spec.result, spec.factors) == ("Z", (("S", "Z", 2), ("C", "A", 1)))
    assert spec.describe() == "dE = -coef sin(2 z) cos(A')"


def test_rigorous_generated_terms_agree_to_first_order():
    coef = 1.0 * ARCSEC
    for name in ("PAA2E", "PSZ2", "PZE1", "HZSZ2", "HSCZ"):
        linear = px.AltAz(px.terms.tpoint([name], values={name: coef}, form="linear"))
        rigorous = px.AltAz(px.terms.tpoint([name], values={name: coef}, form="rigorous"))
        nominal = px.AltAz([])
        d_lin, d_rig = linear(ALTAZ), rigorous(ALTAZ)
        assert np.max(np.asarray(px.rotations.angle_between(d_lin, nominal(ALTAZ)))) > 0.05 * coef, name
        assert np.all(np.asarray(px.rotations.angle_between(d_lin, d_rig)) < 1e-9), name


# ----------------------------------------------------------------- refusals


@pytest.mark.parametrize(
    "name, mount, message",
    [
        ("TX10", "altaz", "no public definition"),
        ("AUX1H", "altaz", "corrects the equatorial coordinates"),  # built on its mount: tests/test_tpoint_auxiliary.py
        ("A1E", "equatorial", "corrects the alt-az coordinates"),
        ("IH", "altaz", "equatorial term"),
        ("HCES", "altaz", "equatorial term"),
        ("NRX", "equatorial", "alt-az term"),
        ("HXCA", "altaz", r"'X' \(east-west"),
        ("HASQ", "altaz", r"'Q' \(parallactic angle\)"),
        ("PAQ1", "altaz", r"'Q' \(parallactic angle\)"),
        ("PHH1", "altaz", r"'H' \(hour angle\)"),
        ("PAA1", "equatorial", "alt-az term"),
        ("PEE1", "equatorial", "alt-az term"),
        ("PED1", "altaz", r"'D' \(declination\)"),
        ("PDA1", "equatorial", r"'A' \(azimuth\)"),
    ],
)
def test_tpoint_names_not_yet_in_pointax(name, mount, message):
    with pytest.raises(px.terms.NotYetInPointax, match=message) as info:
        px.terms.tpoint(name, mount=mount, latitude=LAT)
    assert "TPOINT's, not yet in pointax" in str(info.value) or "TPOINT's but not yet in pointax" in str(info.value)
    assert isinstance(info.value, ValueError)


@pytest.mark.parametrize("name", ["XX", "TX11", "HBCA", "PBA", "AUX3A", "NRZ"])
def test_unknown_names_are_not_called_tpoints(name):
    with pytest.raises(ValueError) as info:
        px.terms.tpoint(name)
    assert not isinstance(info.value, px.terms.NotYetInPointax)
    assert "not yet in pointax" not in str(info.value)


def test_model_file_with_new_terms_reads_and_one_with_tx10_is_refused(tmp_path):
    path = tmp_path / "nasmyth.mod"
    records = [ModelTerm("IA", 12.0, 0.1), ModelTerm("IE", -3.0, 0.1), ModelTerm("NRX", 4.5, 0.2),
               ModelTerm("NRY", -2.25, 0.2), ModelTerm("PAA1E2", 1.5, 0.1), ModelTerm("HZSZ2", 0.5, 0.1)]  # fmt: skip
    path.write_text(format_model(records, caption="nasmyth"))
    model = read_model(path).model()
    assert model.parameter_names == ["IA", "IE", "NRX", "NRY", "PAA1E2", "HZSZ2"]
    assert np.isfinite(np.asarray(model(ALTAZ))).all()
    bad = tmp_path / "tx10.mod"
    bad.write_text(format_model([ModelTerm("IA", 1.0, 0.1), ModelTerm("TX10", 2.0, 0.1)], caption="tx10"))
    with pytest.raises(TpointFormatError, match=r"term record TX10: .*TPOINT's but not yet in pointax"):
        read_model(bad).model()


# ----------------------------------------------------------------- JAX, linearity, fitting


NEW_ALTAZ = "NRX NRY CRX CRY FLOP TFP ANL AWL CAL NPAEL TXL PAA2E PSZ2 HZSZ2"
NEW_EQUATORIAL = "TX TFP FLOP DAB DNP HF HFX HFD X2HC HGES HGEC DGES DGEC CD4A CD4B CD5A CD5B CHL MAL MEL NPL PXD1H"


@pytest.mark.parametrize("mount, spec", [("altaz", NEW_ALTAZ), ("equatorial", NEW_EQUATORIAL)])
def test_new_terms_are_neutral_at_zero_and_linear(mount, spec):
    positions = ALTAZ if mount == "altaz" else EQUAT
    for term in px.terms.tpoint(spec, mount=mount, latitude=LAT, form="linear"):
        assert term.linear_sky_offset and term.linear_by_construction and term.neutral_at_zero
        zero = np.asarray(jax.vmap(lambda p, tm=term: tm.sky_offset_at(SkyPoint.at(p)))(jnp.asarray(positions)))
        assert not zero.any(), term.name
        assert _linearity_error(term) == "", term.name


@pytest.mark.slow
def test_jit_vmap_grad_through_a_model_with_new_terms():
    names = NEW_ALTAZ.split()
    values = {n: (k + 1) * 0.7 * ARCSEC for k, n in enumerate(names)}
    model = px.AltAz(px.terms.tpoint(names, values=values))
    theta = jnp.array([values[n] for n in names])
    raw = jnp.asarray(ALTAZ[:4])

    def directions(th):
        return model.with_values(th)(raw)

    jac = jax.jit(jax.jacfwd(lambda th: directions(th).ravel()))(theta)
    h = 1e-3 * ARCSEC
    for k in range(len(names)):
        e = jnp.zeros_like(theta).at[k].set(h)
        fd = (directions(theta + e) - directions(theta - e)).ravel() / (2 * h)
        np.testing.assert_allclose(np.asarray(jac[:, k]), np.asarray(fd), atol=1e-7, err_msg=names[k])


def test_fit_of_the_mmt_run_with_nrx_is_the_fit_with_ia():
    """NRX = IA - ECES in TPOINT's (linear) definitions: swapping IA for NRX beside ECES
    changes the parametrisation, not the fit (NRX takes IA's value, ECES moves by it)."""
    run = px.io.read_tpoint(MMT_DAT, azimuth="S-E")
    base = "IE NPAE CA AN AW TF TX ECES".split()
    with_ia = px.fit(px.AltAz(px.terms.tpoint(["IA", *base], form="linear"), azimuth=run.azimuth), run)
    with_nrx = px.fit(px.AltAz(px.terms.tpoint(["NRX", *base], form="linear"), azimuth=run.azimuth), run)
    assert float(with_nrx.sky_rms) == pytest.approx(float(with_ia.sky_rms), rel=1e-9)
    assert with_nrx.value("NRX") == pytest.approx(with_ia.value("IA"), abs=1e-6)
    assert with_nrx.value("ECES") == pytest.approx(with_ia.value("ECES") + with_ia.value("IA"), abs=1e-6)


@pytest.mark.parametrize(
    "module",
    ["tpoint_special", "equatorial_special", "polynomial", "repertoire", "linear", "equatorial", "harmonic"],
)
def test_each_term_module_imports_first(module):
    """No import cycle: any of the modules may be the first one imported."""
    import subprocess
    import sys

    code = f"import pointax.terms.{module} as m; import pointax as px; print(len(px.terms.LINEAR_TERMS))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == str(len(WALLACE_ALTAZ))

"""TPOINT's auxiliary-reading terms (pointax.terms.tpoint_auxiliary), against the
definitions in P. T. Wallace's tptPterms/tptPtermg: closed forms for the constant
corrections, the identity "auxiliary term = its letter's basic term times the reading"
for the others, a fit of simulated runs, and the reader's auxiliary fields end to end."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import pointax as px
from pointax.io.tpoint import parse_tpoint
from pointax.terms.linear import NotYetInPointax
from pointax.terms.tpoint_auxiliary import Aux1Term, Aux2Term, Aux3Term, ZE, auxiliary_term, is_auxiliary_name, parse_auxiliary

ARCSEC = math.pi / 180 / 3600
RNG = np.random.default_rng(31)
N = 12
ENCODER = np.column_stack([RNG.uniform(-math.pi, math.pi, N), RNG.uniform(0.2, 1.3, N)])  # az, el (alt-az)
HADEC = np.column_stack([RNG.uniform(-1.2, 1.2, N), RNG.uniform(-0.4, 1.1, N)])  # h, dec (equatorial)
READING = RNG.uniform(-5.0, 25.0, N)  # e.g. a temperature, deg C
COEF = 3.0 * ARCSEC  # per unit of the reading
LATITUDE = math.radians(-31.3)


def _enu(az, el):
    """North-through-East azimuth and elevation -> ENU (NumPy, the independent reference)."""
    return np.column_stack([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)])


def _directions(model, encoder, readings=None):
    return np.asarray(model(jnp.asarray(encoder), readings=readings))


# ----------------------------------------------------------------------- names


@pytest.mark.parametrize(
    "name, number, letter",
    [("AUX1H", 1, "H"), ("aux2e", 2, "E"), ("ZH", 1, "H"), ("ZE", 1, "U"), ("A3Z", 3, "Z"), ("A2S", 2, "S")],
)
def test_names_parse_as_wallace_defines_them(name, number, letter):
    mount = "equatorial" if letter in "HDXU" else "altaz"
    assert is_auxiliary_name(name)
    assert parse_auxiliary(name, mount)[1:] == (number, letter)


def test_other_mount_refused_and_unknown_names_named():
    with pytest.raises(NotYetInPointax, match=r"AUX1H.*TPOINT's but not yet in pointax.*latitude"):
        auxiliary_term("AUX1H", mount="altaz")
    with pytest.raises(NotYetInPointax, match=r"A1A.*equatorial mount"):
        auxiliary_term("A1A", mount="equatorial")
    for bad in ("AUX3H", "A4E", "A1Q", "AUX1"):
        assert not is_auxiliary_name(bad)
        with pytest.raises(ValueError, match="not a TPOINT auxiliary term"):
            auxiliary_term(bad)


def test_default_readings_by_position_and_a_named_reading():
    assert type(auxiliary_term("AUX1E")) is Aux1Term and auxiliary_term("AUX1E").readings == ("aux1",)
    assert type(auxiliary_term("A2Z")) is Aux2Term and type(auxiliary_term("A3A")) is Aux3Term
    assert type(auxiliary_term("ZE", mount="equatorial")) is ZE
    t = auxiliary_term("AUX1E", reading="temperature")
    assert t.readings == ("temperature",) and t.name == "AUX1E@temperature"
    assert type(t) is type(auxiliary_term("a1e", reading="temperature"))  # one class per reading: no recompiles
    assert px.AltAz([t]).readings == ("temperature",)


# ------------------------------------------------------------ alt-az: closed forms


@pytest.mark.parametrize("name, d_az, d_el", [("AUX1A", -1.0, 0.0), ("AUX2E", 0.0, 1.0), ("A3Z", 0.0, -1.0)])
def test_constant_corrections_closed_form(name, d_az, d_el):
    """dAz = +coef r in TPOINT's azimuth (South 0, East 90): pointax's N-E azimuth
    changes by -coef r; dEl = +coef r; a zenith-distance change +coef r is dE = -coef r."""
    term = auxiliary_term(name, coef=COEF)
    reading = term.readings[0]
    got = _directions(px.AltAz([term]), ENCODER, {reading: READING})
    want = _enu(ENCODER[:, 0] + d_az * COEF * READING, ENCODER[:, 1] + d_el * COEF * READING)
    np.testing.assert_allclose(got, want, atol=1e-13)


def test_cross_elevation_term_closed_form():
    """AUX1S: "change LR on the sky equal to AUX1S * AUX1", dAz = -coef r / cos E
    (pointax's azimuth) at the corrected elevation; here E is unchanged."""
    term = auxiliary_term("AUX1S", coef=COEF)
    got = _directions(px.AltAz([term]), ENCODER, {"aux1": READING})
    want = _enu(ENCODER[:, 0] - COEF * READING / np.cos(ENCODER[:, 1]), ENCODER[:, 1])
    np.testing.assert_allclose(got, want, atol=1e-12)


@pytest.mark.parametrize("name, basic", [("AUX1A", "IA"), ("AUX1E", "IE"), ("AUX2S", "CA"), ("A1Z", "FLOP")])
def test_altaz_terms_are_their_basic_term_times_the_reading(name, basic):
    aux = auxiliary_term(name, coef=COEF)
    reading = aux.readings[0]
    got = _directions(px.AltAz([aux]), ENCODER, {reading: READING})
    for k in range(N):  # the basic term with coefficient coef * r, observation by observation
        base = px.AltAz(px.terms.tpoint(basic, form="linear", values={basic: COEF * READING[k]}))
        np.testing.assert_allclose(got[k], np.asarray(base.direction(jnp.asarray(ENCODER[k]))), atol=1e-14)


# ----------------------------------------------------------------- equatorial


@pytest.mark.parametrize("name, basic", [("AUX1H", "IH"), ("AUX2D", "ID"), ("AUX1X", "CH"), ("ZH", "IH"), ("ZE", "ME"), ("A3D", "ID")])
def test_equatorial_terms_are_their_basic_term_times_the_reading(name, basic):
    """Wallace: ZH is dHA = +ZH*AUX1 (= AUX1H); ZE is ME's rotation times AUX1."""
    aux = auxiliary_term(name, coef=COEF, mount="equatorial")
    reading = aux.readings[0]
    got = _directions(px.Equatorial([aux], latitude=LATITUDE), HADEC, {reading: READING})
    for k in range(N):
        terms = px.terms.tpoint(basic, form="linear", mount="equatorial", latitude=LATITUDE, values={basic: COEF * READING[k]})
        base = px.Equatorial(terms, latitude=LATITUDE)
        np.testing.assert_allclose(got[k], np.asarray(base.direction(jnp.asarray(HADEC[k]))), atol=1e-14)


def test_hour_angle_term_closed_form():
    """AUX1H: dHA = +coef r, dDec = 0: the direction at (h + coef r, dec)."""
    term = auxiliary_term("AUX1H", coef=COEF, mount="equatorial")
    got = _directions(px.Equatorial([term], latitude=LATITUDE), HADEC, {"aux1": READING})
    h, d, phi = HADEC[:, 0] + COEF * READING, HADEC[:, 1], LATITUDE
    want = np.column_stack(
        [-np.cos(d) * np.sin(h), np.cos(phi) * np.sin(d) - np.sin(phi) * np.cos(d) * np.cos(h),
         np.sin(phi) * np.sin(d) + np.cos(phi) * np.cos(d) * np.cos(h)]
    )  # fmt: skip
    np.testing.assert_allclose(got, want, atol=1e-13)


# ------------------------------------------------------------ derivatives, fits


def test_derivative_in_the_coefficient_matches_finite_differences():
    def elevation(c):
        m = px.AltAz([Aux1Term(coef=c, label="AUX1E", result="E")])
        return m(jnp.asarray(ENCODER), readings={"aux1": jnp.asarray(READING)})[:, 2]

    grad = np.asarray(jax.jacfwd(elevation)(COEF))
    h = 1e-7
    fd = (np.asarray(elevation(COEF + h)) - np.asarray(elevation(COEF - h))) / (2 * h)
    np.testing.assert_allclose(grad, fd, rtol=1e-6, atol=1e-10)
    np.testing.assert_allclose(grad, READING * np.cos(ENCODER[:, 1] + COEF * READING), rtol=1e-9)  # d sin E / dc


def test_fit_recovers_auxiliary_coefficients_jointly_with_basic_terms():
    """A noise-free run whose elevation drifts with aux1 and azimuth with aux2: the fit
    returns the true coefficients (the model is exactly the truth's)."""
    n = 40
    rng = np.random.default_rng(7)
    encoder = np.column_stack([rng.uniform(-math.pi, math.pi, n), rng.uniform(0.25, 1.25, n)])
    readings = {"aux1": rng.uniform(0, 20, n), "aux2": rng.uniform(-3, 3, n)}
    truth = {"IA": 40 * ARCSEC, "IE": -25 * ARCSEC, "AUX1E": 0.8 * ARCSEC, "AUX2A": -2.5 * ARCSEC}
    terms = px.terms.tpoint("IA IE", form="linear", values={"IA": truth["IA"], "IE": truth["IE"]}) + (
        auxiliary_term("AUX1E", coef=truth["AUX1E"]),
        auxiliary_term("AUX2A", coef=truth["AUX2A"]),
    )
    target = _directions(px.AltAz(terms), encoder, readings)
    obs = px.Observations(encoder, target, readings=readings)
    start = px.terms.tpoint("IA IE", form="linear") + (auxiliary_term("AUX1E"), auxiliary_term("AUX2A"))
    result = px.fit(px.AltAz(start), obs)
    for name, value in truth.items():
        assert result.value(name) == pytest.approx(value / ARCSEC, abs=1e-6), name  # arcsec


def test_reader_auxiliary_fields_drive_the_terms_end_to_end():
    """A TPOINT file whose records carry two auxiliary readings: the fit of AUX1E and
    AUX2S on what the reader gives recovers the coefficients the file was written with."""
    rng = np.random.default_rng(3)
    n = 30
    az, el = rng.uniform(0, 360, n), rng.uniform(20, 75, n)
    aux1, aux2 = np.round(rng.uniform(0, 15, n), 2), np.round(rng.uniform(-2, 2, n), 3)
    c1, c2 = 1.5 * ARCSEC, -4.0 * ARCSEC
    # observed = raw + offsets: dE = +c1 aux1, dA = -c2 aux2 / cos E (E the observed elevation)
    el_obs = el + np.degrees(c1 * aux1)
    az_obs = az - np.degrees(c2 * aux2 / np.cos(np.radians(el_obs)))
    rows = [f"{a:.9f} {e:.9f} {ra:.9f} {re:.9f} {x1} {x2}" for a, e, ra, re, x1, x2 in zip(az_obs % 360, el_obs, az, el, aux1, aux2)]
    run = parse_tpoint("\n".join(["aux run", ": ALTAZ", "+31 41 19.6 2021 8 21"] + rows) + "\n")
    assert set(run.observations.readings) == {"aux1", "aux2", "time"}
    result = px.fit(run.model([auxiliary_term("AUX1E"), auxiliary_term("AUX2S")]), run.observations)
    assert result.value("AUX1E") == pytest.approx(c1 / ARCSEC, abs=1e-4)  # arcsec; 1e-9 deg fields round
    assert result.value("AUX2S") == pytest.approx(c2 / ARCSEC, abs=1e-4)


def test_tpoint_builds_auxiliary_terms_by_name_in_either_form():
    for form in ("linear", "rigorous"):
        terms = px.terms.tpoint("IA IE AUX1E A3S", form=form, values={"AUX1E": COEF})
        assert [t.name for t in terms] == ["IA", "IE", "AUX1E", "A3S"]
        assert terms[2].coef == COEF and px.AltAz(terms).readings == ("aux1", "aux3")
    terms = px.terms.tpoint("IH ZE AUX2X", mount="equatorial", latitude=LATITUDE)
    assert px.Equatorial(terms, latitude=LATITUDE).readings == ("aux1", "aux2")
    with pytest.raises(NotYetInPointax, match="AUX1H"):
        px.terms.tpoint("AUX1H")

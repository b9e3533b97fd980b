"""TPOINT's harmonic terms generated from their names (pointax.terms.harmonic).

References, all outside the code under test: the harmonic functions written out here in
numpy from DESIGN.md's definition (A' = 180 deg - A with A as the data count it; dA = -coef
f, dE = +coef f, dA cos E = -coef f); the named centring terms ACEC ACES ECEC ECES
(TPOINT's identities); the azimuth-convention table worked out by hand from the ENU
azimuth; an ordinary least-squares fit of the real MMT run in numpy; central finite
differences for the autodiff Jacobians.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import MMT_DAT

import pointax as px
from pointax.io import (
    ModelTerm,
    TpointFormatError,
    format_model,
    parse_model,
    read_model,
    write_model,
)
from pointax.terms import Harmonic, RigorousHarmonic, harmonic_term, parse_harmonic

ARCSEC = np.pi / 648000
s, c, t = np.sin, np.cos, np.tan
RNG = np.random.default_rng(7)
POSITIONS = np.stack([RNG.uniform(-np.pi, 2 * np.pi, 9), RNG.uniform(0.15, 1.4, 9)], -1)

# name -> (what is corrected, f(A', E)) written out by hand.
FUNCTIONS = {
    "HACA2": ("A", lambda a, e: c(2 * a)),
    "HASA": ("A", lambda a, e: s(a)),
    "HESE5": ("E", lambda a, e: s(5 * e)),
    "HECA3": ("E", lambda a, e: c(3 * a)),
    "HESACE": ("E", lambda a, e: s(a) * c(e)),
    "HSCA5CE8": ("S", lambda a, e: c(5 * a) * c(8 * e)),
    "HSSE2": ("S", lambda a, e: s(2 * e)),
    "HACA12SE": ("A", lambda a, e: c(12 * a) * s(e)),
    "HECECE": ("E", lambda a, e: c(e) ** 2),
}


def tpoint_offset(name, coef, A, E):
    """DESIGN.md's definition: (dA, dE) observed - raw at the position (A, E)."""
    result, f = FUNCTIONS[name]
    value = f(np.pi - A, E)
    if result == "A":
        return np.array([-coef * value, 0.0])
    if result == "E":
        return np.array([0.0, coef * value])
    return np.array([-coef * value / c(E), 0.0])


# ------------------------------------------------------------------ names


@pytest.mark.parametrize(
    "name, result, factors",
    [
        ("HACA2", "A", (("C", "A", 2),)),
        ("HESE5", "E", (("S", "E", 5),)),
        ("HESACE", "E", (("S", "A", 1), ("C", "E", 1))),
        ("HSCA5CE8", "S", (("C", "A", 5), ("C", "E", 8))),
        ("haca", "A", (("C", "A", 1),)),
        ("HSSE12", "S", (("S", "E", 12),)),
        ("HACA12SE3", "A", (("C", "A", 12), ("S", "E", 3))),
    ],
)
def test_names_parse(name, result, factors):
    spec = parse_harmonic(name)
    assert (spec.name, spec.result, spec.factors) == (name.upper(), result, factors)


@pytest.mark.parametrize(
    "name, message",
    [
        ("HBCA2", r"character 2 is 'B', expected A \(azimuth\), E \(elevation\) or S"),
        ("H", r"character 2 is the end of the name"),
        ("HA", r"character 3 is the end of the name, expected S \(sine\) or C \(cosine\)"),
        ("HAXA", r"character 3 is 'X', expected S \(sine\) or C"),
        ("HACX2", r"character 4 is 'X', expected A \(azimuth\) or E \(elevation\) as the argument"),
        ("HACA2X", r"character 6 is 'X', expected S \(sine\) or C"),
        ("HACA0", r"multiplier '0' must be an integer >= 1"),
        ("HACA02", r"multiplier '02'"),
        ("HACASECE", r"at most 2 factors .* 'CE' follows the second"),
        ("HACAS", r"character 6 is the end of the name, expected A \(azimuth\) or E"),
    ],
)
def test_bad_names_say_what_is_wrong(name, message):
    with pytest.raises(ValueError, match=message):
        parse_harmonic(name)
    with pytest.raises(ValueError, match=message):
        px.terms.tpoint(f"IA {name}")


# Plain numbers as values on purpose (the names, not the units, are tested here).
@pytest.mark.filterwarnings("ignore:.*most likely in degrees:pointax.core.errors.InputWarning")
def test_tpoint_factory_builds_harmonics_by_name():
    terms = px.terms.tpoint("IA IE HACA2 HESE5", values={"HACA2": 2.0, "hese5": 3.0}, form="linear")
    assert [term.name for term in terms] == ["IA", "IE", "HACA2", "HESE5"]
    assert isinstance(terms[2], Harmonic) and float(terms[2].coef) == 2.0 and float(terms[3].coef) == 3.0
    rigorous = px.terms.tpoint("HACA2 HSCA", form="rigorous")
    assert all(isinstance(term, RigorousHarmonic) for term in rigorous)
    model = px.AltAz(terms)
    assert model.parameter_names == ["IA", "IE", "HACA2", "HESE5"]
    with pytest.raises(ValueError, match="unknown TPOINT term 'XX'.*harmonic terms named"):
        px.terms.tpoint("IA XX")
    with pytest.raises(ValueError, match="unknown term form"):
        harmonic_term("HACA2", form="curvy")
    assert parse_harmonic("HSCA5CE8").describe() == "dA cos E = -coef cos(5 A') cos(8 E)"


# ------------------------------------------------------------------ definitions


@pytest.mark.parametrize("name", sorted(FUNCTIONS))
def test_linear_form_is_the_tpoint_definition(name):
    coef = 1.7
    term = harmonic_term(name, coef, form="linear")
    for A, E in POSITIONS:
        got = np.asarray(term.sky_offset(jnp.array([A, E])))
        np.testing.assert_allclose(got, tpoint_offset(name, coef, A, E), rtol=1e-13, atol=1e-14)


@pytest.mark.parametrize("named, harmonic", [("ACEC", "HACA1"), ("ACES", "HASA1"), ("ECEC", "HECE1"), ("ECES", "HESE1")])
@pytest.mark.parametrize("form", ["linear", "rigorous"])
def test_tpoint_identities(named, harmonic, form):
    """ACEC = HACA1, ACES = HASA1, ECEC = HECE1, ECES = HESE1, term by term and in a model."""
    coef = 25 * ARCSEC
    a, b = px.terms.tpoint([named, harmonic], form=form, values={named: coef, harmonic: coef})
    for A, E in POSITIONS:
        angles = jnp.array([A, E])
        for hook in ("sky_offset", "encoder_offset"):
            x, y = getattr(a, hook)(angles), getattr(b, hook)(angles)
            assert (x is None) == (y is None), hook
            if x is not None:
                np.testing.assert_allclose(np.asarray(x), np.asarray(y), rtol=1e-14, atol=1e-20)
    for azimuth in px.AZIMUTH_CONVENTIONS:
        d_a = px.AltAz([a], azimuth=azimuth)(POSITIONS)
        d_b = px.AltAz([b], azimuth=azimuth)(POSITIONS)
        np.testing.assert_allclose(np.asarray(d_a), np.asarray(d_b), atol=1e-15)


@pytest.mark.parametrize(
    "azimuth, file_azimuth, expected_a_prime",
    [
        # A' = 180 deg - A(file), worked out by hand from A_NE for each way of counting.
        ("N-E", lambda a_ne: a_ne, lambda a_ne: np.pi - a_ne),  # A' counts from South through East
        ("S-E", lambda a_ne: np.pi - a_ne, lambda a_ne: a_ne),  # A' counts from North through East
        ("S-W", lambda a_ne: a_ne - np.pi, lambda a_ne: -a_ne),  # A' counts from North through West
    ],
)
def test_azimuth_inside_harmonics_for_each_convention(azimuth, file_azimuth, expected_a_prime):
    """The sky direction a harmonic sees depends on how the data count azimuth: the
    table of pointax.terms.harmonic. Checked with odd multipliers (where it shows)."""
    coef = 10 * ARCSEC
    terms = px.terms.tpoint("HASA HACA HASA3", values={"HASA": coef, "HACA": coef, "HASA3": coef}, form="linear")
    model = px.AltAz(terms, azimuth=azimuth)
    for a_ne in np.linspace(-3.0, 3.0, 7):
        el = 0.6
        a_file = file_azimuth(a_ne)
        # The direction the file's angles name is the one at North-East azimuth a_ne.
        d = np.asarray(px.AltAz([], azimuth=azimuth)(np.array([[a_file, el]])))[0]
        np.testing.assert_allclose(d, [np.sin(a_ne) * np.cos(el), np.cos(a_ne) * np.cos(el), np.sin(el)], atol=1e-15)
        a_prime = expected_a_prime(a_ne)
        want = -coef * (np.sin(a_prime) + np.cos(a_prime) + np.sin(3 * a_prime))
        got = sum(float(term.sky_offset(jnp.array([a_file, el]))[0]) for term in model.terms)
        assert got == pytest.approx(want, abs=1e-18)


SAMPLE = ["HACA2", "HASA", "HESE5", "HECA3", "HESACE", "HSCA5CE8", "HSSE2"]


@pytest.mark.parametrize("name", SAMPLE)
def test_rigorous_form_equals_linear_form_to_first_order(name):
    coef = 1.0 * ARCSEC
    linear = px.AltAz([harmonic_term(name, coef, form="linear")])
    rigorous = px.AltAz([harmonic_term(name, coef, form="rigorous")])
    d_lin, d_rig, d_nom = linear(POSITIONS), rigorous(POSITIONS), px.AltAz([])(POSITIONS)
    assert np.max(np.asarray(px.rotations.angle_between(d_lin, d_nom))) > 0.3 * coef
    assert np.all(np.asarray(px.rotations.angle_between(d_lin, d_rig)) < 1e-9)


def test_rigorous_cross_elevation_term_is_exact_at_the_zenith():
    """HSCA2 rigorous: an exact sideways offset of |coef cos 2A'|, no pole at the zenith."""
    coef = 30 * ARCSEC
    model = px.AltAz([harmonic_term("HSCA2", coef, form="rigorous")])
    for A in (0.3, 1.9):
        d = np.asarray(model(np.array([[A, np.pi / 2]])))[0]
        assert np.isfinite(d).all()
        assert float(px.rotations.angle_between(d, jnp.array([0.0, 0.0, 1.0]))) == pytest.approx(
            abs(coef * np.cos(2 * (np.pi - A))), rel=1e-6
        )


def test_autodiff_jacobian_matches_central_differences():
    """d(residuals)/d(coefficients) from JAX against central differences (rel 1e-6), for
    harmonic terms of every kind in both forms, together in one model."""
    terms = [
        harmonic_term("HSCA5CE8", 40 * ARCSEC, form="linear"),
        harmonic_term("HESACE", -30 * ARCSEC, form="linear"),
        harmonic_term("HACA2", 25 * ARCSEC, form="rigorous"),
        harmonic_term("HSCA2", 35 * ARCSEC, form="rigorous"),
        harmonic_term("HECE3", 20 * ARCSEC, form="rigorous"),
    ]
    model = px.AltAz([px.terms.IA(coef=100 * ARCSEC), px.terms.rigorous.CA(coef=-20 * ARCSEC), *terms])
    rng = np.random.default_rng(3)
    encoder = np.stack([rng.uniform(-np.pi, np.pi, 10), rng.uniform(0.2, 1.3, 10)], -1)
    obs = px.simulate(px.AltAz([]), encoder)
    y0 = np.asarray(model.values())

    @jax.jit
    def residual(y):
        return px.residuals(model.with_values(y), obs).reshape(-1)

    jac = np.asarray(jax.jacfwd(residual)(jnp.asarray(y0)))
    for k in range(2, len(y0)):
        h = 1e-4 * abs(y0[k])
        step = np.zeros_like(y0)
        step[k] = h
        fd = (np.asarray(residual(jnp.asarray(y0 + step))) - np.asarray(residual(jnp.asarray(y0 - step)))) / (2 * h)
        assert np.max(np.abs(fd)) > 0
        np.testing.assert_allclose(jac[:, k], fd, rtol=0, atol=1e-6 * np.max(np.abs(fd)), err_msg=model.parameter_names[k])


# ------------------------------------------------------------------ a real run


MMT_TERMS = "IA IE AN AW HACA2 HESA2 HSCA3 HESACE"


def _ols_reference(run):
    """The harmonic and basic terms at the observed position, d = observed - raw (numpy)."""
    A, E = run.observed.T
    dA = (A - run.encoder[:, 0] + np.pi) % (2 * np.pi) - np.pi
    dE = E - run.encoder[:, 1]
    zero, one, Ap = np.zeros_like(A), np.ones_like(A), np.pi - A
    basis = [
        (-one, zero), (zero, one), (-s(A) * t(E), -c(A)), (-c(A) * t(E), s(A)),  # IA IE AN AW
        (-c(2 * Ap), zero), (zero, s(2 * Ap)), (-c(3 * Ap) / c(E), zero), (zero, s(Ap) * c(E)),
    ]
    J = np.array([np.concatenate([fa * c(E), fe]) for fa, fe in basis]).T
    y = np.concatenate([dA * c(E), dE])
    x, *_ = np.linalg.lstsq(J, y, rcond=None)
    rms = np.sqrt(np.sum((y - J @ x) ** 2) / len(A))
    return x, rms * np.sqrt(np.diag(np.linalg.inv(J.T @ J))), rms


def test_harmonic_fit_of_the_mmt_run_matches_independent_least_squares():
    run = px.io.read_tpoint(MMT_DAT, azimuth="S-E")
    # Gauss-Newton: the problem is linear, and it compiles faster than LM.
    # The reference is least squares of the linear form's offsets at the observed position.
    result = px.fit(px.AltAz(px.terms.tpoint(MMT_TERMS, form="linear"), azimuth=run.azimuth), run, solver="gauss-newton")
    assert bool(result.converged)
    x, sigma, rms = _ols_reference(run)
    assert list(result.names) == MMT_TERMS.split()
    np.testing.assert_allclose(np.asarray(result.values) / ARCSEC, x / ARCSEC, atol=0.005)
    np.testing.assert_allclose(np.asarray(result.sigmas) / ARCSEC, sigma / ARCSEC, atol=0.005)
    assert float(result.sky_rms) / ARCSEC == pytest.approx(rms / ARCSEC, abs=0.001)


# ------------------------------------------------------------------ model files

HARMONIC_MODEL = """\
Harmonic model
T  80   0.8148   42.060  -0.0485
  IA      +1209.4890     1.13600
  IE         -2.8170     0.27000
  HACA2      -0.3250     0.20800
& HSCA5CE8   +0.7000     0.10000
 =HESACE     +0.5990
END
"""


def test_model_file_with_harmonic_terms_reads_builds_and_writes_back(tmp_path):
    mf = parse_model(HARMONIC_MODEL, path="harm.mod")
    assert mf.names == ["IA", "IE", "HACA2", "HSCA5CE8", "HESACE"]
    for form, cls in (("linear", Harmonic), ("rigorous", RigorousHarmonic)):
        model = mf.model(form=form, azimuth="S-E")
        assert model.parameter_names == mf.names
        assert isinstance(model.terms[2], cls)
        assert model.fixed == frozenset({"HESACE"})
        for term in mf.terms:
            assert float(model.get(term.name)) == pytest.approx(term.value * ARCSEC, rel=1e-15)
    model = mf.model(azimuth="S-E")
    path = tmp_path / "again.mod"
    write_model(path, model, caption="again")
    again = read_model(path)
    assert again.names == mf.names
    assert [term.value for term in again.terms] == pytest.approx([term.value for term in mf.terms], abs=1e-4)
    assert [term.fixed for term in again.terms] == [False, False, False, False, True]
    rebuilt = again.model(azimuth="S-E")
    np.testing.assert_allclose(np.asarray(rebuilt(POSITIONS)), np.asarray(model(POSITIONS)), atol=1e-12)


def test_model_file_with_an_unknown_term_names_file_and_line(tmp_path):
    path = tmp_path / "bad.mod"
    path.write_text(format_model([ModelTerm("IA", 1.0, 0.1), ModelTerm("HBCA2", 2.0, 0.1)], caption="bad"))
    mf = read_model(path)
    with pytest.raises(TpointFormatError, match=rf"{path}:3: term record HBCA2: harmonic term 'HBCA2': character 2"):
        mf.model()
    with pytest.raises(ValueError, match="unknown term form"):
        mf.model(form="curvy")

"""The term library: TPOINT definitions, katpoint equivalents, rigorous forms, Jacobians.

References: TPOINT's basis functions written out here (DESIGN.md's table), katpoint's
own ``PointingModel.offset``, first-order agreement between each rigorous rotation and
its linear form, and central finite differences for every autodiff Jacobian.
"""

from __future__ import annotations

import importlib.util
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import EXAMPLES

import pointax as px

ARCSEC = np.pi / 648000

# TPOINT's definitions: (dA, dE) = observed - raw per unit coefficient, at (A, E).
s, c, t = np.sin, np.cos, np.tan
TPOINT_BASIS = {
    "IA": lambda A, E: (-1.0, 0.0),
    "IE": lambda A, E: (0.0, 1.0),
    "CA": lambda A, E: (-1 / c(E), 0.0),
    "NPAE": lambda A, E: (-t(E), 0.0),
    "AN": lambda A, E: (-s(A) * t(E), -c(A)),
    "AW": lambda A, E: (-c(A) * t(E), s(A)),
    "TF": lambda A, E: (0.0, -c(E)),
    "TX": lambda A, E: (0.0, -1 / t(E)),
    "ACEC": lambda A, E: (c(A), 0.0),
    "ACES": lambda A, E: (-s(A), 0.0),
    "ECEC": lambda A, E: (0.0, c(E)),
    "ECES": lambda A, E: (0.0, s(E)),
    # TPOINT's polynomial variable is its own azimuth A_T = 180 deg - A, in (-180, 180] deg.
    "PAA1": lambda A, E: (-np.arctan2(s(A), -c(A)), 0.0),
    "PEE1": lambda A, E: (0.0, E),
}

# katpoint parameter index (P1 = 0) and the factor k with P = k * coef.
KATPOINT = {
    "IA": (1, +1),
    "IE": (7, -1),
    "CA": (4, -1),
    "NPAE": (3, +1),
    "AN": (5, +1),
    "AW": (6, -1),
    "TF": (8, +1),
    "ACEC": (13, -1),
    "ACES": (14, +1),
    "ECEC": (8, -1),
    "ECES": (11, -1),
    "PEE1": (9, -1),
}  # PAA1: P12 = -PAA1 plus an azimuth zero point (A_T = pi - A on one branch), not tested here.
# The terms above; pointax.terms.tpoint_special's are tested in test_tpoint_repertoire.py.
ALL = list(TPOINT_BASIS)

POSITIONS = np.array([[0.3, 0.4], [2.0, 1.1], [-2.5, 0.7], [4.0, 0.25], [1.2, 1.35]])


def test_every_required_term_is_in_both_forms():
    required = "IA IE CA NPAE AN AW TF TX ACEC ACES ECEC ECES PAA1 PEE1".split()
    assert list(px.terms.LINEAR_TERMS)[: len(required)] == required
    assert sorted(px.terms.rigorous.RIGOROUS_TERMS) == sorted(px.terms.LINEAR_TERMS)
    for name in required:
        for cls in (px.terms.LINEAR_TERMS[name], px.terms.rigorous.RIGOROUS_TERMS[name]):
            assert cls.__doc__ and len(cls.__doc__) > 40, f"{cls} needs a docstring"
        assert "katpoint" in px.terms.LINEAR_TERMS[name].__doc__ or name in ("TX",)


@pytest.mark.parametrize("name", ALL)
def test_linear_basis_is_tpoints_definition(name):
    term = px.terms.LINEAR_TERMS[name](coef=1.0)
    for A, E in POSITIONS:
        got = np.asarray(term.sky_offset(jnp.array([A, E])))
        np.testing.assert_allclose(got, np.broadcast_to(TPOINT_BASIS[name](A, E), (2,)), rtol=1e-14, atol=1e-15)


@pytest.mark.parametrize("name", sorted(KATPOINT))
def test_katpoint_equivalent(name):
    """katpoint's offset is raw minus requested: the negative of TPOINT's observed - raw."""
    katpoint = pytest.importorskip("katpoint")
    index, factor = KATPOINT[name]
    coef = 20 * ARCSEC
    values = np.zeros(22)
    values[index - 1] = factor * coef
    pm = katpoint.PointingModel(values)
    term = px.terms.LINEAR_TERMS[name](coef=coef)
    for A, E in POSITIONS:
        k_az, k_el = pm.offset(A, E)
        ours = np.asarray(term.sky_offset(jnp.array([A, E])))
        np.testing.assert_allclose(ours, [-k_az, -k_el], atol=1e-15)


def test_model_places_linear_terms_at_the_sky_position():
    """s = raw + sum coef * f(s): TPOINT evaluates its terms at the observed position."""
    coefs = {"IA": 1200, "IE": -30, "NPAE": 20, "CA": -15, "AN": 10, "AW": -12, "TF": 25, "TX": -3}
    values = {k: v * ARCSEC for k, v in coefs.items()}
    model = px.AltAz(px.terms.tpoint(list(coefs), values=values, form="linear"))
    for raw in POSITIONS:
        sky = np.asarray(model.sky_angles(jnp.array(raw)))
        offset = sum(v * ARCSEC * np.asarray(TPOINT_BASIS[k](*sky)) for k, v in coefs.items())
        np.testing.assert_allclose(sky - raw, offset, atol=1e-15)


@pytest.mark.parametrize("name", ALL)
def test_rigorous_form_equals_linear_form_to_first_order(name):
    """With a 1" coefficient the two forms differ only at second order (< 1e-9 rad)."""
    coef = 1.0 * ARCSEC
    linear = px.AltAz([px.terms.LINEAR_TERMS[name](coef=coef)])
    rigorous = px.AltAz([px.terms.rigorous.RIGOROUS_TERMS[name](coef=coef)])
    nominal = px.AltAz([])
    d_lin, d_rig, d_nom = linear(POSITIONS), rigorous(POSITIONS), nominal(POSITIONS)
    shift = np.asarray(px.rotations.angle_between(d_lin, d_nom))
    assert np.max(shift) > 0.3 * coef  # the term does something
    err = np.asarray(px.rotations.angle_between(d_lin, d_rig))
    assert np.all(err < 1e-9), err


def test_rigorous_terms_are_exact_at_the_zenith():
    """The rigorous form has no pole: CA stays a pure cross-elevation offset of |CA|."""
    ca = 30 * ARCSEC
    model = px.AltAz(px.terms.tpoint("CA NPAE AN AW", form="rigorous", values={"CA": ca}))
    for el in (np.pi / 2 - 1e-9, np.pi / 2):
        d = model(np.array([[0.7, el]]))
        assert np.isfinite(np.asarray(d)).all()
        assert float(px.rotations.angle_between(d[0], jnp.array([0.0, 0.0, 1.0]))) == pytest.approx(ca, rel=1e-6)


def test_tpoint_factory_errors():
    with pytest.raises(ValueError, match="unknown TPOINT term 'XX'"):
        px.terms.tpoint("IA XX")
    with pytest.raises(ValueError, match="unknown term form"):
        px.terms.tpoint("IA", form="curvy")
    with pytest.raises(ValueError, match="not in the list"):
        px.terms.tpoint("IA", values={"IE": 1.0})
    assert [t.name for t in px.terms.tpoint("ia, ie  ca")] == ["IA", "IE", "CA"]


# ------------------------------------------------------------------ Jacobians


def _load_example_term():
    spec = importlib.util.spec_from_file_location("new_error_term", EXAMPLES / "new_error_term.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["new_error_term"] = module
    spec.loader.exec_module(module)
    return module.AzWobble(amp=7 * ARCSEC, phase=0.6)


def _jacobian_cases():
    cases = []
    for form, library in px.terms.FORMS.items():
        for name, cls in library.items():
            cases.append((f"{form}-{name}", lambda cls=cls: cls(coef=40 * ARCSEC)))
    cases.append(("example-AzWobble", _load_example_term))
    return cases


CASES = _jacobian_cases()


@pytest.mark.parametrize("make", [c[1] for c in CASES], ids=[c[0] for c in CASES])
def test_autodiff_jacobian_matches_central_differences(make):
    """d(residuals)/d(parameters) from JAX against central finite differences (rel 1e-6).

    The term sits in a model with two other terms (so chain and sky stages interact);
    the Jacobian with respect to the term's own parameters is checked. The step is
    1e-4 of the parameter (at least 1e-6 rad): directions carry ~1e-16 absolute
    rounding, so a smaller step would measure rounding, not the derivative."""
    term = make()
    companions = [px.terms.IA(coef=100 * ARCSEC), px.terms.rigorous.CA(coef=-20 * ARCSEC)]
    if term.name in ("IA", "CA"):
        companions = [px.terms.IE(coef=100 * ARCSEC), px.terms.rigorous.NPAE(coef=-20 * ARCSEC)]
    model = px.AltAz(companions + [term])
    rng = np.random.default_rng(1)
    encoder = np.stack([rng.uniform(-np.pi, np.pi, 12), rng.uniform(0.2, 1.3, 12)], -1)
    obs = px.simulate(px.AltAz([]), encoder)  # targets differ from the model
    n_term = len(px.terms.param_fields(term))
    y0 = np.asarray(model.values())

    def residual(y):
        return px.residuals(model.with_values(y), obs).reshape(-1)

    jac = np.asarray(jax.jacfwd(residual)(jnp.asarray(y0)))[:, -n_term:]
    for k in range(n_term):
        h = 1e-4 * max(abs(y0[-n_term + k]), 0.01)
        step = np.zeros_like(y0)
        step[-n_term + k] = h
        fd = (np.asarray(residual(jnp.asarray(y0 + step))) - np.asarray(residual(jnp.asarray(y0 - step)))) / (2 * h)
        scale = np.max(np.abs(fd))
        assert scale > 0
        np.testing.assert_allclose(jac[:, k], fd, rtol=0, atol=1e-6 * scale)

"""The level-mount paper's model families, each against a NumPy evaluation of the paper's
formulas written out here (not by calling pointax):

* harmonic: eqs 1-2;  basic: eqs 3-4 (with eps cos L - theta sin L);
* rotation: the matrices of eqs 9 and 11-15 as printed, plus eqs 16-17;
* linearised: eqs 6-7 applied to the exact M of eq 15, term by term (eqs 18-19 as
  derived, since the printed eq 18 is damaged), and the second-order agreement with
  the rigorous model (differences scale as t^2 when the parameters scale as t);
* recovery of simulated parameters by px.fit.

Sign (the paper's eq 20): Delta = encoder reading - sky, so the mount points at
eq 5 of (reading - Delta(reading)).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import pointax as px
from pointax.terms.model_factories import XY, XY_FAMILIES, xy_family
from pointax.core.mounts import XYMount
from pointax.terms import xy

ARCSEC = np.pi / 648000


# ---------------------------------------------------------------------- references


def xy_direction(L, B):
    """Eq 5: (sin L cos B, sin B, cos L cos B) in (East, North, Up)."""
    return np.stack([np.sin(L) * np.cos(B), np.sin(B), np.cos(L) * np.cos(B)], axis=-1)


def xy_angles(d):
    return np.stack([np.arctan2(d[..., 0], d[..., 2]), np.arcsin(np.clip(d[..., 1], -1, 1))], axis=-1)


def readings(n=60, min_elevation_deg=20.0, seed=0):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(8 * n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v = v[v[:, 2] > np.sin(np.radians(min_elevation_deg))][: n - 1]
    return np.concatenate([[[0.0, 0.0]], xy_angles(v)])  # the zenith too


def pointing_of(delta_fn, enc):
    """Eq 5 at (reading - Delta(reading))."""
    dL, dB = delta_fn(enc[:, 0], enc[:, 1])
    return xy_direction(enc[:, 0] - dL, enc[:, 1] - dB)


def harmonic_delta(a, b):
    """Eqs 1-2: DL cos B = sum a_k g_k, DB = sum b_k g_k."""

    def delta(L, B):
        sL, cL, sB, cB = np.sin(L), np.cos(L), np.sin(B), np.cos(B)
        g = np.stack(
            [
                np.ones_like(L), sB, cL * cB, sL * cB,
                sB**2, cL * sB * cB, sL * sB * cB,
                sB**3, cL * sB**2 * cB, sL * sB**2 * cB,
                sB**4, cL * sB**3 * cB, sL * sB**3 * cB,
            ]
        )  # fmt: skip
        return (a @ g) / cB, b @ g

    return delta


def basic_delta(eps, theta, phi, C, a1, a2, mu, a1p, a2p, u, printed_sign=False):
    """Eqs 3-4; the printed eq 4 has + theta sin L, a rigid tilt gives - theta sin L."""

    def delta(L, B):
        tB = np.tan(B)
        dL = eps * np.sin(L) * tB + theta * np.cos(L) * tB + phi * tB + C / np.cos(B) + a1 * np.sin(L) + a2 * np.cos(L) + mu
        dB = eps * np.cos(L) + (1 if printed_sign else -1) * theta * np.sin(L) + a1p * np.sin(B) + a2p * np.cos(B) + u
        return dL, dB

    return delta


# The linearised functions (eqs 18-19 re-derived), written out: DL = sum a_k f_k, DB = sum b_k h_k.
def linearised_functions(L, B):
    sL, cL, sB, cB = np.sin(L), np.cos(L), np.sin(B), np.cos(B)
    tL, tB = sL / cL, sB / cB
    f = [
        np.ones_like(L),  # a0
        1 / (cL * cB),  # a1
        1 / cB,  # a2
        tL / cB,  # a3
        tB / cL,  # a4
        tL * tB / cB,  # a5
        tL * tB,  # a6
        tB,  # a7
        sL * tL * tB / cB,  # a8
        cL * tL * tB / cB,  # a9 = sin L tan B / cos B
        sL * sB * tL * tB / cB,  # a10 = sin L tan L tan^2 B
        cL * sB * tL * tB / cB,  # a11 = sin L tan^2 B
        sL * tL * tB,  # a12
        cL * tL * tB,  # a13 = sin L tan B
        sL,  # a14
        cL,  # a15
    ]
    h = [np.ones_like(L), 1 / cB, sL / cB, cL / cB, sL * tB, cL * tB, sL, cL, sB, cB]  # b0 .. b9
    return np.stack(f), np.stack(h)


PAPER_A_NAMES = [
    "dL_1", "dL_secL_secB", "dL_secB", "dL_tanL_secB", "dL_secL_tanB", "dL_tanL_tanB_secB",
    "dL_tanL_tanB", "dL_tanB", "dL_sinL_tanL_tanB_secB", "dL_sinL_tanB_secB",
    "dL_sinL_tanL_tanB^2", "dL_sinL_tanB^2", "dL_sinL_tanL_tanB", "dL_sinL_tanB", "dL_sinL", "dL_cosL",
]  # fmt: skip
PAPER_B_NAMES = [
    "dB_1", "dB_secB", "dB_sinL_secB", "dB_cosL_secB", "dB_sinL_tanB", "dB_cosL_tanB",
    "dB_sinL", "dB_cosL", "dB_sinB", "dB_cosB",
]  # fmt: skip


def paper_M(L, B, v, Lv, phi, C):
    """Eq 15, M = Mv ML Mphi MB MC, with the matrices as printed (eqs 9, 11-14; eq 11's
    first row, lost in print, is (cos L, 0, sin L) by eq 5)."""
    cv, sv, cl, sl = np.cos(v), np.sin(v), np.cos(Lv), np.sin(Lv)
    Mv = np.array(
        [
            [cl**2 * (1 - cv) + cv, -sl * sv, sl * cl * (1 - cv)],
            [sl * sv, cv, -cl * sv],
            [sl * cl * (1 - cv), cl * sv, cv + sl**2 * (1 - cv)],
        ]
    )
    ML = np.array([[np.cos(L), 0, np.sin(L)], [0, 1, 0], [-np.sin(L), 0, np.cos(L)]])
    Mphi = np.array([[np.cos(phi), -np.sin(phi), 0], [np.sin(phi), np.cos(phi), 0], [0, 0, 1]])
    MB = np.array([[1, 0, 0], [0, np.cos(B), np.sin(B)], [0, -np.sin(B), np.cos(B)]])
    MC = np.array([[np.cos(C), 0, np.sin(C)], [0, 1, 0], [-np.sin(C), 0, np.cos(C)]])
    return Mv @ ML @ Mphi @ MB @ MC


def rotation_pointing(enc, v, Lv, phi, C, a0p, b0p, e1, L0, e2, B0):
    """Eq 15 applied to (0, 0, 1) at the readings corrected by eqs 16-17
    (Delta L = a'0 + e1 sin(L - L0), Delta B = b'0 + e2 sin(B - B0))."""
    out = []
    for Lr, Br in enc:
        L = Lr - a0p - e1 * np.sin(Lr - L0)
        B = Br - b0p - e2 * np.sin(Br - B0)
        out.append(paper_M(L, B, v, Lv, phi, C) @ [0.0, 0.0, 1.0])
    return np.array(out)


# The issue's example mount (eq 9's v = 100" at Lv = -60 deg, phi 30", C 60", zero points
# -10" and -130", eccentricities 60" and 50" with phases chosen here).
PAPER = dict(
    v=100 * ARCSEC, Lv=np.radians(-60), phi=30 * ARCSEC, C=60 * ARCSEC, a0p=-10 * ARCSEC, b0p=-130 * ARCSEC,
    e1=60 * ARCSEC, L0=np.radians(20), e2=50 * ARCSEC, B0=np.radians(-70),
)  # fmt: skip


def rotation_values(v, Lv, phi, C, a0p, b0p, e1, L0, e2, B0):
    """The rotation family's parameters for the paper's symbols (written out here)."""
    return {
        "tilt_rot.up": v * np.cos(Lv),
        "tilt_rot.west": v * np.sin(Lv),
        "nonperp_rot": phi,
        "collim_rot": C,
        "L_zero": a0p,
        "B_zero": b0p,
        "L_ecc_sin": e1 * np.cos(L0),  # e1 sin(L - L0) = e1 cos L0 sin L - e1 sin L0 cos L
        "L_ecc_cos": -e1 * np.sin(L0),
        "B_ecc_sin": e2 * np.cos(B0),
        "B_ecc_cos": -e2 * np.sin(B0),
    }


@jax.jit
def _pointing(model, enc):
    return jax.vmap(model.direction)(enc)


def model_pointing(model, enc):
    """Where ``model`` points for readings ``enc`` (one compilation per model structure)."""
    return np.asarray(_pointing(model, jnp.asarray(enc)))


def add_axis_noise(obs, sigma_l, sigma_b, seed):
    """Observations with Gaussian noise added along the X-Y mount's own axes: sigma_l on
    the sky across L (dL cos B), sigma_b in B (the mount frame's tangent plane)."""
    frame = np.asarray(XYMount().frame)
    offsets = np.random.default_rng(seed).normal(size=(len(obs), 2)) * [sigma_l, sigma_b]
    noisy = np.asarray(px.rotations.offset_direction(jnp.asarray(np.asarray(obs.target) @ frame), offsets)) @ frame.T
    return px.Observations(obs.encoder, noisy, convention=obs.convention)


# ---------------------------------------------------------------------- the families


def test_family_names_and_sizes():
    sizes = {"harmonic": 26, "basic": 10, "rotation": 10, "linearised": 26}
    assert set(XY_FAMILIES) == set(sizes)
    for name, n in sizes.items():
        assert len(XY(name).parameter_names) == n
    assert XY("linearised").parameter_names == PAPER_A_NAMES + PAPER_B_NAMES
    assert xy_family("linearized") == xy_family("linearised")
    with pytest.raises(ValueError, match="unknown X-Y model family 'physical'"):
        xy_family("physical")
    with pytest.raises(KeyError, match="no parameter 'IA'"):
        xy_family("basic", {"IA": 1.0})
    with pytest.raises(ValueError, match="unknown basic term 'tilt'"):
        xy.Basic("tilt")
    with pytest.raises(ValueError, match="not rotation-family parameters"):
        xy.linearised_from_rotation({"tilt_up": 1.0})


def test_harmonic_family_is_eqs_1_2():
    rng = np.random.default_rng(11)
    a, b = rng.normal(0, 60 * ARCSEC, 13), rng.normal(0, 60 * ARCSEC, 13)
    # The paper's a_0 .. a_12 and b_0 .. b_12, by the functions' names.
    g = ["1", "sinB", "cosL_cosB", "sinL_cosB", "sinB^2", "cosL_sinB_cosB", "sinL_sinB_cosB", "sinB^3",
         "cosL_sinB^2_cosB", "sinL_sinB^2_cosB", "sinB^4", "cosL_sinB^3_cosB", "sinL_sinB^3_cosB"]  # fmt: skip
    values = {f"SHL_{k}": a[i] for i, k in enumerate(g)} | {f"SHB_{k}": b[i] for i, k in enumerate(g)}
    model = XY(xy_family("harmonic", values))
    enc = readings()
    np.testing.assert_allclose(model_pointing(model, enc), pointing_of(harmonic_delta(a, b), enc), atol=2e-16)


def test_basic_family_is_eqs_3_4():
    rng = np.random.default_rng(12)
    p = dict(zip(["eps", "theta", "phi", "C", "a1", "a2", "mu", "a1p", "a2p", "u"], rng.normal(0, 80 * ARCSEC, 10)))
    names = {"eps": "tilt_up", "theta": "tilt_west", "phi": "nonperp", "C": "collim", "a1": "L_ecc_sin",
             "a2": "L_ecc_cos", "mu": "L_zero", "a1p": "B_ecc_sin", "a2p": "B_ecc_cos", "u": "B_zero"}  # fmt: skip
    model = XY(xy_family("basic", {names[k]: v for k, v in p.items()}))
    enc = readings()
    np.testing.assert_allclose(model_pointing(model, enc), pointing_of(basic_delta(**p), enc), atol=2e-16)


def test_linearised_family_is_eqs_18_19():
    rng = np.random.default_rng(13)
    a, b = rng.normal(0, 40 * ARCSEC, 16), rng.normal(0, 40 * ARCSEC, 10)
    model = XY(xy_family("linearised", dict(zip(PAPER_A_NAMES, a)) | dict(zip(PAPER_B_NAMES, b))))
    enc = readings()

    def delta(L, B):
        f, h = linearised_functions(L, B)
        return a @ f, b @ h

    np.testing.assert_allclose(model_pointing(model, enc), pointing_of(delta, enc), atol=2e-16)


# At 300 times the paper's sizes the zero offsets are tens of degrees, on purpose.
@pytest.mark.filterwarnings("ignore:.*most likely in degrees:pointax.core.errors.InputWarning")
@pytest.mark.parametrize("scale", [1.0, 300.0])
def test_rotation_family_is_eq_15_exactly(scale):
    """Rigorous: the same as the printed matrices at the paper's sizes and at 300 times
    them (v = 8.3 deg, C = 5 deg), where any linearisation would be far off."""
    p = {k: (v * scale if k not in ("Lv", "L0", "B0") else v) for k, v in PAPER.items()}
    model = XY(xy_family("rotation", rotation_values(**p)))
    enc = readings()
    np.testing.assert_allclose(model_pointing(model, enc), rotation_pointing(enc, **p), atol=1e-15)
    # The helper for the paper's polar symbols gives the same values.
    helper = xy.rotation_values(
        v=p["v"], Lv=p["Lv"], phi=p["phi"], C=p["C"], L_zero=p["a0p"], B_zero=p["b0p"],
        L_ecc=p["e1"], L_ecc_phase=p["L0"], B_ecc=p["e2"], B_ecc_phase=p["B0"],
    )  # fmt: skip
    for k, v in rotation_values(**p).items():
        assert helper[k] == pytest.approx(v, abs=1e-18)


def test_primary_axis_rotation_is_eq_9_and_smooth_at_zero():
    for v, Lv in [(0.3, -1.0), (1e-7, 2.0), (2.0, 0.4)]:
        cv, sv, cl, sl = np.cos(v), np.sin(v), np.cos(Lv), np.sin(Lv)
        eq9 = np.array(
            [
                [cl**2 * (1 - cv) + cv, -sl * sv, sl * cl * (1 - cv)],
                [sl * sv, cv, -cl * sv],
                [sl * cl * (1 - cv), cl * sv, cv + sl**2 * (1 - cv)],
            ]
        )
        got = np.asarray(xy.primary_axis_rotation(v * np.cos(Lv), v * np.sin(Lv)))
        np.testing.assert_allclose(got, eq9, atol=1e-16)
    # At zero (where fits start) the Jacobian is the generator: dR/d(up) = [e_x]x, dR/d(west) = [e_z]x.
    jac = jax.jacfwd(lambda w: xy.primary_axis_rotation(w[0], w[1]))(jnp.zeros(2))
    np.testing.assert_allclose(np.asarray(jac[..., 0]), [[0, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-15)
    np.testing.assert_allclose(np.asarray(jac[..., 1]), [[0, -1, 0], [1, 0, 0], [0, 0, 0]], atol=1e-15)


def test_linearised_coefficients_are_eqs_6_7_of_the_exact_M():
    """Term by term: eqs 6-7 applied to the exact M of eq 15 give the 16 + 10 functions
    with linearised_from_rotation's coefficients plus the three second-order functions
    the family leaves out (tan L, tan L tan^2 B in DL; tan B in DB)."""
    p = dict(v=np.radians(2.0), Lv=np.radians(-60), phi=np.radians(1.5), C=np.radians(-1.0))
    coef = xy.linearised_from_rotation(rotation_values(**p, a0p=0.0, b0p=0.0, e1=0.0, L0=0.0, e2=0.0, B0=0.0))
    a = np.array([float(coef[n]) for n in PAPER_A_NAMES])
    b = np.array([float(coef[n]) for n in PAPER_B_NAMES])
    enc = readings(40)
    L, B = enc[:, 0], enc[:, 1]
    d = np.array([paper_M(Lk, Bk, **p) @ [0.0, 0.0, 1.0] for Lk, Bk in enc])
    dX = d[:, 0] - np.sin(L) * np.cos(B)  # DX / R
    dY = d[:, 1] - np.sin(B)  # DY / R
    dL = dX / (np.cos(L) * np.cos(B)) + np.tan(L) * np.tan(B) * dY / np.cos(B)  # eq 6
    dB = dY / np.cos(B)  # eq 7
    # The coefficients of the left-out functions, read off the same M (element m_ij).
    Mv = paper_M(0.0, 0.0, p["v"], p["Lv"], 0.0, 0.0)
    second = np.cos(p["phi"]) * np.cos(p["C"])
    left_out_L = (Mv[0, 0] * np.cos(p["C"]) - 1) * np.tan(L) + (Mv[1, 1] * second - 1) * np.tan(L) * np.tan(B) ** 2
    left_out_B = (Mv[1, 1] * second - 1) * np.tan(B)
    f, h = linearised_functions(L, B)
    # The family's Delta is encoder - sky; eqs 6-7 give sky - encoder.
    np.testing.assert_allclose(-(a @ f) + left_out_L, dL, atol=1e-15)
    np.testing.assert_allclose(-(b @ h) + left_out_B, dB, atol=1e-15)


def _max_angle(d1, d2):
    return float(np.max(np.arccos(np.clip(np.sum(d1 * d2, axis=-1), -1, 1))))


def test_linearised_and_basic_agree_with_the_rigorous_model_to_second_order():
    """Parameters t * p: rigorous minus linearised (and minus basic) scales as t^2, while
    the errors themselves scale as t. The printed eq 4 (+ theta sin L) does not: its
    error is first order."""
    enc = readings(40)
    nominal = xy_direction(enc[:, 0], enc[:, 1])
    base = {k: (v * 20 if k not in ("Lv", "L0", "B0") else v) for k, v in PAPER.items()}  # v = 2000", ...
    rot = XY(xy_family("rotation"))
    lin = XY(xy_family("linearised"))
    basic = XY(xy_family("basic"))
    diffs = {"linearised": [], "basic": [], "printed eq 4": [], "size": []}
    ts = [1.0, 0.5, 0.25, 0.125]
    for t in ts:
        p = {k: (v * t if k not in ("Lv", "L0", "B0") else v) for k, v in base.items()}
        values = rotation_values(**p)
        rigorous = model_pointing(rot.set(**values), enc)
        np.testing.assert_allclose(rigorous, rotation_pointing(enc, **p), atol=1e-15)
        linear = model_pointing(lin.set(**xy.linearised_from_rotation(values)), enc)
        first = model_pointing(basic.set(**xy.basic_from_rotation(values)), enc)
        printed = basic_delta(
            eps=p["v"] * np.cos(p["Lv"]), theta=p["v"] * np.sin(p["Lv"]), phi=p["phi"], C=-p["C"],
            a1=values["L_ecc_sin"], a2=values["L_ecc_cos"], mu=p["a0p"],
            a1p=values["B_ecc_sin"], a2p=values["B_ecc_cos"], u=p["b0p"], printed_sign=True,
        )  # fmt: skip
        diffs["linearised"].append(_max_angle(rigorous, linear))
        diffs["basic"].append(_max_angle(rigorous, first))
        diffs["printed eq 4"].append(_max_angle(rigorous, pointing_of(printed, enc)))
        diffs["size"].append(_max_angle(rigorous, nominal))
    for key in ("linearised", "basic"):
        ratios = np.array(diffs[key][:-1]) / np.array(diffs[key][1:])
        np.testing.assert_allclose(ratios, 4.0, rtol=0.1, err_msg=f"{key}: {diffs[key]}")
        # And small: second order in parameters of about 0.01 rad.
        assert diffs[key][0] < 0.02 * diffs["size"][0]
    np.testing.assert_allclose(np.array(diffs["size"][:-1]) / np.array(diffs["size"][1:]), 2.0, rtol=0.05)
    printed_ratios = np.array(diffs["printed eq 4"][:-1]) / np.array(diffs["printed eq 4"][1:])
    np.testing.assert_allclose(printed_ratios, 2.0, rtol=0.1)
    assert diffs["printed eq 4"][-1] > 10 * diffs["basic"][-1]


# ---------------------------------------------------------------------- fits


def test_fit_recovers_the_rotation_family():
    """The issue's example mount, 68 stars above 25 deg, noise 4.1" across L and 2" in B
    (as the issue's example, on the sky: dL cos B and dB). The per-axis RMS of the fit's
    residuals is that noise: the residuals are in the mount's axes."""
    enc = readings(68, min_elevation_deg=25.0, seed=21)
    truth_values = rotation_values(**PAPER)
    truth = XY(xy_family("rotation", truth_values))
    obs = add_axis_noise(px.simulate(truth, enc), 4.1 * ARCSEC, 2.0 * ARCSEC, seed=5)
    assert obs.convention == "xy"
    result = px.fit(XY("rotation"), obs)
    assert bool(result.converged), result.report()
    for name, value in truth_values.items():
        got, sigma = result.value(name) * ARCSEC, result.sigma(name) * ARCSEC
        assert abs(got - value) < 4 * sigma, (name, got / ARCSEC, value / ARCSEC, sigma / ARCSEC)
    # Per-axis RMS of the residuals (dL cos B, dB): the noise put in.
    rms = np.sqrt(np.mean(np.asarray(result.residuals) ** 2, axis=0)) / ARCSEC
    np.testing.assert_allclose(rms, [4.1, 2.0], rtol=0.3)
    np.testing.assert_allclose(float(result.sky_rms) / ARCSEC, np.hypot(*rms), rtol=1e-12)


def test_fit_recovers_the_linearised_family():
    rng = np.random.default_rng(22)
    enc = readings(146, min_elevation_deg=25.0, seed=23)
    values = dict(zip(PAPER_A_NAMES + PAPER_B_NAMES, rng.normal(0, 30 * ARCSEC, 26)))
    obs = px.simulate(XY(xy_family("linearised", values)), enc, noise=1.0 * ARCSEC, seed=6)
    result = px.fit(XY("linearised"), obs, solver="gauss-newton")  # a linear model: a few steps
    assert bool(result.converged), result.report()
    pulls = np.array([(result.value(n) * ARCSEC - v) / (result.sigma(n) * ARCSEC) for n, v in values.items()])
    assert np.all(np.abs(pulls) < 4.5), pulls
    assert 0.7 < float(result.sky_rms) / ARCSEC / np.sqrt(2) < 1.3

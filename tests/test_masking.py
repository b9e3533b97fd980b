"""Masks: ``--mask`` rows, ``--mask-above`` (TPOINT's MASK R > x), ``--reject`` (the
robust flagging rule), and how the two compare on the MMT run.

References: NumPy least squares of TPOINT's linear definitions over the same rows, and a
NumPy iteratively-reweighted fit of the Cauchy loss for the robust rule
(tests/tpoint_numpy.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import tpoint_numpy as ref
from conftest import MMT_DAT

from pointax.cli import main
from pointax.fitting.masking import format_rows, parse_rows

EIGHT = "IA IE NPAE CA AN AW TF TX".split()
RAYLEIGH_MEDIAN = np.sqrt(2 * np.log(2))  # median of a 2-D Gaussian's norm, in sigmas


@pytest.fixture(autouse=True)
def no_compilation_cache(monkeypatch):
    monkeypatch.setenv("POINTAX_JAX_CACHE", "")


@pytest.fixture(scope="module")
def run():
    return ref.read_run(MMT_DAT)


def fit_json(capsys, *options) -> dict:
    code = main(["fit", str(MMT_DAT), "--azimuth", "S-E", "--residuals", "tpoint", "--form", "linear", "--json", *options])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    return out


def values_of(out) -> np.ndarray:
    return np.array([t["value_arcsec"] for t in out["terms"]])


def test_parse_rows():
    np.testing.assert_array_equal(parse_rows("17,19-21", 80), [16, 18, 19, 20])
    np.testing.assert_array_equal(parse_rows("3 1  2,2", 5), [0, 1, 2])
    np.testing.assert_array_equal(parse_rows("78-", 80), [77, 78, 79])
    np.testing.assert_array_equal(parse_rows("*", 3), [0, 1, 2])
    assert format_rows([16, 18, 19, 20]) == "17,19-21" and format_rows([]) == ""
    with pytest.raises(ValueError, match=r"--mask: row 81 is outside 1..80"):
        parse_rows("81", 80, option="--mask")
    with pytest.raises(ValueError, match="row 0 is outside"):
        parse_rows("0", 80)
    with pytest.raises(ValueError, match="'x' is not a row number"):
        parse_rows("x", 80)
    with pytest.raises(ValueError, match="runs backwards"):
        parse_rows("5-3", 80)


def test_mask_rows_against_numpy(run, capsys):
    observed, raw, _ = run
    out = fit_json(capsys, "--mask", "3,10-12")
    used = np.ones(len(observed), bool)
    used[[2, 9, 10, 11]] = False
    expected = ref.lstsq(EIGHT, observed, raw, used) / ref.ARCSEC
    np.testing.assert_allclose(values_of(out), expected, atol=1e-6)
    assert out["n_obs"] == 76 and out["masked"] == [2, 9, 10, 11]
    r = ref.tpoint_residuals(EIGHT, expected * ref.ARCSEC, observed, raw)
    assert abs(out["sky_rms_arcsec"] - np.sqrt(np.sum(r[used] ** 2) / 76) / ref.ARCSEC) < 1e-6
    flags = [(e["masked"], e["used"]) for e in out["observations"]]
    assert flags == [(not u, bool(u)) for u in used]


def test_mask_above_is_fit_mask_refit(run, capsys):
    """--mask-above 1.5: least squares of all, mask on-sky residuals above 1.5", refit."""
    observed, raw, _ = run
    out = fit_json(capsys, "--mask-above", "1.5")
    every = np.ones(len(observed), bool)
    first = ref.lstsq(EIGHT, observed, raw, every)
    distance = np.hypot(*ref.tpoint_residuals(EIGHT, first, observed, raw).T) / ref.ARCSEC
    used = distance <= 1.5
    assert 2 < (~used).sum() < 20
    np.testing.assert_allclose(values_of(out), ref.lstsq(EIGHT, observed, raw, used) / ref.ARCSEC, atol=1e-6)
    assert out["masked"] == list(np.flatnonzero(~used)) and out["n_obs"] == int(used.sum())


def robust_reference(observed, raw, reject):
    """pointax's robust rule by NumPy: two Cauchy fits (sum c^2 log(1 + |r|^2 / c^2) over
    observations, |r| the on-sky norm) by iteratively reweighted least squares, c twice
    the robust sigma (median norm / 1.1774) of the residuals before each; then flag norms
    above ``reject`` robust sigmas of the final robust fit."""
    A, E = observed[:, 0], observed[:, 1]
    X = np.concatenate([np.stack([ref.basis(k, A, E)[0] * np.cos(E) for k in EIGHT], -1),
                        np.stack([ref.basis(k, A, E)[1] for k in EIGHT], -1)])
    y = np.concatenate([ref.wrap(A - raw[:, 0]) * np.cos(E), E - raw[:, 1]])
    n = len(A)

    def norms(c):
        r = (y - X @ c).reshape(2, n)
        return np.hypot(r[0], r[1])

    c = np.zeros(len(EIGHT))
    for _ in range(2):
        scale = np.median(norms(c)) / RAYLEIGH_MEDIAN
        c2 = (2 * scale) ** 2
        for _ in range(500):
            w = 1 / (1 + norms(c) ** 2 / c2)
            sw = np.sqrt(np.concatenate([w, w]))
            new = np.linalg.lstsq(X * sw[:, None], y * sw, rcond=None)[0]
            done = np.max(np.abs(new - c)) < 1e-15
            c = new
            if done:
                break
    scale = np.median(norms(c)) / RAYLEIGH_MEDIAN
    return norms(c) > reject * scale, scale


def test_reject_flags_by_the_robust_rule(run, capsys):
    observed, raw, _ = run
    out = fit_json(capsys, "--reject", "3")
    flagged, scale = robust_reference(observed, raw, 3.0)
    assert out["loss"] == "cauchy" and out["outliers"] == list(np.flatnonzero(flagged))
    used = ~flagged
    np.testing.assert_allclose(values_of(out), ref.lstsq(EIGHT, observed, raw, used) / ref.ARCSEC, atol=1e-6)
    assert [e["outlier"] for e in out["observations"]] == list(flagged)


def test_robust_rule_and_mask_r_on_the_mmt_run(run, capsys):
    """The README's comparison on the MMT run: --reject 3 flags rows 39 and 79 (robust
    sigma 0.610", a limit of 1.83" on the robust fit's residuals); after the 8-term
    least-squares fit MASK R > 6 masks nothing, MASK R > 2 row 79 only, MASK R > 1.8 the
    same two rows as the robust rule."""
    observed, raw, _ = run
    flagged, scale = robust_reference(observed, raw, 3.0)
    assert list(np.flatnonzero(flagged) + 1) == [39, 79]
    assert abs(scale / ref.ARCSEC - 0.610) < 0.001
    every = np.ones(len(observed), bool)
    distance = np.hypot(*ref.tpoint_residuals(EIGHT, ref.lstsq(EIGHT, observed, raw, every), observed, raw).T)
    distance /= ref.ARCSEC
    assert not np.any(distance > 6)
    assert list(np.flatnonzero(distance > 2) + 1) == [79]
    assert list(np.flatnonzero(distance > 1.8) + 1) == [39, 79]
    for limit, rows in (("6", []), ("2", [79]), ("1.8", [39, 79])):
        assert [i + 1 for i in fit_json(capsys, "--mask-above", limit)["masked"]] == rows, limit
    # --reject 2.5 flags 8 rows; MASK R > 1.5 masks those and row 7.
    flagged, _ = robust_reference(observed, raw, 2.5)
    assert list(np.flatnonzero(flagged) + 1) == [13, 19, 22, 39, 49, 50, 51, 79]
    assert [i + 1 for i in fit_json(capsys, "--reject", "2.5")["outliers"]] == [13, 19, 22, 39, 49, 50, 51, 79]
    assert list(np.flatnonzero(distance > 1.5) + 1) == [7, 13, 19, 22, 39, 49, 50, 51, 79]


def test_mask_option_errors(capsys):
    assert main(["fit", str(MMT_DAT), "--mask", "90"]) == 2
    assert "--mask: row 90 is outside 1..80" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:  # an argument error: argparse's exit
        main(["fit", str(MMT_DAT), "--mask-above", "0"])
    assert exit_info.value.code == 2 and "'0' must be a positive number" in capsys.readouterr().err
    assert main(["fit", str(MMT_DAT), "--reject", "3", "--loss", "linear"]) == 2
    assert "does not apply to --loss linear" in capsys.readouterr().err

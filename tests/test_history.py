"""Run history (pointax.analysis.history): runs ordered by time, coefficients per run,
drift alarms, the exact JSON, the plot, a network compared with its last fit.

References: TPOINT's linear least squares in NumPy (tests/tpoint_numpy.py) on runs
simulated in NumPy (tests/history_runs.py) for every value, sigma and change; the
false-alarm rate from the normal distribution (erfc) with a binomial bound; the MJD of
a date counted by hand from 1858-11-17.
"""

from __future__ import annotations

import datetime
import json
import math

import numpy as np
import pytest

import pointax as px
from history_runs import TERMS, TRUTH_ARCSEC, mjd, reference_fit, simulate_run, write_tpoint
from pointax.analysis.history import (
    compare_with_previous,
    change_sigmas,
    date_of_mjd,
    history,
    mjd_of_date,
    read_previous,
)

N_RUNS = 16
START = datetime.date(2019, 3, 1)


def _model():
    # TPOINT's linear terms and residuals: the fit is linear least squares, as the reference.
    return px.AltAz(px.terms.tpoint(" ".join(TERMS), form="linear"), azimuth="N-E", residual_form="tpoint")


def _series(tmp_path, coefs_per_run, seed=0, name="run"):
    """Write one TPOINT file per run (dates 60 days apart); (paths, [(observed, raw)])."""
    paths, data = [], []
    for k, coefs in enumerate(coefs_per_run):
        observed, raw = simulate_run(coefs, seed=1000 * seed + k)
        path = tmp_path / f"{name}{k:02d}.dat"
        write_tpoint(path, observed, raw, START + datetime.timedelta(days=60 * k))
        paths.append(path)
        data.append((observed, raw))
    return paths, data


def _read(paths):
    return [px.io.read_tpoint(p) for p in paths]


def _reference_z(data, i, j):
    """The change of term j from run i - 1 to run i in sigmas, by NumPy least squares."""
    (v0, s0, _), (v1, s1, _) = reference_fit(*data[i - 1]), reference_fit(*data[i])
    return (v1[j] - v0[j]) / math.hypot(s0[j], s1[j])


# --------------------------------------------------------------------------- the alarms


@pytest.fixture(scope="module")
def jump(tmp_path_factory):
    """16 runs; IE jumps by 5 of its combined sigmas (from the reference fit of a run)
    at run 9 and stays there."""
    tmp = tmp_path_factory.mktemp("jump")
    _, s, _ = reference_fit(*simulate_run(TRUTH_ARCSEC, seed=99))
    step = 5.0 * math.sqrt(2.0) * s[TERMS.index("IE")]
    coefs = [dict(TRUTH_ARCSEC, IE=TRUTH_ARCSEC["IE"] + (step if k >= 9 else 0.0)) for k in range(N_RUNS)]
    paths, data = _series(tmp, coefs, seed=1)
    order = list(reversed(range(N_RUNS)))  # given newest first: the history orders them by date
    h = history(_read([paths[k] for k in order]), _model())
    return h, paths, data


def test_a_five_sigma_jump_is_alarmed_at_its_run_and_nowhere_else(jump):
    h, paths, data = jump
    j = TERMS.index("IE")
    ie = [a for a in h.alarms if a.term == "IE"]
    assert [a.file for a in ie] == [str(paths[9])]
    assert ie[0].previous == str(paths[8])
    assert ie[0].change_sigma == pytest.approx(_reference_z(data, 9, j), abs=1e-6)
    assert ie[0].change_sigma > 3.0
    # Every other change of every term, recomputed from the reference fits.
    z = np.array([[_reference_z(data, i, t) for t in range(len(TERMS))] for i in range(1, N_RUNS)])
    expected = {(str(paths[i + 1]), TERMS[t]) for i, t in zip(*np.nonzero(np.abs(z) > 3.0))}
    assert {(a.file, a.term) for a in h.alarms} == expected


def test_runs_are_ordered_by_their_file_dates_and_match_the_reference(jump):
    h, paths, data = jump
    assert [r.file for r in h.runs] == [str(p) for p in paths]
    for k, r in enumerate(h.runs):
        assert r.time == mjd(START + datetime.timedelta(days=60 * k))
        assert r.time_from in ("file", "readings")  # the reader may give every record the date as its time
        values, sigmas, rms = reference_fit(*data[k])
        got = r.terms()
        assert [t["name"] for t in got] == list(TERMS)
        np.testing.assert_allclose([t["value_arcsec"] for t in got], values, atol=1e-6)
        np.testing.assert_allclose([t["sigma_arcsec"] for t in got], sigmas, rtol=1e-6)
        assert r.sky_rms_arcsec == pytest.approx(rms, rel=1e-6)


def test_stationary_runs_raise_no_more_false_alarms_than_the_binomial_bound(tmp_path):
    """15 consecutive pairs x 8 terms at 3 sigma: each comparison alarms with probability
    at most erfc(3/sqrt(2)) = 0.27% (less: TPOINT's sigmas scale the Sky RMS of both
    residual components, larger than the standard errors). The count must stay below the
    smallest k with P(X >= k) < 1e-3 for X ~ Binomial(120, 0.0027)."""
    paths, data = _series(tmp_path, [TRUTH_ARCSEC] * N_RUNS, seed=2)
    h = history(_read(paths), _model())
    n = (N_RUNS - 1) * len(TERMS)
    p = math.erfc(3.0 / math.sqrt(2.0))
    assert p == pytest.approx(0.0026998, rel=1e-4)

    def tail(k):  # P(X >= k)
        return 1.0 - sum(math.comb(n, i) * p**i * (1 - p) ** (n - i) for i in range(k))

    bound = next(k for k in range(n + 1) if tail(k) < 1e-3)
    assert bound == 4
    assert len(h.alarms) < bound, h.table()
    # The changes themselves, against the reference: centred, and smaller than N(0, 1)
    # by about 1/sqrt(2) (TPOINT's sigma definition).
    z = change_sigmas(h.values_arcsec(), h.sigmas_arcsec())
    ref = np.array([[_reference_z(data, i, t) for t in range(len(TERMS))] for i in range(1, N_RUNS)])
    np.testing.assert_allclose(z, ref, atol=1e-6)
    assert 0.5 < np.std(z) < 0.95


def test_change_sigmas_closed_form():
    z = change_sigmas([[1.0, 0.0], [4.0, 0.0], [4.0, 1.0]], [[3.0, 1.0], [4.0, np.inf], [4.0, 1.0]])
    np.testing.assert_allclose(z[:, 0], [3.0 / 5.0, 0.0])
    assert np.isnan(z[0, 1]) and np.isnan(z[1, 1])


# --------------------------------------------------------------------------- JSON, table, time


def test_json_has_exactly_the_issue_keys(jump):
    h, paths, data = jump
    d = json.loads(h.to_json())
    assert set(d) == {"runs", "alarms"}
    for run in d["runs"]:
        assert set(run) == {"file", "time", "n_obs", "sky_rms_arcsec", "terms"}
        assert isinstance(run["time"], float) and run["n_obs"] == 40
        for term in run["terms"]:
            assert set(term) == {"name", "value_arcsec", "sigma_arcsec"}
    assert d["alarms"] and all(set(a) == {"file", "term", "change_sigma"} for a in d["alarms"])
    assert {"file": str(paths[9]), "term": "IE"} in [{k: a[k] for k in ("file", "term")} for a in d["alarms"]]


def test_table_lists_runs_in_order_and_the_alarms(jump):
    h, paths, _ = jump
    text = h.table()
    rows = [line for line in text.splitlines() if line.startswith("run")][1:]
    assert [r.split()[0] for r in rows] == [p.name for p in paths]
    assert f"{paths[9].name}  IE  +" in text
    assert START.isoformat() in text


def test_mjd_against_days_counted_from_the_epoch():
    assert mjd_of_date(1858, 11, 17) == 0.0
    assert mjd_of_date(2000, 1, 1, hours=12.0) == 51544.5  # J2000.0
    assert mjd_of_date(2021, 8, 21) == 59447.0
    assert date_of_mjd(59447.0) == "2021-08-21" and date_of_mjd(59447.5) == "2021-08-21 12:00"


def test_runs_without_a_time_keep_the_order_given_with_a_warning(tmp_path):
    observed, raw = simulate_run(TRUTH_ARCSEC, seed=5)
    write_tpoint(tmp_path / "b.dat", observed, raw, datetime.date(2022, 1, 1))
    write_tpoint(tmp_path / "a.dat", observed, raw, None)
    with pytest.warns(px.io.InputWarning, match="no time for .*a.dat"):
        h = history(_read([tmp_path / "b.dat", tmp_path / "a.dat"]), _model())
    assert [r.file.rsplit("/", 1)[-1] for r in h.runs] == ["b.dat", "a.dat"]
    assert h.runs[1].time is None and h.to_dict()["runs"][1]["time"] is None
    assert any("no time" in n for n in h.notes)


def test_bad_arguments_are_refused():
    obs = px.Observations(np.radians([[10.0, 40.0]]), np.array([[0.0, 0.8, 0.6]]), convention="S-E")
    with pytest.raises(ValueError, match="no runs"):
        history([], _model())
    with pytest.raises(ValueError, match="alarm"):
        history([obs], _model(), alarm=0)
    with pytest.raises(ValueError, match="encoder convention 'S-E'"):
        history([obs], _model())


def test_the_figure_draws_each_term_and_marks_the_alarms(jump):
    pytest.importorskip("matplotlib")
    h, _, _ = jump
    fig = h.figure()
    assert len(fig.axes) == len(TERMS)
    marked = sum(len(line.get_xdata()) for ax in fig.axes for line in ax.lines if line.get_gid() == "alarm")
    assert marked == len(h.alarms)
    ie = fig.axes[TERMS.index("IE")]
    x = [line for line in ie.lines if line.get_gid() == "alarm"][0].get_xdata()
    # decimal year of run 9's date, by hand: 2000 + (MJD - 51544.5) / 365.25
    assert x[0] == pytest.approx(2000 + (mjd(START + datetime.timedelta(days=540)) - 51544.5) / 365.25)


# --------------------------------------------------------------------------- a network against its last fit


def _site(name, values, sigmas, status="converged"):
    return {"site": name, "status": status,
            "terms": [{"name": n, "value_arcsec": v, "sigma_arcsec": s} for n, v, s in zip(("IA", "IE"), values, sigmas)]}  # fmt: skip


def test_network_moves_beyond_the_alarm_are_named(tmp_path):
    before = [_site("a", [10.0, 5.0], [1.0, 1.0]), _site("b", [0.0, 0.0], [0.3, 0.4]), _site("gone", [0, 0], [1, 1])]
    now = [_site("a", [10.5, 5.0], [1.0, 1.0]), _site("b", [0.0, 2.6], [0.3, 0.3]), _site("new", [0, 0], [1, 1])]
    moves, notes = compare_with_previous(now, before, alarm=3.0)
    assert [(m.site, m.term) for m in moves] == [("b", "IE")]
    assert moves[0].change_sigma == pytest.approx(2.6 / math.hypot(0.4, 0.3))  # 5.2
    assert any("gone" in n for n in notes) and any("new" in n for n in notes)
    path = tmp_path / "previous.json"
    path.write_text(json.dumps(before))
    assert read_previous(path) == before
    path.write_text("{not json")
    with pytest.raises(px.io.FileFormatError, match="previous.json:1: not JSON"):
        read_previous(path)


# --------------------------------------------------------------------------- the joint fit


def test_joint_fit_recovers_a_thermal_tf_and_a_drifting_ia(tmp_path):
    """8 runs at 0-20 deg C, 60 days apart: TF = 14" + 0.6"/deg C (T - 10), IA drifts
    0.05"/day; the joint fit (TF with temperature, IA with time, the rest shared) against
    NumPy least squares with the same columns, and the truth within 2 sigma."""
    from tpoint_numpy import ARCSEC, basis

    temps = [0.0, 12.0, 4.0, 20.0, 8.0, 16.0, 2.0, 18.0]
    runs, data = [], []
    for k, temp in enumerate(temps):
        date = START + datetime.timedelta(days=60 * k)
        coefs = dict(TRUTH_ARCSEC, TF=14.0 + 0.6 * (temp - 10.0), IA=120.0 + 0.05 * (mjd(date) - mjd(START)))
        observed, raw = simulate_run(coefs, seed=300 + k)
        write_tpoint(tmp_path / f"t{k}.dat", observed, raw, date, temperature=temp)
        runs.append(px.io.read_tpoint(tmp_path / f"t{k}.dat"))
        data.append((observed, raw, temp, mjd(date)))
    h = history(runs, _model())
    joint = h.joint_fit({"TF": "temperature", "IA": "time"}, reference={"temperature": 10.0, "time": mjd(START)})
    result = joint.result
    assert result.converged
    # Reference: the eight columns plus IA x (t - t0) and TF x (T - 10).
    X, y = [], []
    for observed, raw, temp, t in data:
        A, E = observed[:, 0], observed[:, 1]
        cols = [np.concatenate([basis(n, A, E)[0] * np.cos(E), basis(n, A, E)[1]]) for n in TERMS]
        cols.append(cols[TERMS.index("IA")] * (t - mjd(START)))
        cols.append(cols[TERMS.index("TF")] * (temp - 10.0))
        X.append(np.stack(cols, axis=-1))
        y.append(np.concatenate([((A - raw[:, 0] + np.pi) % (2 * np.pi) - np.pi) * np.cos(E), E - raw[:, 1]]))
    X, y = np.concatenate(X), np.concatenate(y)
    ref = np.linalg.lstsq(X, y, rcond=None)[0] / ARCSEC
    got = {n: result.value(n, "arcsec") for n in result.names}
    assert got["IA@time.t1"] == pytest.approx(ref[8], abs=1e-7)
    assert got["TF@temperature.slope"] == pytest.approx(ref[9], abs=1e-7)
    assert got["TF@temperature.value"] == pytest.approx(ref[TERMS.index("TF")], abs=1e-6)
    sigma = dict(zip(result.names, np.asarray(result.sigmas) / ARCSEC))
    assert abs(got["TF@temperature.slope"] - 0.6) < 2 * sigma["TF@temperature.slope"]
    assert abs(got["IA@time.t1"] - 0.05) < 2 * sigma["IA@time.t1"]
    assert joint.reference == {"temperature": 10.0, "time": mjd(START)}
    assert set(joint.to_dict()) >= {"files", "varying", "reference", "terms"}
    with pytest.raises(ValueError, match="no term 'XX'"):
        h.joint_fit({"XX": "temperature"})


# --------------------------------------------------------------------------- real runs of the MMT


def test_real_mmt_runs_over_four_years():
    """The MMT's 2021 run (examples/data) and its 2023 and 2025 runs (tests/data/mmt_runs,
    from pytelpoint's raw logs), given out of order: ordered by date; the 2021 values are
    TPOINT's own (its model file, within 0.01"), the others NumPy least squares's."""
    from conftest import MMT_DAT, MMT_MOD, REPO
    from tpoint_numpy import read_model_values, read_run

    folder = REPO / "tests" / "data" / "mmt_runs"
    paths = [folder / "mmt_20250326.dat", MMT_DAT, folder / "mmt_20230702.dat"]
    model = px.AltAz(px.terms.tpoint(" ".join(TERMS), form="linear"), azimuth="S-E", residual_form="tpoint")
    h = history([px.io.read_tpoint(p, azimuth="S-E") for p in paths], model)
    assert [r.file for r in h.runs] == [str(paths[1]), str(paths[2]), str(paths[0])]
    assert [date_of_mjd(r.time) for r in h.runs] == ["2021-08-21", "2023-07-02", "2025-03-26"]
    values, sigmas, _, _ = read_model_values(MMT_MOD)
    got = {t["name"]: t for t in h.runs[0].terms()}
    for name in TERMS:
        assert got[name]["value_arcsec"] == pytest.approx(values[name], abs=0.01)
        assert got[name]["sigma_arcsec"] == pytest.approx(sigmas[name], abs=0.01)
    for run, path in zip(h.runs[1:], (paths[2], paths[0])):
        observed, raw, _ = read_run(path)
        values, sigmas, _ = reference_fit(observed, raw)
        np.testing.assert_allclose([t["value_arcsec"] for t in run.terms()], values, atol=1e-6)
        np.testing.assert_allclose([t["sigma_arcsec"] for t in run.terms()], sigmas, rtol=1e-6)

"""The residual listing: ``pointax fit --json``'s per-observation entries and ``--list``
(TPOINT's SLIST).

Reference: the file read plainly and the rigorous residuals computed by NumPy at the
fitted coefficients (tests/tpoint_numpy.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import tpoint_numpy as ref
from conftest import MMT_DAT

from pointax.cli import main
from pointax.analysis.listing import LISTING_KEYS

EIGHT = "IA IE NPAE CA AN AW TF TX".split()


@pytest.fixture(autouse=True)
def no_compilation_cache(monkeypatch):
    monkeypatch.setenv("POINTAX_JAX_CACHE", "")


# TPOINT's linear terms: the NumPy reference computes their residuals.
MASKED_FIT = ["fit", str(MMT_DAT), "--azimuth", "S-E", "--mask", "39,79", "--form", "linear"]


@pytest.fixture(scope="module")
def masked_fit():
    """``pointax fit --mask 39,79 --form linear --json`` of the MMT run (sky residuals), as printed."""
    import contextlib
    import io

    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        code = main([*MASKED_FIT, "--json"])
    assert code == 0
    return json.loads(buffer.getvalue())


def test_entries_against_the_file_and_numpy_residuals(masked_fit):
    observed, raw, lines = ref.read_run(MMT_DAT)
    entries = masked_fit["observations"]
    assert len(entries) == 80 and all(tuple(e) == LISTING_KEYS for e in entries)
    assert [e["row"] for e in entries] == list(range(1, 81))
    assert [e["line"] for e in entries] == list(lines)
    got = np.array([[e["observed_az_deg"], e["observed_el_deg"], e["raw_az_deg"], e["raw_el_deg"]] for e in entries])
    np.testing.assert_allclose(got, np.degrees(np.concatenate([observed, raw], axis=1)), atol=1e-12)
    # Residuals of the fitted model at every row (masked ones too), computed by NumPy.
    coefs = np.array([t["value_arcsec"] for t in masked_fit["terms"]]) * ref.ARCSEC
    r = ref.sky_residuals(EIGHT, coefs, observed, raw) / ref.ARCSEC
    dx, de, ds = (np.array([e[k] for e in entries]) for k in ("dx_arcsec", "de_arcsec", "ds_arcsec"))
    np.testing.assert_allclose(dx, r[:, 0], atol=1e-6)
    np.testing.assert_allclose(de, r[:, 1], atol=1e-6)
    np.testing.assert_allclose(ds, np.hypot(r[:, 0], r[:, 1]), atol=1e-6)
    masked = np.zeros(80, bool)
    masked[[38, 78]] = True
    assert [e["masked"] for e in entries] == list(masked) and [e["used"] for e in entries] == list(~masked)
    assert not any(e["outlier"] for e in entries) and masked_fit["masked"] == [38, 78]
    # Sky RMS over the used rows, from the entries.
    assert abs(np.sqrt(np.mean(ds[~masked] ** 2)) - masked_fit["sky_rms_arcsec"]) < 1e-6


def test_list_prints_an_slist_table(masked_fit, capsys):
    assert main([*MASKED_FIT, "--list"]) == 0
    out = capsys.readouterr().out
    report, table = out.split("Residuals, observed minus model", 1)
    assert "Sky RMS" in report and "(azimuth S-E)" in table.splitlines()[0]
    rows = [line.split() for line in table.splitlines() if line[:6].strip().isdigit()]
    assert len(rows) == 80
    for row, e in zip(rows, masked_fit["observations"]):
        assert int(row[0]) == e["row"] and int(row[1]) == e["line"]
        assert float(row[2]) == pytest.approx(e["observed_az_deg"], abs=6e-5)
        assert float(row[5]) == pytest.approx(e["raw_el_deg"], abs=6e-5)
        assert float(row[6]) == pytest.approx(e["dx_arcsec"], abs=0.006)
        assert float(row[8]) == pytest.approx(e["ds_arcsec"], abs=0.006)
        assert (row[-1] == "M") == e["masked"]
    assert "78 of 80 observations used; 2 masked (M)" in table


def test_plot_option_writes_the_figure(masked_fit, tmp_path, capsys):
    path = tmp_path / "fit.svg"
    assert main(["fit", str(MMT_DAT), "--azimuth", "S-E", "--mask", "39,79", "--plot", str(path)]) == 0
    assert str(path) in capsys.readouterr().err
    head = path.read_bytes()[:3000]
    assert b"<svg" in head
    assert main(["fit", str(MMT_DAT), "--azimuth", "S-E", "--plot", str(tmp_path / "fit.xyz")]) == 2
    assert "fit.xyz" in capsys.readouterr().err and not (tmp_path / "fit.xyz").exists()


def test_entries_reuse_the_fit_and_compile_at_most_once():
    """The listing takes the fit's own residuals and evaluates only the masked
    observations', in one compiled call: counted, not timed (op by op, ``--json`` once
    compiled some 70 small programs, 4 s). Reference: the residuals evaluated afresh."""
    import jax

    import pointax as px
    from pointax.analysis.listing import observation_entries
    from pointax.fitting.masking import all_residuals

    run = px.io.read_tpoint(MMT_DAT, azimuth="S-E")
    model = px.AltAz(px.terms.tpoint(" ".join(EIGHT)), azimuth=run.azimuth)
    compiled = []
    jax.monitoring.register_event_duration_secs_listener(
        lambda event, duration, **kw: compiled.append(event) if event == "/jax/core/compile/backend_compile_duration" else None
    )
    for rows in ([], [38, 78], [3, 5, 7]):
        weights = np.ones(len(run))
        weights[rows] = 0.0
        result = px.fit(model, run, weights=weights)
        masked = weights == 0
        before = len(compiled)
        entries = observation_entries(run, result, masked)
        if rows != [38, 78]:  # the first masked listing may compile the evaluation once
            assert len(compiled) == before, rows
        fresh = all_residuals(result.model, run.observations) / px.units.ARCSEC
        got = np.array([[e["dx_arcsec"], e["de_arcsec"]] for e in entries])
        np.testing.assert_allclose(got, fresh, rtol=0, atol=1e-9)
        assert [e["masked"] for e in entries] == list(masked)


@pytest.mark.parametrize("form", ["sky", "tpoint"])
def test_plot_data_equal_the_listing_exactly(form):
    """The plots, the HTML report and the listing show the same residual at every row,
    masked ones included, in the fit's own residual form: all take them from
    :func:`pointax.fitting.masking.observation_residuals`."""
    import pointax as px
    from pointax.analysis.listing import format_listing, observation_entries
    from pointax.plots.data import residual_data

    run = px.io.read_tpoint(MMT_DAT, azimuth="S-E")
    masked = np.zeros(len(run), bool)
    masked[[38, 78]] = True
    weight = np.where(masked, 0.0, 1.0)
    obs = px.Observations(run.observations.encoder, run.observations.target, weight, run.observations.convention)
    model = px.AltAz(px.terms.tpoint(" ".join(EIGHT)), azimuth=run.azimuth, residual_form=form)
    result = px.fit(model, obs)
    entries = observation_entries(run, result, masked)
    data = residual_data(result, obs)
    listed = np.array([[e["dx_arcsec"], e["de_arcsec"]] for e in entries])
    np.testing.assert_array_equal(data.residuals, listed)
    np.testing.assert_array_equal(data.distance, [e["ds_arcsec"] for e in entries])
    np.testing.assert_array_equal(data.masked, masked)
    np.testing.assert_array_equal(data.used, [e["used"] for e in entries])
    assert np.all(np.hypot(*listed[masked].T) > 0.01)  # the masked rows are evaluated, not the fit's 0
    # The Sky RMS the listing prints is the fit's, as the plots' circle and title.
    (rms,) = [line for line in format_listing(run, result, masked).splitlines() if line.startswith("Sky RMS")]
    assert rms.endswith(f"{float(result.sky_rms) / px.units.ARCSEC:.4f}")
    assert data.sky_rms == float(result.sky_rms) / px.units.ARCSEC

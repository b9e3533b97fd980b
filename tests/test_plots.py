"""pointax.plots: what each figure draws equals the residuals (read back from the
figure's artists, not from pixels), against numpy computations from the file's own
angles; masked and outlier observations get their own artists; files written are valid.
"""

from __future__ import annotations

import math
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

pytest.importorskip("matplotlib", reason="matplotlib (pointax[plot]) is not installed")

import pointax as px  # noqa: E402
from pointax.plots import fit_figure, save_figure, tpoint_graph  # noqa: E402

from conftest import MMT_DAT  # noqa: E402

ARCSEC = math.pi / (180 * 3600)
MASKED = (3, 7)  # 0-based rows given weight 0
FLAGGED = (10,)  # 0-based rows passed as outliers


@pytest.fixture(scope="module")
def mmt():
    """The bundled MMT run (azimuth S-E), rows 3 and 7 masked, fitted with the eight
    basic terms."""
    run = px.io.read_tpoint(MMT_DAT, azimuth="S-E")
    weight = np.ones(len(run))
    weight[list(MASKED)] = 0.0
    obs = px.Observations(run.observations.encoder, run.observations.target, weight, run.observations.convention)
    model = px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"), azimuth="S-E")
    result = px.fit(model, obs)
    return run, obs, result


def artists(ax, gid):
    """Lines of ``ax`` with ``gid``."""
    return [line for line in ax.get_lines() if line.get_gid() == gid]


def groups_expected(n):
    masked = np.zeros(n, bool)
    masked[list(MASKED)] = True
    outlier = np.zeros(n, bool)
    outlier[list(FLAGGED)] = True
    return {"used": ~masked & ~outlier, "outlier": outlier, "masked": masked}


def reference_masked_residuals(run, result):
    """Residuals (arcsec) of the masked rows from the fitted model, in numpy: the
    observed direction's offset from where the model points, in the tangent plane at
    the observed direction, in the file's (S-E) frame."""
    mirror = np.diag([1.0, -1.0, 1.0])  # ENU -> S-E frame (its own inverse)
    out = []
    where = np.asarray(result.model(np.asarray(run.encoder[list(MASKED)])))  # (k, 3) ENU
    for k, i in enumerate(MASKED):
        predicted = where[k] @ mirror
        target = np.asarray(run.observations.target[i]) @ mirror
        az, el = math.atan2(target[0], target[1]), math.asin(target[2])
        e_az = np.array([math.cos(az), -math.sin(az), 0.0])
        e_el = np.array([-math.sin(el) * math.sin(az), -math.sin(el) * math.cos(az), math.cos(el)])
        depth = predicted @ target
        out.append([-(predicted @ e_az) / depth, -(predicted @ e_el) / depth])
    return np.array(out) / ARCSEC


def test_importing_pointax_plots_imports_no_matplotlib():
    code = "import sys, pointax.plots\nprint('matplotlib' in sys.modules)"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "False"


def test_a_missing_matplotlib_is_a_clear_error_before_any_fit():
    code = (
        "import sys\n"
        "sys.modules['matplotlib'] = None  # as if not installed\n"
        "from pointax.cli import main\n"
        f"status = main(['plot', {str(MMT_DAT)!r}, '-o', 'x.png'])\n"
        "print(status, 'jax' in sys.modules)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.stdout.split() == ["2", "False"], proc.stderr
    assert "pip install 'pointax[plot]'" in proc.stderr


def test_residual_panels_draw_the_residuals_against_the_readings(mmt):
    run, obs, result = mmt
    fig = fit_figure(result, obs, "residuals", outliers=list(FLAGGED))
    res = np.asarray(result.residuals) / ARCSEC  # (n, 2) arcsec; masked rows 0 in the fit
    res[list(MASKED)] = reference_masked_residuals(run, result)
    readings = np.degrees(run.encoder)  # raw azimuth (S-E) and elevation as the file has them
    readings[:, 0] = np.mod(readings[:, 0], 360.0)
    groups = groups_expected(len(run))
    panels = fig.axes[:4]  # component i against angle j, row-major
    for k, ax in enumerate(panels):
        i, j = divmod(k, 2)
        for gid, mask in groups.items():
            (line,) = artists(ax, gid)
            x, y = line.get_data()
            np.testing.assert_allclose(x, readings[mask, j], atol=1e-9)
            np.testing.assert_allclose(y, res[mask, i], atol=2e-6)
    assert "cross-elevation" in panels[0].get_ylabel() and "arcsec" in panels[0].get_ylabel()
    assert "azimuth" in panels[0].get_xlabel() and "S-E" in panels[0].get_xlabel()
    # The right panel: elevation residual against cross-elevation residual.
    scatter = fig.axes[4]
    for gid, mask in groups.items():
        (line,) = artists(scatter, gid)
        np.testing.assert_allclose(np.column_stack(line.get_data()), res[mask], atol=2e-6)
    # The masked rows are genuinely away from zero (not the fit's placeholder 0).
    assert np.all(np.hypot(*res[list(MASKED)].T) > 0.01)
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert any(t.startswith("masked") for t in labels) and any(t.startswith("outlier") for t in labels)


def test_sky_map_vectors_are_the_residuals_on_the_sky(mmt):
    run, obs, result = mmt
    fig = fit_figure(result, obs, "sky", outliers=list(FLAGGED))
    ax = fig.axes[0]
    res = np.asarray(result.residuals) / ARCSEC
    res[list(MASKED)] = reference_masked_residuals(run, result)
    # Independent: the file's observed azimuth counts from South through East, so the
    # North-East azimuth is 180 deg - A and a residual along increasing S-E azimuth is
    # one along decreasing N-E azimuth.
    az = np.radians(180.0) - run.observed[:, 0]
    zd = 90.0 - np.degrees(run.observed[:, 1])
    d_az, d_el = -res[:, 0], res[:, 1]
    x, y = zd * np.sin(az), zd * np.cos(az)  # East right, North up
    u = d_az * np.cos(az) - d_el * np.sin(az)  # increasing elevation points to the centre
    v = -d_az * np.sin(az) - d_el * np.cos(az)
    quivers = {c.get_gid(): c for c in ax.collections if c.get_gid()}
    for gid, mask in groups_expected(len(run)).items():
        q = quivers[f"{gid}-vectors"]
        np.testing.assert_allclose(q.U, u[mask], atol=2e-6)
        np.testing.assert_allclose(q.V, v[mask], atol=2e-6)
        np.testing.assert_allclose(q.get_offsets(), np.column_stack([x, y])[mask], atol=1e-9)
        (line,) = artists(ax, gid)
        np.testing.assert_allclose(np.column_stack(line.get_data()), np.column_stack([x, y])[mask], atol=1e-9)
    texts = {t.get_text() for t in ax.texts}
    assert {"N", "E", "S", "W"} <= texts
    # A star above where the model pointed (dE > 0) gets an arrow towards the zenith.
    i = int(np.argmax(d_el * groups_expected(len(run))["used"]))
    assert u[i] * x[i] + v[i] * y[i] < 0


def test_histogram_counts_are_numpys(mmt):
    run, obs, result = mmt
    fig = fit_figure(result, obs, "histogram", outliers=list(FLAGGED))
    res = np.asarray(result.residuals) / ARCSEC
    res[list(MASKED)] = reference_masked_residuals(run, result)
    distance = np.hypot(res[:, 0], res[:, 1])
    ax = fig.axes[2]
    for gid, mask in groups_expected(len(run)).items():
        patches = [p for p in ax.patches if p.get_gid() == gid]
        edges = np.array([p.get_x() for p in patches] + [patches[-1].get_x() + patches[-1].get_width()])
        counts, _ = np.histogram(distance[mask], bins=edges)
        np.testing.assert_array_equal([p.get_height() for p in patches], counts)
        assert sum(counts) == mask.sum()


def test_tpoint_commands_by_name(mmt):
    run, obs, result = mmt
    res = np.asarray(result.residuals) / ARCSEC
    used = np.ones(len(run), bool)
    used[list(MASKED)] = False
    az = np.mod(np.degrees(run.observed[:, 0]), 360.0)  # observed azimuth as the file counts it
    zd = 90.0 - np.degrees(run.observed[:, 1])
    from pointax.plots.tpoint_panels import parse_command

    assert parse_command("G S A") == parse_command("gsa") == parse_command("G  s a") == ("G", "S", "A")
    assert parse_command("GAM Z") == parse_command("G AM Z") == parse_command("gamz") == ("G", "AM", "Z")
    assert parse_command("g hist") == parse_command("GDIST") == ("GHIST",)
    (line,) = artists(tpoint_graph("gsa", result, obs).axes[0], "used")
    np.testing.assert_allclose(line.get_data()[0], az[used], atol=1e-9)
    np.testing.assert_allclose(line.get_data()[1], res[used, 0], atol=2e-6)
    (line,) = artists(tpoint_graph("G Z Z", result, obs).axes[0], "used")
    np.testing.assert_allclose(line.get_data()[0], zd[used], atol=1e-9)
    np.testing.assert_allclose(line.get_data()[1], -res[used, 1], atol=2e-6)  # dZ = -dE
    (line,) = artists(tpoint_graph("G AM Z", result, obs).axes[0], "used")
    np.testing.assert_allclose(line.get_data()[1], res[used, 0] / np.cos(run.observed[used, 1]), atol=2e-6)
    (line,) = artists(tpoint_graph("G V A", result, obs).axes[0], "used")
    np.testing.assert_allclose(line.get_data()[1], np.hypot(res[used, 0], res[used, 1]), atol=2e-6)
    a9 = tpoint_graph("A9", result, obs)
    titles = [ax.get_title() for ax in a9.axes if ax.get_title()]
    for panel in ("G S A", "G Z A", "G V A", "G S Z", "G Z Z", "G AM Z", "GSCAT", "GSMAP", "GHIST"):
        assert any(t.startswith(panel) for t in titles), (panel, titles)
    with pytest.raises(ValueError, match="valid: .*GSMAP"):
        tpoint_graph("G Q A", result, obs)
    with pytest.raises(ValueError, match="equatorial"):
        tpoint_graph("G X H", result, obs)


def test_unknown_kind_names_the_valid_ones(mmt):
    _, obs, result = mmt
    with pytest.raises(ValueError, match="summary, residuals, sky"):
        fit_figure(result, obs, "pie")


def test_files_written_are_valid(mmt, tmp_path):
    from PIL import Image

    _, obs, result = mmt
    fig = fit_figure(result, obs, "scatter")
    png = tmp_path / "fit.png"
    text = save_figure(fig, png, dpi=50)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with Image.open(png) as image:
        assert image.size == tuple(int(round(s * 50)) for s in fig.get_size_inches())
    assert text.startswith("PNG image") and str(png) in text
    svg = tmp_path / "fit.svg"
    save_figure(fig, svg)
    assert ET.parse(svg).getroot().tag.endswith("svg")
    pdf = tmp_path / "fit.PDF"
    save_figure(fig, pdf)
    assert pdf.read_bytes()[:5] == b"%PDF-"
    ps = tmp_path / "fit.ps"
    assert "PostScript" in save_figure(fig, ps)
    assert ps.read_bytes()[:4] == b"%!PS"
    with pytest.raises(ValueError, match=r"\.png, \.svg, \.pdf"):
        save_figure(fig, tmp_path / "fit.jpg")
    assert not (tmp_path / "fit.jpg").exists()


def test_heliostat_figure_draws_each_series():
    from pointax.analysis.heliostat import HeliostatCalibration
    from pointax.plots import heliostat_figure

    rng = np.random.default_rng(1)
    before, after, loo = (rng.uniform(1, 20, 12) * 1e-3 for _ in range(3))
    outliers = np.zeros(12, bool)
    outliers[[2, 9]] = True
    cal = HeliostatCalibration(tuple(f"s{i}" for i in range(12)), None, before, after, loo, outliers, np.ones(12, bool))
    fig = heliostat_figure(cal)
    ax, bars = fig.axes
    x = np.arange(1, 13)
    for name, err in (("before", before), ("after", after), ("loo", loo)):
        for kind, mask in (("used", ~outliers), ("outlier", outliers)):
            (line,) = artists(ax, f"{name}-{kind}")
            np.testing.assert_allclose(np.column_stack(line.get_data()), np.column_stack([x, err * 1e3])[mask])
        (bar,) = [p for p in bars.patches if p.get_gid() == f"rms-{name}"]
        assert bar.get_height() == pytest.approx(np.sqrt(np.mean((err[~outliers] * 1e3) ** 2)))


def test_network_figure_shows_each_sites_rms_and_status():
    from pointax.analysis.network import NetworkResult
    from pointax.plots import network_figure

    sites = (
        {"site": "a", "format": "tpoint", "status": "converged", "reason": "", "sky_rms_arcsec": 0.93},
        {"site": "b", "format": "paint", "status": "degenerate", "reason": "t1n", "error_mrad": {"rms": {"after": 1.5}}},
        {"site": "c", "format": "sun", "status": "failed", "reason": "bad file", "converged": False},
    )
    fig = network_figure(NetworkResult("m.csv", sites))
    ax = fig.axes[0]
    heights = {p.get_gid(): (p.get_x() + p.get_width() / 2, p.get_height()) for p in ax.patches if p.get_gid()}
    assert heights["converged"] == pytest.approx((0.0, 0.93))
    assert heights["degenerate"] == pytest.approx((1.0, 1.5e-3 / ARCSEC))  # mrad -> arcsec
    assert heights["failed"] == pytest.approx((2.0, 0.0))
    assert artists(ax, "failed-no-rms")


def test_families_figure_shows_rms_in_and_out_of_sample():
    from pointax.analysis.comparison import Comparison, FamilyStats
    from pointax.fitting.statistics import AxisRMS
    from pointax.plots import families_figure

    def row(label, total_in, total_out, m, bic):
        return FamilyStats(label, None, object(), m, AxisRMS(0, 0, total_in * ARCSEC, 60), 0.0,
                           AxisRMS(0, 0, total_out * ARCSEC, 20), 0.0, 0.0, bic, {}, (), True)

    rows = (row("basic", 6.3, 7.1, 8, 120.0), row("harmonic", 6.5, 8.0, 26, 150.0))
    comparison = Comparison(rows, "holdout", "60 + 20 stars", 60, 20, "sky", ("az", "el"))
    fig = families_figure(comparison)
    ax, ax2 = fig.axes
    inside = sorted((p.get_x(), p.get_height()) for p in ax.patches if p.get_gid() == "in-sample")
    outside = sorted((p.get_x(), p.get_height()) for p in ax.patches if p.get_gid() == "out-of-sample")
    assert [h for _, h in inside] == pytest.approx([6.3, 6.5])
    assert [h for _, h in outside] == pytest.approx([7.1, 8.0])
    (bic,) = artists(ax2, "bic")
    np.testing.assert_allclose(np.column_stack(bic.get_data()), [[8, 0.0], [26, 30.0]])


def test_pointax_plot_writes_one_file_per_figure(tmp_path, capsys):
    from pointax.cli import main

    out = tmp_path / "mmt.svg"
    status = main(["plot", str(MMT_DAT), "--azimuth", "S-E", "--kind", "sky", "--tpoint", "G Z Z", "-o", str(out)])
    assert status == 0
    printed = capsys.readouterr().out.splitlines()
    written = [tmp_path / "mmt-sky.svg", tmp_path / "mmt-GZZ.svg"]
    for path, line in zip(written, printed):
        assert ET.parse(path).getroot().tag.endswith("svg")
        assert line.startswith("SVG drawing") and line.endswith(str(path))
    pdf = tmp_path / "both.pdf"
    assert main(["plot", str(MMT_DAT), "--azimuth", "S-E", "--kind", "sky", "--kind", "histogram", "-o", str(pdf)]) == 0
    assert pdf.read_bytes()[:5] == b"%PDF-" and "2 pages" in capsys.readouterr().out
    assert main(["plot", str(MMT_DAT), "--tpoint", "G Q A", "-o", str(out)]) == 2
    assert "unknown TPOINT graphics command 'G Q A'" in capsys.readouterr().err


def test_equatorial_fit_is_drawn_in_declination_axes_and_on_the_sky():
    """An equatorial mount's residuals are (dH cos dec, d dec): the panels say so, G D H
    draws d dec against the hour angle, and the sky map's arrows are the offset from
    where the model points to the star, resolved on the horizon (numpy, from the
    directions themselves)."""
    from pointax.terms.model_factories import Equatorial

    lat = np.radians(31.7)
    rng = np.random.default_rng(3)
    h, dec = rng.uniform(-1.2, 1.2, 200), rng.uniform(-0.4, 1.3, 200)
    up = np.sin(lat) * np.sin(dec) + np.cos(lat) * np.cos(dec) * np.cos(h)
    keep = up > 0.35
    enc = np.stack([h[keep], dec[keep]], 1)[:30]
    truth = Equatorial(px.terms.tpoint("IA IE CA", form="rigorous", values={"IA": 60 * ARCSEC, "IE": -40 * ARCSEC,
                                                                              "CA": 25 * ARCSEC}), latitude=lat)
    obs = px.simulate(truth, enc, noise=2.0 * ARCSEC, seed=4)
    result = px.fit(Equatorial(px.terms.tpoint("IA IE", form="rigorous"), latitude=lat), obs)
    res = np.asarray(result.residuals) / ARCSEC

    fig = fit_figure(result, obs, "residuals")
    assert "cross-declination" in fig.axes[0].get_ylabel() and "declination" in fig.axes[2].get_ylabel()
    assert "hour angle" in fig.axes[0].get_xlabel()
    (line,) = artists(tpoint_graph("G D H", result, obs).axes[0], "used")
    target = np.asarray(obs.target)
    hour_angle = np.degrees(np.arctan2(-target[:, 0], np.cos(lat) * target[:, 2] - np.sin(lat) * target[:, 1]))
    np.testing.assert_allclose(line.get_data()[0], hour_angle, atol=1e-9)
    np.testing.assert_allclose(line.get_data()[1], res[:, 1], atol=1e-9)

    # The sky map: (star - model pointing) resolved along increasing azimuth and elevation.
    predicted = np.asarray(result.model(np.asarray(obs.encoder)))
    az, el = np.arctan2(target[:, 0], target[:, 1]), np.arcsin(target[:, 2])
    e_az = np.stack([np.cos(az), -np.sin(az), 0 * az], 1)
    e_el = np.stack([-np.sin(el) * np.sin(az), -np.sin(el) * np.cos(az), np.cos(el)], 1)
    offset = target - predicted
    d_az, d_el = np.sum(offset * e_az, 1) / ARCSEC, np.sum(offset * e_el, 1) / ARCSEC
    (q,) = [c for c in fit_figure(result, obs, "sky").axes[0].collections if c.get_gid() == "used-vectors"]
    np.testing.assert_allclose(q.U, d_az * np.cos(az) - d_el * np.sin(az), atol=1e-3)
    np.testing.assert_allclose(q.V, -d_az * np.sin(az) - d_el * np.cos(az), atol=1e-3)


def test_drawn_residuals_and_rms_circle_are_the_listings(mmt):
    """What the scatter panel draws is the listing's residuals to the last bit, and its
    circle is the fit's Sky RMS (the one the report and the listing print)."""
    from pointax.analysis.listing import observation_entries

    run, obs, result = mmt
    masked = np.zeros(len(run), bool)
    masked[list(MASKED)] = True
    listed = np.array([[e["dx_arcsec"], e["de_arcsec"]] for e in observation_entries(run, result, masked)])
    fig = fit_figure(result, obs, "scatter")
    ax = fig.axes[0]
    for gid, mask in (("used", ~masked), ("masked", masked)):
        (line,) = artists(ax, gid)
        np.testing.assert_array_equal(np.column_stack(line.get_data()), listed[mask])
    (circle,) = artists(ax, "rms-circle")
    radius = np.hypot(*circle.get_data())
    np.testing.assert_allclose(radius, float(result.sky_rms) / px.units.ARCSEC, rtol=1e-12)

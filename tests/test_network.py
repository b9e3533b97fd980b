"""Networks of sites from a manifest: manifest errors, bad sites isolated, per-site JSON
as `pointax fit --json`, progress bar, summary, exit status.

References: each simulated site's truth (written in its file by
examples/make_network_data.py); TPOINT's own model of the bundled MMT run; the JSON of
`pointax fit --json` for the same file; PAINT's heliostat calibrated alone.
"""

from __future__ import annotations

import argparse
import io
import json
import re

import numpy as np
import pytest
from conftest import EXAMPLES, MMT_DAT, MMT_MOD

import pointax as px
from pointax.cli import main as pointax_main
from pointax.cli.fit_network import add_fit_network_parser, run_fit_network
from pointax.analysis.network import (
    ManifestError,
    fit_network,
    read_manifest,
)

NETWORK = EXAMPLES / "data" / "network"
MANIFEST = NETWORK / "manifest.csv"
CLEAN = ["ts-01", "ts-02", "ts-03", "ts-04"]


@pytest.fixture(autouse=True)
def no_compilation_cache(monkeypatch):
    """Keep `pointax fit` from writing JAX's compilation cache into the home folder."""
    monkeypatch.setenv("POINTAX_JAX_CACHE", "")


@pytest.fixture(scope="module")
def example():
    return fit_network(MANIFEST)


def _run(argv: list[str]) -> tuple[int, str, str]:
    parser = argparse.ArgumentParser(prog="pointax")
    add_fit_network_parser(parser.add_subparsers(dest="command"))
    out, err = io.StringIO(), io.StringIO()
    code = run_fit_network(parser.parse_args(["fit-network", *argv]), stdout=out, stderr=err)
    return code, out.getvalue(), err.getvalue()


def _truth(site: str) -> dict[str, float]:
    """The simulated truth (degrees) from the comment line of the site's file."""
    text = (NETWORK / f"{site}.txt").read_text()
    line = re.search(r"truth \(deg\): (.*)", text).group(1).split()
    return {k: float(v) for k, v in zip(line[::2], line[1::2])}


# ------------------------------------------------------------- fitting the example network


def test_statuses_and_reasons(example):
    by_site = {d["site"]: d for d in example.sites}
    assert [d["site"] for d in example.sites] == CLEAN + ["ts-05", "ts-06", "mmt"]
    assert {s: by_site[s]["status"] for s in by_site} == {
        **dict.fromkeys(CLEAN, "converged"), "ts-05": "degenerate", "ts-06": "failed", "mmt": "converged"
    }
    # The stuck azimuth axis: tilts and pitch zero cannot be told apart.
    assert {"mu0", "nu0", "omega0"} <= set(by_site["ts-05"]["reason"].split(": ", 1)[1].split(", "))
    # The unreadable file: the reader's message names file, line and column.
    assert re.search(r"ts-06\.txt:13: column 3 \(sun_az_deg\): '.*;.*' is not a number", by_site["ts-06"]["reason"])
    assert by_site["ts-06"]["converged"] is False
    assert example.counts == {"converged": 5, "degenerate": 1, "failed": 1}
    assert not example.all_converged


def test_every_site_gets_its_own_answer(example):
    """Values land on the right site (the sites' encoder zeros differ by degrees): each
    within 5 sigma (+ the truth's 4-decimal rounding) of the site's own truth."""
    by_site = {d["site"]: d for d in example.sites}
    for site in CLEAN:
        truth = _truth(site)
        for term in by_site[site]["terms"]:
            assert term["unit"] == "deg"
            assert abs(term["value"] - truth[term["name"]]) < 5 * term["sigma"] + 1e-4, (site, term)
    # The TPOINT site reproduces TPOINT's own model of this run.
    tpoint = px.io.read_model(MMT_MOD)
    mmt = by_site["mmt"]
    assert [t["name"] for t in mmt["terms"]] == tpoint.names
    for got, want in zip(mmt["terms"], tpoint.terms):
        assert got["value_arcsec"] == pytest.approx(want.value, abs=0.01)
        assert got["sigma_arcsec"] == pytest.approx(want.sigma, abs=0.01)


def test_json_per_site_is_pointax_fit_json_plus_site_and_status(capsys):
    code, out, err = _run([str(MANIFEST), "--json", "--quiet"])
    assert code == 1 and err == ""
    sites = json.loads(out)
    assert [s["site"] for s in sites] == CLEAN + ["ts-05", "ts-06", "mmt"]
    assert pointax_main(["fit", str(MMT_DAT), "--azimuth", "S-E", "--json"]) == 0
    solo = json.loads(capsys.readouterr().out)
    mmt = sites[-1]
    assert set(mmt) == set(solo) | {"site", "format", "status", "reason"}
    assert mmt["status"] == "converged" and mmt["reason"] == "" and mmt["format"] == "tpoint"
    assert mmt["caption"] == solo["caption"] and mmt["form"] == solo["form"] and mmt["n_obs"] == solo["n_obs"]
    for a, b in zip(mmt["terms"], solo["terms"]):
        assert a["name"] == b["name"]
        assert a["value_arcsec"] == pytest.approx(b["value_arcsec"], abs=1e-6)  # batch = solo fit
        assert a["sigma_arcsec"] == pytest.approx(b["sigma_arcsec"], rel=1e-6)
    np.testing.assert_allclose(np.array(mmt["correlation"]), np.array(solo["correlation"]), atol=1e-8)
    sun_keys = set(solo) - {"file", "caption", "form", "residuals", "start_model"}  # what FitResult.to_dict gives
    for s in sites[:5]:
        assert set(s) == sun_keys | {"site", "format", "file", "status", "reason"}
    assert set(sites[5]) == {"site", "format", "file", "status", "reason", "converged"}


def test_progress_bar_and_summary_on_stderr_unless_quiet():
    code, out, err = _run([str(MANIFEST), "--json"])
    assert code == 1
    json.loads(out)  # standard output stays pure JSON
    assert "fitting" not in err  # no progress bar where standard error is not a terminal
    assert "7 sites: 5 converged, 1 degenerate, 1 failed" in err
    code, out, err = _run([str(MANIFEST), "--quiet"])
    assert code == 1 and err == ""
    lines = out.splitlines()
    assert lines[0].split()[:4] == ["site", "format", "status", "n_obs"]
    assert re.match(r"ts-01\s+sun\s+converged\s+60\s+0\.0\d+ deg\s+\d+\s+mu0 ", lines[1])
    summary = out[out.index("7 sites:") :].splitlines()
    assert summary[0].startswith("7 sites: 5 converged, 1 degenerate, 1 failed")
    assert re.match(r"\s+degenerate\s+ts-05\s+cannot be told apart: mu0, nu0, omega0", summary[1])
    assert re.match(r"\s+failed\s+ts-06\s+\S*ts-06\.txt:13: column 3", summary[2])
    assert len(summary) == 3


def test_exit_status_zero_when_all_converge_and_two_for_a_bad_manifest(tmp_path):
    good = tmp_path / "good.csv"
    good.write_text(f"site,path,format,azimuth\nmmt,{MMT_DAT},tpoint,S-E\n")
    code, out, _ = _run([str(good), "--quiet"])
    assert code == 0 and "1 sites: 1 converged, 0 degenerate, 0 failed" in out
    bad = tmp_path / "bad.csv"
    bad.write_text("site,path,format\nmmt,nowhere.dat,tpoint\n")
    code, out, err = _run([str(bad)])
    assert code == 2 and out == ""
    assert re.search(r"bad\.csv:2: field 'path': no such file: .*nowhere\.dat", err)
    code, _, err = _run([str(tmp_path / "absent.csv")])
    assert code == 2 and "absent.csv" in err


def test_progress_callback_counts_sites(example):
    seen = []
    again = fit_network(MANIFEST, progress=lambda done, total: seen.append((done, total)))
    # The five sun sites in one chunk and the TPOINT site, fitted side by side (either
    # may finish first); ts-06 is not fitted.
    assert seen in ([(5, 6), (6, 6)], [(1, 6), (6, 6)])
    assert [d["status"] for d in again.sites] == [d["status"] for d in example.sites]


def test_small_groups_go_to_the_full_loop_side_by_side(example, monkeypatch):
    """Groups of fewer than SMALL_GROUP sites skip the fast pass (steps=0), and the
    groups run in a pool of threads; the answers are those of the example's run
    (the same compiled programs: equal bit for bit)."""
    import threading

    from pointax.analysis import network

    calls = []
    real = network.fit_batch

    def spy(model, batch, **kwargs):
        calls.append((batch.encoder.shape[0], kwargs.get("steps"), threading.get_ident()))
        return real(model, batch, **kwargs)

    pools = []

    class Pool(network.ThreadPoolExecutor):
        def __init__(self, max_workers=None, **kwargs):
            pools.append(max_workers)
            super().__init__(max_workers=max_workers, **kwargs)

    monkeypatch.setattr(network, "fit_batch", spy)
    monkeypatch.setattr(network, "ThreadPoolExecutor", Pool)
    monkeypatch.setattr(network.os, "cpu_count", lambda: 2)
    again = fit_network(MANIFEST)
    assert sorted((n, steps) for n, steps, _ in calls) == [(1, 0), (5, 0)]
    # A pool of two threads, and no group fitted in the calling thread. (Which of the two
    # threads fits which group is the pool's: one that finishes its group first may take
    # the other too, as it did once on a busy CI machine.)
    assert pools == [2] and threading.get_ident() not in {t for *_, t in calls}
    for a, b in zip(again.sites, example.sites):
        assert a.keys() == b.keys() and a["status"] == b["status"]
        if "values" in a:
            assert a["values"] == b["values"]


def test_the_stored_full_loop_compiles_with_the_fast_options(monkeypatch, tmp_path):
    """The batch's full loop read from / written to the stored programs compiles with
    XLA's quicker options, as the in-memory one does (twice the compile time without)."""
    from pointax.fitting import batch, programs

    class Stop(Exception):
        pass

    seen = {}

    def call(name, fn, args, static, structure, fast_compile=False):
        seen[name] = fast_compile
        raise Stop

    monkeypatch.setattr(programs, "directory", lambda: tmp_path)
    monkeypatch.setattr(programs, "call", call)
    one = px.Observations(np.full((4, 2), 0.1), np.tile([0.0, 0.6, 0.8], (4, 1)), convention="turntable")
    sites = px.stack_observations([one, one])
    with pytest.raises(Stop):
        batch._fit_sites(px.Turntable("full"), np.zeros((2, 5)), sites, px.FitOptions())
    assert seen == {"batch_full_loop": True}


def test_sites_done_add_up_across_parts():
    """The network's progress: the parts' own counts summed, whatever their order."""
    from pointax.analysis.network import _SitesDone

    seen = []
    done = _SitesDone(lambda d, t: seen.append((d, t)), 9, 3)
    done.part(1)(2)
    done.part(0)(4)
    done.part(1)(3)
    done.part(2)(2)
    assert seen == [(2, 9), (6, 9), (7, 9), (9, 9)]


def test_a_site_that_does_not_converge_says_why(tmp_path):
    """Gauss-Newton on the stuck-azimuth site runs into its step limit: 'failed', and
    the reason is optimistix's message (not a lost code)."""
    manifest = tmp_path / "stuck.csv"
    manifest.write_text(f"site,path,format\nts-05,{NETWORK / 'ts-05.txt'},sun\n")
    (site,) = fit_network(manifest, solver="gauss-newton", max_steps=16).sites
    assert site["status"] == "failed" and site["converged"] is False
    assert "maximum number of steps" in site["reason"] and site["reason"] == site["message"]


def test_paint_site_matches_calibrate_heliostat(shared_data, tmp_path):
    folder = shared_data / "paint" / "AA39"
    manifest = tmp_path / "paint.csv"
    manifest.write_text(f"site,path,format,focal_spot\naa39,{folder},paint,HeliOS\n")
    (site,) = fit_network(manifest).sites
    cal = px.calibrate_heliostat(folder)
    want = cal.to_dict()
    assert set(site) == set(want) | {"site", "format", "directory", "status", "reason"}
    assert site["status"] == ("converged" if bool(cal.result.converged) else "failed")
    assert site["outliers"] == want["outliers"]
    for a, b in zip(site["params"], want["params"]):
        assert a["name"] == b["name"] and a["value"] == pytest.approx(b["value"], abs=1e-12)


# ------------------------------------------------------------- the manifest


def _manifest(tmp_path, text: str):
    (tmp_path / "a.txt").write_text("10 200 150 40\n")
    (tmp_path / "heliostat").mkdir(exist_ok=True)
    path = tmp_path / "m.csv"
    path.write_text(text)
    return path


def test_manifest_reads_rows_defaults_and_comments(tmp_path):
    path = _manifest(
        tmp_path,
        "# a comment\n\nsite, path, format, terms, azimuth, form, focal_spot\n"
        "a, a.txt, sun, , , ,\n"
        "b, a.txt, sun, simple\n"
        '  c , a.txt, tpoint, "IA, IE", S-E, rigorous,\n'
        "d, heliostat, paint, t1n t2n, , , UTIS\n",
    )
    a, b, c, d = read_manifest(path)
    assert (a.site, a.format, a.terms, a.line) == ("a", "sun", ("mu0", "nu0", "omega0", "alpha0", "beta0"), 4)
    assert a.path == tmp_path / "a.txt"
    assert b.terms == ("alpha0", "beta0")
    assert (c.site, c.terms, c.azimuth, c.form) == ("c", ("IA", "IE"), "S-E", "rigorous")
    assert (d.terms, d.focal_spot, d.path) == (("t1n", "t2n"), "UTIS", tmp_path / "heliostat")
    assert a.model_key != b.model_key


@pytest.mark.parametrize(
    "text, match",
    [
        ("site,path,format,colour\na,a.txt,sun,red\n", r"m\.csv:1: unknown column 'colour'"),
        ("site,path\na,a.txt\n", r"m\.csv:1: the header row lacks the column\(s\) format"),
        ("site,path,format,path\n", r"m\.csv:1: column\(s\) path appear more than once"),
        ("site,path,format\na,a.txt,sun,extra\n", r"m\.csv:2: 4 fields, but the header names 3 columns"),
        ("site,path,format\n,a.txt,sun\n", r"m\.csv:2: field 'site': is empty"),
        ("site,path,format\na,a.txt,csv\n", r"m\.csv:2: field 'format': unknown format 'csv'; expected one of sun, tpoint, paint"),
        ("site,path,format\na,a.txt,sun\n# x\na,a.txt,sun\n", r"m\.csv:4: field 'site': site 'a' appears twice \(first on line 2\)"),
        ("site,path,format\na,b.txt,sun\n", r"m\.csv:2: field 'path': no such file: .*b\.txt"),
        ("site,path,format\na,a.txt,paint\n", r"m\.csv:2: field 'path': no such folder: .*a\.txt"),
        ("site,path,format,azimuth\na,a.txt,sun,S-E\n", r"m\.csv:2: field 'azimuth': applies to format tpoint, not to sun"),
        ("site,path,format,azimuth\na,a.txt,tpoint,E-N\n", r"m\.csv:2: field 'azimuth': unknown azimuth convention 'E-N'"),
        ("site,path,format,form\na,a.txt,tpoint,exact\n", r"m\.csv:2: field 'form': unknown term form 'exact'"),
        ("site,path,format,residuals\na,a.txt,tpoint,angles\n", r"m\.csv:2: field 'residuals': unknown residual form 'angles'"),
        ("site,path,format,residuals\na,a.txt,sun,tpoint\n", r"m\.csv:2: field 'residuals': applies to format tpoint, not to sun"),
        ("site,path,format,focal_spot\na,heliostat,paint,eye\n", r"m\.csv:2: field 'focal_spot': unknown focal-spot method 'eye'"),
        ("site,path,format,terms\na,a.txt,sun,mu0 IA\n", r"m\.csv:2: field 'terms': unknown turntable parameter 'IA'"),
        ("site,path,format,terms\na,a.txt,tpoint,IA XX\n", r"m\.csv:2: field 'terms': unknown TPOINT term 'XX'"),
        ("# nothing\n", r"m\.csv: no sites"),
        ("site,path,format\n", r"m\.csv: no sites"),
    ],
)
def test_manifest_errors_name_file_line_and_field(tmp_path, text, match):
    with pytest.raises(ManifestError, match=match):
        read_manifest(_manifest(tmp_path, text))


def test_tpoint_residuals_from_the_manifest_equal_pointax_fit(tmp_path, capsys):
    manifest = tmp_path / "m.csv"
    manifest.write_text(f"site,path,format,azimuth,residuals\nmmt,{MMT_DAT},tpoint,S-E,tpoint\n")
    site = fit_network(manifest).sites[0]
    assert pointax_main(["fit", str(MMT_DAT), "--azimuth", "S-E", "--residuals", "tpoint", "--json"]) == 0
    solo = json.loads(capsys.readouterr().out)
    assert site["residuals"] == "tpoint" and site["status"] == "converged"
    for ours, theirs in zip(site["terms"], solo["terms"]):
        assert ours["value_arcsec"] == pytest.approx(theirs["value_arcsec"], abs=1e-8)


def test_manifest_errors_stop_before_any_fit(tmp_path):
    path = _manifest(tmp_path, "site,path,format\na,a.txt,sun\nb,missing.txt,sun\n")
    with pytest.raises(ManifestError, match="m.csv:3"):
        fit_network(path)


def test_progress_bar_on_a_terminal_only(tmp_path, monkeypatch):
    """progress=True draws pointax.fitting.progress's bar on standard error when it is a
    terminal, counting sites; nothing in a pipe."""

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    good = _manifest(tmp_path, f"site,path,format,azimuth\nmmt,{MMT_DAT},tpoint,S-E\n")
    for stream, drawn in ((Terminal(), True), (io.StringIO(), False)):
        monkeypatch.setattr("sys.stderr", stream)
        fit_network(good, progress=True)
        assert bool(re.search(r"fitting: .*1/1", stream.getvalue())) == drawn
        assert drawn or stream.getvalue() == ""


def test_a_results_methods_are_plain_bound_methods():
    """A FitResult hands out plain bound methods, not equinox's BoundMethod modules
    (building one per call cost the 10,000-site network's report 0.5 ms a site)."""
    import types

    from test_io_sun import simulated_site

    obs, _ = simulated_site(3, n=20)
    one = px.fit(px.Turntable("full", start=obs), obs)
    assert type(one.to_dict) is types.MethodType and type(one.warnings) is types.MethodType
    assert one.to_dict()["n_obs"] == int(one.n_obs)

"""Progress bars (pointax.fitting.progress, tqdm): drawn on a terminal only, silent in pipes,
logs and with --quiet; the long-running functions count their work."""

from __future__ import annotations

import argparse
import io
import re
import sys

import pytest

from conftest import MMT_DAT

from pointax.fitting.progress import progress_bar


class Terminal(io.StringIO):
    """A stream that says it is a terminal."""

    def isatty(self):
        return True


def test_bar_on_a_terminal_only():
    tty, pipe = Terminal(), io.StringIO()
    for stream in (tty, pipe):
        with progress_bar(4, "work", "step", enabled=True, stream=stream) as bar:
            for _ in range(4):
                bar.update()
    assert re.search(r"work: .*4/4", tty.getvalue())
    assert pipe.getvalue() == ""
    quiet = Terminal()
    with progress_bar(4, "work", enabled=False, stream=quiet) as bar:
        bar.update(4)
        assert not bar.active
    assert quiet.getvalue() == ""


def test_callback_form_sets_done_and_total():
    tty = Terminal()
    bar = progress_bar(0, "fitting", "site", enabled=True, stream=tty)
    bar(3, 6)
    bar(6, 6)
    bar.close()
    assert re.search(r"fitting: .*6/6", tty.getvalue())


def _fit_network_args(quiet: bool):
    from pointax.cli.fit_network import add_fit_network_parser

    parser = argparse.ArgumentParser(prog="pointax")
    add_fit_network_parser(parser.add_subparsers(dest="command"))
    return parser.parse_args(["fit-network", str(MMT_DAT)] + (["--quiet"] if quiet else []))


@pytest.mark.parametrize("quiet, terminal, drawn", [(False, True, True), (False, False, False), (True, True, False)])
def test_fit_network_draws_its_bar_on_a_terminal_unless_quiet(monkeypatch, quiet, terminal, drawn):
    import pointax.analysis.network
    from pointax.cli.fit_network import run_fit_network
    from pointax.analysis.network import NetworkResult

    def fake_fit_network(manifest, progress=False, **options):
        if progress:
            progress(2, 5)
            progress(5, 5)
        site = {"site": "a", "format": "tpoint", "status": "converged", "reason": "", "sky_rms_arcsec": 1.0}
        return NetworkResult(str(manifest), (site,))

    monkeypatch.setattr(pointax.analysis.network, "fit_network", fake_fit_network)
    err = Terminal() if terminal else io.StringIO()
    code = run_fit_network(_fit_network_args(quiet), stdout=io.StringIO(), stderr=err)
    assert code == 0
    assert bool(re.search(r"fitting: .*5/5", err.getvalue())) == drawn


def test_compare_counts_every_fit_of_every_fold(monkeypatch):
    """Two families, 2 folds: each family is fitted once on all stars and once per fold."""
    import pointax as px

    run = px.io.read_tpoint(MMT_DAT, azimuth="S-E")
    tty = Terminal()
    monkeypatch.setattr(sys, "stderr", tty)
    families = {"IA IE": px.AltAz(px.terms.tpoint("IA IE"), azimuth="S-E"),
                "IA IE CA": px.AltAz(px.terms.tpoint("IA IE CA"), azimuth="S-E")}
    px.compare(families, run.observations, folds=2, progress=True)
    assert re.search(r"compare IA IE CA: .*6/6", tty.getvalue())
    silent = io.StringIO()
    monkeypatch.setattr(sys, "stderr", silent)
    px.compare(families, run.observations, folds=2, progress=True)
    assert silent.getvalue() == ""


def test_leave_one_out_counts_its_folds(monkeypatch):
    """Every fold of the compiled loop moves the bar once, on a terminal only; the
    results equal the silent run's (the bar changes nothing computed)."""
    import numpy as np

    import pointax as px

    run = px.io.read_tpoint(MMT_DAT, azimuth="S-E")
    model = px.AltAz(px.terms.tpoint("IA IE CA"), azimuth="S-E")
    tty = Terminal()
    monkeypatch.setattr(sys, "stderr", tty)
    drawn = px.leave_one_out(model, run, progress=True)
    assert re.search(r"leave-one-out: .*80/80", tty.getvalue())
    silent = io.StringIO()
    monkeypatch.setattr(sys, "stderr", silent)
    quiet = px.leave_one_out(model, run, progress=True)
    assert silent.getvalue() == ""
    np.testing.assert_array_equal(np.asarray(drawn.errors), np.asarray(quiet.errors))

"""Column-wise per-site records of a batched fit (pointax.fitting.batch_records,
pointax.analysis.batch_listing) and the column-wise sun-file reading equal the per-site
and line-by-line code they replace, to the bit.

References, written here: the per-site loop `site_statuses` had (one FitResult per
site), `site_result(result, k).to_dict()`, `observation_entries` of each site cut to
its rows, and the sun reader's line-by-line parse (`_parse_lines`). Compared through
`json.dumps` too, so a float that differs in its last bit (or 0.0 against -0.0) fails.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json

import jax
import numpy as np
import pytest
from conftest import EXAMPLES

import pointax as px
from pointax.analysis import network
from pointax.analysis.batch_listing import batch_observation_entries
from pointax.analysis.listing import observation_entries
from pointax.fitting.batch import PER_ROW_FIELDS, site_result
from pointax.fitting.batch_records import site_dicts, site_statuses
from pointax.fitting.ranges import range_warning
from pointax.io.sun import SunFormatError, _parse_lines, parse_sun_observations

NETWORK = EXAMPLES / "data" / "network"


@pytest.fixture(autouse=True)
def no_compilation_cache(monkeypatch):
    monkeypatch.setenv("POINTAX_JAX_CACHE", "")


def _reference_statuses(result):
    """The per-site loop site_statuses had before it went column-wise."""
    out = []
    for k in range(int(np.shape(result.converged)[0])):
        one = site_result(result, k)
        degenerate = [n for n, d in zip(one.names, np.asarray(one.degenerate)) if d]
        if not bool(one.converged):
            out.append({"status": "failed", "reason": one.message})
        elif degenerate:
            out.append({"status": "degenerate", "reason": "cannot be told apart: " + ", ".join(degenerate)})
        else:
            out.append({"status": "converged", "reason": range_warning(np.asarray(one.values), one.model.free_parameters)})
    return out


def _reference_entries(run, result, k):
    one = site_result(result, k)
    n = len(run)
    every_row = bool(np.all(np.asarray(run.observations.weight) > 0))
    rows = dataclasses.replace(one, **{f: np.asarray(getattr(one, f))[:n] for f in PER_ROW_FIELDS})
    return observation_entries(run, rows, residuals=np.asarray(one.residuals)[:n] if every_row else None)


def _rows(name: str) -> list[str]:
    return [x for x in (NETWORK / name).read_text().splitlines() if x.strip() and not x.startswith("#")]


@pytest.fixture(scope="module")
def small_network(tmp_path_factory):
    """Clean sites, a degenerate one (ts-05), a too-short one (failed), a shorter one
    with weight-0 rows (residuals evaluated), one with an absurd row (warnings), one
    with a weight column; fitted in one batch as fit_network does."""
    folder = tmp_path_factory.mktemp("net")
    lines = ["site, path, format, terms"]
    for name in ("ts-01", "ts-02", "ts-03", "ts-05"):
        (folder / f"{name}.txt").write_text((NETWORK / f"{name}.txt").read_text())
        lines.append(f"{name}, {name}.txt, sun, full")
    rows = _rows("ts-04.txt")
    extra = {
        "few": rows[:2],
        "masked": [r + (" 0" if i % 5 == 2 else " 0.5") for i, r in enumerate(rows[:15])],
        "absurd": rows[:3] + [" ".join(rows[3].split()[:3] + ["%.6f" % (float(rows[3].split()[3]) + 25)])] + rows[4:],
        "weighted": [r + " 2" for r in rows],
    }
    for name, body in extra.items():
        (folder / f"{name}.txt").write_text("# test site\n" + "\n".join(body) + "\n")
        lines.append(f"{name}, {name}.txt, sun, full")
    (folder / "manifest.csv").write_text("\n".join(lines) + "\n")
    entries = network.read_manifest(folder / "manifest.csv")
    loaded, failed = network._read_sites(entries)
    assert not failed
    runs = [loaded[e.site] for e in entries]
    model = network._batch_model(entries[0])
    batch = px.stack_observations([r.observations for r in runs])
    result = px.fit_batch(model, batch, values=network._start_values(entries, runs, model))
    return folder / "manifest.csv", runs, jax.tree.map(np.asarray, result)


def test_statuses_equal_the_per_site_loop(small_network):
    _, _, result = small_network
    new, ref = site_statuses(result), _reference_statuses(result)
    assert json.dumps(new) == json.dumps(ref)
    assert {d["status"] for d in new} == {"converged", "degenerate", "failed"}  # every branch taken
    assert px.site_statuses(result) == ref  # the public name goes column-wise too


def test_dicts_equal_to_dict_of_each_site(small_network):
    _, _, result = small_network
    new = site_dicts(result)
    ref = [site_result(result, k).to_dict() for k in range(len(new))]
    assert json.dumps(new) == json.dumps(ref)
    assert new == ref
    assert any(d["warnings"] for d in ref) and any(not d["warnings"] for d in ref)  # both paths taken


def test_dicts_with_fixed_parameters_and_outliers(small_network):
    """A model with a fixed parameter and a robust loss (outlier lists): same dicts."""
    _, runs, _ = small_network
    model = px.Turntable("full").restructured(fixed=["omega0"])
    batch = px.stack_observations([r.observations for r in runs[:3]])
    result = jax.tree.map(np.asarray, px.fit_batch(model, batch, loss="cauchy"))
    new = site_dicts(result)
    ref = [site_result(result, k).to_dict() for k in range(len(new))]
    assert new[0]["fixed"] and json.dumps(new) == json.dumps(ref)


def test_observation_entries_equal_the_per_site_listing(small_network):
    _, runs, result = small_network
    new = batch_observation_entries(runs, result)
    ref = [_reference_entries(run, result, k) for k, run in enumerate(runs)]
    assert json.dumps(new) == json.dumps(ref)
    assert [len(e) for e in new] == [len(r) for r in runs]
    masked_site = new[runs.index(next(r for r in runs if r.path.endswith("masked.txt")))]
    assert not all(e["used"] for e in masked_site)  # weight-0 rows listed, not used


def test_network_without_observations_leaves_out_only_those_keys(small_network):
    manifest, _, _ = small_network
    full = network.fit_network(manifest)
    lean = network.fit_network(manifest, observations=False)
    for a, b in zip(full.sites, lean.sites):
        a = dict(a)
        if "observations" in a:
            assert a.pop("masked") == [] and a.pop("masked_rows") == []
            assert len(a.pop("observations")) == a["n_obs"] or a["site"] in {"masked", "few"}
        assert json.dumps(a) == json.dumps(b)
    assert lean.table() == full.table()


# ------------------------------------------------------------------- sun files, column-wise


SUN_TEXTS = [
    "# a comment\n10 20 30 40\n11 21 31 41 0.5\n\n12, 22, 32, 42  # trailing\n13 23 33 43 0\n",
    "10 20 30 40\r\n11 21 31 41\r\n12 22 32 42\r\n",
    "  # only\n# comments\n10 20 30 40 1e0\n-350 359.5 -0.5 -1\n",
    "10 20 30 40\n10 20 30 40\n",  # repeated rows: the warning still comes
]


@pytest.mark.parametrize("text", SUN_TEXTS)
def test_sun_columns_equal_the_line_by_line_reading(text):
    with pytest.warns() if "10 20 30 40\n10 20 30 40" in text else _nothing():
        run = parse_sun_observations(text, "x.txt")
    degrees, weights, lines, comments = _parse_lines(text, "x.txt")
    np.testing.assert_array_equal(run.encoder, np.radians(degrees[:, :2]))
    np.testing.assert_array_equal(run.sun, np.radians(degrees[:, 2:]))
    np.testing.assert_array_equal(run.weight, weights)
    assert run.lines.tolist() == lines and list(run.comments) == comments


@pytest.mark.parametrize(
    "text, message",
    [
        ("10 20 30 40\n10 20 abc 40\n", r"x\.txt:2: column 3 \(sun_az_deg\): 'abc' is not a number"),
        ("10 20 30 40\n10 20 30 nan\n", r"x\.txt:2: column 4 \(sun_el_deg\): 'nan' is not finite"),
        ("10 20 30 40\n10 20 30\n", r"x\.txt:2: expected 4 or 5 numbers"),
        ("10 20 30 91\n", r"x\.txt:1: column 4 .*outside -90\.\.90"),
        ("10 20 30 40 -1\n", r"x\.txt:1: column 5 \(weight\): weight -1 is negative"),
        ("10 20 400 40\n", r"x\.txt:1: column 3 .*outside -360\.\.360"),
        ("# nothing\n", r"no observations"),
    ],
)
def test_bad_sun_files_still_name_line_and_column(text, message):
    with pytest.raises(SunFormatError, match=message):
        parse_sun_observations(text, "x.txt")


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def test_encoder_zeros_equal_estimate_zeros_site_by_site(small_network):
    """The stacked start values are estimate_zeros of each site's rows of positive weight, to the bit."""
    from pointax.terms.sun_vector import estimate_zeros

    _, runs, _ = small_network
    ref = np.array(
        [estimate_zeros(np.asarray(r.observations.encoder)[r.weight > 0], np.asarray(r.observations.target)[r.weight > 0]) for r in runs]
    )
    np.testing.assert_array_equal(network._encoder_zeros(runs), ref)


def test_the_table_does_not_build_observation_entries(small_network, monkeypatch):
    """pointax fit-network without --json builds no observation entries (they are most of
    a large network's Python time and the table shows none); with --json it does."""
    import io

    from pointax.cli import main as pointax_main

    manifest, _, _ = small_network
    built = []
    real = network.batch_observation_entries
    monkeypatch.setattr(network, "batch_observation_entries", lambda *a: built.append(1) or real(*a))
    with contextlib.redirect_stdout(io.StringIO()) as out:
        pointax_main(["fit-network", str(manifest), "--quiet"])
    assert not built and "sky rms" in out.getvalue().lower()
    with contextlib.redirect_stdout(io.StringIO()) as out:
        pointax_main(["fit-network", str(manifest), "--quiet", "--json"])
    assert built and all("observations" in d for d in json.loads(out.getvalue()) if d["status"] != "failed")


def test_only_the_unusual_sites_go_through_to_dict(small_network, monkeypatch):
    """The column-wise guard: a site with no warning and an empty message is never a
    FitResult of its own (at 10,000 sites that cost seconds), the others are."""
    from pointax.fitting.result import FitResult

    _, _, result = small_network
    ref = [site_result(result, k).to_dict() for k in range(int(np.shape(result.converged)[0]))]
    calls = []
    real = FitResult.to_dict
    monkeypatch.setattr(FitResult, "to_dict", lambda self: calls.append(1) or real(self))
    site_dicts(result)
    unusual = sum(1 for d in ref if d["warnings"] or d["message"])
    assert 0 < unusual < len(ref) and len(calls) == unusual

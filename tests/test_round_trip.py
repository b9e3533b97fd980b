"""Exact round trips (issue 20, item 5): a model written to a file and read back is the
same model to 1e-12 rad; NaN is refused at write; ``Model.values()`` is float64 with or
without JAX's x64 mode.

References: the values the test draws itself (numpy's float64), compared with what the
reader gives back; Python's own float parsing decides what "the same float" is.
"""

from __future__ import annotations

import json
import math
import warnings

import jax
import numpy as np
import pytest

import pointax as px
from pointax.core.errors import InputWarning
from pointax.io import ModelTerm, format_model, parse_model, read_model, write_model
from pointax.io.tpoint_model import exact_decimal

ARCSEC = math.pi / (180 * 3600)
NAMES = "IA IE CA NPAE AN AW TF TX HACA2 HESE5 HSCA5CE8".split()


def _random_model(rng, scale_arcsec):
    values = {n: float(rng.normal(0.0, scale_arcsec) * ARCSEC) for n in NAMES}
    # Values on the edge of a fixed-point layout: tiny, huge, one ulp off a round number.
    values["TF"] = -0.00004999 * ARCSEC
    values["TX"] = float(np.nextafter(12.5, 13.0)) * ARCSEC
    return px.AltAz(px.terms.tpoint(NAMES, values=values), azimuth="S-E"), values


@pytest.mark.parametrize("seed, scale", [(0, 1.0), (1, 100.0), (2, 1e5), (3, 1e-6)])
def test_tpoint_model_file_round_trip_is_exact(tmp_path, seed, scale):
    rng = np.random.default_rng(seed)
    huge = scale > 3600 * 10  # coefficients of tens of degrees: pointax warns, and still keeps them
    with warnings.catch_warnings(record=True) as built:
        warnings.simplefilter("always", InputWarning)
        model, values = _random_model(rng, scale)
    path = tmp_path / "m.mod"
    write_model(path, model)
    with warnings.catch_warnings(record=True) as read:
        warnings.simplefilter("always", InputWarning)
        back = read_model(path).model(azimuth="S-E")
    built, read = ([w for w in ws if issubclass(w.category, InputWarning)] for ws in (built, read))
    assert bool(built) == huge and bool(read) == huge
    # Read from a file, the warning names the file, the line and the file's unit.
    for w in read:
        assert str(w.message).startswith(f"{path}:") and "model files give arcseconds" in str(w.message), w.message
    assert back.parameter_names == model.parameter_names
    for name in NAMES:
        assert abs(float(back.get(name)) - values[name]) <= 1e-12, name
    # In arcseconds the file gives back the very float64 that was written.
    for term in read_model(path).terms:
        assert term.value == float(model.get(term.name)) / ARCSEC


def test_fit_result_model_file_round_trip(tmp_path):
    truth = px.AltAz(px.terms.tpoint("IA IE CA NPAE AN AW TF", values={"IA": px.arcsec(30), "AN": px.arcsec(-7)}))
    rng = np.random.default_rng(5)
    enc = np.column_stack([rng.uniform(0, 2 * np.pi, 40), rng.uniform(0.2, 1.4, 40)])
    obs = px.simulate(truth, enc, noise=px.arcsec(1.0), seed=3)
    result = px.fit(px.AltAz(px.terms.tpoint("IA IE CA NPAE AN AW TF")), obs)
    path = tmp_path / "fit.mod"
    with pytest.warns(UserWarning, match="no run given, so the refraction constants are written as 0"):
        write_model(path, result)
    read = read_model(path)
    assert read.n_obs == 40
    assert read.sky_rms == float(result.sky_rms) / ARCSEC
    for name, v, s in zip(result.names, np.asarray(result.values), np.asarray(result.sigmas)):
        term = next(t for t in read.terms if t.name == name)
        assert abs(term.value * ARCSEC - v) <= 1e-12
        assert abs(term.sigma * ARCSEC - s) <= 1e-12
    # The JSON summary gives back the same values too (json writes floats exactly).
    summary = json.loads(json.dumps(result.to_dict()))
    for row, v in zip(summary["terms"], np.asarray(result.values)):
        assert abs(row["value_arcsec"] * ARCSEC - v) <= 1e-12


def test_fixed_point_layout_keeps_tpoint_look():
    # Values that need no more than TPOINT's 4 decimals keep TPOINT's layout.
    text = format_model([ModelTerm("IA", 1209.2612, 1.28477)], n_obs=80, sky_rms=0.9318, refraction=(42.06, -0.0485))
    assert "+1209.2612" in text and "1.28477" in text and "0.9318" in text and "42.060" in text
    # The issue's case: -0.00004999" was written as -0.0000.
    assert exact_decimal(-0.00004999, 4, sign=True) == "-0.00004999"
    assert float(exact_decimal(1 / 3, 4)) == 1 / 3


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
def test_non_finite_value_is_refused_at_write(tmp_path, bad):
    model = px.AltAz(px.terms.tpoint("IA IE", values={"IE": bad}))
    path = tmp_path / "nan.mod"
    with pytest.raises(ValueError, match=r"value of term IE is .*cannot hold NaN or infinity"):
        write_model(path, model)
    assert not path.exists()


def test_non_finite_sky_rms_is_refused():
    with pytest.raises(ValueError, match="Sky RMS"):
        format_model([ModelTerm("IA", 1.0)], n_obs=3, sky_rms=float("nan"))


def test_values_are_float64_outside_x64_mode():
    v = np.array([1.2345678901234567e-5, -3.3e-7, 2.0 / 3.0 * 1e-4])
    with jax.enable_x64(False):
        assert not jax.config.jax_enable_x64
        model = px.AltAz(px.terms.tpoint("IA IE CA")).with_values(v)
        got = model.values()
        assert got.dtype == np.float64
        np.testing.assert_array_equal(np.asarray(got), v)
        again = model.with_values(model.values())
        np.testing.assert_array_equal(np.asarray(again.values()), v)


def test_parse_of_written_text_is_identity_for_every_flag():
    terms = [
        ModelTerm("IA", 1209.261243187, 1.2847712),
        ModelTerm("NPAE", -0.0, None, fixed=True),
        ModelTerm("HSCASE3", -6.756540000001, 1.607351, parallel=True),
    ]
    back = parse_model(format_model(terms))
    assert back.terms == tuple(terms)

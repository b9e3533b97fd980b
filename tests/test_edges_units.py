"""Issue 30, units at the Python API's edges: a value whose unit pointax assumes
(radians, East-North-Up unit vectors) is checked for plausibility where it enters
(:func:`pointax.core.units.check_angle_radians`, :func:`pointax.core.units.check_unit_vectors`),
and a mistake is named with the value, what was expected and the likely unit."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pointax as px
from pointax.io import InputWarning
from pointax.core.units import (
    ImplausibleValueError,
    angle_radians_problem,
    check_unit_vectors,
    offsets_scale_problem,
    unit_vectors_problem,
)


def test_model_set_refuses_degrees_where_radians_are_expected():
    with pytest.raises(ImplausibleValueError, match=r"alpha0 = 60\.5.*radians.*degrees.*px\.deg"):
        px.Turntable().set(alpha0=60.5)


def test_model_set_takes_radians_and_quantities():
    model = px.Turntable().set(alpha0=math.radians(60.5))
    assert model.get("alpha0") == pytest.approx(math.radians(60.5))


def test_model_set_warns_of_a_pointing_term_beyond_ten_degrees():
    model = px.AltAz(px.terms.tpoint("IA IE"))
    with pytest.warns(InputWarning, match=r"IA = 0\.5.*pointing term"):
        model.set(IA=0.5)


def test_tpoint_values_refuse_arcseconds():
    with pytest.raises(ImplausibleValueError, match=r"IA = 1209\.26.*arcseconds.*px\.arcsec"):
        px.terms.tpoint("IA", values={"IA": 1209.26})


def test_tpoint_values_in_radians_are_taken():
    (term,) = px.terms.tpoint("IA", values={"IA": px.arcsec(1209.26)})
    assert float(term.coef) == pytest.approx(px.arcsec(1209.26))


def test_observations_refuse_azimuth_elevation_in_degrees_as_targets():
    encoder = np.radians([[180.0, 45.0], [90.0, 30.0]])
    target = np.array([[180.0, 45.0, 0.0], [90.0, 30.0, 0.0]])
    with pytest.raises(ImplausibleValueError, match=r"target.*not unit vectors.*azimuth/elevation in degrees"):
        px.Observations(encoder, target)


def test_observations_skip_padding_rows_of_weight_zero():
    encoder = np.zeros((2, 2))
    target = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    obs = px.Observations(encoder, target, weight=[1.0, 0.0])
    assert len(obs) == 2


def test_command_check_warns_of_degrees():
    with pytest.warns(InputWarning, match=r"direction.*length 185\.5"):
        check_unit_vectors([180.0, 45.0, 0.0], "direction", warn=True)


@settings(max_examples=200, deadline=None)
@given(st.floats(-1e6, 1e6, allow_nan=False))
def test_angle_problem_names_the_value_and_a_unit_that_fits(value):
    problem = angle_radians_problem(value, "x")
    if abs(value) <= 2 * math.pi:
        assert problem is None
    else:
        assert problem is not None and f"x = {value:g}" in problem
        assert "degrees" in problem or "arcminutes" in problem or "arcseconds" in problem or "no angle unit" in problem


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 360), st.floats(0, 90)), min_size=1, max_size=20))
def test_az_el_degrees_are_never_taken_as_unit_vectors(rows):
    vectors = np.array([[a, e, 0.0] for a, e in rows])
    norms = np.linalg.norm(vectors, axis=1)
    problem = unit_vectors_problem(vectors, "target")
    assert (problem is None) == bool(np.all(np.abs(norms - 1) <= 1e-3))


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-0.05, 0.05, allow_nan=False), min_size=3, max_size=30))
def test_degree_offsets_read_as_arcsec_are_named(degrees):
    problem = offsets_scale_problem(np.asarray(degrees) * px.ARCSEC if hasattr(px, "ARCSEC") else np.asarray(degrees) * math.pi / 648000, "dxel", "arcsec")
    if any(d != 0 for d in degrees):
        assert problem is not None and "degrees" in problem
    else:
        assert problem is None


def test_no_warning_for_plausible_values():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        px.AltAz(px.terms.tpoint("IA IE")).set(IA=px.arcsec(1209.26))
        px.terms.tpoint("IA IE", values={"IA": px.arcsec(30), "IE": -px.arcsec(5)})


def test_command_check_leaves_vectors_it_normalises_alone():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_unit_vectors([[0.0, 0.0, 1.5], [0.0, 0.0, 0.0], [np.nan, 0, 0]], "direction", warn=True, tolerance=1.0)


def test_reader_boundary_names_the_file_of_a_check_in_another_module(tmp_path):
    from pointax.io.errors import file_errors
    from pointax.core.units import check_angle_radians

    @file_errors(px.io.FileFormatError)
    def read_angle(path):
        check_angle_radians(float(path.read_text()), "angle")

    path = tmp_path / "angle.txt"
    path.write_text("60.5")
    with pytest.raises(px.io.FileFormatError, match=r"angle\.txt: ImplausibleValueError: angle = 60\.5.*degrees"):
        read_angle(path)

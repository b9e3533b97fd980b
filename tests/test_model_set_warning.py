"""Issue 30: the implausible-value warnings of ``Model.set`` name the user's line, not
equinox's method wrapper (a fixed ``stacklevel`` pointed into equinox/_module)."""

from __future__ import annotations

import warnings

import pytest

import pointax as px
from pointax.io import InputWarning


def _model():
    return px.AltAz(px.terms.tpoint("IA IE NPAE"))


def test_pointing_term_in_degrees_warns_at_the_callers_line():
    model = _model()
    with pytest.warns(InputWarning, match=r"IA = 0\.5: expected a pointing term in radians") as record:
        model.set(IA=0.5)  # degrees meant
    assert len(record) == 1
    assert record[0].filename == __file__
    assert record[0].lineno == test_pointing_term_in_degrees_warns_at_the_callers_line.__code__.co_firstlineno + 3


def _helper_in_user_code(model):
    return model.set(IE=-0.4)


def test_warning_names_the_users_frame_that_called_set():
    with pytest.warns(InputWarning) as record:
        _helper_in_user_code(_model())
    assert record[0].filename == __file__
    assert record[0].lineno == _helper_in_user_code.__code__.co_firstlineno + 1


def test_other_angle_beyond_a_turn_warns_at_the_callers_line():
    """A turntable's mu0 (an angle not modulo a turn) given as 100: named, at this line."""
    model = px.Model(px.TurntableMount(), px.terms.turntable("full"))
    with pytest.warns(InputWarning, match=r"mu0 = 100") as record:
        model.set(mu0=100.0)
    assert record[0].filename == __file__


def test_plausible_values_do_not_warn():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _model().set(IA=px.arcsec(30), IE=-px.arcsec(12))

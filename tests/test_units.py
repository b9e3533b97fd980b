"""Units at the API edges (issue 20, item 2): astropy Quantity, Angle and SkyCoord are
converted where angles and directions enter; a bare number stays radians; a Quantity is
converted or refused, never stripped; ``import pointax`` does not import astropy.

References: astropy's own conversions (``Quantity.to_value``, ``SkyCoord.alt/az``) and
the ENU formula (sin A cos E, cos A cos E, sin E) written out here.
"""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

import pointax as px

u = pytest.importorskip("astropy.units")
coords = pytest.importorskip("astropy.coordinates")


def _enu(az, el):
    return np.stack([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)], axis=-1)


def test_observations_take_quantities_and_angles():
    target = _enu(np.radians([10.0, 200.0]), np.radians([20.0, 60.0]))
    obs = px.Observations([[10.0, 20.0], [200.0, 60.0]] * u.deg, target)
    np.testing.assert_allclose(obs.encoder, np.radians([[10.0, 20.0], [200.0, 60.0]]), rtol=0, atol=1e-15)
    obs = px.Observations(coords.Angle([[600.0, 36000.0]], unit=u.arcmin), target[:1])
    np.testing.assert_allclose(obs.encoder, [[math.radians(10.0), math.radians(600.0)]], rtol=1e-15)


def test_bare_numbers_stay_radians():
    obs = px.Observations([[0.5, 0.25]], [[0.0, 0.0, 1.0]])
    assert obs.encoder.tolist() == [[0.5, 0.25]]


def test_targets_from_skycoord_in_altaz_and_from_az_el_quantity():
    az, el = np.array([10.0, 123.0, 300.0]), np.array([5.0, 45.0, 80.0])
    want = _enu(np.radians(az), np.radians(el))
    sky = coords.SkyCoord(az=az * u.deg, alt=el * u.deg, frame="altaz")
    np.testing.assert_allclose(px.Observations(np.zeros((3, 2)), sky).target, want, atol=1e-15)
    pairs = np.stack([az, el], axis=-1) * u.deg
    np.testing.assert_allclose(px.Observations(np.zeros((3, 2)), pairs).target, want, atol=1e-15)


def test_skycoord_in_another_frame_is_refused():
    with pytest.raises(ValueError, match="ICRS frame.*transform it first"):
        px.Observations([[0.0, 0.0]], coords.SkyCoord(ra=[1.0] * u.deg, dec=[2.0] * u.deg))


def test_quantity_that_is_not_an_angle_is_refused_not_stripped():
    with pytest.raises(ValueError, match="encoder: a Quantity in m cannot be converted to rad"):
        px.Observations([[1.0, 2.0]] * u.m, [[0.0, 0.0, 1.0]])


def test_model_set_and_get_in_units():
    model = px.AltAz(px.terms.tpoint("IA IE")).set(IA=10.0 * u.arcsec, IE=coords.Angle(-0.5, u.deg))
    assert float(model.get("IA")) == pytest.approx(10.0 * math.pi / 648000.0, rel=1e-15)
    assert model.get("IE", "arcsec") == pytest.approx(-1800.0, rel=1e-14)
    q = model.get("IA", u.arcsec)
    assert isinstance(q, u.Quantity) and q.value == pytest.approx(10.0, rel=1e-14)
    with pytest.raises(ValueError, match="parameter IA: a Quantity in s cannot be converted"):
        model.set(IA=3.0 * u.s)


def test_simulate_and_model_call_take_quantities():
    truth = px.AltAz(px.terms.tpoint("IA IE"), azimuth="N-E").set(IA=20 * u.arcsec)
    encoder = [[30.0, 40.0], [120.0, 60.0]] * u.deg
    obs = px.simulate(truth, encoder, noise=0 * u.arcsec)
    ref = px.simulate(truth, np.radians([[30.0, 40.0], [120.0, 60.0]]))
    np.testing.assert_array_equal(obs.encoder, ref.encoder)
    np.testing.assert_allclose(obs.target, ref.target, atol=1e-15)
    np.testing.assert_allclose(np.asarray(truth(encoder)), np.asarray(truth(ref.encoder)), atol=1e-15)


def test_command_takes_quantity_directions_and_limits():
    model = px.AltAz(px.terms.tpoint("IA IE"), azimuth="N-E").set(IA=30 * u.arcsec, IE=-10 * u.arcsec)
    az_el = [[100.0, 30.0], [250.0, 70.0]] * u.deg
    c = px.command(model, az_el, limits=((-180, 180), (0, 90)) * u.deg)
    ref = px.command(model, _enu(np.radians([100.0, 250.0]), np.radians([30.0, 70.0])), limits=((-math.pi, math.pi), (0, math.pi / 2)))
    assert bool(np.all(c.ok))
    np.testing.assert_allclose(np.asarray(c.reading), np.asarray(ref.reading), atol=1e-12)
    np.testing.assert_allclose(np.asarray(c.limits), np.radians([[-180, 180], [0, 90]]), atol=1e-15)
    sky = coords.SkyCoord(az=[100.0, 250.0] * u.deg, alt=[30.0, 70.0] * u.deg, frame="altaz")
    np.testing.assert_allclose(np.asarray(px.command(model, sky).reading), np.asarray(ref.reading), atol=1e-12)


def test_limits_in_degrees_as_bare_numbers_are_refused():
    model = px.AltAz(px.terms.tpoint("IA"))
    with pytest.raises(ValueError, match="axis 1 max is 360 rad, beyond 2 turns: it looks like degrees"):
        px.command(model, [0.0, 0.6, 0.8], limits=((0, 360), None))


def test_import_pointax_does_not_import_astropy():
    code = "import sys, pointax, pointax.core.units; print('astropy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_with_weight_checks_the_targets_it_gives_weight_and_not_the_encoder_again():
    """A target that is no unit vector is accepted at weight 0 and refused once a copy
    gives it weight; encoder readings in degrees are warned of when the observations are
    made, not again by the copy."""
    import warnings

    from pointax.core.units import ImplausibleValueError

    target = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 2.0]])
    obs = px.Observations(np.zeros((2, 2)), target, weight=[1.0, 0.0])
    with pytest.raises(ImplausibleValueError, match="target"):
        obs.with_weight([1.0, 1.0])
    with pytest.warns(px.io.InputWarning, match="look like degrees"):
        degrees = px.Observations(np.full((2, 2), 90.0), target[:1].repeat(2, 0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        np.testing.assert_array_equal(np.asarray(degrees.with_weight([2.0, 1.0]).weight), [2.0, 1.0])

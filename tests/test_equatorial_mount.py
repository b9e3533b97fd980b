"""The equatorial mount: hour angle and declination at a latitude, both pier sides.

References: the standard spherical trigonometry of hour angle / declination to
altitude / azimuth written out here, astropy's HADec -> AltAz transformation, central
finite differences for the residuals, the forward model for commands, and simulated
observations for a fit.
"""

from __future__ import annotations

import warnings

import astropy.units as u
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from astropy.coordinates import AltAz, EarthLocation, HADec
from astropy.time import Time
from astropy.utils import iers

import pointax as px
from pointax.terms.model_factories import Equatorial
from pointax.core.mounts import EquatorialMount

ARCSEC = np.pi / 648000


def hadec_to_altaz(h, dec, lat):
    """Textbook spherical trigonometry: altitude and azimuth (North through East)."""
    sin_alt = np.sin(lat) * np.sin(dec) + np.cos(lat) * np.cos(dec) * np.cos(h)
    az = np.arctan2(-np.cos(dec) * np.sin(h), np.cos(lat) * np.sin(dec) - np.sin(lat) * np.cos(dec) * np.cos(h))
    return np.arcsin(sin_alt), az


def altaz_to_enu(alt, az):
    return np.stack([np.sin(az) * np.cos(alt), np.cos(az) * np.cos(alt), np.sin(alt)], axis=-1)


def hadec_direction(h, dec, lat):
    alt, az = hadec_to_altaz(h, dec, lat)
    return altaz_to_enu(alt, az)


def sky_hadec(n, lat, min_elevation_deg=10.0, seed=0):
    """(H, dec) of directions spread over the sky above ``min_elevation_deg``, from the
    textbook inverse (dec = asin(sin lat sin alt + cos lat cos alt cos az), ...)."""
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(10 * n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v = v[v[:, 2] > np.sin(np.radians(min_elevation_deg))][:n]
    alt, az = np.arcsin(v[:, 2]), np.arctan2(v[:, 0], v[:, 1])
    dec = np.arcsin(np.sin(lat) * np.sin(alt) + np.cos(lat) * np.cos(alt) * np.cos(az))
    h = np.arctan2(-np.sin(az) * np.cos(alt), np.cos(lat) * np.sin(alt) - np.sin(lat) * np.cos(alt) * np.cos(az))
    return np.stack([h, dec], -1), v


LATITUDES = [np.radians(x) for x in (31.689, -33.9, 0.0, 52.2, 89.0)]


@jax.jit
def _pointing(model, enc):
    return jax.vmap(model.direction)(enc)


@pytest.mark.parametrize("lat", LATITUDES)
def test_pointing_is_the_spherical_trigonometry_on_both_pier_sides(lat):
    rng = np.random.default_rng(3)
    h = rng.uniform(-np.pi, np.pi, 40)
    dec = rng.uniform(-np.pi / 2, np.pi / 2, 40)
    model = Equatorial([], latitude=lat)
    expected = hadec_direction(h, dec, lat)
    np.testing.assert_allclose(np.asarray(_pointing(model, jnp.stack([h, dec], -1))), expected, atol=2e-15)
    # The other pier side: (H + 180 deg, 180 deg - dec) points the same way.
    flipped = jnp.stack([h + np.pi, np.pi - dec], -1)
    np.testing.assert_allclose(np.asarray(_pointing(model, flipped)), expected, atol=2e-15)
    # The nominal inverse returns the reading of the side nearest the current one.
    mount = model.mount
    frame = np.asarray(mount.frame)
    for k in range(5):
        d = jnp.asarray(frame.T @ expected[k])
        np.testing.assert_allclose(np.asarray(mount.angles_of(d, jnp.array([h[k], dec[k]]))), [h[k], dec[k]], atol=1e-12)
        side_b = np.asarray(mount.angles_of(d, jnp.array([h[k] + np.pi, np.pi - dec[k]])))
        np.testing.assert_allclose(side_b, [h[k] + np.pi, np.pi - dec[k]], atol=1e-12)


def test_pointing_agrees_with_astropy_hadec_to_altaz():
    location = EarthLocation.from_geodetic(lon=-110.885 * u.deg, lat=31.689 * u.deg, height=2600 * u.m)
    time = Time("2021-08-21T06:00:00")
    rng = np.random.default_rng(4)
    h, dec = rng.uniform(-np.pi, np.pi, 30), rng.uniform(-1.2, 1.4, 30)
    with iers.conf.set_temp("auto_download", False), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sky = HADec(ha=h * u.rad, dec=dec * u.rad, obstime=time, location=location)
        altaz = sky.transform_to(AltAz(obstime=time, location=location))
    expected = altaz_to_enu(altaz.alt.rad, altaz.az.rad)
    got = np.asarray(_pointing(Equatorial([], latitude=np.radians(31.689)), jnp.stack([h, dec], -1)))
    np.testing.assert_allclose(got, expected, atol=1e-12)


@pytest.mark.parametrize("h, dec", [(0.0, 0.3), (0.5, 0.2), (-2.0, -0.4), (1.0, 1.2)])
def test_fit_residuals_are_dH_cosdec_and_ddec(h, dec):
    lat = np.radians(20.0)  # (0, 0.3) is within 10 deg of the zenith: no pole there
    dh, ddec = 2e-6, -3e-6
    model = Equatorial([], latitude=lat)
    obs = px.Observations(np.array([[h, dec]]), hadec_direction(h + dh, dec + ddec, lat)[None], convention="ha-dec")
    r = np.asarray(px.residuals(model, obs))[0]
    np.testing.assert_allclose(r, [dh * np.cos(dec), ddec], atol=2e-11)
    step = 1e-6
    e_h = (hadec_direction(h + step, dec, lat) - hadec_direction(h - step, dec, lat)) / (2 * step) / np.cos(dec)
    e_d = (hadec_direction(h, dec + step, lat) - hadec_direction(h, dec - step, lat)) / (2 * step)
    offset = hadec_direction(h + dh, dec + ddec, lat) - hadec_direction(h, dec, lat)
    np.testing.assert_allclose(r, [offset @ e_h, offset @ e_d], atol=2e-11)
    ar = model.mount.axis_residuals(model(np.array([h, dec])), hadec_direction(h + dh, dec + ddec, lat))
    np.testing.assert_allclose(np.asarray(ar), r, atol=1e-18)


# Generic rigorous rotations in the equatorial mount's frame: IA (hour-angle zero point),
# IE (declination zero point), CA (collimation), NPAE (axis non-perpendicularity), AN/AW
# (polar-axis tilts).
TERMS = "IA IE CA NPAE AN AW"
TRUTH = {"IA": 40.0, "IE": -25.0, "CA": 30.0, "NPAE": -15.0, "AN": 20.0, "AW": -35.0}


def equatorial_model(lat, values=None):
    values = {k: v * ARCSEC for k, v in (values or {}).items()}
    return Equatorial(px.terms.tpoint(TERMS, form="rigorous", values=values), latitude=lat)


def test_command_inverts_the_model_on_both_pier_sides():
    lat = np.radians(-29.25)
    model = equatorial_model(lat, TRUTH)
    model = model.with_values(model.values())  # arrays, not Python floats: one compilation
    hadec, wanted = sky_hadec(40, lat, min_elevation_deg=5.0, seed=7)
    for side in ("normal", "flipped"):
        cmd = px.command(model, wanted, solution=side)
        assert bool(np.all(np.asarray(cmd.ok))), cmd.reasons()
        np.testing.assert_allclose(np.asarray(model(cmd.reading)), wanted, atol=1e-12)
        dec_axis = np.asarray(cmd.reading)[:, 1]
        assert np.all(np.cos(dec_axis) > 0) if side == "normal" else np.all(np.cos(dec_axis) < 0)
    # Error-free (the same model at zero): the normal side reads (H, dec), the flipped one
    # (H + 180 deg, 180 deg - dec).
    perfect = model.with_values(jnp.zeros(len(TRUTH)))
    normal = px.command(perfect, wanted, solution="normal", limits=((-np.pi, np.pi), None))
    np.testing.assert_allclose(np.asarray(normal.reading), hadec, atol=1e-12)
    flipped = px.command(perfect, wanted, solution="flipped", limits=((-np.pi, np.pi), None))
    expected = np.stack([hadec[:, 0] + np.pi, np.pi - hadec[:, 1]], -1)
    expected[:, 0] = (expected[:, 0] + np.pi) % (2 * np.pi) - np.pi
    np.testing.assert_allclose(np.asarray(flipped.reading), expected, atol=1e-12)
    assert normal.axis_names == ("ha", "dec")


def test_fit_recovers_simulated_parameters_from_both_pier_sides():
    lat = np.radians(-29.25)
    hadec, _ = sky_hadec(60, lat, min_elevation_deg=20.0, seed=8)
    # Half the stars observed on the other pier side.
    enc = hadec.copy()
    enc[1::2] = np.stack([hadec[1::2, 0] + np.pi, np.pi - hadec[1::2, 1]], -1)
    obs = px.simulate(equatorial_model(lat, TRUTH), enc, noise=1.0 * ARCSEC, seed=9)
    assert obs.convention == "ha-dec"
    result = px.fit(equatorial_model(lat), obs)
    assert bool(result.converged), result.report()
    for name, value in TRUTH.items():
        assert abs(result.value(name) - value) < 4 * result.sigma(name), (name, result.value(name), result.sigma(name))
    assert 0.7 < float(result.sky_rms) / ARCSEC / np.sqrt(2) < 1.3


def test_latitude_is_checked_and_traceable():
    with pytest.raises(ValueError, match="latitude 2.0 rad is not within"):
        EquatorialMount(2.0)
    with pytest.raises(ValueError, match="one number"):
        EquatorialMount([0.1, 0.2])
    with pytest.raises(ValueError, match="give the site's latitude"):
        Equatorial([])
    assert EquatorialMount(0.3).convention == "ha-dec"

    # One compiled function serves many latitudes (latitude is a pytree leaf).
    def zenith_dec(lat):
        model = px.Model(EquatorialMount(lat))
        return model.direction(jnp.array([0.0, lat]))

    lats = jnp.array([-0.5, 0.1, 0.9])
    np.testing.assert_allclose(np.asarray(jax.vmap(zenith_dec)(lats)), np.tile([0.0, 0.0, 1.0], (3, 1)), atol=1e-15)

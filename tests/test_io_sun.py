"""The sun-observation text format of turntable calibrations (pointax.io.sun).

References: the direction of (azimuth, elevation) written out here in NumPy; the
sun-vector paper's Table 1 and its fitted values (DESIGN.md); a turntable simulated
with the paper's formula in NumPy (``simulated_site``, also used by the network and
distributed tests).
"""

from __future__ import annotations

import numpy as np
import pytest

import pointax as px
from pointax.io.sun import (
    SunFormatError,
    format_sun_observations,
    parse_sun_observations,
    read_sun_observations,
    write_sun_observations,
)

# The paper's Table 1: sun altitude, azimuth, encoder pitch and azimuth, degrees.
ALTITUDE = [50.469, 52.704, 53.210, 53.704, 53.965, 54.187, 49.208, 46.623]
AZIMUTH = [141.022, 147.820, 148.951, 150.703, 151.689, 152.562, 222.086, 227.280]
PITCH = [216.460, 218.653, 219.173, 219.656, 219.964, 220.118, 215.150, 212.557]
AZ_ENCODER = [279.436, 272.655, 271.506, 269.764, 268.775, 267.830, 198.259, 193.104]
# DESIGN.md: fitting the 8 rows gives these (degrees).
TABLE1_FIT = {"mu0": 0.075, "nu0": 0.014, "omega0": -0.095, "alpha0": 60.542, "beta0": 165.893}

PAPER_TRUTH_DEG = (0.0751, 0.0145, -0.0947, 60.5425, 165.8931)  # mu0 nu0 omega0 alpha0 beta0


# ------------------------------------------------------------- a simulated turntable


def paper_direction(p, alpha, beta):
    """S = Rx(mu0) Ry(nu0) Rz'(alpha0 - alpha) Ry(omega0) Rx(beta - beta0) (0, 1, 0),
    the paper's formula, vectorised over observations; Rz'(t) = [[c, s, 0], [-s, c, 0], [0, 0, 1]]."""
    mu0, nu0, omega0, alpha0, beta0 = p
    b, a = beta - beta0, alpha0 - alpha
    x, y, z = np.zeros_like(b), np.cos(b), np.sin(b)  # Rx(b) (0, 1, 0)
    x, z = np.cos(omega0) * x + np.sin(omega0) * z, -np.sin(omega0) * x + np.cos(omega0) * z  # Ry(omega0)
    x, y = np.cos(a) * x + np.sin(a) * y, -np.sin(a) * x + np.cos(a) * y  # Rz'(a)
    x, z = np.cos(nu0) * x + np.sin(nu0) * z, -np.sin(nu0) * x + np.cos(nu0) * z  # Ry(nu0)
    y, z = np.cos(mu0) * y - np.sin(mu0) * z, np.sin(mu0) * y + np.cos(mu0) * z  # Rx(mu0)
    return np.stack([x, y, z], axis=-1)


def simulated_site(seed: int, n: int = 60, noise_deg: float = 0.02):
    """A turntable near the paper's geometry following the sun for a day (elevation
    above 10 deg), Gaussian noise on the sky. Returns (Observations, truth radians)."""
    rng = np.random.default_rng(seed)
    truth = np.radians(np.asarray(PAPER_TRUTH_DEG) + rng.normal(0, [0.02, 0.02, 0.03, 5.0, 1.0]))
    lat, dec = np.radians(rng.uniform(20, 50)), np.radians(rng.uniform(-23, 23))
    cos_hmax = (np.sin(np.radians(10)) - np.sin(lat) * np.sin(dec)) / (np.cos(lat) * np.cos(dec))
    hour = np.sort(rng.uniform(-1, 1, n)) * np.arccos(np.clip(cos_hmax, -1, 1))
    el = np.arcsin(np.sin(lat) * np.sin(dec) + np.cos(lat) * np.cos(dec) * np.cos(hour))
    az = np.arctan2(-np.cos(dec) * np.sin(hour), np.sin(dec) * np.cos(lat) - np.cos(dec) * np.sin(lat) * np.cos(hour))
    encoder = np.stack([(truth[3] - az) % (2 * np.pi), truth[4] + el], axis=1)  # nominal pointing at the sun
    s = paper_direction(truth, encoder[:, 0], encoder[:, 1])
    s_az, s_el = np.arctan2(s[:, 0], s[:, 1]), np.arcsin(s[:, 2])
    e_az = np.stack([np.cos(s_az), -np.sin(s_az), 0 * s_az], axis=1)
    e_el = np.stack([-np.sin(s_el) * np.sin(s_az), -np.sin(s_el) * np.cos(s_az), np.cos(s_el)], axis=1)
    noise = rng.normal(0, np.radians(noise_deg), (n, 2))
    target = s + noise[:, :1] * e_az + noise[:, 1:] * e_el
    target /= np.linalg.norm(target, axis=1, keepdims=True)
    return px.Observations(encoder, target, convention="turntable"), truth


def sun_azel(obs) -> np.ndarray:
    """``(n, 2)`` azimuth (North through East) and elevation of the observed directions."""
    t = np.asarray(obs.target)
    return np.stack([np.arctan2(t[:, 0], t[:, 1]) % (2 * np.pi), np.arcsin(t[:, 2])], axis=1)


# ------------------------------------------------------------- reading


def test_reads_columns_comments_and_weights(tmp_path):
    text = (
        "# turntable 7, calibration day\n"
        "# alpha_deg beta_deg sun_az_deg sun_el_deg [weight]\n"
        "\n"
        "279.436 216.460 141.022 50.469\n"
        "272.655, 218.653, 147.820, 52.704, 0.5   # a trailing comment\n"
        "  198.259\t215.150 222.086 49.208 0\n"
    )
    path = tmp_path / "t7.txt"
    path.write_text(text)
    run = read_sun_observations(path)
    assert len(run) == 3 and run.path == str(path)
    assert run.comments == ("turntable 7, calibration day", "alpha_deg beta_deg sun_az_deg sun_el_deg [weight]")
    np.testing.assert_array_equal(run.lines, [4, 5, 6])
    np.testing.assert_array_equal(run.weight, [1.0, 0.5, 0.0])
    deg = np.array([[279.436, 216.460, 141.022, 50.469], [272.655, 218.653, 147.820, 52.704], [198.259, 215.150, 222.086, 49.208]])
    np.testing.assert_allclose(run.encoder, deg[:, :2] * np.pi / 180, rtol=0, atol=1e-15)
    az, el = deg[:, 2] * np.pi / 180, deg[:, 3] * np.pi / 180
    enu = np.stack([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)], axis=1)
    obs = run.observations
    assert obs.convention == "turntable"
    np.testing.assert_allclose(np.asarray(obs.target), enu, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(np.asarray(obs.weight), run.weight)


def test_round_trip_keeps_the_numbers(tmp_path):
    obs, _ = simulated_site(3, n=20)
    weight = np.linspace(0.5, 1.5, 20)
    path = tmp_path / "site.txt"
    write_sun_observations(path, obs.encoder, sun_azel(obs), weight, comments=["simulated"])
    run = read_sun_observations(path)
    assert run.comments[0] == "simulated"
    # Nine decimals of a degree: 1.7e-11 rad.
    np.testing.assert_allclose(run.encoder, np.asarray(obs.encoder), rtol=0, atol=2e-11)
    np.testing.assert_allclose(np.asarray(run.observations.target), np.asarray(obs.target), rtol=0, atol=3e-11)
    np.testing.assert_allclose(run.weight, weight, rtol=1e-11)


def test_paper_table1_file_fits_to_the_papers_values():
    """The format's conventions (sun azimuth North through East, encoders as read) give
    the paper's own parameters from its Table 1."""
    text = "".join(f"{a} {p} {az} {alt}\n" for a, p, az, alt in zip(AZ_ENCODER, PITCH, AZIMUTH, ALTITUDE))
    run = parse_sun_observations(text, "table1.txt")
    result = px.fit(px.Turntable("full", start=run.observations), run.observations)
    assert bool(result.converged)
    for name, value in TABLE1_FIT.items():
        assert result.value(name) == pytest.approx(value, abs=0.0015), name


# ------------------------------------------------------------- errors


@pytest.mark.parametrize(
    "line, match",
    [
        ("1 2 3", r"bad\.txt:3: expected 4 or 5 numbers .* got 3"),
        ("1 2 3 4 5 6", r"bad\.txt:3: expected 4 or 5 numbers .* got 6"),
        ("1 2 east 4", r"bad\.txt:3: column 3 \(sun_az_deg\): 'east' is not a number"),
        ("1 nan 3 4", r"bad\.txt:3: column 2 \(beta_deg\): 'nan' is not finite"),
        ("1 2 3 95", r"bad\.txt:3: column 4 \(sun_el_deg\): elevation 95 is outside -90..90 deg"),
        ("1 2 3 4 -1", r"bad\.txt:3: column 5 \(weight\): weight -1 is negative"),
    ],
)
def test_bad_lines_name_file_line_and_column(line, match):
    text = "# header\n10 200 150 40\n" + line + "\n"
    with pytest.raises(SunFormatError, match=match):
        parse_sun_observations(text, "bad.txt")


def test_empty_missing_and_binary_files(tmp_path):
    with pytest.raises(SunFormatError, match=r"empty\.txt: no observations"):
        parse_sun_observations("# only a comment\n\n", "empty.txt")
    with pytest.raises(FileNotFoundError):
        read_sun_observations(tmp_path / "absent.txt")
    binary = tmp_path / "binary.txt"
    binary.write_bytes(b"\xff\xfe\x00\x81garbage")
    with pytest.raises(SunFormatError, match="binary.txt: not a text file"):
        read_sun_observations(binary)
    with pytest.raises(ValueError, match="shape"):
        format_sun_observations(np.zeros((3, 2)), np.zeros((4, 2)))

"""Issue 30: which reading the inverse commands (cable wrap, ``near``) and what
``pointax command`` does with a model file, ``--near`` and azimuth conventions.

Reference: the forward model (``model(reading)`` must point at the direction) and the
readings' distance from the middle of the limits or from ``near``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import pointax as px
from pointax.cli import main
from pointax.core.rotations import azel_to_enu_numpy

from numpy_rotations import angle_between
from conftest import MMT_MOD

VALUES = {"IA": 25.0, "IE": -18.0, "CA": 14.0, "NPAE": -6.0, "AN": 11.0, "AW": -9.0, "TF": 22.0}


def _model():
    return px.AltAz(px.terms.tpoint(" ".join(VALUES), values={k: px.arcsec(v) for k, v in VALUES.items()}))



@pytest.mark.parametrize(
    "limits_deg, az, expected",
    [
        # A cable wrap of -270..270 deg: azimuth 90 is commanded to ~90, not ~-270 (the
        # end of the wrap); 265 to ~-95 (nearer the middle than 265).
        ((-270.0, 270.0), [90.0, 265.0, -100.0, 170.0], [90.0, -95.0, -100.0, 170.0]),
        ((0.0, 360.0), [90.0, 350.0, 5.0], [90.0, 350.0, 5.0]),
        ((-180.0, 540.0), [90.0, 350.0, 10.0, 300.0], [90.0, 350.0, 10.0, 300.0]),
    ],
    ids=["-270..270", "0..360", "-180..540"],
)
def test_default_branch_is_nearest_the_middle_of_the_limits(limits_deg, az, expected):
    model = _model()
    d = azel_to_enu_numpy(np.radians(az), np.radians(np.full(len(az), 35.0)))
    c = px.command(model, d, limits=(np.radians(limits_deg), None))
    assert bool(np.all(np.asarray(c.ok))), c.reasons()
    reading = np.asarray(c.reading)
    np.testing.assert_allclose(np.degrees(reading[:, 0]), expected, atol=0.05)
    assert np.max(angle_between(np.asarray(model(reading)), d)) < 1e-10


def test_near_picks_the_branch_and_the_twin():
    model = _model()
    limits = (np.radians([-270.0, 270.0]), np.radians([0.0, 180.0]))
    d = azel_to_enu_numpy(np.radians([90.0, 90.0, 90.0]), np.radians([0.7, 0.7, 60.0]))
    near = np.radians([[-250.0, 1.0], [80.0, 1.0], [-80.0, 150.0]])
    c = px.command(model, d, limits=limits, near=near)
    assert bool(np.all(np.asarray(c.ok))), c.reasons()
    reading = np.degrees(np.asarray(c.reading))
    np.testing.assert_allclose(reading[:2, 0], [-270.0, 90.0], atol=0.05)
    assert np.all(reading[:2, 1] < 1.0)  # the normal solution, at the horizon
    # Near an over-the-top reading: the twin (az - 180, 180 - el) is nearer.
    np.testing.assert_allclose(reading[2], [-90.0, 120.0], atol=0.05)
    assert int(np.asarray(c.solution)[2]) == 1
    assert np.max(angle_between(np.asarray(model(np.asarray(c.reading))), d)) < 1e-10
    # Without near at 0.7 deg: the normal solution, never over the top.
    c = px.command(model, d[:2], limits=limits)
    assert np.all(np.asarray(c.solution) == 0) and np.all(np.degrees(np.asarray(c.reading))[:, 1] < 1.0)


# ------------------------------------------------------------------ pointax command


def _mmt():
    return px.io.read_model(MMT_MOD).model(azimuth="N-E")


def test_cli_model_without_mount_is_altaz(tmp_path, capsys):
    path = tmp_path / "dirs.txt"
    path.write_text("90 30\n10 0.7\n200 75\n")
    assert main(["command", str(path), "--model", str(MMT_MOD), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    model = _mmt()
    for row in out:
        assert row["input_azimuth"] == "N-E" and row["reading_azimuth"] == "N-E"
        reading = np.radians([row["az_deg"], row["el_deg"]])
        wanted = azel_to_enu_numpy(*np.radians(row["input_deg"]))
        assert angle_between(np.asarray(model(reading)), wanted) < 1e-9


def test_cli_turntable_with_model_file_is_an_error(tmp_path, capsys):
    path = tmp_path / "dirs.txt"
    path.write_text("90 30\n")
    assert main(["command", str(path), "--model", str(MMT_MOD), "--mount", "turntable"]) == 2
    assert "not turntable" in capsys.readouterr().err


def test_cli_equatorial_model_needs_mount_and_latitude(tmp_path, capsys):
    path = tmp_path / "dirs.txt"
    path.write_text("90 30\n")
    mod = tmp_path / "eq.mod"
    mod.write_text("Equatorial model\nT   80   0.9318   42.060  -0.0485\n  IH   +120.0  1.0\n  ID   -30.0  1.0\nEND\n")
    assert main(["command", str(path), "--model", str(mod)]) == 2
    assert "--latitude" in capsys.readouterr().err
    assert main(["command", str(path), "--model", str(mod), "--mount", "equatorial"]) == 2
    assert "--latitude" in capsys.readouterr().err
    assert main(["command", str(path), "--model", str(mod), "--mount", "equatorial", "--latitude", "31.7", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)[0]
    model = px.io.read_model(mod).model(mount="equatorial", latitude=np.radians(31.7))
    reading = np.radians([row["ha_deg"], row["dec_deg"]])
    assert angle_between(np.asarray(model(reading)), azel_to_enu_numpy(*np.radians([90.0, 30.0]))) < 1e-9


def test_cli_near_and_cable_wrap(tmp_path, capsys):
    path = tmp_path / "dirs.txt"
    path.write_text("90 30\n")
    base = ["command", str(path), "--model", str(MMT_MOD), "--limits=-270,270,,", "--json"]
    assert main(base) == 0
    default = json.loads(capsys.readouterr().out)[0]["az_deg"]
    assert main(base + ["--near=-200,45"]) == 0
    near = json.loads(capsys.readouterr().out)[0]["az_deg"]
    assert abs(default - 90.0) < 1.0 and abs(near + 270.0) < 1.0
    assert main(base + ["--near", "x"]) == 2
    assert "--near" in capsys.readouterr().err


def test_cli_table_names_azimuth_conventions(tmp_path, capsys):
    path = tmp_path / "dirs.txt"
    path.write_text("90 30\n")
    assert main(["command", str(path), "--model", str(MMT_MOD), "--azimuth", "S-E"]) == 0
    out = capsys.readouterr().out
    assert "azimuth N-E (from North through East)" in out and "az in the S-E convention" in out

"""``pointax centroid``: PNG (8 and 16 bit), FITS and .npy frames in, per-frame centre,
radius, method, status and reason out; exit codes 0 / 1 / 2."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("kornia")
Image = pytest.importorskip("PIL.Image")

from astropy.io import fits  # noqa: E402

from pointax.cli.centroid import add_centroid_parser, run_centroid  # noqa: E402
from pointax.sunsensor.frames import Detector, synthetic_frames  # noqa: E402
from pointax.sunsensor.imageio import FrameReadError, read_frame  # noqa: E402

X, Y = [300.27, 811.64, 640.05], [200.81, 700.33, 512.5]


def parse(argv):
    parser = argparse.ArgumentParser(prog="pointax")
    add_centroid_parser(parser.add_subparsers(dest="command", required=True))
    return parser.parse_args(["centroid", *argv])


def run(argv, capsys):
    code = run_centroid(parse(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """The same three suns as 16-bit PNG, 8-bit PNG, FITS (uint16 via BZERO) and .npy."""
    root = tmp_path_factory.mktemp("frames")
    f16 = synthetic_frames(X, Y, seed=1)
    f8 = synthetic_frames(X, Y, seed=1, detector=Detector(bits=8, gain=40.0, read_noise=8.0, bias=2.0))
    paths = {}
    for k in range(3):
        paths[f"png16_{k}"] = root / f"sun{k}_16.png"
        Image.fromarray(f16.images[k]).save(paths[f"png16_{k}"])
        paths[f"png8_{k}"] = root / f"sun{k}_8.png"
        Image.fromarray(f8.images[k]).save(paths[f"png8_{k}"])
        paths[f"fits_{k}"] = root / f"sun{k}.fits"
        fits.PrimaryHDU(f16.images[k]).writeto(paths[f"fits_{k}"])
        paths[f"npy_{k}"] = root / f"sun{k}.npy"
        np.save(paths[f"npy_{k}"], f16.images[k])
    paths["empty"] = root / "empty.npy"
    np.save(paths["empty"], np.full((1024, 1280), 40, np.uint16))
    paths["colour"] = root / "colour.png"
    Image.fromarray(np.zeros((64, 64, 3), np.uint8)).save(paths["colour"])
    paths["garbage"] = root / "garbage.png"
    paths["garbage"].write_bytes(b"not a png at all")
    paths["text"] = root / "frame.txt"
    paths["text"].write_text("1 2 3")
    return {k: str(v) for k, v in paths.items()}, f16


def test_readers_return_the_stored_frames(files):
    paths, f16 = files
    for key in ("png16_0", "fits_0", "npy_0"):
        frame = read_frame(paths[key])
        assert frame.dtype == np.uint16, key
        np.testing.assert_array_equal(frame, f16.images[0])
    assert read_frame(paths["png8_0"]).dtype == np.uint8
    for key, words in [("colour", "one channel"), ("garbage", "not a readable PNG"), ("text", "unknown frame format")]:
        with pytest.raises(FrameReadError, match=words) as err:
            read_frame(paths[key])
        assert paths[key] in str(err.value)
    with pytest.raises(FrameReadError, match="no such file"):
        read_frame(paths["text"] + ".missing.npy")


@pytest.mark.parametrize("kind, saturation", [("png16", "4095"), ("png8", None), ("fits", "4095"), ("npy", "4095")])
def test_json_output_has_the_centres_of_every_format(files, capsys, kind, saturation):
    paths, _ = files
    argv = [paths[f"{kind}_{k}"] for k in range(3)] + ["--json"] + (["--saturation", saturation] if saturation else [])
    code, out, _ = run(argv, capsys)
    assert code == 0
    rows = json.loads(out)
    assert [r["frame"] for r in rows] == [paths[f"{kind}_{k}"] for k in range(3)]
    for r, x, y in zip(rows, X, Y):
        assert set(r) == {"frame", "x", "y", "radius", "method", "status", "reason"}
        assert r["status"] == "ok" and r["reason"] == "" and r["method"] == "intensity"
        # Origin at the centre of the top-left pixel, x right, y down: the frames' truth.
        assert abs(r["x"] - x) < 0.03 and abs(r["y"] - y) < 0.03
        assert 13.5 < r["radius"] < 17.5


def test_bad_frames_exit_1_and_bad_input_exit_2_but_every_frame_is_reported(files, capsys):
    paths, _ = files
    code, out, _ = run([paths["npy_0"], paths["empty"], "--json", "--saturation", "4095"], capsys)
    rows = json.loads(out)
    assert code == 1
    assert rows[0]["status"] == "ok" and rows[1]["status"] == "no_sun" and rows[1]["x"] is None
    assert "no sun" in rows[1]["reason"]
    code, out, err = run([paths["npy_0"], paths["garbage"], paths["colour"], "--json"], capsys)
    rows = json.loads(out)
    assert code == 2
    assert [r["status"] for r in rows] == ["ok", "bad_input", "bad_input"]
    assert paths["garbage"] in rows[1]["reason"] and paths["garbage"] in err
    assert "one channel" in rows[2]["reason"]
    code, _, err = run([paths["npy_0"], "--radius", "-3"], capsys)
    assert code == 2 and "--radius" in err


def test_text_output_and_methods(files, capsys):
    paths, _ = files
    code, out, _ = run([paths["npy_1"], paths["empty"], "--method", "limb", "--saturation", "4095"], capsys)
    lines = out.strip().splitlines()
    assert code == 1 and lines[0].split()[:4] == ["frame", "x", "y", "radius"]
    assert "limb" in lines[1] and "ok" in lines[1] and f"{X[1]:.1f}" in lines[1]
    assert "no_sun: no sun" in lines[2]


def test_parser_is_light_and_the_stand_alone_entry_point_runs(files, capsys):
    import subprocess
    import sys

    from pointax.sunsensor.centroids import METHODS as CENTROID_METHODS
    from pointax.cli.centroid import METHODS, main

    assert METHODS == CENTROID_METHODS
    # Building the `pointax` parser must not import torch (the lead wires it into
    # pointax.cli, which every `pointax fit` imports).
    code = "import sys, pointax.cli.centroid; sys.exit('torch' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0
    paths, _ = files
    assert main([paths["npy_2"], "--saturation", "4095"]) == 0
    assert "intensity" in capsys.readouterr().out


def test_the_pointax_command_end_to_end(files):
    """Through the installed entry point (a subprocess), as a user runs it."""
    import subprocess
    import sys

    paths, _ = files
    npy = [paths[f"npy_{k}"] for k in range(len(X))]
    proc = subprocess.run(
        [sys.executable, "-m", "pointax", "centroid", *npy, "--json", "--saturation", "4095"], capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    rows = json.loads(proc.stdout)
    assert [r["status"] for r in rows] == ["ok"] * len(npy)
    assert np.max(np.abs([r["x"] for r in rows] - np.array(X))) < 0.05
    assert np.max(np.abs([r["y"] for r in rows] - np.array(Y))) < 0.05

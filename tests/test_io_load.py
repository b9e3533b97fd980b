"""pointax.io.load_run and detect_format: one reader for every run format, the format
told from the file.

References: the format readers themselves (read_tpoint, read_gpoint, read_paint,
read_sun_observations, read_xy_run) on the same files; the bundled runs, whose formats
are known.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import EXAMPLES, MMT_DAT, REPO

import pointax as px
from pointax.io import (
    RUN_FORMATS,
    FormatDetectionError,
    GpointRun,
    PaintRun,
    SunRun,
    TpointRun,
    XYRun,
    detect_format,
    load_run,
    read_gpoint,
    read_sun_observations,
    read_tpoint,
    read_xy_run,
    write_xy_run,
)

GPOINT_SAMPLE = Path(__file__).parent / "data" / "gpoint" / "altaz_manual.txt"
SUN_SITE = EXAMPLES / "data" / "network" / "ts-01.txt"


def same_observations(a, b):
    np.testing.assert_array_equal(np.asarray(a.encoder), np.asarray(b.encoder))
    np.testing.assert_array_equal(np.asarray(a.target), np.asarray(b.target))
    np.testing.assert_array_equal(np.asarray(a.weight), np.asarray(b.weight))
    assert a.convention == b.convention


@pytest.fixture
def xy_file(tmp_path):
    obs = px.Observations(
        np.radians([[10.0, 20.0], [30.0, -5.0], [200.0, 45.0]]),
        np.array([[0.1, 0.2, 0.97467943], [0.3, 0.1, 0.94868330], [-0.5, 0.7, 0.50990195]]),
        convention="xy",
    )
    path = tmp_path / "run.xy"
    write_xy_run(path, obs, comments=("three stars",))
    return path


def test_formats_of_the_bundled_files(xy_file):
    assert detect_format(MMT_DAT) == "tpoint"
    assert detect_format(GPOINT_SAMPLE) == "gpoint"
    assert detect_format(SUN_SITE) == "sun"
    assert detect_format(xy_file) == "xy"
    assert detect_format(EXAMPLES / "data") == "paint"  # a folder
    assert set(RUN_FORMATS) == {"tpoint", "gpoint", "paint", "sun", "xy", "offsets"}
    assert detect_format(REPO / "tests" / "data" / "offsets" / "radio_xel.csv") == "offsets"


def test_formats_of_the_shared_files(shared_data):
    assert detect_format(shared_data / "tpoint" / "mmt_20210821.dat") == "tpoint"
    for path in sorted((shared_data / "tpoint" / "equatorial").glob("*.dat")):
        assert detect_format(path) == "tpoint", path
    assert detect_format(shared_data / "paint" / "AA39") == "paint"


def test_load_run_reads_each_format_as_its_reader(xy_file):
    run = load_run(MMT_DAT, azimuth="S-E")
    assert isinstance(run, TpointRun) and run.azimuth == "S-E"
    same_observations(run.observations, read_tpoint(MMT_DAT, azimuth="S-E").observations)
    assert load_run(MMT_DAT, "tpoint").azimuth == "N-E"

    run = load_run(GPOINT_SAMPLE)
    assert isinstance(run, GpointRun)
    same_observations(run.observations, read_gpoint(GPOINT_SAMPLE).observations)

    run = load_run(SUN_SITE)
    assert isinstance(run, SunRun)
    same_observations(run.observations, read_sun_observations(SUN_SITE).observations)

    run = load_run(xy_file)
    assert isinstance(run, XYRun) and run.path == str(xy_file)
    same_observations(run.observations, read_xy_run(xy_file))


def test_load_run_reads_a_paint_folder(shared_data):
    from pointax.io import read_paint

    folder = shared_data / "paint" / "AA39"
    run = load_run(folder, focal_spot="UTIS")
    assert isinstance(run, PaintRun)
    same_observations(run.observations, read_paint(folder, focal_spot="UTIS").observations)


def test_sun_and_xy_files_told_apart_by_a_weight_column_or_their_comments(tmp_path):
    five = tmp_path / "five.txt"
    five.write_text("1 2 3 4 0.5\n5 6 7 8\n")
    assert detect_format(five) == "sun"
    sun = tmp_path / "sun.txt"
    sun.write_text("# alpha_deg beta_deg sun_az_deg sun_el_deg\n1 2 3 4\n")
    assert detect_format(sun) == "sun"
    xy = tmp_path / "xy.txt"
    xy.write_text("# L B L0 B0\n1 2 3 4\n")
    assert detect_format(xy) == "xy"


def test_a_format_that_cannot_be_told_is_refused_naming_the_file_and_the_formats(tmp_path):
    four = tmp_path / "four.txt"
    four.write_text("1 2 3 4\n5 6 7 8\n")
    with pytest.raises(FormatDetectionError) as info:
        load_run(four)
    message = str(info.value)
    assert str(four) in message and "L B L0 B0" in message
    assert all(name in message for name in RUN_FORMATS)
    prose = tmp_path / "notes.txt"
    prose.write_text("hello\nworld\n")
    with pytest.raises(FormatDetectionError, match="cannot tell the format"):
        detect_format(prose)
    empty = tmp_path / "empty.txt"
    empty.write_text("")
    with pytest.raises(FormatDetectionError, match="empty file"):
        detect_format(empty)
    binary = tmp_path / "frame.npy"
    binary.write_bytes(b"\x93NUMPY\x01\x00\0\0")
    with pytest.raises(FormatDetectionError, match="not a text file"):
        detect_format(binary)


def test_a_missing_file_and_wrong_arguments(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.dat"):
        load_run(tmp_path / "missing.dat")
    with pytest.raises(FormatDetectionError, match="unknown format 'fits'"):
        load_run(MMT_DAT, "fits")
    with pytest.raises(ValueError, match="azimuth do not apply to gpoint runs"):
        load_run(GPOINT_SAMPLE, azimuth="S-E")


def test_a_broken_tpoint_file_is_still_told_tpoint_and_its_reader_says_why(tmp_path):
    bad = tmp_path / "bad.dat"
    bad.write_text("caption\n: ALTAZ\n+31 41 19.6\n10 20 30 4x\n")
    assert detect_format(bad) == "tpoint"
    with pytest.raises(px.io.TpointFormatError, match="bad.dat:4:"):
        load_run(bad)


def test_the_command_line_tells_the_format_from_the_file(capsys):
    """``pointax fit`` without --format routes a gpoint file to gpoint's checks, and
    refuses a sun file naming the command that fits it (no fit needed)."""
    from pointax.cli import main

    assert main(["fit", str(GPOINT_SAMPLE), "--azimuth", "S-E"]) == 2
    assert "South through West" in capsys.readouterr().err
    assert main(["fit", str(SUN_SITE)]) == 2
    err = capsys.readouterr().err
    assert str(SUN_SITE) in err and "fit-network" in err

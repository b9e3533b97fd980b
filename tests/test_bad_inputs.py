"""A corpus of bad inputs (issue 20, items 1-4): every case must give a clear error
(naming the file, the line and the field where it has them), a warning that does, or a
flag (a status, an ``ok=False``, a fit warning). None may pass silently or give a
traceback of another kind.

The cases are built from real files: the bundled MMT TPOINT run and model
(``examples/data``), the gpoint sample (``tests/data/gpoint``), the PAINT heliostat
AA39 (``../shared/data/paint``, skipped when absent), and sun and X-Y files written
here. ``test_corpus_counts`` prints the counts of cases, clear errors and flags.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
import shutil
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import pointax as px
from pointax.io import FileFormatError, InputWarning

from conftest import EXAMPLES, MMT_DAT, SHARED_DATA

MMT_MOD = EXAMPLES / "data" / "mmt_20210821.mod"
GPOINT = Path(__file__).parent / "data" / "gpoint" / "altaz_manual.txt"
PAINT = SHARED_DATA / "paint" / "AA39"
FIRST_OBS = 21  # line of the MMT file's first observation record


@dataclasses.dataclass(frozen=True)
class Case:
    """``run(tmp_path)`` does the bad thing; ``kind`` says what must come of it:
    'error' (an exception of ``error`` whose message matches every pattern), 'warning'
    (an InputWarning whose message matches) or 'flag' (``run`` returns the flag's text,
    which must match)."""

    name: str
    kind: str
    run: Callable
    patterns: tuple[str, ...]
    error: type = ValueError
    needs: Path | None = None


CASES: list[Case] = []


def case(name, kind, *patterns, error=ValueError, needs=None):
    def register(fn):
        CASES.append(Case(name, kind, fn, patterns, error, needs))
        return fn

    return register


# ------------------------------------------------------------------ TPOINT runs


def _mmt_lines() -> list[str]:
    return MMT_DAT.read_text().splitlines()


def _write(tmp: Path, name: str, lines) -> Path:
    path = tmp / name
    path.write_text("\n".join(lines) + "\n")
    return path


def _mmt_with(tmp: Path, line: int, fields: dict[int, str] | None = None, text: str | None = None) -> Path:
    lines = _mmt_lines()
    if text is not None:
        lines[line - 1] = text
    else:
        tokens = lines[line - 1].split()
        for k, v in (fields or {}).items():
            tokens[k - 1] = v
        lines[line - 1] = " ".join(tokens)
    return _write(tmp, "run.dat", lines)


def _read_run(path):
    return px.io.read_tpoint(path, azimuth="S-E")


for _field, _value, _what in [
    (1, "400.0", "field 1 \\(observed azimuth\\).*outside -360..360"),
    (1, "-365.5", "field 1 \\(observed azimuth\\).*outside -360..360"),
    (3, "-400.0", "field 3 \\(raw azimuth\\).*outside -360..360"),
    (2, "95.0", "field 2 \\(observed elevation\\).*outside -90..90"),
    (2, "-5.0", "field 2 \\(observed elevation\\).*below the horizon"),
    (4, "200.0", "field 4 \\(raw elevation\\).*outside -90..180"),
    (2, "abc", "field 2 \\(observed elevation\\).*not a number"),
    (3, "nan", "field 3 \\(raw azimuth\\).*not finite"),
    (4, "inf", "field 4 \\(raw elevation\\).*not finite"),
    (1, "1,5", "field 1 \\(observed azimuth\\).*not a number"),
]:

    @case(f"tpoint-field{_field}-{_value}", "error", rf"run\.dat:{FIRST_OBS}:", _what, error=FileFormatError)
    def _(tmp, f=_field, v=_value):
        _read_run(_mmt_with(tmp, FIRST_OBS, {f: v}))


@case("tpoint-three-fields", "error", rf"run\.dat:{FIRST_OBS}:", "3 fields", error=FileFormatError)
def _(tmp):
    _read_run(_mmt_with(tmp, FIRST_OBS, text="192.3 77.3 -167.2"))


@case("tpoint-eight-fields", "error", rf"run\.dat:{FIRST_OBS}:", "8 fields", error=FileFormatError)
def _(tmp):  # four fields and four trailing numbers: one more than TPOINT's three auxiliary readings
    _read_run(_mmt_with(tmp, FIRST_OBS, text="192.3 77.3 -167.2 77.3 1 2 3 4"))


@case("tpoint-mixed-columns", "error", rf"run\.dat:{FIRST_OBS + 1}:", "5 fields, earlier records have 4", error=FileFormatError)
def _(tmp):
    _read_run(_mmt_with(tmp, FIRST_OBS + 1, text="193.3 77.28 -166.27 77.28 10.0"))


@case("tpoint-in-radians", "error", rf"run\.dat:{FIRST_OBS}:", "look like radians", "field 2 \\(observed elevation\\)", error=FileFormatError)
def _(tmp):
    lines = _mmt_lines()
    for k in range(FIRST_OBS - 1, len(lines)):
        tokens = lines[k].split()
        if len(tokens) == 4 and not lines[k].startswith("!"):
            lines[k] = " ".join(f"{math.radians(float(t)):.9f}" for t in tokens)
    _read_run(_write(tmp, "run.dat", lines))


@case("tpoint-row-twice", "warning", rf"run\.dat:{FIRST_OBS + 1}:", f"line {FIRST_OBS + 1} = line {FIRST_OBS}", "counted as an observation")
def _(tmp):
    lines = _mmt_lines()
    lines.insert(FIRST_OBS, lines[FIRST_OBS - 1])
    _read_run(_write(tmp, "run.dat", lines))


@case("tpoint-every-row-twice", "warning", r"run\.dat:\d+:", "80 of 160 observation records repeat")
def _(tmp):
    lines = _mmt_lines()
    _read_run(_write(tmp, "run.dat", lines[: FIRST_OBS - 1] + lines[FIRST_OBS - 1 :] * 2))


@case("tpoint-rows-after-end", "warning", rf"run\.dat:{FIRST_OBS + 3}:", "after END .* were ignored")
def _(tmp):
    lines = _mmt_lines()
    lines.insert(FIRST_OBS + 1, "END")
    _read_run(_write(tmp, "run.dat", lines))


@case("tpoint-no-altaz", "error", r"run\.dat:19:", "ALTAZ", error=FileFormatError)
def _(tmp):
    lines = [line for line in _mmt_lines() if line.strip() != ": ALTAZ"]
    path = _write(tmp, "run.dat", lines)
    _read_run(path)


@case("tpoint-bad-latitude", "error", r"run\.dat:20:", "latitude .* not a valid d m s", error=FileFormatError)
def _(tmp):
    _read_run(_mmt_with(tmp, 20, {2: "61"}))


@case("tpoint-bad-month", "error", r"run\.dat:20:", "date .* not year month day", error=FileFormatError)
def _(tmp):
    _read_run(_mmt_with(tmp, 20, {5: "13"}))


@case("tpoint-empty", "error", r"run\.dat: ", "empty file", error=FileFormatError)
def _(tmp):
    _read_run(_write(tmp, "run.dat", ["! only a comment"]))


@case("tpoint-no-observations", "error", r"run\.dat: ", "no observation records", error=FileFormatError)
def _(tmp):
    _read_run(_write(tmp, "run.dat", _mmt_lines()[:FIRST_OBS - 1]))


@case("tpoint-binary", "error", r"run\.dat: ", "not a text file", error=FileFormatError)
def _(tmp):
    path = tmp / "run.dat"
    path.write_bytes(b"\xff\xfe\x00\x81 binary \x00")
    _read_run(path)


@case("tpoint-option-after-parameters", "error", rf"run\.dat:{FIRST_OBS}:", "option record", error=FileFormatError)
def _(tmp):
    _read_run(_mmt_with(tmp, FIRST_OBS, text=": NODA"))


# ------------------------------------------------------------------ TPOINT models


def _mod_with(tmp: Path, line: int, text: str | None = None, insert: bool = False, drop: bool = False) -> Path:
    lines = MMT_MOD.read_text().splitlines()
    if drop:
        del lines[line - 1]
    elif insert:
        lines.insert(line - 1, text)
    else:
        lines[line - 1] = text
    return _write(tmp, "model.mod", lines)


for _line, _text, _what in [
    (3, "  IA      nan     1.28477", "field 2 \\(value \\(arcsec\\)\\).*not finite"),
    (4, "  IE      +nan     0.30382", "field 2 \\(value \\(arcsec\\)\\).*not finite"),
    (5, "  NPAE    -3.47    inf", "field 3 \\(sigma \\(arcsec\\)\\).*not finite"),
    (6, "  CA      -5.9x    1.8", "field 2 \\(value \\(arcsec\\)\\).*not a number"),
    (7, "  AN      +2.49    0.11  7", "4 fields"),
    (8, "  IA      +1.0     0.1", "term IA appears twice"),
    (2, "T   80   0.9318   42.060", "fit-summary record 'T' has 4 fields"),
    (3, "  =", "field 1 \\(term name\\) is missing"),
    (3, "  1A   +1.0", "not a name"),
]:

    @case(f"model-line{_line}-{_text.split()[0]}", "error", rf"model\.mod:{_line}:", _what, error=FileFormatError)
    def _(tmp, line=_line, text=_text):
        px.io.read_model(_mod_with(tmp, line, text))


@case("model-no-terms", "error", r"model\.mod: ", "no term records", error=FileFormatError)
def _(tmp):
    px.io.read_model(_write(tmp, "model.mod", ["caption", "T 80 0.9 42.0 -0.05", "END"]))


@case("model-no-end", "error", r"model\.mod: ", "no END line", error=FileFormatError)
def _(tmp):
    px.io.read_model(_mod_with(tmp, 11, drop=True))


@case("model-after-end", "warning", r"model\.mod:12:", "after END .* ignored")
def _(tmp):
    lines = MMT_MOD.read_text().splitlines() + ["  CA  +1.0  0.1"]
    px.io.read_model(_write(tmp, "model.mod", lines))


@case("model-unknown-term", "error", r"model\.mod:3:", "term record XYZZY", error=FileFormatError)
def _(tmp):
    px.io.read_model(_mod_with(tmp, 3, "  XYZZY   +1.0   0.1")).model()


@case("model-write-nan", "error", "value of term IE is nan", "cannot hold NaN")
def _(tmp):
    model = px.AltAz(px.terms.tpoint("IA IE", values={"IE": float("nan")}))
    px.io.write_model(tmp / "out.mod", model)


@case("model-write-inf-sky-rms", "error", "Sky RMS is inf")
def _(tmp):
    px.io.format_model([px.io.ModelTerm("IA", 1.0)], n_obs=3, sky_rms=float("inf"))


# ------------------------------------------------------------------ gpoint


def _gpoint_with(tmp: Path, line: int, fields: dict[int, str] | None = None, text: str | None = None) -> Path:
    lines = GPOINT.read_text().splitlines()
    if text is not None:
        lines[line - 1] = text
    else:
        tokens = lines[line - 1].split()
        for k, v in (fields or {}).items():
            tokens[k - 1] = v
        lines[line - 1] = "\t".join(tokens)
    return _write(tmp, "run.txt", lines)


for _fields, _what in [
    ({8: "400.0"}, "mount azimuth.*outside -360..360"),
    ({7: "200.0"}, "elevation .* outside -90..90"),
    ({7: "-8.0"}, "observed elevation .*below the horizon"),
    ({4: "x"}, "field 4 \\(target Dec \\(deg\\)\\).*not a number"),
    ({6: "nan"}, "not finite"),
]:

    @case(f"gpoint-{'-'.join(f'{k}={v}' for k, v in _fields.items())}", "error", r"run\.txt:3:", _what, error=FileFormatError)
    def _(tmp, fields=_fields):
        px.io.read_gpoint(_gpoint_with(tmp, 3, fields))


@case("gpoint-short-row", "error", r"run\.txt:3:", "has 3 fields", error=FileFormatError)
def _(tmp):
    px.io.read_gpoint(_gpoint_with(tmp, 3, text="1 2 3"))


@case("gpoint-no-header", "error", r"run\.txt: ", "no header line", error=FileFormatError)
def _(tmp):
    px.io.read_gpoint(_gpoint_with(tmp, 2, text="# just a comment"))


@case("gpoint-header-on-line-1", "error", r"run\.txt:1:", "line 1, which gpoint skips", error=FileFormatError)
def _(tmp):
    lines = GPOINT.read_text().splitlines()[1:]
    px.io.read_gpoint(_write(tmp, "run.txt", lines))


@case("gpoint-gem-header-altaz-rows", "error", r"run\.txt:3:", "gem row has 8 fields", error=FileFormatError)
def _(tmp):
    px.io.read_gpoint(_gpoint_with(tmp, 2, text="# gem -20.8 -32.53 1850.0"))


@case("gpoint-row-twice", "warning", r"run\.txt:4:", "line 4 = line 3")
def _(tmp):
    lines = GPOINT.read_text().splitlines()
    lines.insert(3, lines[2])
    px.io.read_gpoint(_write(tmp, "run.txt", lines))


@case("gpoint-in-radians", "error", r"run\.txt:3:", "look like radians", error=FileFormatError)
def _(tmp):
    lines = GPOINT.read_text().splitlines()
    for k in range(2, len(lines)):
        tokens = lines[k].split()
        for j in (4, 5, 6, 7):
            tokens[j] = f"{math.radians(float(tokens[j])):.9f}"
        lines[k] = "\t".join(tokens)
    px.io.read_gpoint(_write(tmp, "run.txt", lines))


# ------------------------------------------------------------------ sun files

SUN_ROWS = [
    "279.436 216.460 141.022 50.469",
    "272.655 218.653 147.820 52.704",
    "260.100 221.300 160.200 55.100",
    "250.000 222.900 175.500 56.300",
]


def _sun(tmp: Path, row: int | None = None, text: str | None = None, rows=None) -> Path:
    lines = ["# alpha_deg beta_deg sun_az_deg sun_el_deg"] + list(SUN_ROWS if rows is None else rows)
    if row is not None:
        lines[row - 1] = text
    return _write(tmp, "sun.txt", lines)


for _text, _what in [
    ("279.4 216.4 141.0 95.0", "column 4 \\(sun_el_deg\\).*outside -90..90"),
    ("279.4 216.4 141.0 -5.0", "column 4 \\(sun_el_deg\\).*below the horizon"),
    ("279.4 216.4 500.0 50.0", "column 3 \\(sun_az_deg\\).*outside -360..360"),
    ("-720.0 216.4 141.0 50.0", "column 1 \\(alpha_deg\\).*outside -360..360"),
    ("279.4 1000.0 141.0 50.0", "column 2 \\(beta_deg\\).*outside -360..360"),
    ("279.4 216.4 141.0 50.0 -1", "column 5 \\(weight\\).*negative"),
    ("279.4 216.4 141.0", "expected 4 or 5 numbers"),
    ("279.4 nan 141.0 50.0", "column 2 \\(beta_deg\\).*not finite"),
]:

    @case(f"sun-{_text.replace(' ', '_')}", "error", r"sun\.txt:3:", _what, error=FileFormatError)
    def _(tmp, text=_text):
        px.io.read_sun_observations(_sun(tmp, 3, text))


@case("sun-in-radians", "error", r"sun\.txt:2:", "look like radians", error=FileFormatError)
def _(tmp):
    rows = [" ".join(f"{math.radians(float(t)):.9f}" for t in r.split()) for r in SUN_ROWS]
    px.io.read_sun_observations(_sun(tmp, rows=rows))


@case("sun-row-twice", "warning", r"sun\.txt:4:", "line 4 = line 3")
def _(tmp):
    px.io.read_sun_observations(_sun(tmp, rows=SUN_ROWS[:2] + SUN_ROWS[1:]))


@case("sun-empty", "error", r"sun\.txt: ", "no observations", error=FileFormatError)
def _(tmp):
    px.io.read_sun_observations(_sun(tmp, rows=[]))


# ------------------------------------------------------------------ X-Y runs

XY_ROWS = ["10.0 20.0 10.01 20.02", "-30.0 45.0 -29.99 45.01", "50.0 -10.0 50.02 -9.98", "5.0 60.0 5.01 60.02"]


def _xy(tmp: Path, rows) -> Path:
    return _write(tmp, "run.xy", rows)


for _text, _what in [
    ("10.0 20.0 10.01 95.0", "field B0.*outside -90..90"),
    ("400.0 20.0 10.01 20.0", "field L.*outside -360..360"),
    ("10.0 x 10.01 20.0", "field B.*not a number"),
    ("10.0 20.0 10.01", "expected 4 numbers"),
]:

    @case(f"xy-{_text.replace(' ', '_')}", "error", r"run\.xy:2:", _what, error=FileFormatError)
    def _(tmp, text=_text):
        px.io.read_xy_run(_xy(tmp, [XY_ROWS[0], text] + XY_ROWS[2:]))


@case("xy-in-radians", "error", r"run\.xy:1:", "look like radians", error=FileFormatError)
def _(tmp):
    px.io.read_xy_run(_xy(tmp, [" ".join(f"{math.radians(float(t)):.9f}" for t in r.split()) for r in XY_ROWS]))


@case("xy-row-twice", "warning", r"run\.xy:3:", "line 3 = line 2")
def _(tmp):
    px.io.read_xy_run(_xy(tmp, XY_ROWS[:2] + XY_ROWS[1:]))


# ------------------------------------------------------------------ PAINT


def _paint_copy(tmp: Path) -> Path:
    folder = tmp / "AA39"
    shutil.copytree(PAINT, folder)
    tower = SHARED_DATA / "paint" / "tower-measurements.json"
    shutil.copy(tower, tmp / tower.name)
    return folder


def _edit_sample(folder: Path, edit) -> Path:
    path = sorted(folder.glob("*-calibration-properties.json"))[0]
    data = json.loads(path.read_text())
    edit(data)
    path.write_text(json.dumps(data, indent=2))
    return path


for _axis, _value in [(1, 999999), (2, -5), (1, -1)]:

    @case(
        f"paint-motor-axis{_axis}-{_value}",
        "error",
        r"151375-calibration-properties\.json",
        rf"axis_{_axis}_motor_position.*outside the range of actuator {_axis}",
        error=FileFormatError,
        needs=PAINT,
    )
    def _(tmp, axis=_axis, value=_value):
        folder = _paint_copy(tmp)
        _edit_sample(folder, lambda d: d["motor_position"].__setitem__(f"axis_{axis}_motor_position", value))
        px.io.read_paint(folder)


@case("paint-sun-elevation-95", "error", r"calibration-properties\.json", "sun_elevation.*outside -90..90", error=FileFormatError, needs=PAINT)
def _(tmp):
    folder = _paint_copy(tmp)
    _edit_sample(folder, lambda d: d.__setitem__("sun_elevation", 95.0))
    px.io.read_paint(folder)


@case("paint-no-focal-spot", "error", r"calibration-properties\.json", "focal_spot", error=FileFormatError, needs=PAINT)
def _(tmp):
    folder = _paint_copy(tmp)
    _edit_sample(folder, lambda d: d.__setitem__("focal_spot", {}))
    px.io.read_paint(folder)


@case("paint-not-json", "error", r"calibration-properties\.json", error=FileFormatError, needs=PAINT)
def _(tmp):
    folder = _paint_copy(tmp)
    sorted(folder.glob("*-calibration-properties.json"))[0].write_text("{ not json")
    px.io.read_paint(folder)


# ------------------------------------------------------------------ the Python API


def _mmt_obs():
    return px.io.read_tpoint(MMT_DAT, azimuth="S-E").observations


@case("api-encoder-in-degrees", "warning", "Observations: encoder", "look like degrees")
def _(tmp):
    obs = _mmt_obs()
    px.Observations(np.degrees(np.asarray(obs.encoder)), obs.target, convention="S-E")


@case("api-quantity-not-an-angle", "error", "encoder", "cannot be converted to rad")
def _(tmp):
    import astropy.units as u

    px.Observations([[1.0, 0.5]] * u.m, [[0.0, 0.0, 1.0]])


@case("api-skycoord-not-altaz", "error", "target", "ICRS frame", "transform it first")
def _(tmp):
    import astropy.units as u
    from astropy.coordinates import SkyCoord

    px.Observations([[1.0, 0.5]], SkyCoord(ra=[10] * u.deg, dec=[20] * u.deg))


@case("api-quantity-directions-shape", "error", "direction", "azimuth and elevation")
def _(tmp):
    import astropy.units as u

    px.command(px.AltAz(px.terms.tpoint("IA")), [[1.0, 2.0, 3.0]] * u.deg)


@case("api-set-wrong-unit", "error", "parameter IA", "cannot be converted")
def _(tmp):
    import astropy.units as u

    px.AltAz(px.terms.tpoint("IA IE")).set(IA=3 * u.m)


@case("api-one-observation-eight-terms", "error", "1 observation\\(s\\) give 2 residuals for 8 free parameters", "sigma")
def _(tmp):
    px.fit(px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"), azimuth="S-E"), _mmt_obs()[:1])


@case("api-three-observations-eight-terms", "error", "3 observation\\(s\\) give 6 residuals for 8 free parameters")
def _(tmp):
    px.fit(px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"), azimuth="S-E"), _mmt_obs()[:3])


@case("api-four-observations-eight-terms", "error", "4 observation\\(s\\) give 8 residuals for 8 free parameters")
def _(tmp):
    px.fit(px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"), azimuth="S-E"), _mmt_obs()[:4])


@case("api-leave-one-out-too-few", "error", "each fold keeps 4 observation\\(s\\), 8 residuals for 8 free parameters")
def _(tmp):
    px.leave_one_out(px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"), azimuth="S-E"), _mmt_obs()[:5])


@case("api-absurd-sky-rms", "flag", "Sky RMS .* absurd", "wrong unit")
def _(tmp):
    obs = _mmt_obs()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", InputWarning)
        wrong = px.Observations(np.degrees(np.asarray(obs.encoder)), obs.target, convention="S-E")
    result = px.fit(px.AltAz(px.terms.tpoint("IA IE"), azimuth="S-E"), wrong)
    return " | ".join(result.warnings())


@case("api-empty-term-list", "flag", "no free parameters .*empty term list")
def _(tmp):
    result = px.fit(px.AltAz(px.terms.tpoint(""), azimuth="S-E"), _mmt_obs())
    return " | ".join(result.warnings())


@case("api-every-parameter-fixed", "flag", "no free parameters")
def _(tmp):
    result = px.fit(px.AltAz(px.terms.tpoint("IA IE"), azimuth="S-E", fixed=["IA", "IE"]), _mmt_obs())
    return " | ".join(result.warnings())


for _limits, _what in [
    (((1.0, 0.0), None), "axis 1 is inverted"),
    ((None, (1.5, -0.1)), "axis 2 is inverted"),
    (((0.0, 360.0), None), "axis 1 max is 360 rad.*looks like degrees"),
    ((None, (0.0, 90.0)), "axis 2 max is 90 rad.*looks like degrees"),
    (((float("nan"), 1.0), None), "axis 1 min is NaN"),
    (((0.0, 1.0, 2.0), None), "each axis limit must be"),
]:

    @case(f"api-limits-{_limits}", "error", "limits", _what)
    def _(tmp, limits=_limits):
        px.command(px.AltAz(px.terms.tpoint("IA")), [0.0, 0.6, 0.8], limits=limits)


@case("api-limits-quantity-inverted", "error", "axis 2 is inverted")
def _(tmp):
    import astropy.units as u

    px.command(px.AltAz(px.terms.tpoint("IA")), [0.0, 0.6, 0.8], limits=((0, 360), (90, 0)) * u.deg)


# ------------------------------------------------------------------ the command line


def _cli(argv, capsys):
    from pointax.cli import main

    with warnings.catch_warnings():
        status = main(argv)
    out = capsys.readouterr()
    return status, out.err


@case("cli-limits-inverted", "flag", "exit 2", "axis 1 is inverted: min 90 deg is above max 0 deg")
def _(tmp, capsys):
    path = _write(tmp, "dirs.txt", ["100 30"])
    status, err = _cli(["command", str(path), "--mount", "altaz", "--params", "IA=3", "--limits", "90,0,,"], capsys)
    return f"exit {status}: {err}"


@case("cli-limits-beyond-two-turns", "flag", "exit 2", "field 2 is 1000 deg, beyond two turns")
def _(tmp, capsys):
    path = _write(tmp, "dirs.txt", ["100 30"])
    status, err = _cli(["command", str(path), "--params", "alpha0=1", "--limits", "0,1000,,"], capsys)
    return f"exit {status}: {err}"


@case("cli-directions-elevation-95", "flag", "exit 2", r"dirs\.txt:1: elevation outside")
def _(tmp, capsys):
    path = _write(tmp, "dirs.txt", ["100 95"])
    status, err = _cli(["command", str(path), "--params", "alpha0=1"], capsys)
    return f"exit {status}: {err}"


@case("cli-nominal-model", "flag", "exit 0", "warning: --model: no --model file and no --params: commanding the nominal model")
def _(tmp, capsys):
    path = _write(tmp, "dirs.txt", ["100 30"])
    status, err = _cli(["command", str(path), "--mount", "altaz"], capsys)
    return f"exit {status}: {err}"


@case("cli-fit-radians-file", "flag", "exit 2", r"run\.dat:21:", "look like radians")
def _(tmp, capsys):
    lines = _mmt_lines()
    for k in range(FIRST_OBS - 1, len(lines)):
        tokens = lines[k].split()
        lines[k] = " ".join(f"{math.radians(float(t)):.9f}" for t in tokens)
    path = _write(tmp, "run.dat", lines)
    status, err = _cli(["fit", str(path), "--azimuth", "S-E"], capsys)
    return f"exit {status}: {err}"


# ------------------------------------------------------------------ sun-sensor frames


@case("frame-two-suns", "flag", "inconsistent", "more than one sun")
def _(tmp):
    pytest.importorskip("torch")
    from pointax.sunsensor import centroid

    h, w, r = 256, 320, 12.0
    yy, xx = np.mgrid[0:h, 0:w]
    frame = 100.0 + np.random.default_rng(0).normal(0, 3, (h, w))
    for x, y in ((80, 120), (240, 100)):
        frame += 2000.0 * (((xx - x) ** 2 + (yy - y) ** 2) <= r * r)
    found = centroid(frame[None].astype(np.float32), radius=r, saturation=4095)
    return f"{found.status[0]}: {found.reason[0]}"


# ------------------------------------------------------------------ the tests


def _check(c: Case, tmp_path, capsys):
    if c.needs is not None and not Path(c.needs).exists():
        pytest.skip(f"{c.needs} not found")
    args = (tmp_path, capsys) if "capsys" in c.run.__code__.co_varnames[: c.run.__code__.co_argcount] else (tmp_path,)
    if c.kind == "error":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", InputWarning)
            with pytest.raises(c.error) as info:
                c.run(*args)
        text = str(info.value)
    elif c.kind == "warning":
        with pytest.warns(InputWarning) as record:
            c.run(*args)
        text = " | ".join(str(w.message) for w in record if issubclass(w.category, InputWarning))
    else:
        text = c.run(*args)
    assert "Traceback" not in text
    for pattern in c.patterns:
        assert re.search(pattern, text), f"{c.name}: {pattern!r} not in {text!r}"
    return text


@pytest.mark.parametrize("c", CASES, ids=[c.name for c in CASES])
def test_bad_input(c, tmp_path, capsys):
    _check(c, tmp_path, capsys)


def test_corpus_counts():
    kinds = [c.kind for c in CASES]
    counts = {k: kinds.count(k) for k in ("error", "warning", "flag")}
    print(f"bad-input corpus: {len(CASES)} cases: {counts['error']} clear errors, "
          f"{counts['warning']} warnings, {counts['flag']} flags")
    assert len(CASES) >= 60
    assert len({c.name for c in CASES}) == len(CASES)

"""The README's commands: every indented ``pointax ...`` / ``.venv/bin/...`` line (and
each inline ``.venv/bin/...`` command) is found and checked, in a temporary folder
holding a copy of ``examples/`` (with ``../shared`` beside it when the checkout has one),
so that nothing a command writes lands in the repository.

* cheap commands run for real and must exit 0 (``pointax --version``; the first
  command, ``pointax fit`` of the bundled MMT run);
* the first ``pointax plan`` example runs for real (about 20 s) and must exit 0;
* expensive ones (the sun plan: 25 s; the whole test suite; ``pip install``; the
  examples and benchmarks; ``fit-network`` of the bundled manifest, a minute, and
  exit 1 by design) are checked at argument level: their options parse and pass
  ``pointax plan``'s own option checks (which import nothing numerical), a
  benchmark's ``[--quick]`` is one of its options, a script exists, a pip extra is
  defined; ``POINTAX_README_SLOW=1`` runs every ``pointax plan`` example for real;
* synopses (``pointax fit DATA [--terms ...]``) are checked option by option against
  the subcommand's parser: every ``--option`` they show is one it accepts;
* every synopsis also runs for real as a worked example on the bundled data
  (:data:`WORKED_EXAMPLES`: the MMT run, the tests' gpoint and offsets tables, a PAINT
  folder of ../shared, a frame written by the test), each a few seconds, all in one
  process through ``pointax.cli.main`` (what the installed entry point calls; the cheap
  commands above run the entry point itself): exit 0 and a key line of its output (a
  value the README states, or the fitted truth of synthetic data). Those that take longer are
  skipped, saying why (:data:`SLOW_SYNOPSES`): ``pointax compare`` (15 s of CPU for
  two families), ``pointax fit-network`` (a minute), ``pointax plan`` (20-30 s: the
  test above runs the first).
"""

from __future__ import annotations

import argparse
import ast
import os
import re
import shlex
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
SHARED = ROOT.parent / "shared"
SLOW = os.environ.get("POINTAX_README_SLOW") == "1"

# A synopsis names placeholders (DATA, FILE, ...) or optional parts in brackets.
_PLACEHOLDER = re.compile(r"(?<![-\w.])(?:[A-Z][A-Z0-9_.]*[A-Z0-9](?:\.\.\.)?|\.\.\.)(?![\w])|\[")


def indented_commands(text: str) -> list[tuple[int, str]]:
    """``(line number, command)`` for each indented command line of the README, a
    synopsis's continuation lines (indented further, after it) joined to it."""
    lines = text.splitlines()
    out: list[tuple[int, str]] = []
    fenced = False
    for i, line in enumerate(lines):
        if line.lstrip().startswith("```"):
            fenced = not fenced
            continue
        if fenced or not line.startswith("    "):
            continue
        body = line.strip()
        if re.match(r"(pointax |\.venv/bin/|bash |python )", body):
            indent = len(line) - len(line.lstrip())
            j = i + 1
            while j < len(lines) and lines[j].strip() and len(lines[j]) - len(lines[j].lstrip()) > indent:
                body += " " + lines[j].strip()
                j += 1
            out.append((i + 1, body))
    return out


def inline_commands(text: str) -> list[tuple[int, str]]:
    """``(line number, command)`` for each inline code span that is a ``.venv/bin/``
    command."""
    out = []
    for i, line in enumerate(text.splitlines()):
        out += [(i + 1, m) for m in re.findall(r"`(\.venv/bin/[^`]+)`", line)]
    return out


def _strip_comment(command: str) -> str:
    return command.split("  #")[0].strip()


def _pointax_argv(command: str) -> list[str] | None:
    """The ``pointax`` arguments of a command (after ``&&``, without ``.venv/bin/``), or None."""
    part = _strip_comment(command).split("&&")[-1].strip()
    words = shlex.split(part)
    if not words or Path(words[0]).name != "pointax":
        return None
    return words[1:]


def _is_synopsis(command: str) -> bool:
    return bool(_PLACEHOLDER.search(_strip_comment(command).split("&&")[-1]))


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    from pointax.cli import build_parser

    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


@pytest.fixture(scope="module")
def readme() -> str:
    return README.read_text()


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    """A temporary checkout-like folder: ``work/examples`` (a copy), ``work/.venv``
    (a link to this one), and ``shared`` beside ``work`` (a link) when there is one."""
    base = tmp_path_factory.mktemp("readme")
    work = base / "work"
    work.mkdir()
    shutil.copytree(ROOT / "examples", work / "examples")
    (work / ".venv").symlink_to(ROOT / ".venv")
    if SHARED.is_dir():
        (base / "shared").symlink_to(SHARED)
    return work


def _run(command: list[str], cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.run(command, cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env)


def test_the_readme_commands_are_found(readme):
    """The extraction sees the commands the README shows (a guard against a silent
    change of layout that would leave the other tests checking nothing)."""
    found = [c for _, c in indented_commands(readme)]
    assert any("pointax fit examples/data/mmt_20210821.dat --azimuth S-E" in c for c in found)
    assert sum(c.startswith("pointax plan ") for c in found) == 2
    assert any(c.startswith("pointax fit DATA [--terms") and "[--json]" in c for c in found)  # continuation lines joined
    assert any(c == ".venv/bin/pointax --version" for c in found)
    assert any("benchmarks/planning.py" not in c and "benchmarks/" in c for _, c in inline_commands(readme))


def test_cheap_commands_run_and_exit_0(readme, workdir):
    """The commands that take seconds run for real, in the temporary folder."""
    ran = []
    for lineno, command in indented_commands(readme):
        argv = _pointax_argv(command)
        if argv is None or _is_synopsis(command) or argv[:1] == ["plan"]:
            continue
        if any(a.startswith("../shared") for a in argv) and not (workdir.parent / "shared").is_dir():
            continue
        proc = _run([str(ROOT / ".venv" / "bin" / "pointax"), *argv], workdir)
        assert proc.returncode == 0, f"README line {lineno}: {command}\n{proc.stderr[-2000:]}"
        ran.append(argv)
    assert ["--version"] in ran
    assert ["fit", "examples/data/mmt_20210821.dat", "--azimuth", "S-E"] in ran
    out = _run([str(ROOT / ".venv" / "bin" / "pointax"), "fit", "examples/data/mmt_20210821.dat", "--azimuth", "S-E", "--json"], workdir)
    assert '"converged": true' in out.stdout
    assert not any(p.name != "examples" and p.name != ".venv" for p in workdir.iterdir()), list(workdir.iterdir())


def test_plan_examples_pass_the_option_checks_and_the_first_runs(readme, workdir):
    """``pointax plan`` takes 20-30 s a run here: every README example is parsed and
    passes every option check of ``pointax plan`` (no numerical library needed); the
    first (the star plan with ``--target-rms``, which exited 1: its stars set before
    their turn and the target was missed) runs for real and must reach its target, exit
    0; with POINTAX_README_SLOW=1 the others run too."""
    import json

    from pointax.cli import build_parser
    from pointax.cli.plan import check_options

    plans = [(n, c) for n, c in indented_commands(readme) if c.startswith("pointax plan ")]
    assert plans
    for k, (lineno, command) in enumerate(plans):
        args = build_parser().parse_args(_pointax_argv(command))
        check_options(args)  # raises ValueError on contradicting options
        if k == 0 or SLOW:
            proc = _run([str(ROOT / ".venv" / "bin" / "pointax"), *_pointax_argv(command)], workdir, timeout=600)
            assert proc.returncode == 0, f"README line {lineno}: {command}\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}"
            if k == 0:
                out = json.loads(proc.stdout)
                assert out["stopped"] == "target" and out["predicted"]["rms_arcsec"] <= args.target_rms, out["predicted"]


def test_synopses_name_only_options_their_subcommand_accepts(readme):
    """Each synopsis line (placeholders, brackets) names a subcommand, and every
    ``--option`` it shows is an option of that subcommand's parser."""
    parsers = _subparsers()
    checked = 0
    for lineno, command in indented_commands(readme):
        argv = _pointax_argv(command)
        if argv is None:
            continue
        assert argv and (argv[0] in parsers or argv[0].startswith("-")), f"README line {lineno}: unknown subcommand in {command}"
        if argv[0].startswith("-"):
            continue
        known = {s for a in parsers[argv[0]]._actions for s in a.option_strings}
        shown = set(re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*|-[a-z])(?=[\s=\]|,]|$)", _strip_comment(command)))
        unknown = sorted(shown - known)
        assert not unknown, f"README line {lineno}: pointax {argv[0]} has no {', '.join(unknown)}"
        checked += 1
    assert checked >= 15


def test_scripts_exist_and_their_options_are_real(readme):
    """Inline ``.venv/bin/python SCRIPT [--quick]`` commands: the script exists, and an
    option the README shows is one its argument parser defines (read from its source,
    so that nothing runs); the pip lines' extras exist in pyproject.toml."""
    for lineno, command in inline_commands(readme) + indented_commands(readme):
        part = _strip_comment(command).split("&&")[-1].strip()
        words = part.replace("[", " ").replace("]", " ").split()
        if len(words) < 2 or words[0] != ".venv/bin/python" or not words[1].endswith(".py"):
            continue
        script = ROOT / words[1]
        assert script.is_file(), f"README line {lineno}: {words[1]} does not exist"
        options = [w for w in words[2:] if w.startswith("--")]
        if options:
            tree = ast.parse(script.read_text())
            defined = {
                arg.value
                for node in ast.walk(tree)
                if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "add_argument"
                for arg in node.args
                if isinstance(arg, ast.Constant) and isinstance(arg.value, str)
            }
            assert set(options) <= defined, f"README line {lineno}: {words[1]} has no {sorted(set(options) - defined)}"
    import tomllib

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    for extra in set(re.findall(r"pointax\[(\w+)\]|\"\.\[(\w+)\]\"", readme)):
        name = next(e for e in extra if e)
        assert name in extras, f"README names the extra [{name}], which pyproject.toml does not define"


def test_the_plan_example_writes_outside_the_repository(tmp_path):
    """examples/plan_pointing_run.py writes its sky map to a temporary folder by
    default (it used to overwrite the tracked examples/plan_skymap.png, the README's
    figure); importing it runs nothing."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("plan_pointing_run_example", ROOT / "examples" / "plan_pointing_run.py")
    module = importlib.util.module_from_spec(spec)
    before = (ROOT / "examples" / "plan_skymap.png").stat().st_mtime_ns
    spec.loader.exec_module(module)
    assert (ROOT / "examples" / "plan_skymap.png").stat().st_mtime_ns == before
    default = Path(module.DEFAULT_SKYMAP).resolve()
    assert ROOT not in default.parents, default
    assert "examples/plan_skymap.png" in README.read_text()  # the README's figure stays the tracked one


def test_shared_data_commands_skip_cleanly_without_shared(workdir):
    """Commands on ../shared run only where it exists beside the checkout."""
    if not (workdir.parent / "shared").is_dir():
        pytest.skip("../shared is not beside the checkout: its README commands are not run")
    assert (workdir.parent / "shared" / "data").is_dir()


# ---------------------------------------------------------------- the synopses, run as worked examples

MMT = "examples/data/mmt_20210821.dat"
MMT_MOD = "examples/data/mmt_20210821.mod"
TESTS_DATA = ROOT / "tests" / "data"

SLOW_SYNOPSES = {
    "pointax fit-network MANIFEST": "a minute for the bundled manifest, exit 1 by design; options checked above",
    "pointax compare DATA": "about 15 s of CPU (two families, in and out of sample); options checked above",
}
"""Synopses not run: why (each over 10 s). ``pointax plan``'s examples are concrete
commands, run by test_plan_examples_pass_the_option_checks_and_the_first_runs."""

WORKED_EXAMPLES = [
    # (synopsis prefix, argv with {out} for the output folder, regex the stdout must match, files written)
    (
        "pointax fit DATA [--terms",
        ["fit", MMT, "--terms", "IA,IE,CA,NPAE,AN,AW,TF,TX", "--model", MMT_MOD, "--fix", "IA", "--azimuth", "S-E",
         "--write-model", "{out}/fit.mod"],
        r"Sky RMS =\s+0\.93\d\d",  # TPOINT's 0.9319" for these 8 terms (README, "Two commands")
        ["fit.mod"],
    ),
    (
        "pointax fit TABLE [--format offsets]",
        ["fit", str(TESTS_DATA / "offsets" / "radio_xel.csv"), "--format", "offsets", "--columns", "_,az,el,dxel,del",
         "--units", "arcsec", "--terms", "IA,IE,CA,NPAE,AN,AW"],
        r"\n\s+5\s+AN\s+\+(5\.[5-9]|6\.[0-4])\d*\s",  # the table's true AN, 6"
        [],
    ),
    (
        "pointax fit DATA ... [--mask",
        ["fit", MMT, "--azimuth", "S-E", "--mask", "17,19-21", "--list", "--plot", "{out}/fit.png"],
        r"76 of 80 observations used; 4 masked \(M\)",
        ["fit.png"],
    ),
    (
        "pointax fit DATA ... [--mask",
        ["fit", MMT, "--azimuth", "S-E", "--reject", "3", "--list"],
        r"2 outlier\(s\) beyond 3 sigma: observations 39, 79",  # the README's "--reject 3 flags rows 39 and 79"
        [],
    ),
    (
        "pointax fit DIR --format paint",
        ["fit", "../shared/data/paint/AA39", "--format", "paint", "--loo", "no"],
        r"HeliostatMount\(heliostat\): t1n t1u t2e t2n",
        [],
    ),
    (
        "pointax fit FILE --format gpoint",
        ["fit", str(TESTS_DATA / "gpoint" / "altaz_manual.txt"), "--format", "gpoint", "--terms",
         "ia,ie,tn,te,npae,npoa,tf,az:sin:az:2,HACA2"],
        r"\n\s+2\s+ie\s+-4[4-6]\.\d+\s+\d\.\d+\n\s+3\s+tn\s+\+1[45]\.\d+\s",  # the synthetic run's ie -45", tn 15"
        [],
    ),
    (
        "pointax centroid FRAME",
        ["centroid", "{out}/frame.npy"],
        r"frame\.npy\s+70\.[23]\d*\s+40\.[56]\d*\s+1[45]\.\d+\s+\w+\s+ok",  # the disk drawn at (70.3, 40.6)
        [],
    ),
    (
        "pointax command DIRECTIONS",
        ["command", "{out}/directions.txt", "--model", MMT_MOD, "--azimuth", "S-E"],
        r"90\.0000\s+30\.0000\s+90\.33\d+\s+30\.00\d+\s+yes",  # issue 30: az 90 is commanded to 90.33, not -269.67
        [],
    ),
    (
        "pointax tpoint [SCRIPT",
        ["tpoint", "{out}/session.tpt"],
        r"OUTMOD: \S*session\.mod \(N 80, Sky RMS 0\.93\d\d\)",  # two FITs converge to TPOINT's 0.9319"
        ["session.mod"],
    ),
    (
        "pointax plot DATA",
        ["plot", MMT, "--azimuth", "S-E", "--kind", "summary", "-o", "{out}/summary.png"],
        r"PNG image, \d+ x \d+ px",
        ["summary.png"],
    ),
    (
        "pointax report DATA",
        ["report", MMT, "--azimuth", "S-E", "--title", "MMT", "-o", "{out}/report.html"],
        r"HTML report, \d+ kB, \d+ images",
        ["report.html"],
    ),
]  # fmt: skip


def _synopses(readme: str) -> list[str]:
    return [c for _, c in indented_commands(readme) if c.startswith("pointax ") and _is_synopsis(c)]


def test_every_synopsis_runs_as_a_worked_example_or_says_why_not(readme):
    for synopsis in _synopses(readme):
        examples = [e for e in WORKED_EXAMPLES if synopsis.startswith(e[0])]
        skipped = [k for k in SLOW_SYNOPSES if synopsis.startswith(k)]
        assert examples or skipped, f"README synopsis without a worked example: {synopsis}"
    for prefix, *_ in WORKED_EXAMPLES:  # and every example is of a synopsis the README shows
        assert any(s.startswith(prefix) for s in _synopses(readme)), prefix


def _inputs(out: Path) -> None:
    """The files the worked examples read that the bundled data lacks."""
    import numpy as np

    y, x = np.mgrid[:96, :128]
    np.save(out / "frame.npy", (((x - 70.3) ** 2 + (y - 40.6) ** 2 < 15**2) * 200.0 + 5.0).astype(np.float32))
    (out / "directions.txt").write_text("180 45\n90 30\n270 60\n")
    (out / "session.tpt").write_text(
        f"indat {ROOT / MMT}\nuse IA IE CA NPAE AN AW TF TX\nfit\nfit\noutmod session.mod\n"
    )


def _skip_reason(argv: list[str], workdir: Path) -> str | None:
    """Why a worked example cannot run here (a missing extra or ../shared), or None."""
    import importlib.util

    if any(a.startswith("../shared") for a in argv) and not (workdir.parent / "shared").is_dir():
        return "../shared is not beside the checkout"
    if argv[0] == "centroid" and not all(importlib.util.find_spec(m) for m in ("torch", "kornia")):
        return "pointax centroid needs the vision extra (torch, kornia)"
    if (argv[0] in ("plot", "report") or "--plot" in argv) and importlib.util.find_spec("matplotlib") is None:
        return "plots need the plot extra (matplotlib)"
    return None


# The worked examples run in one process, each through ``pointax.cli.main`` (what the
# installed ``pointax`` calls; the entry point itself runs above), with its own standard
# output and error and its exit status: one import of the numerical libraries instead of
# one per example, and the examples that fit the same model share its compiled fit.
_DRIVER = """
import contextlib, io, json, sys, traceback
from pointax.cli import main
out = []
for argv in json.loads(sys.argv[1]):
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        try:
            code = main(argv)
        except SystemExit as err:
            code = err.code if isinstance(err.code, int) else 1
        except Exception:
            traceback.print_exc()
            code = 1
    out.append({"code": code or 0, "stdout": stdout.getvalue(), "stderr": stderr.getvalue()})
print(json.dumps(out))
"""


@pytest.fixture(scope="module")
def worked_examples(workdir, tmp_path_factory) -> list[dict]:
    """Each worked example's ``argv`` (with its output folder), and ``skip`` (why it does
    not run here) or the ``code``, ``stdout`` and ``stderr`` of its run."""
    import json

    runs = []
    for k, (_, argv, _, _) in enumerate(WORKED_EXAMPLES):
        out = tmp_path_factory.mktemp(f"example{k}")
        _inputs(out)
        argv = [a.format(out=out) for a in argv]
        runs.append({"argv": argv, "out": out, "skip": _skip_reason(argv, workdir)})
    todo = [r for r in runs if r["skip"] is None]
    if todo:
        proc = _run([str(ROOT / ".venv" / "bin" / "python"), "-c", _DRIVER, json.dumps([r["argv"] for r in todo])], workdir)
        assert proc.returncode == 0, proc.stderr[-3000:]
        for r, result in zip(todo, json.loads(proc.stdout.splitlines()[-1]), strict=True):
            r.update(result)
    return runs


@pytest.mark.parametrize(
    "k, key, written",
    [(k, key, written) for k, (_, _, key, written) in enumerate(WORKED_EXAMPLES)],
    ids=[f"{e[1][0]}-{k}" for k, e in enumerate(WORKED_EXAMPLES)],
)
def test_synopsis_worked_example_runs(worked_examples, k, key, written):
    run = worked_examples[k]
    if run["skip"]:
        pytest.skip(run["skip"])
    command = "pointax " + " ".join(run["argv"])
    assert run["code"] == 0, f"{command}\n{run['stdout'][-2000:]}\n{run['stderr'][-2000:]}"
    assert re.search(key, run["stdout"]), f"{command}: no {key!r} in\n{run['stdout'][-3000:]}"
    for name in written:
        assert (run["out"] / name).stat().st_size > 0, name

"""TPOINT's command language as observatories write it (issue 27): procedure files in
the shape of MMT's public bino.procs (not copied: its repository has no licence), every
construct they use, on the shared MMT run.

Reference: tests/tpoint_numpy.py (TPOINT's terms, the rigorous residuals, one
Gauss-Newton step), here with fixed terms: each model file the procedure writes is
checked against the same steps in plain NumPy.
"""

from __future__ import annotations

import io
import shutil
from pathlib import Path

import numpy as np
import pytest
import tpoint_numpy as ref
from conftest import MMT_DAT

from pointax.cli import main
from pointax.procedures import ProcedureError, Runner, Session
from pointax.procedures.parser import NOT_IMPLEMENTED, Quoted, lines_of, resolve, split, tokens

EIGHT = "IA IE NPAE CA AN AW TF TX".split()
TOLERANCE = 0.01  # arcsec: values, sigmas and Sky RMS of each model file


@pytest.fixture(autouse=True)
def no_compilation_cache(monkeypatch):
    monkeypatch.setenv("POINTAX_JAX_CACHE", "")


@pytest.fixture
def mmt_run(shared_data) -> Path:
    return shared_data / "tpoint" / "mmt_20210821.dat"


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text)
    return path


def session_runner() -> tuple[Session, Runner]:
    session = Session(out=io.StringIO(), azimuth="S-E")
    return session, Runner(session, err=io.StringIO())


def run_text(runner: Runner, text: str, folder: Path) -> None:
    runner.run_lines(iter(list(lines_of(text.splitlines(), "t.ptp", folder))))


# --------------------------------------------------------------------------- NumPy steps


class Reference:
    """TPOINT's FIT steps on one run in plain NumPy: one Gauss-Newton step of the free
    terms (the others held), the rigorous residuals, TPOINT's statistics."""

    def __init__(self, path: Path):
        self.observed, self.raw, _ = ref.read_run(path)
        self.n = len(self.observed)

    def residuals(self, names, coefs):
        return ref.sky_residuals(names, np.asarray(coefs, np.float64), self.observed, self.raw)

    def step(self, names, coefs, used, free=None, h=1e-7):
        """``(coefs, rms, sigmas by free name)`` after one FIT."""
        coefs = np.asarray(coefs, np.float64)
        free = list(names) if free is None else list(free)
        index = [names.index(k) for k in free]

        def r(c):
            return self.residuals(names, c)[used].reshape(-1)

        columns = []
        for k in index:
            e = np.zeros(len(coefs))
            e[k] = h
            columns.append((r(coefs + e) - r(coefs - e)) / (2 * h))
        J = np.stack(columns, axis=-1)
        new = coefs.copy()
        new[index] -= np.linalg.lstsq(J, r(coefs), rcond=None)[0]
        rms, _, sigmas = ref.statistics(self.residuals(names, new), used, J, len(index))
        return new, rms, dict(zip(free, sigmas))

    def above(self, names, coefs, limit):
        """Observations whose on-sky residual exceeds ``limit`` arcsec (MASK R > limit)."""
        return np.hypot(*self.residuals(names, coefs).T) / ref.ARCSEC > limit


def check_model_file(path, names, coefs, rms, sigmas, n):
    """The model file holds ``coefs`` (radians), the sigmas of the free terms (none for
    fixed ones), N and the Sky RMS, each within :data:`TOLERANCE`."""
    values, file_sigmas, file_n, file_rms = ref.read_model_values(path)
    assert list(values) == list(names), path.name
    np.testing.assert_allclose([values[k] for k in names], np.asarray(coefs) / ref.ARCSEC, atol=TOLERANCE, err_msg=path.name)
    assert sorted(file_sigmas) == sorted(sigmas), path.name
    np.testing.assert_allclose(
        [file_sigmas[k] for k in sigmas], [sigmas[k] / ref.ARCSEC for k in sigmas], atol=TOLERANCE, err_msg=path.name
    )
    assert file_n == n and abs(file_rms - rms / ref.ARCSEC) < TOLERANCE, path.name


# --------------------------------------------------------------------------- (1) every construct

PROCEDURES = """\
! The observatory's procedures, in the shape of MMT's bino.procs.
; a comment line of the other kind
PROC MAIN   (the whole analysis: free text after the name is a comment)
    indat "run data.dat"          ; a quoted name holding a blank
    CAPT 'MMT test run'
    USE IA IE NPAE CA AN AW TF TX
    FIT
    outmod step0.mod              ! one FIT: one Gauss-Newton step from zero
    fit
    outmod step1.mod
    call plots
    gc b page.ps
    MASK 3
    MASK 10-12
    FIT
    outmod 'step2.mod'
    UNMASK ALL
    MASK R > 2.0
    FIX CA NPAE
    FIT
    outmod step3.mod
    UNMASK
    FIX                           ! bare: every term in use
    USE HESA
    FIT
    outmod step4.mod
    LOSE HESA
    LOSE                          ! bare: every term
    USE IA IE
    FIT
    FIT
    outmod "step5.mod"
RETURN

PROC PLOTS  (some favourite plots; a 3 x 3 page)
    CAPT OFF
    GC
    CLRNG OFF
    PLTZ TL
    G S A
    PLTZ TC
    GAM Z
    PLTZ BL
    GSCAT A
    PLTZ BR
    GSMAP
    CAPT ON
    PLTZ BC
    GDIST
    CLRNG ON
    PLTZ
RETURN
"""

MAIN = """\
inpro procs.ptp
help
HELP fit
call main
END
FROB                              ! after END: never read
"""


def reference_steps(run: Reference):
    """The model files MAIN writes, computed in NumPy: ``{name: (names, coefs, rms,
    sigmas, N)}``. Each FIT is one step from the values of the one before, as
    TPOINT's; step1 is the second FIT from zero (converged), step0 the first (it stops
    short: IA is 1209")."""
    every = np.ones(run.n, bool)
    files = {}
    c0, rms, sig = run.step(EIGHT, np.zeros(8), every)
    files["step0"] = (EIGHT, c0, rms, sig, run.n)
    c1, rms, sig = run.step(EIGHT, c0, every)
    files["step1"] = (EIGHT, c1, rms, sig, run.n)
    used = every.copy()
    used[[2, 9, 10, 11]] = False  # MASK 3, MASK 10-12 (numbers from 1)
    c2, rms, sig = run.step(EIGHT, c1, used)
    files["step2"] = (EIGHT, c2, rms, sig, int(used.sum()))
    used = ~run.above(EIGHT, c2, 2.0)  # UNMASK ALL, MASK R > 2.0
    assert 0 < (~used).sum() < 10
    free = [k for k in EIGHT if k not in ("CA", "NPAE")]
    c3, rms, sig = run.step(EIGHT, c2, used, free)
    files["step3"] = (EIGHT, c3, rms, sig, int(used.sum()))
    nine = EIGHT + ["HESA"]  # UNMASK, FIX (all eight), USE HESA: HESA alone is fitted
    c4, rms, sig = run.step(nine, np.append(c3, 0.0), every, ["HESA"])
    files["step4"] = (nine, c4, rms, sig, run.n)
    two = ["IA", "IE"]  # LOSE HESA, LOSE (all), USE IA IE from zero, FIT twice
    c5, _, _ = run.step(two, np.zeros(2), every)
    c5, rms, sig = run.step(two, c5, every)
    files["step5"] = (two, c5, rms, sig, run.n)
    return files


def test_every_construct_against_numpy_steps(mmt_run, tmp_path):
    """A procedure file using every construct observatories write, run on the MMT run:
    each model file equals NumPy's steps within 0.01"; the PLTZ page holds the plots in
    their panels and is written by GC B FILE; CAPT OFF / ON switch the page caption and
    CAPT TEXT is the model files' caption; HELP lists; END stops reading."""
    shutil.copy(mmt_run, tmp_path / "run data.dat")
    write(tmp_path, "procs.ptp", PROCEDURES)
    session, runner = session_runner()
    runner.run_file(write(tmp_path, "main.ptp", MAIN))
    out = session.out.getvalue()

    for name, (names, coefs, rms, sigmas, n) in reference_steps(Reference(mmt_run)).items():
        check_model_file(tmp_path / f"{name}.mod", names, coefs, rms, sigmas, n)
        assert (tmp_path / f"{name}.mod").read_text().splitlines()[0] == "MMT test run"
    # The page: five plots in their PLTZ panels, the caption shown (CAPT ON before GDIST).
    panels = {
        (ax.get_subplotspec().rowspan.start, ax.get_subplotspec().colspan.start): ax.get_title().split(":")[0]
        for ax in session.figure.axes
        if ax.get_title()
    }
    assert panels == {(0, 0): "G S A", (0, 1): "G AM Z", (2, 0): "GSCAT", (2, 2): "GSMAP", (2, 1): "GHIST"}
    assert session.figure.get_suptitle().startswith("MMT test run - N = 80")
    assert (tmp_path / "page.ps").read_bytes()[:4] == b"%!PS"
    # What the session said: notes for the settings, bare GC, GSCAT's option; HELP.
    assert "GC: graphics device kept; nothing written" in out
    assert "GSCAT A: drawn in panel BL; TPOINT options A not used" in out
    assert "CLRNG: display setting accepted (OFF)" in out and "CAPT OFF: captions on plots hidden" in out
    assert "OUTDAT" in out and "  FIT: one linearised (Gauss-Newton) adjustment" in out
    assert "FROB" not in out and session.zone is None and session.page is None


# --------------------------------------------------------------------------- (2) CAPT


def test_capt_switch_is_not_a_caption(tmp_path):
    """CAPT ON / CAPT OFF show or hide the caption on plots and leave the model files'
    caption alone; CAPT TEXT (and CAPT "ON", quoted) is the caption."""
    session, runner = session_runner()

    def first_line(name):
        return (tmp_path / name).read_text().splitlines()[0]

    run_text(runner, f"indat {MMT_DAT}\nuse IA IE\nfit\nCAPT OFF\noutmod off.mod\ng s a", tmp_path)
    run_caption = session.run.caption
    assert first_line("off.mod") == run_caption and run_caption not in ("ON", "OFF")
    assert session.figure.get_suptitle() == ""
    run_text(runner, "capt on\noutmod on.mod\ng s a", tmp_path)
    assert first_line("on.mod") == run_caption
    assert session.figure.get_suptitle().startswith(f"{run_caption} - N = ")
    run_text(runner, "CAPT The new caption\noutmod text.mod\ng s a", tmp_path)
    assert first_line("text.mod") == "The new caption"
    assert session.figure.get_suptitle().startswith("The new caption - N = ")
    run_text(runner, 'CAPT "ON"\noutmod quoted.mod\nCAPT\noutmod back.mod', tmp_path)
    assert first_line("quoted.mod") == "ON" and first_line("back.mod") == run_caption


# --------------------------------------------------------------------------- (3) unknown / noted


def test_unknown_word_is_an_error_naming_file_and_line(tmp_path, capsys):
    s = write(tmp_path, "bad.ptp", "! comment\nPLTE 2\nGSCATTER\n")
    assert main(["tpoint", str(s)]) == 2
    assert f"{s}:3: " in capsys.readouterr().err
    s = write(tmp_path, "bad2.ptp", "CAPT fine\n\nFROBNICATE 3 ; comment\nSHOW\n")
    assert main(["tpoint", str(s)]) == 2
    captured = capsys.readouterr()
    assert f"{s}:3: unknown command FROBNICATE" in captured.err and "mount:" not in captured.out
    s = write(tmp_path, "quote.ptp", "CAPT ok\nindat \"run.dat\n")
    assert main(["tpoint", str(s)]) == 2
    assert f"{s}:2: the quote \" opened at column 7 is not closed" in capsys.readouterr().err


def test_tpoint_commands_not_implemented_are_noted_and_the_run_goes_on(tmp_path, capsys):
    """OUTDAT, OUTPRO, CHAIN, PARALLEL, GHYST, ADJUST S and a G plot of letters pointax
    does not read: one line each, and the commands after them run."""
    s = write(
        tmp_path, "noted.ptp",
        f"indat {MMT_DAT}\nuse IA IE\nfit\nOUTDAT copy.dat\noutpro p.ptp\nchain\nparallel\nGHYST\n"
        "G Q W\nADJUST S\nadjust t\nPLTON xw\noutmod after.mod\n",
    )  # fmt: skip
    assert main(["tpoint", "--azimuth", "S-E", str(s)]) == 0
    out = capsys.readouterr().out.splitlines()
    for word in NOT_IMPLEMENTED:
        assert sum(line.startswith(f"{word}: TPOINT's command to") and "not implemented" in line for line in out) == 1
    assert any(line.startswith("GHYST: TPOINT's hysteresis plot: not drawn") for line in out)
    assert any(line.startswith("G Q W: not drawn: unknown TPOINT graphics command") for line in out)
    assert any(line.startswith("ADJUST S (") and "not implemented" in line for line in out)
    assert any(line.startswith("ADJUST T: ") for line in out)
    assert (tmp_path / "after.mod").exists() and not (tmp_path / "copy.dat").exists()


def test_interactive_prompt_reads_the_same_language():
    """At the prompt: quotes keep ``;`` and ``!`` as text, a TPOINT command not
    implemented is noted, an unknown word is an error, and the session goes on."""
    out, err = io.StringIO(), io.StringIO()
    runner = Runner(Session(out=out), err=err)
    text = 'CAPT "quoted; not ! a comment" ; a comment\noutpro procs.ptp\nFROB\nshow\n'
    assert runner.run_stream(io.StringIO(text), interactive=True) == 1
    assert "CAPT: quoted; not ! a comment\n" in out.getvalue()
    assert "OUTPRO: TPOINT's command to write the defined procedures to a file: not implemented" in out.getvalue()
    assert "<stdin>:3: unknown command FROB" in err.getvalue() and "SHOW: no data" in out.getvalue()


def test_help_and_a_bad_first_word_do_not_import_jax(tmp_path):
    """A script that only asks for HELP, sets a caption and then fails never imports JAX
    (the compilation cache is turned on at the first command that computes)."""
    import subprocess
    import sys

    s = write(tmp_path, "light.ptp", "help\nCAPT OFF\nCLRNG ON\nOUTDAT x.dat\nFROB\n")
    code = (
        "import sys\nfrom pointax.cli import main\n"
        f"rc = main(['tpoint', {str(s)!r}])\n"
        "print('rc', rc, 'jax' in sys.modules)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.stdout.strip().splitlines()[-1] == "rc 2 False", proc.stdout + proc.stderr
    assert f"{s}:5: unknown command FROB" in proc.stderr


# --------------------------------------------------------------------------- the parser


def test_words_quotes_and_comments():
    assert split('indat "bino raw.dat"  ; comment') == ("INDAT", ["bino raw.dat"])
    assert split("outmod 'a!b.mod' ! comment") == ("OUTMOD", ["a!b.mod"])
    assert split("  ; only a comment") is None and split("! another") is None
    assert split("PROC A9   (9 favourite plots for an altaz)")[1][0] == "A9"
    assert isinstance(tokens('CAPT "ON"')[1], Quoted) and not isinstance(tokens("CAPT ON")[1], Quoted)
    assert tokens("MASK R>6.0") == ["MASK", "R>6.0"]
    assert resolve("outd") == "OUTDAT" and resolve("Adjust") == "ADJUST" and resolve("gam") == "G"
    with pytest.raises(ValueError, match="ambiguous: OUTMOD, OUTDAT, OUTPRO"):
        resolve("OUT")


def test_fix_unfix_lose_bare_act_on_every_term(tmp_path):
    session, runner = session_runner()
    run_text(runner, f"indat {MMT_DAT}\nuse IA IE CA\nfix\n", tmp_path)
    assert session.fixed == {"IA", "IE", "CA"}
    run_text(runner, "unfix\nfix ca\n", tmp_path)
    assert session.fixed == {"CA"}
    run_text(runner, "lose ie\n", tmp_path)
    assert session.terms == ["IA", "CA"]
    run_text(runner, "lose\n", tmp_path)
    assert session.terms == [] and session.fixed == set()


def test_pltz_and_gc_forms(tmp_path):
    """PLTZ refuses a panel TPOINT does not have; GC alone writes nothing; GC P FILE
    and a quoted GC name write the page; a PROC needs a name."""
    session, runner = session_runner()
    with pytest.raises(ProcedureError, match="t.ptp:1: PLTZ: takes one panel of TL, TC"):
        run_text(runner, "PLTZ XX", tmp_path)
    run_text(runner, f"indat {MMT_DAT}\nuse IA IE\nfit\npltz cc\ng e n\ngc\npltz\n", tmp_path)
    assert list(tmp_path.glob("*.ps")) == []
    run_text(runner, 'gc p "my page.pdf"', tmp_path)
    assert (tmp_path / "my page.pdf").read_bytes()[:5] == b"%PDF-"
    with pytest.raises(ProcedureError, match="t.ptp:1: GC: "):  # quoted: a file name, not device P
        run_text(runner, 'gc "P"', tmp_path)
    assert not (tmp_path / "P").exists()
    with pytest.raises(ProcedureError, match="PROC needs a procedure name"):
        run_text(runner, "PROC", tmp_path)


# --------------------------------------------------------------------------- (4) a bino.procs-shaped file

# Written for this test in the shape of MMT's public bino.procs (whose repository has no
# licence, so its text is not copied here): a run procedure that fits, masks, adds a
# harmonic and writes a model file and a nine-panel page after each step, and a plot
# procedure whose PROC line carries free text, with a bare GC, CAPT OFF / ON switches,
# PLTZ panels and GSCAT with TPOINT's option.
SHAPED_PROCS = """\
PROC STEPS
    indat "run copy.dat"
    use ia ie npae ca an aw tf tx
    fit
    call A9
    gc b step1.ps
    outmod step1.mod
    mask r > 6
    fit
    call A9
    gc b step2.ps
    outmod step2.mod
    use hesa
    fit
    call A9
    gc b step3.ps
    outmod step3.mod
    mask r > 2
    fit
    call A9
    gc b step4.ps
    outmod step4.mod
RETURN

PROC A9   nine residual plots for an alt-az mount (free text after the name)
    CAPT OFF
    GC
    CLRNG OFF
    PLTZ TL
    G S A
    PLTZ TC
    G S Z
    PLTZ TR
    G Z A
    PLTZ CL
    G Z Z
    PLTZ CC
    G V A
    PLTZ CR
    GAM Z
    PLTZ BL
    GSCAT A
    PLTZ BC
    GDIST
    CAPT ON
    PLTZ BR
    GSMAP
    CLRNG ON
    PLTZ
RETURN
"""


def test_bino_procs_shaped_file_runs(mmt_run, tmp_path, capsys):
    """A procedure file in the shape of MMT's bino.procs (a quoted INDAT of a name with
    a blank, the MMT run copied there), then CALL STEPS: four model files and four
    nine-panel pages, the last fit on the stars MASK R > 2 left."""
    shutil.copy(mmt_run, tmp_path / "run copy.dat")
    procs = write(tmp_path, "steps.procs", SHAPED_PROCS)
    call = write(tmp_path, "call.ptp", "call steps\n")
    assert main(["tpoint", "--azimuth", "S-E", str(procs), str(call)]) == 0
    out = capsys.readouterr().out
    for k in range(1, 5):
        assert ref.read_model_values(tmp_path / f"step{k}.mod")[0]["IA"] == pytest.approx(1209.3, abs=0.5)
        assert (tmp_path / f"step{k}.ps").read_bytes()[:4] == b"%!PS"
    values, _, n, rms = ref.read_model_values(tmp_path / "step4.mod")
    assert "HESA" in values and 70 < n < 80 and rms < 0.95
    assert out.count("GSCAT A: drawn in panel BL") == 4 and "not implemented" not in out

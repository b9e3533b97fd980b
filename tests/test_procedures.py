"""``pointax tpoint``: TPOINT procedures on the MMT run.

References: an independent NumPy implementation of TPOINT's terms, its linear least
squares, the rigorous residuals and one Gauss-Newton step (tests/tpoint_numpy.py), and
TPOINT's own model file of the run.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
import tpoint_numpy as ref
from conftest import MMT_DAT, MMT_MOD

from pointax.cli import main
from pointax.io import TpointFormatError
from pointax.procedures import ProcedureError, Runner, Session
from pointax.procedures.parser import resolve
from pointax.procedures.session import read_run

EIGHT = "IA IE NPAE CA AN AW TF TX".split()


@pytest.fixture(autouse=True)
def no_compilation_cache(monkeypatch):
    monkeypatch.setenv("POINTAX_JAX_CACHE", "")


def script(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text)
    return path


def check_model_file(path, names, coefs, rms, sigmas, n):
    """The model file holds ``coefs`` (radians), their sigmas, N and the Sky RMS (4 and
    5 decimals in the file)."""
    values, file_sigmas, file_n, file_rms = ref.read_model_values(path)
    assert list(values) == names
    np.testing.assert_allclose([values[k] for k in names], np.asarray(coefs) / ref.ARCSEC, atol=2e-4)
    np.testing.assert_allclose([file_sigmas[k] for k in names], np.asarray(sigmas) / ref.ARCSEC, atol=2e-4)
    assert file_n == n
    assert abs(file_rms - rms / ref.ARCSEC) < 2e-4


# --------------------------------------------------------------------------- done when


def test_observatory_procedure_matches_numpy_steps(shared_data, tmp_path, capsys):
    """Read the run, fit 8 terms, MASK R > 6, fit, add HESA, fit, MASK R > 2, fit: a
    model file and a plot after each FIT, each model file equal to NumPy's steps."""
    data = shared_data / "tpoint" / "mmt_20210821.dat"
    (tmp_path / "out").mkdir()
    procs = script(
        tmp_path,
        "procs.ptp",
        "! procedures of the observatory\n"
        "PROC SAVE1\n  outmod out/step1.mod\n  g s a\n  gc out/step1.png\nRETURN\n"
        "PROC SAVE2\n  OUTMOD out/step2.mod\n  G S A\n  GC out/step2.png\nRETURN\n",
    )
    main_script = script(
        tmp_path,
        "observatory.ptp",
        f"InDat {data}      ! the run\n"
        f"inpro {procs.name}\n"
        "use IA IE NPAE CA AN AW TF TX\n"
        "fit\n"
        "call save1\n"
        "MASK R > 6\n"
        "FIT\n"
        "save2\n"
        "USE HESA\n"
        "fit\n"
        "outm out/step3.mod\n"
        "GSMAP\n"
        "gc out/step3.svg\n"
        "mask r>2\n"
        "fit\n"
        "outmod out/step4.mod\n"
        "GHIST\n"
        "GC out/step4.pdf\n",
    )
    # The NumPy steps (tests/tpoint_numpy.py) are of TPOINT's linear terms: --form linear.
    assert main(["tpoint", "--azimuth", "S-E", "--form", "linear", str(main_script)]) == 0
    out = capsys.readouterr().out

    observed, raw, _ = ref.read_run(data)
    used = np.ones(len(observed), bool)
    steps = []
    # FIT from zero: one Gauss-Newton step (it stops short: IA is 1209").
    c, rms, popn, sig = ref.gauss_newton_step(EIGHT, np.zeros(8), observed, raw, used)
    steps.append((EIGHT, c, rms, sig, used.copy()))
    # MASK R > 6, FIT.
    used &= np.hypot(*ref.sky_residuals(EIGHT, c, observed, raw).T) / ref.ARCSEC <= 6
    c, rms, popn, sig = ref.gauss_newton_step(EIGHT, c, observed, raw, used)
    steps.append((EIGHT, c, rms, sig, used.copy()))
    # USE HESA (from 0), FIT.
    nine = EIGHT + ["HESA"]
    c, rms, popn, sig = ref.gauss_newton_step(nine, np.append(c, 0.0), observed, raw, used)
    steps.append((nine, c, rms, sig, used.copy()))
    # MASK R > 2, FIT.
    used &= np.hypot(*ref.sky_residuals(nine, c, observed, raw).T) / ref.ARCSEC <= 2
    c, rms, popn, sig = ref.gauss_newton_step(nine, c, observed, raw, used)
    steps.append((nine, c, rms, sig, used.copy()))
    assert 0 < (~used).sum() < 10  # MASK R > 2 masked some stars, R > 6 none here

    for k, (names, coefs, rms, sig, u) in enumerate(steps, 1):
        check_model_file(tmp_path / "out" / f"step{k}.mod", names, coefs, rms, sig, int(u.sum()))
    # The first FIT prints the change of each coefficient (from 0: its value).
    assert f"IA        {steps[0][1][0] / ref.ARCSEC:+10.4f} {steps[0][1][0] / ref.ARCSEC:+12.4f}" in out
    # A second FIT converges: TPOINT's own model file of the converged 8-term fit.
    tpoint_values, tpoint_sigmas, tpoint_n, tpoint_rms = ref.read_model_values(MMT_MOD)
    values, sigmas, n, rms = ref.read_model_values(tmp_path / "out" / "step2.mod")
    for name in EIGHT:
        assert abs(values[name] - tpoint_values[name]) < 0.005, name
        assert abs(sigmas[name] - tpoint_sigmas[name]) < 0.005, name
    assert n == tpoint_n and abs(rms - tpoint_rms) < 0.001
    # The plots: PNG, SVG and PDF files, each as its extension says.
    assert (tmp_path / "out" / "step1.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "out" / "step2.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert b"<svg" in (tmp_path / "out" / "step3.svg").read_bytes()[:2000]
    assert (tmp_path / "out" / "step4.pdf").read_bytes()[:5] == b"%PDF-"


def test_linear_residuals_fix_lose_mask_against_numpy_lstsq(tmp_path, capsys):
    """With TPOINT's linear residuals one FIT is the linear least-squares solution:
    FIX, LOSE, MASK and UNMASK by number against NumPy's lstsq."""
    s = script(
        tmp_path,
        "linear.ptp",
        f"indat {MMT_DAT}\n"
        "use ia ie npae ca an aw tf tx\n"
        "fit\noutmod a.mod\n"
        "fit\noutmod b.mod\n"  # a second FIT changes nothing
        "lose tx\nmask 3 10-12\nfit\noutmod c.mod\n"
        "unmask 11\nfit\noutmod d.mod\n"
        "fix ca\nunmask\nfit\noutmod e.mod\n",
    )
    assert main(["tpoint", "--azimuth", "S-E", "--residuals", "tpoint", "--form", "linear", str(s)]) == 0
    capsys.readouterr()
    observed, raw, _ = ref.read_run(MMT_DAT)
    n = len(observed)

    def expect(names, used, fixed=None):
        free = [k for k in names if k != fixed]
        c = ref.lstsq(free, observed, raw, used, fixed=None if fixed is None else {fixed: held[fixed]})
        full = dict(zip(free, c))
        if fixed is not None:
            full[fixed] = held[fixed]
        coefs = np.array([full[k] for k in names])
        r = ref.tpoint_residuals(names, coefs, observed, raw)
        A, E = observed[:, 0], observed[:, 1]
        J = np.concatenate([np.stack([ref.basis(k, A, E)[0] * np.cos(E) for k in free], -1)[used],
                            np.stack([ref.basis(k, A, E)[1] for k in free], -1)[used]])
        rms, _, sig = ref.statistics(r, used, J, len(free))
        return coefs, rms, dict(zip(free, sig))

    every = np.ones(n, bool)
    seven = EIGHT[:-1]
    masked = every.copy()
    masked[[2, 9, 10, 11]] = False
    for name, names, used in (("a", EIGHT, every), ("b", EIGHT, every), ("c", seven, masked)):
        coefs, rms, sig = expect(names, used)
        check_model_file(tmp_path / f"{name}.mod", names, coefs, rms, [sig[k] for k in names], int(used.sum()))
    unmasked11 = masked.copy()
    unmasked11[10] = True
    coefs, rms, sig = expect(seven, unmasked11)
    check_model_file(tmp_path / "d.mod", seven, coefs, rms, [sig[k] for k in seven], int(unmasked11.sum()))
    held = dict(zip(seven, coefs))  # CA fixed at its value of the last FIT
    coefs, rms, sig = expect(seven, every, fixed="CA")
    values, sigmas, file_n, file_rms = ref.read_model_values(tmp_path / "e.mod")
    np.testing.assert_allclose([values[k] for k in seven], coefs / ref.ARCSEC, atol=2e-4)
    assert "CA" not in sigmas and file_n == n and abs(file_rms - rms / ref.ARCSEC) < 2e-4
    free = [k for k in seven if k != "CA"]
    np.testing.assert_allclose([sigmas[k] for k in free], [sig[k] / ref.ARCSEC for k in free], atol=2e-4)
    assert "=CA" in (tmp_path / "e.mod").read_text().replace(" =", "=")


# --------------------------------------------------------------------------- the language


def test_words_are_case_insensitive_and_abbreviated():
    assert resolve("outm") == "OUTMOD" and resolve("Indat") == "INDAT" and resolve("UNM") == "UNMASK"
    assert resolve("gsmap") == "G" and resolve("GC") == "GC" and resolve("g") == "G"
    assert resolve("clrng") == "CLRNG" and resolve("pltz") == "PLTZ" and resolve("fauto") == "FAUTO"
    assert resolve("mine", ["MINE"]) == "PROC:MINE"
    with pytest.raises(ValueError, match="ambiguous: FIX, FIT"):
        resolve("FI")
    with pytest.raises(ValueError, match="unknown command FROB"):
        resolve("FROB")


def test_unknown_command_names_file_and_line(tmp_path, capsys):
    s = script(tmp_path, "bad.ptp", "! a comment\n\nCAPT first\nFROB 3\nSHOW\n")
    assert main(["tpoint", str(s)]) == 2
    captured = capsys.readouterr()
    assert f"{s}:4: unknown command FROB" in captured.err
    assert "CAPT: first" in captured.out and "mount:" not in captured.out  # stopped at line 4


def test_error_inside_a_procedure_names_its_line_and_the_call(tmp_path, capsys):
    s = script(tmp_path, "p.ptp", "PROC INNER\n  CAPT x\n  NOPE\nRETURN\nINNER\n")
    assert main(["tpoint", str(s)]) == 2
    err = capsys.readouterr().err
    assert f"{s}:3: unknown command NOPE (" in err and err.rstrip().endswith(f"(in procedure INNER, called at {s}:5)")


def test_interactive_session_goes_on_after_an_error():
    out, err = io.StringIO(), io.StringIO()
    runner = Runner(Session(out=out), err=err)
    errors = runner.run_stream(io.StringIO("frob\ncapt after the error\nfit\nshow\n"), interactive=True)
    assert errors == 2  # FROB, and FIT without data
    assert "<stdin>:1: unknown command FROB" in err.getvalue()
    assert "<stdin>:3: FIT: no data: read a run with INDAT FILE first" in err.getvalue()
    assert "CAPT: after the error" in out.getvalue() and "pointax> " in out.getvalue()
    assert "SHOW: no data" in out.getvalue()


def test_procedures_inpro_call_and_relative_names(tmp_path, capsys):
    sub = tmp_path / "sub"
    sub.mkdir()
    script(sub, "lib.ptp", "PROC HELLO\n  CAPT hello from lib\nRETURN\nPROC TWICE\n  hello\n  call hello\nRETURN\n")
    s = script(sub, "main.ptp", "inpro lib.ptp\ntwice\n")
    assert main(["tpoint", str(s)]) == 0
    out = capsys.readouterr().out
    assert out.count("CAPT: hello from lib") == 2 and "procedures HELLO TWICE" in out
    loop = script(tmp_path, "loop.ptp", "PROC LOOP\n LOOP\nRETURN\nLOOP\n")
    assert main(["tpoint", str(loop)]) == 2
    assert "more than 32 nested calls" in capsys.readouterr().err
    for text, message in (
        ("RETURN\n", ":1: RETURN outside a procedure definition"),
        ("PROC P\nCAPT x\n", ":1: PROC P: no RETURN before the end of"),
        ("PROC USE\nRETURN\n", ":1: PROC USE: that is a command's name"),
        ("INPRO missing.ptp\n", ":1: INPRO: "),
    ):
        bad = script(tmp_path, "bad.ptp", text)
        assert main(["tpoint", str(bad)]) == 2
        assert message in capsys.readouterr().err, text


def test_end_stops_a_script_and_settings_are_noted(tmp_path, capsys):
    s = script(tmp_path, "end.ptp", "PLTE 5\nclrng 1 2\nEND\nFROB\n")
    assert main(["tpoint", str(s)]) == 0
    out = capsys.readouterr().out
    assert "PLTE: display setting accepted (5)" in out and "CLRNG: display setting accepted (1 2)" in out


def test_mount_option(tmp_path, capsys):
    # A file without a mount record is read as alt-az with --mount altaz (the default),
    # its line numbers those of the file.
    text = MMT_DAT.read_text().replace(": ALTAZ\n", "")
    plain = tmp_path / "plain.dat"
    plain.write_text(text)
    run = read_run(plain, "altaz", "S-E")
    _, _, lines = ref.read_run(plain)
    np.testing.assert_array_equal(run.lines, lines)
    # Read as equatorial, the four numbers are hour angles and declinations: refused.
    with pytest.raises(TpointFormatError, match=r"plain\.dat:\d+: observation record: field 1 \(star HA\)"):
        read_run(plain, "equatorial")
    # A file that names its mount is read as it says, whatever --mount.
    assert read_run(MMT_DAT, "equatorial", "S-E").mount == "altaz"


def test_errors_before_data(tmp_path):
    session = Session(out=io.StringIO())
    runner = Runner(session, err=io.StringIO())
    with pytest.raises(ProcedureError, match="INDAT FILE first"):
        runner.run_lines(iter([next(iter(_lines("MASK R > 3", tmp_path)))]))
    with pytest.raises(ProcedureError, match="GC: no figure yet"):
        runner.run_lines(iter(_lines("GC x.png", tmp_path)))


def _lines(text, folder):
    from pointax.procedures.parser import lines_of

    return list(lines_of(text.splitlines(), "t.ptp", folder))


def test_fauto_adds_a_term_the_data_hold(tmp_path, capsys):
    """FAUTO through the model builder: a 5" HESA signal added to the run's observed
    elevations is found, and FIT then gives NumPy's least squares of the 9 terms."""
    observed, raw, lines = ref.read_run(MMT_DAT)
    shifted = observed[:, 1] + 5 * ref.ARCSEC * ref.basis("HESA", observed[:, 0], observed[:, 1])[1]
    text = MMT_DAT.read_text().splitlines()
    for k, number in enumerate(lines):
        fields = text[number - 1].split()
        fields[1] = f"{np.degrees(shifted[k]):.12f}"
        text[number - 1] = " ".join(fields)
    (tmp_path / "hesa.dat").write_text("\n".join(text) + "\n")
    s = script(tmp_path, "fauto.ptp", "indat hesa.dat\nuse IA IE NPAE CA AN AW TF TX\nfit\nfauto HESA HECA\nfit\noutmod f.mod\n")
    assert main(["tpoint", "--azimuth", "S-E", "--form", "linear", str(s)]) == 0
    out = capsys.readouterr().out
    assert "add" in out and "HESA" in out
    values, _, _, _ = ref.read_model_values(tmp_path / "f.mod")
    nine = EIGHT + ["HESA"]
    assert list(values) == nine
    # FAUTO's model is fitted to convergence, so the FIT after it is the converged fit:
    # NumPy's Gauss-Newton steps from zero until they stop changing.
    observed[:, 1] = shifted
    used = np.ones(len(observed), bool)
    coefs = np.zeros(9)
    for _ in range(4):
        coefs = ref.gauss_newton_step(nine, coefs, observed, raw, used)[0]
    np.testing.assert_allclose([values[k] for k in nine], coefs / ref.ARCSEC, atol=2e-4)
    assert abs(values["HESA"] - 5.2) < 0.5  # the added 5" and the run's own small HESA


def test_gc_postscript_says_so(tmp_path, capsys):
    s = script(tmp_path, "ps.ptp", f"indat {MMT_DAT}\nuse IA IE\nfit\ng e n\ngc plot.ps\ngc plot.eps\n")
    assert main(["tpoint", "--azimuth", "S-E", str(s)]) == 0
    out = capsys.readouterr().out
    assert "GC: PostScript" in out
    assert (tmp_path / "plot.ps").read_bytes()[:4] == b"%!PS"
    assert (tmp_path / "plot.eps").read_bytes()[:4] == b"%!PS"


def test_tpoint_session_forms_of_plot_commands(tmp_path, capsys):
    """Forms seen in observatories' TPOINT sessions: ``call a9`` (A9 as a procedure),
    ``gc p`` (writes tpoint.ps), ``gc b FILE``, ``plton xw``. The A9 drawn equals the
    bare command's nine panels (read from the figure's titles); a procedure named A9
    takes precedence; E9 on an alt-az run is refused by name."""
    from pointax.plots.tpoint_panels import A9_PANELS

    s = script(
        tmp_path, "forms.ptp",
        f"plton xw\nindat {MMT_DAT}\nuse IA IE\nfit\ncall a9\ngc p\na9\ngc b nine.pdf\n",
    )  # fmt: skip
    assert main(["tpoint", "--azimuth", "S-E", str(s)]) == 0
    out = capsys.readouterr().out
    assert out.count("A9: drawn") == 2 and "PLTON: display setting accepted" in out
    assert (tmp_path / "tpoint.ps").read_bytes()[:4] == b"%!PS"
    assert (tmp_path / "nine.pdf").read_bytes()[:5] == b"%PDF-" and "black and white" in out
    session = Session(out=io.StringIO())
    runner = Runner(session, err=io.StringIO())
    runner.run_lines(iter(_lines(f"indat {MMT_DAT}\nuse IA IE\nfit\ncall a9", tmp_path)))
    titles = [ax.get_title() for ax in session.figure.axes if ax.get_title()]
    assert [t.split(":")[0] for t in titles] == list(A9_PANELS)
    before = len(session.out.getvalue())
    runner.run_lines(iter(_lines("proc a9\nshow\nreturn\ncall a9", tmp_path)))
    after = session.out.getvalue()[before:]
    assert "A9: drawn" not in after and "data:" in after  # the procedure's SHOW ran instead
    with pytest.raises(ProcedureError, match="E9 is the equatorial set"):
        runner.run_lines(iter(_lines("e9", tmp_path)))


def test_e9_draws_the_equatorial_set(shared_data):
    """E9 on the German-mount run: nine panels, the cross-declination residual against
    hour angle equal to the fit's first residual component (read from the artists)."""
    import pointax as px
    from pointax.plots import tpoint_graph
    from pointax.plots.tpoint_panels import E9_PANELS

    run = px.io.read_tpoint(shared_data / "tpoint" / "equatorial" / "cgx-l-data.dat")
    result = px.fit(run.model(px.terms.tpoint("IH ID CH NP MA ME", mount="equatorial", latitude=run.latitude)), run)
    fig = tpoint_graph("E9", result, run)
    axes = [ax for ax in fig.axes if ax.get_title()]
    assert [ax.get_title().split(":")[0] for ax in axes] == list(E9_PANELS)
    first = axes[0]
    y = np.concatenate([line.get_ydata() for line in first.get_lines() if line.get_gid() == "used"])
    np.testing.assert_allclose(np.sort(y), np.sort(np.asarray(result.residuals)[:, 0] / px.units.ARCSEC), rtol=1e-9, atol=1e-9)

"""The fitting core (pointax.fitting): structure as data (USE / LOSE / FIX / MASK do not
recompile, counted with JAX's own compilation events), the union's equivalence with
a fit of the model alone, options as one object, and refused false linearity claims.

References: the same fits computed by a model of exactly the user's structure (the
union's extra terms at 0 must change nothing), and NumPy least squares.
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from compile_counter import COUNTER
from conftest import MMT_DAT

import pointax as px
from pointax.fitting import FitOptions, fit_model, structure
from pointax.core.term import angle_pair
from pointax.core.units import ARCSEC

TERMS = "IA IE NPAE CA AN AW TF TX".split()


@pytest.fixture(scope="module", autouse=True)
def fresh_unions():
    """Start from no union: what other test files fitted in this process must not decide
    which union this file's models are embedded in."""
    structure.clear()


@pytest.fixture(scope="module")
def run():
    return px.io.read_tpoint(MMT_DAT, azimuth="S-E")


def _model(run, names, **kw):
    return px.AltAz(px.terms.tpoint(" ".join(names)), azimuth=run.azimuth, **kw)


@pytest.fixture(scope="module")
def first(run):
    return px.fit(_model(run, TERMS), run)


def test_use_lose_fix_mask_do_not_recompile(run, first):
    """After the first fit: other subsets of its terms, fixed terms at values and masked
    observations run the compiled fit (no XLA compilation at all)."""
    variants = []
    for k in range(len(TERMS)):
        variants.append((_model(run, TERMS[:k] + TERMS[k + 1 :]), {}))
    variants.append((_model(run, ["IA", "IE"]), {}))
    for k, name in enumerate(("IA", "TF", "AW")):
        variants.append((_model(run, TERMS).set(**{name: px.arcsec(10.0 * k)}).fix(name), {}))
    for k in range(3):
        w = np.ones(len(run.observations))
        w[5 * k : 5 * k + 5] = 0
        variants.append((_model(run, TERMS), {"weights": w}))
    with COUNTER as counted:
        results = [px.fit(m, run, **kw) for m, kw in variants]
        _ = [float(r.sky_rms) for r in results]
    assert counted.count == 0
    assert all(bool(r.converged) for r in results)
    assert int(results[-1].n_obs) == len(run.observations) - 5


def test_another_step_limit_does_not_recompile(run, first):
    """The step limit is data of the compiled fit (FitSettings), as the terms, fixes and
    masks are: after the first fit, other limits run it. A fit started away from the
    optimum stops at its limit and says so; given enough steps it takes as many as the
    first fit (20 from the model's zeros) and converges to it."""
    model = _model(run, TERMS)
    with COUNTER as counted:
        results = {k: px.fit(model, run, max_steps=k) for k in (1, 3, 20, 1000)}
        steps = {k: int(r.iterations) for k, r in results.items()}
        converged = {k: bool(r.converged) for k, r in results.items()}
    assert counted.count == 0
    assert steps == {1: 1, 3: 3, 20: int(first.iterations), 1000: int(first.iterations)}
    assert converged == {1: False, 3: False, 20: True, 1000: True}
    assert "maximum number of steps" in results[3].message
    np.testing.assert_array_equal(np.asarray(results[1000].values), np.asarray(first.values))


def test_union_fits_equal_fits_of_the_model_alone(run, first):
    """A subset fitted through the union equals the same fit with exactly the model's
    structure (the core called directly, no union), and NumPy's least squares."""
    sub = ["IA", "IE", "CA", "AN", "AW", "TF"]
    model = _model(run, sub).set(IE=px.arcsec(3.0)).fix("IE")
    through_union = px.fit(model, run)
    obs = run.observations
    alone = jax.jit(lambda m, o: fit_model(m, o, FitOptions()))(model.with_values(model.values()), obs)
    np.testing.assert_allclose(np.asarray(through_union.values), np.asarray(alone.values), rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(through_union.sigmas), np.asarray(alone.sigmas), rtol=1e-9)
    np.testing.assert_allclose(np.asarray(through_union.correlation), np.asarray(alone.correlation), atol=1e-9)
    assert float(through_union.sky_rms) == pytest.approx(float(alone.sky_rms), rel=1e-12)
    assert through_union.names == ("IA", "CA", "AN", "AW", "TF")
    assert float(through_union.model.get("IE")) == pytest.approx(3.0 * ARCSEC)
    # Independent reference: the TPOINT-form fit is linear least squares on DESIGN.md's
    # basis functions; the sky form agrees with it to far below the sigmas.
    assert float(through_union.popn_sd) > float(through_union.sky_rms)


def test_a_term_of_the_other_form_replaces_the_one_of_the_same_name(run, first):
    """Names are unique in a model: a union never carries a linear IA beside a rigorous
    one (checked on the embedding itself: nothing to compile)."""
    assert px.terms.DEFAULT_FORM == "rigorous"  # ``first`` fitted the rigorous terms
    linear = px.AltAz(px.terms.tpoint("IA IE", form="linear"), azimuth=run.azimuth)
    embedding = structure.embed(linear)
    names = [t.name for t in embedding.model.terms]
    assert len(names) == len(set(names))
    kinds = {t.name: type(t) for t in embedding.model.terms}
    assert kinds["IA"] is type(linear.terms[0]) and kinds["IE"] is type(linear.terms[1])
    free = [p.name for p, f in zip(embedding.model.parameters, embedding.free) if f]
    assert free == ["IA", "IE"]
    default = structure.embed(_model(run, ["IA", "IE"]))  # back in the eight-term union
    assert [t.name for t in default.model.terms] == TERMS
    assert list(default.index) == [0, 1] and int(np.sum(default.free)) == 2


def test_non_neutral_terms_are_never_carried(run):
    """A term whose zero is not 'no effect' is not kept in a union for a model that
    lacks it; a union never carries more than MAX_EXTRA_TERMS absent terms."""

    class Offset(px.Term):
        """Adds (1 + c) arcsec to the elevation: not neutral at c = 0."""

        c: float = px.terms.param(0.0)

        def sky_offset(self, angles):
            return angle_pair(0.0, (1.0 + self.c) * ARCSEC)

    assert not structure.is_neutral(Offset())
    assert structure.is_neutral(px.terms.tpoint("IA")[0])
    with_offset = _model(run, ["IA", "IE"]).with_terms(Offset())
    assert "Offset" in [t.name for t in structure.embed(with_offset).model.terms]
    plain = structure.embed(_model(run, ["IA", "IE"]))
    assert "Offset" not in [t.name for t in plain.model.terms]
    many = px.terms.tpoint("IA IE HACA1 HACA2 HACA3 HACA4 HASA1 HASA2 HASA3 HASA4 HECE1 HECE2 HECE3 HECE4 HESE1 HESE2 HESE3 HESE4 HESA2")
    structure.embed(px.AltAz(many, azimuth=run.azimuth))
    small = structure.embed(_model(run, ["IA", "IE"]))
    assert len(small.model.terms) - 2 <= structure.MAX_EXTRA_TERMS


def test_options_as_one_object(run, first):
    options = FitOptions(solver="gauss-newton", max_steps=50)
    a = px.fit(_model(run, TERMS), run, options=options)
    b = px.fit(_model(run, TERMS), run, solver="gauss-newton", max_steps=50)
    np.testing.assert_array_equal(np.asarray(a.values), np.asarray(b.values))
    with pytest.raises(ValueError, match="either options= or the keywords"):
        px.fit(_model(run, TERMS), run, options=options, solver="lm", loss="cauchy")
    with pytest.raises(ValueError, match="unknown solver"):
        FitOptions(solver="newton")
    with pytest.raises(ValueError, match="max_steps must be a positive integer"):
        FitOptions(max_steps=0)


class Squared(px.Term):
    """Claims linearity but is quadratic in its coefficient."""

    coef: float = px.terms.param(0.0)
    linear_sky_offset = True

    def sky_offset(self, angles):
        return angle_pair(self.coef**2 * 1e4 * jnp.sin(angles[0]), 0.0)


class Shifted(px.Term):
    """Claims linearity but is affine with a constant."""

    coef: float = px.terms.param(0.0)
    linear_sky_offset = True

    def sky_offset(self, angles):
        return angle_pair(self.coef + 1e-6, 0.0)


@pytest.mark.parametrize("term, why", [(Squared(), "does not double"), (Shifted(), "is not zero")])
def test_false_linearity_claims_are_refused(term, why):
    with pytest.raises(ValueError, match=f"term {type(term).__name__} declares linear_sky_offset = True, but it {why}"):
        px.AltAz((term,), residual_form="tpoint")


def test_library_claims_hold_numerically():
    """The library's linear terms skip the checks when a model is built (they are linear
    and neutral at 0 by construction); here the checks run on every one of them."""
    from pointax.core.term import _linearity_error

    names = "IA IE NPAE CA AN AW TF TX ACEC ACES ECEC ECES PAA1 PEE1 HACA2 HESE4 HSCA5CE8"
    terms = px.terms.tpoint(names, form="linear")
    assert all(t.linear_by_construction and t.neutral_at_zero for t in terms)
    for t in terms:
        assert _linearity_error(t) == "", t.name
        assert structure._probe_values([t]) == [True], t.name


def test_every_library_term_declares_its_neutral_zero_truly():
    """Every TPOINT term of both forms and both mounts declares itself neutral at 0 (so a
    union carries it switched off without a probe, which would compile), and the probe
    agrees: at every parameter 0 each hook returns nothing, a zero offset or the
    identity rotation, exactly."""
    from pointax.terms import library

    lat = px.deg(33.4)
    extra = {"altaz": "HACA2 HESE4 HSCA5CE8 HZSZ2 PAA1E2 PEE2", "equatorial": "HHSH2 HDCD HXSH2CD PHH1 PDD2"}
    for mount, table in (("altaz", library.FORMS), ("equatorial", library.EQUATORIAL_FORMS)):
        for form in ("linear", "rigorous"):
            built = px.terms.tpoint(list(table[form]) + extra[mount].split(), form=form, mount=mount, latitude=lat)
            for t in built:
                assert t.neutral_at_zero is True, (mount, form, t.name)
            assert structure._probe_values(list(built)) == [True] * len(built), (mount, form)


def test_use_lose_fix_mask_do_not_recompile_in_either_form(run):
    """The same USE / LOSE / FIX / MASK loop in the form that is not the default, from a
    fresh family of unions: after its first fit nothing compiles."""
    other = ({"linear", "rigorous"} - {px.terms.DEFAULT_FORM}).pop()

    def model(names):
        return px.AltAz(px.terms.tpoint(" ".join(names), form=other), azimuth=run.azimuth)

    px.fit(model(TERMS), run)
    variants = [model(TERMS[:k] + TERMS[k + 1 :]) for k in range(len(TERMS))]
    variants += [model(["IA", "IE"]), model(TERMS).set(TF=px.arcsec(5.0)).fix("TF")]
    w = np.ones(len(run.observations))
    w[:5] = 0
    with COUNTER as counted:
        results = [px.fit(m, run) for m in variants] + [px.fit(model(TERMS), run, weights=w)]
        _ = [float(r.sky_rms) for r in results]
    assert counted.count == 0
    assert all(bool(r.converged) for r in results)


# A fit in a fresh process with the caches on (POINTAX_JAX_CACHE), printing what the
# stored programs did, the values, and which of the solver and term libraries (and the
# model families) that an alt-az fit and its listing do not need it imported;
# ``other-jax`` pretends another JAX version, ``untested-jax`` one that stored
# executables are not used with.
_FRESH_FIT = (
    "import json, sys, pointax as px\n"
    "from pointax.fitting import programs, stored_executables\n"
    "px.enable_compilation_cache()\n"
    "if sys.argv[1:] == ['other-jax']:\n"
    "    programs._VERSIONS[:] = [programs._versions().replace('jax=', 'jax=0.0.0+other ')]\n"
    "if sys.argv[1:] == ['untested-jax']:\n"
    "    stored_executables.TESTED_JAX = ()\n"
    f"run = px.io.read_tpoint({str(MMT_DAT)!r}, azimuth='S-E')\n"
    "r = px.fit(px.AltAz(px.terms.tpoint('IA IE NPAE CA AN AW TF TX'), azimuth=run.azimuth), run)\n"
    "from pointax.analysis.listing import observation_entries  # as pointax fit --json\n"
    "lazy = ('optimistix', 'lineax', 'pointax.analysis.families')\n"
    "lazy += tuple('pointax.terms.' + m for m in ('equatorial', 'gpoint', 'xy'))\n"
    "solvers = sorted(m for m in lazy if m in sys.modules)\n"
    "print(json.dumps({'stats': programs.STATS, 'values': [float(v) for v in r.values], 'solvers': solvers}))\n"
)


def _fresh_fit(cache: Path, *argv: str) -> tuple[dict, str]:
    """:data:`_FRESH_FIT` run in a new process with the caches in ``cache``: its
    report and standard error."""
    import json
    import os
    import subprocess
    import sys

    env = {**os.environ, "POINTAX_JAX_CACHE": str(cache)}
    proc = subprocess.run([sys.executable, "-c", _FRESH_FIT, *argv], capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.splitlines()[-1]), proc.stderr


@pytest.fixture(scope="module")
def stored_fit(tmp_path_factory) -> tuple[Path, dict]:
    """The caches folder after a first fresh-process fit (which traced and stored the
    fit), and that fit's report; tests work on copies of the folder."""
    cache = tmp_path_factory.mktemp("stored") / "cache"
    first, _ = _fresh_fit(cache)
    return cache, first


def _copy_of(stored_fit, tmp_path: Path) -> Path:
    import shutil

    return Path(shutil.copytree(stored_fit[0], tmp_path / "cache"))


def test_a_fresh_process_loads_the_compiled_fit(stored_fit, tmp_path):
    """With the caches on, a second process fitting the same structure runs the stored
    executable instead of tracing and compiling the fit (counted, not timed), imports no
    solver library, and gets the same numbers; clear() empties the folder."""
    first = stored_fit[1]
    cache = _copy_of(stored_fit, tmp_path)
    folder = cache / "programs"
    assert first["stats"]["exported"] == 1 and first["stats"]["stored"] == 1 and first["stats"]["loaded"] == 0
    assert first["stats"]["executables_stored"] == 1 and first["stats"]["executables_loaded"] == 0
    second, err = _fresh_fit(cache)
    assert second["stats"]["exported"] == 0 and second["stats"]["executables_loaded"] == 1 and "unreadable" not in err
    assert second["stats"]["loaded"] == 0 and second["stats"]["executables_stored"] == 0  # the program not even read
    # Neither the solvers nor the term classes an alt-az fit does not use, nor the
    # families that analysis's package once imported with the listing.
    assert first["solvers"] == ["lineax", "optimistix"] and second["solvers"] == []
    assert second["values"] == first["values"]
    assert sorted(p.suffix for p in folder.iterdir()) == [".executable", ".program"]
    from pointax.fitting import programs

    programs.clear(folder)
    assert not folder.exists()


def test_without_its_executable_the_stored_program_is_compiled_and_stored_again(stored_fit, tmp_path):
    """A program whose executable is gone (another machine's folder, a deleted file) is
    read and compiled, not traced, and its executable is stored again; with a JAX
    release that stored executables have not been tested on, the program is compiled
    every time and no executable is read or written."""
    first = stored_fit[1]
    cache = _copy_of(stored_fit, tmp_path)
    folder = cache / "programs"
    (executable,) = folder.glob("*.executable")
    executable.unlink()
    untested, err = _fresh_fit(cache, "untested-jax")
    assert untested["stats"]["loaded"] == 1 and untested["stats"]["exported"] == 0 and "unreadable" not in err
    assert untested["stats"]["executables_loaded"] == 0 and untested["stats"]["executables_stored"] == 0
    assert not executable.exists() and untested["values"] == first["values"]
    second, err = _fresh_fit(cache)
    assert second["stats"]["loaded"] == 1 and second["stats"]["executables_stored"] == 1 and "unreadable" not in err
    assert executable.is_file() and second["values"] == first["values"]
    third, _ = _fresh_fit(cache)
    assert third["stats"]["executables_loaded"] == 1 and third["stats"]["loaded"] == 0


def test_an_unreadable_stored_executable_is_compiled_again_with_a_note(stored_fit, tmp_path):
    """A stored executable that cannot be read (truncated; or written by a pointax of
    another format) is compiled again from its program and replaced, and the process
    says so in one line; the numbers are the same."""
    first = stored_fit[1]
    cache = _copy_of(stored_fit, tmp_path)
    (executable,) = (cache / "programs").glob("*.executable")
    whole = executable.read_bytes()
    for broken in (whole[: len(whole) // 2], whole.replace(b"pointax-executable 1 ", b"pointax-executable 9 ", 1)):
        executable.write_bytes(broken)
        second, err = _fresh_fit(cache)
        assert second["stats"]["executables_unreadable"] == 1 and second["stats"]["loaded"] == 1
        assert second["stats"]["executables_stored"] == 1 and second["stats"]["exported"] == 0
        notes = [line for line in err.splitlines() if "unreadable" in line]
        assert len(notes) == 1 and f"stored executable {executable} unreadable" in notes[0], err
        assert "compiling the fit again" in notes[0] and second["values"] == first["values"]
        third, err = _fresh_fit(cache)  # replaced: read as usual
        assert third["stats"]["executables_loaded"] == 1 and "unreadable" not in err
        assert third["values"] == first["values"]


def test_an_unreadable_stored_program_is_traced_again_with_a_note(stored_fit, tmp_path):
    """A stored program that cannot be read (here truncated: a disk filled while it was
    written by hand, another writer) is traced again and replaced, and the process says
    so in one line; the fit's numbers are those of a fresh trace. An entry written by
    other versions of JAX or its libraries is never read: their versions are part of the
    key."""
    first = stored_fit[1]
    cache = _copy_of(stored_fit, tmp_path)
    folder = cache / "programs"
    (entry,) = folder.glob("*.program")
    entry.write_bytes(entry.read_bytes()[: entry.stat().st_size // 2])
    for executable in folder.glob("*.executable"):  # (else the program is not read)
        executable.unlink()
    second, err = _fresh_fit(cache)
    assert second["stats"]["unreadable"] == 1 and second["stats"]["exported"] == 1 and second["stats"]["stored"] == 1
    notes = [line for line in err.splitlines() if "unreadable" in line]
    assert len(notes) == 1 and f"stored program {entry} unreadable" in notes[0] and "tracing the fit again" in notes[0]
    assert second["values"] == first["values"]
    third, err = _fresh_fit(cache)  # replaced: read as usual
    assert third["stats"]["executables_loaded"] == 1 and third["stats"]["exported"] == 0 and "unreadable" not in err
    other, _ = _fresh_fit(cache, "other-jax")  # another key: traced and stored beside, nothing stale read
    assert other["stats"]["loaded"] == 0 and other["stats"]["exported"] == 1 and other["stats"]["unreadable"] == 0
    assert len(list(folder.glob("*.program"))) == 2 and other["values"] == first["values"]


class _Wobble(px.Term):
    """A user term (defined outside pointax): an azimuth-dependent elevation offset."""

    amplitude: float = px.terms.param(0.0)

    def sky_offset(self, angles):
        return angle_pair(0.0, self.amplitude * jnp.sin(2 * angles[0]))


def test_stored_programs_tell_classes_of_the_same_name_apart(run, tmp_path):
    """The linear and rigorous forms of IA, CA, NPAE are classes of the same name: with
    programs kept on disk, each form's fit must run its own program and equal the fit
    compiled directly (the first key named classes by their bare name, so a worker that
    had fitted one form ran its program for the other: 1e-4 relative off). A user's term
    class gets no key on disk (its source is not in the key): it runs in memory only."""
    from pointax.fitting import programs

    models = [px.AltAz(px.terms.tpoint("IA CA NPAE", form=form), azimuth=run.azimuth) for form in ("linear", "rigorous")]
    structure.clear()  # each model in a union of its own terms: the two forms' unions look alike
    direct = [px.fit(m, run) for m in models]
    assert not np.allclose(np.asarray(direct[0].values), np.asarray(direct[1].values), rtol=0, atol=1e-9)
    before = programs.directory()
    programs.set_directory(tmp_path / "programs")
    programs.clear()  # programs this process keeps in memory would not be stored again
    try:
        for _ in range(2):  # the second round runs the programs kept in memory
            via = [px.fit(m, run) for m in models]
            for a, b in zip(via, direct):
                np.testing.assert_allclose(np.asarray(a.values), np.asarray(b.values), rtol=0, atol=1e-13)
        assert len(list((tmp_path / "programs").glob("*.program"))) == 2  # one per form
    finally:
        programs.set_directory(before)
    tree = lambda m: jax.tree.structure((m, np.zeros(2, bool), run.observations))  # noqa: E731
    assert programs._describe(tree(models[0])) is not None
    assert programs._describe(tree(px.AltAz(px.terms.tpoint("IA") + (_Wobble(),)))) is None


def test_a_program_with_a_host_callback_runs_and_is_never_stored(tmp_path):
    """A host callback holds this process's addresses: such a program must not go to disk
    (another process would call into nothing), and must still run, compiled in memory
    (its result's structure recorded by a trace of its own)."""
    from pointax.fitting import programs

    seen = []

    def fn(x, static):
        jax.debug.callback(lambda v: seen.append(float(v)), x.sum())
        return {"twice": x * 2}

    before = programs.directory()
    programs.set_directory(tmp_path / "programs")
    try:
        out = programs.call("callback-test", fn, (np.ones(3),), "s", lambda x, s: jax.tree.structure({"twice": x}))
    finally:
        programs.set_directory(before)
    np.testing.assert_array_equal(np.asarray(out["twice"]), [2.0, 2.0, 2.0])
    jax.effects_barrier()
    assert seen == [3.0]
    assert not (tmp_path / "programs").exists()


def test_a_fit_at_its_step_limit_on_the_optimum_has_converged():
    """A solver stopped by its step limit where the polishing Gauss-Newton step moves no
    parameter beyond the tolerances is at the optimum: converged (Levenberg-Marquardt
    rejects every step there and optimistix only tests convergence after an accepted one,
    which on some jaxlib builds ran a fit to its limit). Started far away, one step is
    not enough, and the fit says so."""
    run = px.io.read_tpoint("examples/data/mmt_20210821.dat", azimuth="S-E")
    model = px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"), azimuth=run.azimuth)
    best = px.fit(model, run)
    assert bool(best.converged)
    for solver in ("lm", "gauss-newton", "dogleg"):
        again = px.fit(best.model, run, max_steps=1, solver=solver)
        assert bool(again.converged) and again.message == "", solver
        np.testing.assert_allclose(np.asarray(again.values), np.asarray(best.values), rtol=0, atol=1e-12)
    far = px.fit(model, run, max_steps=1)
    assert not bool(far.converged)
    assert "maximum number of steps" in far.message


def test_programs_are_traced_one_at_a_time(monkeypatch, tmp_path):
    """Two threads that need new stored programs trace them one after the other (their
    compilations may overlap): side by side, each trace took as long as both
    (fit-network's model groups, benchmarks/network_scale_notes.md)."""
    import threading
    import time

    from pointax.fitting import programs

    inside, most = [0], [0]

    def export(*args):
        inside[0] += 1
        most[0] = max(most[0], inside[0])
        time.sleep(0.05)
        inside[0] -= 1
        return (lambda *leaves: leaves), [jax.tree.structure((0,))]

    monkeypatch.setattr(programs, "_export", export)
    monkeypatch.setattr(programs, "_DIRECTORY", tmp_path)
    monkeypatch.setattr(programs, "_MEMORY", {})

    def call(k):
        programs.call(f"p{k}", None, (np.zeros(k + 1),), k, lambda *a: jax.tree.structure((0,)))

    threads = [threading.Thread(target=call, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert most[0] == 1

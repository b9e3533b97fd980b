"""The everyday interactive loop on one telescope: start-up, one fit, refits (issue 17's targets).

One run, so that every ratio compares figures taken under the same load:

* **fresh processes** (each a new ``sys.executable``, wall seconds from start to exit,
  rounds alternating between the kinds so that a change of load hits them all alike):

  - ``floor``: ``python -c "import jax, jax.numpy as jnp; jnp.ones(3).sum().block_until_ready()"``,
    the floor of any JAX tool;
  - ``import``: ``python -c "import pointax"``;
  - ``help``: ``python -m pointax --help``;
  - ``fit_warm``: ``python -m pointax fit examples/data/mmt_20210821.dat --azimuth S-E --json``
    with the caches warm (``$POINTAX_JAX_CACHE`` and ``$XDG_CACHE_HOME`` in a temporary
    directory that an untimed run of the same command filled first);
  - ``fit_cold``: the same with new, empty cache directories for every run (fewer rounds);
  - ``typo``: ``python -m pointax fit nonexistent.dat`` (a mistyped file name: it must fail,
    and the time until it says so is measured);
  - ``numpy_lstsq``: a plain NumPy script (written to a temporary file) that reads the MMT
    file and solves the linear TPOINT problem of DESIGN.md (IA IE NPAE CA AN AW TF TX;
    ``numpy.linalg.lstsq`` on (dA cos E, dE), basis functions at the observed position),
    process included: a yardstick.

* **katpoint** (yardstick, in one child process): the run read once with
  ``px.io.read_tpoint(path, azimuth="S-E")``, then ``katpoint.PointingModel().fit`` timed
  in-process, median of many calls. katpoint's parameters used, with the TPOINT term each
  stands for (the same correspondence as ``benchmarks/batch_fit.py``, checked against
  katpoint in ``tests/test_terms.py``): P1 = IA, P3 = NPAE, P4 = -CA, P5 = AN, P6 = -AW,
  P7 = -IE, P8 = TF. katpoint has no TX (cot E) term: it fits those seven. Its azimuth
  counts from North through East, so the file's South-based azimuth is turned by 180 deg.

* **one Python session** (a child process whose caches start empty, so nothing an
  earlier process kept on disk helps it): ``import pointax``, read the run, a first
  fit ``px.fit(px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"), azimuth=run.azimuth),
  run)``, then three kinds of refit, each over ``--variants`` different variants (every
  variant is new to the session, as each step of TPOINT's USE / LOSE / FIX / MASK loop is):

  - ``refit_terms``: another subset of the TPOINT terms (the eight minus one, a different
    one each variant, then minus two): USE / LOSE;
  - ``refit_fixed``: one term fixed at a value (``model.set(**{term: value}).fix(term)``),
    a different term and value each variant: FIX;
  - ``refit_masked``: five observations masked (``weights=`` with five zeros), a
    different five each variant: MASK.

  Each refit is timed up to its result on the host (``float(result.sky_rms)`` and the
  values). The judged figure is the median over the variants of each variant's *first*
  call (that is where a recompilation shows; a pointing engineer runs each step once);
  the JSON also has every first call, a second call of each variant (the same refit
  again: JAX's in-memory caches warm) and how many compilations JAX reported during each
  first call.

Targets (issue 17): fit warm <= 1.6x floor, fit cold <= 6 s, ``--help`` <= 0.5x floor,
``import pointax`` <= 1.3x floor, each refit kind <= 50 ms median. The table shows the
median (and minimum) of each figure, its ratio to the floor's median where a target is a
ratio, the target and PASS/FAIL. A process that fails where it should succeed (or
succeeds where it should fail) is reported and fails its target. Writes
``benchmarks/results/interactive.json`` (``--quick``: ``interactive_quick.json``, which
git ignores, so a short run never overwrites the full one).

    .venv/bin/python benchmarks/interactive.py            # 5 rounds, 2 cold, 8 variants per refit kind
    .venv/bin/python benchmarks/interactive.py --quick    # 2 rounds, 1 cold, 3 variants
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RUN_FILE = "examples/data/mmt_20210821.dat"
AZIMUTH = "S-E"
TERMS = ("IA", "IE", "NPAE", "CA", "AN", "AW", "TF", "TX")
ARCSEC = 3.141592653589793 / 180 / 3600
# katpoint parameter (P-number) and factor k with P = k * TPOINT coefficient; no TX.
KATPOINT = {
    "IA": (1, 1.0), "IE": (7, -1.0), "NPAE": (3, 1.0), "CA": (4, -1.0), "AN": (5, 1.0), "AW": (6, -1.0), "TF": (8, 1.0),
}

FLOOR_CODE = "import jax, jax.numpy as jnp; jnp.ones(3).sum().block_until_ready()"

TARGETS = {
    # name: (figure, kind of target, limit); "ratio": median / floor median
    "fit warm <= 1.6x floor": ("fit_warm", "ratio", 1.6),
    "fit cold <= 6 s": ("fit_cold", "seconds", 6.0),
    "--help <= 0.5x floor": ("help", "ratio", 0.5),
    "import <= 1.3x floor": ("import", "ratio", 1.3),
    "refit terms (USE/LOSE) <= 50 ms": ("refit_terms", "seconds", 0.050),
    "refit fixed (FIX) <= 50 ms": ("refit_fixed", "seconds", 0.050),
    "refit masked (MASK) <= 50 ms": ("refit_masked", "seconds", 0.050),
}

# The NumPy yardstick, run as a script of its own (no pointax, no JAX).
NUMPY_SCRIPT = textwrap.dedent(
    '''
    import json, sys
    import numpy as np

    rows = []
    for line in open(sys.argv[1]):
        fields = line.split()
        if len(fields) != 4 or line.startswith(("!", ":")):
            continue
        try:
            rows.append([float(f) for f in fields])
        except ValueError:
            continue
    d = np.radians(np.array(rows))
    a, e, raw_a, raw_e = d.T                                  # observed A E, raw A E (file's azimuth)
    d_a = (a - raw_a + np.pi) % (2 * np.pi) - np.pi          # observed minus raw
    d_e = e - raw_e
    sa, ca, te, ce = np.sin(a), np.cos(a), np.tan(e), np.cos(e)
    zero, one = np.zeros_like(a), np.ones_like(a)
    # IA IE NPAE CA AN AW TF TX (DESIGN.md): dA and dE per unit coefficient
    f_a = np.stack([-one, zero, -te, -1 / ce, -sa * te, -ca * te, zero, zero], 1)
    f_e = np.stack([zero, one, zero, zero, -ca, sa, -ce, -1 / te], 1)
    design = np.concatenate([f_a * ce[:, None], f_e])
    rhs = np.concatenate([d_a * ce, d_e])
    coef, *_ = np.linalg.lstsq(design, rhs, rcond=None)
    resid = rhs - design @ coef
    n = len(a)
    sky_rms = np.sqrt(np.sum(resid**2) / n)
    sigma = sky_rms * np.sqrt(np.diag(np.linalg.inv(design.T @ design)))
    arcsec = np.degrees(1) * 3600
    print(json.dumps({"n": n, "coef_arcsec": (coef * arcsec).tolist(), "sigma_arcsec": (sigma * arcsec).tolist(),
                      "sky_rms_arcsec": float(sky_rms * arcsec)}))
    '''
)


# =========================================================================== fresh processes


def run_process(cmd: list[str], env: dict | None = None) -> dict:
    """Run ``cmd`` in ROOT; wall seconds from start to exit, CPU seconds of the child
    (user + system, from ``wait4``), exit code, the end of its output."""
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=out, stderr=err, stdin=subprocess.DEVNULL)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        stdout, stderr = out.read().decode(errors="replace"), err.read().decode(errors="replace")
    return {"wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime, "rc": proc.returncode,
            "stdout": stdout, "stderr_tail": stderr[-1500:]}


def cache_env(directory: Path) -> dict:
    """The environment with every cache pointax keeps under ``directory``: JAX's
    compilation cache (``$POINTAX_JAX_CACHE``) and anything kept in the user's cache
    directory (``$XDG_CACHE_HOME``)."""
    (directory / "jax").mkdir(parents=True, exist_ok=True)
    (directory / "xdg").mkdir(parents=True, exist_ok=True)
    return {**os.environ, "POINTAX_JAX_CACHE": str(directory / "jax"), "XDG_CACHE_HOME": str(directory / "xdg")}


def process_kinds(script: Path) -> dict:
    """kind -> (command, expects success)."""
    py = sys.executable
    fit = [py, "-m", "pointax", "fit", RUN_FILE, "--azimuth", AZIMUTH, "--json"]
    return {
        "floor": ([py, "-c", FLOOR_CODE], True),
        "import": ([py, "-c", "import pointax"], True),
        "help": ([py, "-m", "pointax", "--help"], True),
        "fit_warm": (fit, True),
        "fit_cold": (fit, True),
        "typo": ([py, "-m", "pointax", "fit", "nonexistent.dat"], False),
        "numpy_lstsq": ([py, str(script), RUN_FILE], True),
    }


def measure_processes(rounds: int, cold_rounds: int, work: Path) -> dict:
    """Every kind once per round, in turn; the cold fit only in the first ``cold_rounds``."""
    script = work / "numpy_lstsq.py"
    script.write_text(NUMPY_SCRIPT)
    kinds = process_kinds(script)
    warm = cache_env(work / "warm")
    print("  filling the warm caches (one untimed fit) ...", flush=True)
    fill = run_process(kinds["fit_warm"][0], warm)
    samples: dict[str, list[dict]] = {kind: [] for kind in kinds}
    for r in range(rounds):
        for kind, (cmd, expect_ok) in kinds.items():
            if kind == "fit_cold":
                if r >= cold_rounds:
                    continue
                env = cache_env(work / f"cold{r}")
            else:
                env = warm
            s = run_process(cmd, env)
            s["ok"] = (s["rc"] == 0) == expect_ok
            if kind in ("fit_warm", "fit_cold", "numpy_lstsq") and s["rc"] == 0:
                try:
                    s["json"] = json.loads(s["stdout"])
                    s["json_ok"] = True
                except json.JSONDecodeError:
                    s["json_ok"] = False
            if r:
                s.pop("json", None)  # the output of the first round is kept, to read; the rest only checked
            s["stdout_tail"] = s.pop("stdout")[-600:]
            samples[kind].append(s)
            flag = "" if s["ok"] else f"  (unexpected exit code {s['rc']})"
            print(f"  round {r + 1}/{rounds} {kind:<12s} {s['wall_s']:7.3f} s{flag}", flush=True)
    return {"commands": {k: v[0] for k, v in kinds.items()}, "expect_success": {k: v[1] for k, v in kinds.items()},
            "warm_fill": {k: fill[k] for k in ("wall_s", "cpu_s", "rc", "stderr_tail")}, "samples": samples}


# =========================================================================== child: katpoint


def child_katpoint(repeats: int) -> dict:
    import warnings

    import katpoint
    import numpy as np

    import pointax as px

    run = px.io.read_tpoint(RUN_FILE, azimuth=AZIMUTH)
    observed, raw = np.asarray(run.observed, float), np.asarray(run.encoder, float)
    # The file counts azimuth from South through East; katpoint from North through East.
    az = (observed[:, 0] + np.pi) % (2 * np.pi)
    el = observed[:, 1]
    d_az = (raw[:, 0] - observed[:, 0] + np.pi) % (2 * np.pi) - np.pi  # katpoint: raw minus requested
    d_el = raw[:, 1] - observed[:, 1]
    enabled = [KATPOINT[n][0] for n in KATPOINT]
    times = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(repeats):
            t0 = time.perf_counter()
            params, _ = katpoint.PointingModel().fit(az, el, d_az, d_el, enabled_params=enabled, keep_disabled_params=True)
            values = [float(params[KATPOINT[n][0] - 1] / KATPOINT[n][1]) for n in KATPOINT]
            times.append(time.perf_counter() - t0)
    # TPOINT's coefficients as the file's (South-based) azimuth defines them: AN and AW
    # change sign with a 180 deg turn of azimuth. IE and TF differ from the eight-term
    # fit because katpoint has no TX.
    turn = {"AN": -1.0, "AW": -1.0}
    return {"katpoint_version": katpoint.__version__, "params": {n: f"P{KATPOINT[n][0]}" for n in KATPOINT},
            "values_arcsec": {n: turn.get(n, 1.0) * v / ARCSEC for n, v in zip(KATPOINT, values)}, "samples_s": times}


# =========================================================================== child: one session


def child_session(n_variants: int) -> dict:
    t_start = time.perf_counter()
    import jax
    import numpy as np

    import pointax as px

    t_import = time.perf_counter() - t_start
    compiles = {"backend": 0, "trace": 0}

    def listener(name: str, seconds: float, **_) -> None:
        if name == "/jax/core/compile/backend_compile_duration":
            compiles["backend"] += 1
        elif name == "/jax/core/compile/jaxpr_trace_duration":
            compiles["trace"] += 1

    jax.monitoring.register_event_duration_secs_listener(listener)

    run = px.io.read_tpoint(RUN_FILE, azimuth=AZIMUTH)
    n_obs = len(np.asarray(run.encoder))

    def host(result) -> float:
        values = getattr(result, "values", None)  # the fitted values on the host too
        if values is not None:
            np.asarray(values)
        return float(result.sky_rms)

    def timed(call) -> dict:
        before = dict(compiles)
        t0 = time.perf_counter()
        rms = host(call())
        seconds = time.perf_counter() - t0
        return {"s": seconds, "sky_rms_arcsec": rms / ARCSEC,
                "compilations": compiles["backend"] - before["backend"], "traces": compiles["trace"] - before["trace"]}

    model = px.AltAz(px.terms.tpoint(" ".join(TERMS)), azimuth=run.azimuth)
    first = timed(lambda: px.fit(model, run))
    again = timed(lambda: px.fit(model, run))
    fitted = px.fit(model, run)
    fitted_value = {t: float(fitted.value(t)) for t in TERMS}  # arcsec

    # USE / LOSE: the eight minus one (a different one each time), then minus two.
    subsets = [tuple(t for t in TERMS if t != drop) for drop in TERMS]
    subsets += [tuple(t for t in TERMS if t not in (TERMS[k], TERMS[(k + 3) % 8])) for k in range(8)]
    # FIX: a different term each time, at its fitted value plus a few arcsec.
    fixes = [(TERMS[k % 8], fitted_value[TERMS[k % 8]] + 1.0 + k) for k in range(16)]
    # MASK: a different five observations each time.
    rng = np.random.default_rng(17)
    masks = [rng.choice(n_obs, 5, replace=False) for _ in range(16)]

    def terms_call(k):
        m = px.AltAz(px.terms.tpoint(" ".join(subsets[k])), azimuth=run.azimuth)
        return lambda: px.fit(m, run)

    def fixed_call(k):
        name, arcsec = fixes[k]
        return lambda: px.fit(model.set(**{name: arcsec * ARCSEC}).fix(name), run)

    def masked_call(k):
        w = np.ones(n_obs)
        w[masks[k]] = 0.0
        return lambda: px.fit(model, run, weights=w)

    describe = {
        "refit_terms": [" ".join(subsets[k]) for k in range(n_variants)],
        "refit_fixed": [f"{fixes[k][0]} = {fixes[k][1]:.3f}\"" for k in range(n_variants)],
        "refit_masked": [sorted(int(i) for i in masks[k]) for k in range(n_variants)],
    }
    out = {"import_s": t_import, "n_obs": n_obs, "first_fit": first, "first_fit_again": again, "variants": describe}
    for kind, make in (("refit_terms", terms_call), ("refit_fixed", fixed_call), ("refit_masked", masked_call)):
        rows = []
        for k in range(n_variants):
            call = make(k)
            try:
                row = {"first": timed(call), "second": timed(call)}
            except Exception as exc:  # noqa: BLE001 -- report, never crash the benchmark
                row = {"error": f"{type(exc).__name__}: {exc}"[:500]}
            rows.append(row)
            if "first" in row:
                shown = f"{row['first']['s'] * 1e3:9.1f} ms first, {row['second']['s'] * 1e3:8.1f} ms again"
            else:
                shown = row["error"]
            print(f"  {kind:<13s} variant {k + 1}/{n_variants}: {shown}", file=sys.stderr, flush=True)
        out[kind] = rows
    return out


# =========================================================================== children from main


def child(option: list[str], env: dict | None = None) -> dict:
    """This script in a fresh process with a ``--child-...`` option; its last line of
    output as a dict, or ``{"error": ...}``. Its progress (standard error) is passed on."""
    cmd = [sys.executable, str(Path(__file__).resolve()), *option]
    proc = subprocess.run(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, text=True)
    lines = proc.stdout.strip().splitlines()
    if proc.returncode != 0 or not lines:
        return {"error": f"exit code {proc.returncode}", "stdout_tail": proc.stdout[-2000:]}
    return json.loads(lines[-1])


# =========================================================================== summary


def stats(values: list[float]) -> dict:
    return {"median": statistics.median(values), "min": min(values), "max": max(values), "n": len(values)} if values else {}


def summarise(out: dict) -> dict:
    """figure -> {median, min, max, n, all_ok}: seconds."""
    figures = {}
    for kind, samples in out["processes"]["samples"].items():
        figures[kind] = {**stats([s["wall_s"] for s in samples]),
                         "cpu_median": statistics.median([s["cpu_s"] for s in samples]),
                         "all_ok": all(s["ok"] for s in samples)}
    kat = out.get("katpoint", {})
    if "samples_s" in kat:
        figures["katpoint"] = {**stats(kat["samples_s"]), "all_ok": True}
    session = out.get("session", {})
    if "first_fit" in session:
        figures["first_fit"] = {**stats([session["first_fit"]["s"]]), "all_ok": True}
        for kind in ("refit_terms", "refit_fixed", "refit_masked"):
            rows = session[kind]
            firsts = [r["first"]["s"] for r in rows if "first" in r]
            seconds = [r["second"]["s"] for r in rows if "second" in r]
            figures[kind] = {**stats(firsts), "all_ok": all("first" in r for r in rows),
                             "second_median": statistics.median(seconds) if seconds else None,
                             "first_compilations": [r["first"]["compilations"] for r in rows if "first" in r]}
    return figures


def judge(figures: dict) -> dict:
    floor = figures.get("floor", {}).get("median")
    targets = {}
    for name, (figure, kind, limit) in TARGETS.items():
        f = figures.get(figure, {})
        if "median" not in f:
            targets[name] = {"figure": figure, "value": None, "limit": limit, "pass": False, "note": "not measured"}
            continue
        value = f["median"] / floor if kind == "ratio" else f["median"]
        targets[name] = {"figure": figure, "kind": kind, "value": value, "median_s": f["median"], "limit": limit,
                         "pass": bool(value <= limit and f["all_ok"])}
        if not f["all_ok"]:
            targets[name]["note"] = "a run failed (see the samples)"
    return targets


LABELS = {
    "floor": "floor: import jax, one tiny op",
    "import": "import pointax",
    "help": "pointax --help",
    "fit_warm": "pointax fit MMT --json (caches warm)",
    "fit_cold": "pointax fit MMT --json (caches cold)",
    "typo": "pointax fit nonexistent.dat",
    "numpy_lstsq": "numpy lstsq script (process)",
    "katpoint": "katpoint PointingModel.fit (in-process)",
    "first_fit": "session: first px.fit of the run",
    "refit_terms": "session: refit, other terms (USE/LOSE)",
    "refit_fixed": "session: refit, a term fixed (FIX)",
    "refit_masked": "session: refit, 5 obs masked (MASK)",
}


FRESH_PROCESS = ("floor", "import", "help", "fit_warm", "fit_cold", "typo", "numpy_lstsq")


def fmt_s(x: float | None) -> str:
    if x is None:
        return "-"
    return f"{x * 1e3:.1f} ms" if x < 1.0 else f"{x:.2f} s"


def print_table(figures: dict, targets: dict) -> None:
    floor = figures.get("floor", {}).get("median")
    by_figure = {t["figure"]: (name, t) for name, t in targets.items()}
    print(f"\n  {'figure':<42s} {'median':>10s} {'min':>10s} {'n':>3s} {'x floor':>8s} {'target':>10s} {'':>5s}")
    for figure, label in LABELS.items():
        f = figures.get(figure)
        if not f or "median" not in f:
            print(f"  {label:<42s} {'not measured':>10s}")
            continue
        ratio = f"{f['median'] / floor:.2f}" if floor and figure in FRESH_PROCESS else ""
        target, verdict = "", ""
        if figure in by_figure:
            _, t = by_figure[figure]
            target = f"<= {t['limit']}x" if t.get("kind") == "ratio" else f"<= {fmt_s(t['limit'])}"
            verdict = "PASS" if t["pass"] else "FAIL"
        bad = "" if f.get("all_ok", True) else "  (unexpected exit code)"
        print(f"  {label:<42s} {fmt_s(f['median']):>10s} {fmt_s(f['min']):>10s} {f['n']:>3d} {ratio:>8s} "
              f"{target:>10s} {verdict:>5s}{bad}")
    for kind in ("refit_terms", "refit_fixed", "refit_masked"):
        f = figures.get(kind)
        if f and f.get("second_median") is not None:
            print(f"  {'':<4s}{kind}: the same variant again {fmt_s(f['second_median'])} (median); "
                  f"compilations in each first call {f['first_compilations']}")
    print("  (processes: wall seconds, rounds alternating between kinds; refits: first call of each variant, "
          "result on the host)")


# =========================================================================== main


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 rounds, 1 cold, 3 variants, 50 katpoint calls")
    parser.add_argument("--rounds", type=int, default=None, help="rounds of fresh processes (default 5; quick 2)")
    parser.add_argument("--cold-rounds", type=int, default=None, help="rounds with a cold fit (default 2; quick 1)")
    parser.add_argument("--variants", type=int, default=None, help="variants per refit kind (default 8, at most 16; quick 3)")
    parser.add_argument("--katpoint-repeats", type=int, default=None, help="katpoint calls (default 500; quick 50)")
    parser.add_argument("--out", default=None,
                        help="JSON file (default benchmarks/results/interactive.json; --quick: interactive_quick.json)")
    parser.add_argument("--child-katpoint", type=int, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--child-session", type=int, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()

    if args.child_katpoint is not None:
        print(json.dumps(child_katpoint(args.child_katpoint)))
        return {}
    if args.child_session is not None:
        print(json.dumps(child_session(args.child_session)))
        return {}

    rounds = args.rounds or (2 if args.quick else 5)
    cold_rounds = min(rounds, args.cold_rounds or (1 if args.quick else 2))
    n_variants = min(16, args.variants or (3 if args.quick else 8))
    kat_repeats = args.katpoint_repeats or (50 if args.quick else 500)
    if args.out is None:
        args.out = str(HERE / "results" / ("interactive_quick.json" if args.quick else "interactive.json"))

    t_start = time.perf_counter()
    out: dict = {
        "command": " ".join([Path(sys.executable).name, *sys.argv]),
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "python": platform.python_version(),
                    "load_average_at_start": list(os.getloadavg())},
        "quick": args.quick,
        "rounds": rounds,
        "cold_rounds": cold_rounds,
        "variants_per_refit_kind": n_variants,
        "run_file": RUN_FILE,
        "terms": list(TERMS),
    }
    git = run_process(["git", "describe", "--always", "--dirty", "--abbrev=12"])
    out["git"] = git["stdout"].strip() if git["rc"] == 0 else None
    versions = run_process([sys.executable, "-c", "import jax, optimistix, equinox, numpy, json; print(json.dumps({"
                            "'jax': jax.__version__, 'optimistix': optimistix.__version__, 'equinox': equinox.__version__, "
                            "'numpy': numpy.__version__, 'device': str(jax.devices()[0])}))"])
    if versions["rc"] == 0:
        out["machine"].update(json.loads(versions["stdout"].strip().splitlines()[-1]))

    with tempfile.TemporaryDirectory(prefix="pointax-interactive-") as work:
        print(f"fresh processes: {rounds} rounds ({cold_rounds} with a cold fit), kinds alternating")
        out["processes"] = measure_processes(rounds, cold_rounds, Path(work))
        # The children below start with empty caches of their own: nothing kept on disk
        # by earlier runs (or the user's cache directory) helps the session's refits.
        print(f"\nkatpoint: {kat_repeats} fits of the run in one process")
        out["katpoint"] = child(["--child-katpoint", str(kat_repeats)], cache_env(Path(work) / "katpoint"))
        print(f"\none session: first fit, then {n_variants} variants of each refit kind (caches empty at the start)")
        out["session"] = child(["--child-session", str(n_variants)], cache_env(Path(work) / "session"))
    for key in ("katpoint", "session"):
        if "error" in out[key]:
            print(f"  {key} failed: {out[key]['error']}")

    out["figures"] = figures = summarise(out)
    out["targets"] = judge(figures)
    out["machine"]["load_average_at_end"] = list(os.getloadavg())
    out["seconds"] = time.perf_counter() - t_start
    print_table(figures, out["targets"])
    passed = sum(t["pass"] for t in out["targets"].values())
    print(f"\ntargets: {passed} of {len(out['targets'])} pass")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {args.out} ({out['seconds']:.0f} s)")
    return out


if __name__ == "__main__":
    main()

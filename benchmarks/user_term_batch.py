"""A user-defined rotation term in batched fits: ``px.fit_batch`` against a Python loop
of ``px.fit`` over the same sites (issue 17: not slower).

The term is the azimuth-axis wobble of ``examples/new_error_term.py`` with TPOINT's
rigorous basic terms; every site (120 stars, 1" noise) starts the wobble at 1" and phase
0 against a truth of 6" at 35 deg, so every site leaves ``fit_batch``'s fixed-step fast
pass and is fitted by its full loop (the solo fit, site after site, in one compiled
call). Each way is run twice in one process: the first call (tracing and compiling
included) and the second. Values are compared between the two.

    .venv/bin/python benchmarks/user_term_batch.py [--sites 64]

Writes ``benchmarks/results/user_term_batch.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "examples"))

import pointax as px  # noqa: E402
from new_error_term import TRUE_AMP, TRUE_PHASE, AzWobble  # noqa: E402


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sites", type=int, default=64)
    parser.add_argument("--out", default=str(HERE / "results" / "user_term_batch.json"))
    args = parser.parse_args(argv)
    basic = px.terms.tpoint("IA IE NPAE CA AN AW TF", form="rigorous")
    truth = px.AltAz(basic + (AzWobble(amp=TRUE_AMP, phase=TRUE_PHASE),))
    truth = truth.set(IA=px.arcsec(30), IE=px.arcsec(-12), CA=px.arcsec(-9))
    start = px.AltAz(basic + (AzWobble(amp=px.arcsec(1.0)),))
    rng = np.random.default_rng(0)
    sites = []
    for k in range(args.sites):
        enc = np.stack([rng.uniform(0, 2 * np.pi, 120), np.arcsin(rng.uniform(np.sin(0.3), np.sin(1.45), 120))], -1)
        sites.append(px.simulate(truth, enc, noise=px.arcsec(1.0), seed=k))
    batch = px.stack_observations(sites)
    out = {"sites": args.sites, "fit_batch_s": [], "loop_of_fit_s": []}
    for _ in range(2):
        t = time.perf_counter()
        result = px.fit_batch(start, batch)
        batched = np.asarray(result.values)
        out["fit_batch_s"].append(time.perf_counter() - t)
        t = time.perf_counter()
        solo = np.array([np.asarray(px.fit(start, s).values) for s in sites])
        out["loop_of_fit_s"].append(time.perf_counter() - t)
    out["converged"] = int(np.sum(np.asarray(result.converged)))
    out["max_value_difference_rad"] = float(np.max(np.abs(batched - solo)))
    out["fast_pass_iterations"] = "every site leaves the fast pass" if np.all(np.asarray(result.iterations) > 5) else "some sites settle in the fast pass"
    print(f"{args.sites} sites: fit_batch first {out['fit_batch_s'][0]:.2f} s, then {out['fit_batch_s'][1]:.2f} s; "
          f"loop of px.fit first {out['loop_of_fit_s'][0]:.2f} s, then {out['loop_of_fit_s'][1]:.2f} s; "
          f"converged {out['converged']}/{args.sites}; largest value difference {out['max_value_difference_rad']:.1e} rad")  # fmt: skip
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()

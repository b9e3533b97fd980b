"""A/B of batched fits between two checkouts, one process per measurement.

    PYTHONPATH=/path/to/other/checkout .venv/bin/python benchmarks/batch_ab.py /path/to/other/checkout [CASES]
    .venv/bin/python benchmarks/batch_ab.py . [CASES]

Fits ``benchmarks/batch_fit.py``'s simulated turntables (the paper's five parameters)
and TPOINT runs (eight terms, in TPOINT's residual form and in the exact sky form) at
10,000 sites with ``px.fit_batch``; CASES, comma separated, picks some of ``turntable``,
``tpoint`` and ``sky`` (default: all three): the first call (tracing, compilation and the fit) and the best of three
later calls. Prints one JSON line. Run the two checkouts alternately, several rounds, in
one session, and compare the rounds side by side (``benchmarks/interactive_notes.md``).
"""

import json
import sys
import time

import numpy as np

sys.path.insert(0, sys.argv[1] + "/benchmarks")
import batch_fit as bf  # noqa: E402

import pointax as px  # noqa: E402

N_SITES = 10_000


def _time(fit) -> tuple[float, float]:
    start = time.perf_counter()
    np.asarray(fit().values)
    first = time.perf_counter() - start
    best = np.inf
    for _ in range(3):
        start = time.perf_counter()
        np.asarray(fit().values)
        best = min(best, time.perf_counter() - start)
    return first, N_SITES / best


def main() -> None:
    cases = sys.argv[2].split(",") if len(sys.argv) > 2 else ["turntable", "tpoint", "sky"]
    out = {}
    if "turntable" in cases:
        data = bf.simulate_turntables(N_SITES, seed=0)
        obs, starts = bf.observations(data, "turntable", N_SITES), bf.turntable_starts(data)
        turntable = px.Turntable("full")
        out["turntable_first_s"], out["turntable_fits_per_s"] = _time(lambda: px.fit_batch(turntable, obs, values=starts))
    data = bf.simulate_tpoint(N_SITES, seed=1)
    obs = bf.observations(data, "N-E", N_SITES)
    for form in ("tpoint", "sky"):
        if form in cases:
            model = px.AltAz(px.terms.tpoint(" ".join(bf.TPOINT_TERMS), form="linear"), residual_form=form)
            out[f"{form}_first_s"], out[f"{form}_fits_per_s"] = _time(lambda: px.fit_batch(model, obs))
    print(json.dumps(out))


if __name__ == "__main__":
    main()

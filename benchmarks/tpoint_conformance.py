"""pointax against TPOINT on the bundled MMT run: deviations and fit time.

Fits the terms of TPOINT's model file in both forms, prints every value, sigma and the
Sky RMS next to TPOINT's, the largest deviations, and the time of the first (compiling)
and later fits; writes benchmarks/results/tpoint_conformance.json.

    .venv/bin/python benchmarks/tpoint_conformance.py
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import pointax as px

HERE = Path(__file__).resolve().parent
DATA = HERE.parent / "examples" / "data"


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timed fits after the first (default 5)")
    parser.add_argument("--out", default=str(HERE / "results" / "tpoint_conformance.json"))
    args = parser.parse_args()

    run = px.io.read_tpoint(DATA / "mmt_20210821.dat", azimuth="S-E")
    tpoint = px.io.read_model(DATA / "mmt_20210821.mod")
    out = {"data": "examples/data/mmt_20210821.dat", "n_obs": len(run), "tpoint_sky_rms": tpoint.sky_rms, "forms": {}}
    for form in ("linear", "rigorous"):
        model = px.AltAz(px.terms.tpoint(tpoint.names, form=form), azimuth=run.azimuth)
        t0 = time.perf_counter()
        result = px.fit(model, run)
        first = time.perf_counter() - t0
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            px.fit(model, run).values.block_until_ready()
            times.append(time.perf_counter() - t0)
        rows = []
        for term in tpoint.terms:
            v, s = result.value(term.name), result.sigma(term.name)
            rows.append(
                {
                    "name": term.name,
                    "tpoint_value": term.value,
                    "value": v,
                    "d_value": v - term.value,
                    "d_value_in_sigma": (v - term.value) / term.sigma,
                    "tpoint_sigma": term.sigma,
                    "sigma": s,
                    "d_sigma": s - term.sigma,
                }
            )
        sky_rms = float(result.sky_rms) / px.units.ARCSEC
        out["forms"][form] = {
            "terms": rows,
            "sky_rms": sky_rms,
            "d_sky_rms": sky_rms - tpoint.sky_rms,
            "max_abs_d_value_arcsec": max(abs(r["d_value"]) for r in rows),
            "max_abs_d_value_in_sigma": max(abs(r["d_value_in_sigma"]) for r in rows),
            "max_abs_d_sigma_arcsec": max(abs(r["d_sigma"]) for r in rows),
            "converged": bool(result.converged),
            "iterations": int(result.iterations),
            "first_fit_seconds_incl_compile": first,
            "fit_seconds_median": sorted(times)[len(times) // 2] if times else None,
        }
        print(f"\n{form} form: {int(result.iterations)} iterations, converged={bool(result.converged)}")
        print(f"  {'term':<6s} {'TPOINT':>11s} {'pointax':>11s} {'diff':>8s} {'diff/sig':>8s} {'sig TP':>8s} {'sig px':>8s}")
        for r in rows:
            print(
                f"  {r['name']:<6s} {r['tpoint_value']:+11.4f} {r['value']:+11.4f} {r['d_value']:+8.4f} "
                f"{r['d_value_in_sigma']:+8.4f} {r['tpoint_sigma']:8.4f} {r['sigma']:8.4f}"
            )
        f = out["forms"][form]
        print(f"  Sky RMS: TPOINT {tpoint.sky_rms:.4f}  pointax {sky_rms:.4f}  diff {f['d_sky_rms']:+.4f}")
        print(
            f"  largest |diff|: value {f['max_abs_d_value_arcsec']:.4f}\" ({f['max_abs_d_value_in_sigma']:.4f} sigma), "
            f"sigma {f['max_abs_d_sigma_arcsec']:.4f}\""
        )
        print(f"  time: first fit {first:.2f} s (compiles), later fits {f['fit_seconds_median'] * 1e3:.1f} ms (median)")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=2) + "\n")
    print(f"\nwrote {args.out}")
    return out


if __name__ == "__main__":
    main()

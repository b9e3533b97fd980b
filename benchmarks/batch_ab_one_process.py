"""A/B of batched fits between this checkout and another, both in one process.

    .venv/bin/python benchmarks/batch_ab_one_process.py OTHER_CHECKOUT [--cases turntable,tpoint,sky]
        [--calls 30] [--json PATH]

Between processes this machine's speed drifts by 10-15 %, which hides a difference of a
few per cent however many rounds ``benchmarks/batch_ab.py`` runs. Here the other
checkout's package is copied under another name (``pointax_other``, its imports are
relative) and imported beside this one, and the two fit the same simulated sites
(``benchmarks/batch_fit.py``: turntables, and TPOINT runs in TPOINT's residual form and
in the exact sky form, 10,000 sites) with ``px.fit_batch``, calls alternating, each
after two calls that compile. Both packages must give the same values. Prints a table
of the median call and the median of the paired ratios (this checkout's time over the
other's, below 1 when this one is faster) and writes JSON.
"""

from __future__ import annotations

import argparse
import importlib
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import batch_fit as bf  # noqa: E402

import pointax as px  # noqa: E402

N_SITES = 10_000


def load_other(checkout: Path):
    """The other checkout's ``pointax`` package, imported as ``pointax_other``."""
    folder = Path(tempfile.mkdtemp(prefix="pointax-ab-"))
    shutil.copytree(checkout / "pointax", folder / "pointax_other", ignore=shutil.ignore_patterns("__pycache__"))
    sys.path.insert(0, str(folder))
    return importlib.import_module("pointax_other")


def commit(checkout: Path) -> str | None:
    """The checkout's commit (with ``+`` when its tree has changes), or None outside git."""
    try:
        head = subprocess.run(["git", "-C", str(checkout), "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True)
        dirty = subprocess.run(["git", "-C", str(checkout), "status", "--porcelain", "--untracked-files=no"], capture_output=True, text=True)
    except (OSError, subprocess.CalledProcessError):
        return None
    return head.stdout.strip() + ("+" if dirty.stdout.strip() else "")


def tpoint_terms(pkg, spec: str):
    """TPOINT's terms in their linear forms (older packages took no ``form``: linear was their only one)."""
    try:
        return pkg.terms.tpoint(spec, form="linear")
    except TypeError:
        return pkg.terms.tpoint(spec)


def fits_for(case: str, packages: dict) -> dict:
    """One ``fit_batch`` call per package for ``case``, as a function of no arguments."""
    fits = {}
    if case == "turntable":
        data = bf.simulate_turntables(N_SITES, seed=0)
        starts = bf.turntable_starts(data)
    else:
        data = bf.simulate_tpoint(N_SITES, seed=1)
    convention = "turntable" if case == "turntable" else "N-E"
    for name, pkg in packages.items():
        obs = pkg.stack_observations(
            [pkg.Observations(data["encoder"][k], data["target"][k], convention=convention) for k in range(N_SITES)]
        )
        if case == "turntable":
            model = pkg.Turntable("full")
            fits[name] = lambda pkg=pkg, model=model, obs=obs: pkg.fit_batch(model, obs, values=starts)
        else:
            model = pkg.AltAz(tpoint_terms(pkg, " ".join(bf.TPOINT_TERMS)), residual_form=case)
            fits[name] = lambda pkg=pkg, model=model, obs=obs: pkg.fit_batch(model, obs)
    return fits


def measure(fits: dict, calls: int) -> dict[str, np.ndarray]:
    """Seconds per call, the packages alternating (each pair in turned order every other time)."""
    values = {}
    for name, fit in fits.items():
        result = fit()
        values[name] = np.asarray(result.values)
        if not np.all(np.asarray(result.converged)):
            raise SystemExit(f"{name}: not every site converged")
        fit()
    this, other = values["this"], values["other"]
    if not np.allclose(this, other, rtol=0, atol=1e-9):
        raise SystemExit(f"the two checkouts fit different values (largest difference {np.max(np.abs(this - other)):.3g})")
    times = {name: [] for name in fits}
    names = list(fits)
    for k in range(calls):
        for name in names if k % 2 == 0 else names[::-1]:
            start = time.perf_counter()
            np.asarray(fits[name]().values)
            times[name].append(time.perf_counter() - start)
    return {name: np.array(t) for name, t in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[1])
    parser.add_argument("other", type=Path, help="the other checkout (a folder holding pointax/)")
    parser.add_argument("--cases", default="turntable,tpoint,sky")
    parser.add_argument("--calls", type=int, default=30)
    parser.add_argument("--json", type=Path, default=HERE / "results" / "batch_ab_one_process.json")
    args = parser.parse_args()
    packages = {"this": px, "other": load_other(args.other.resolve())}
    rows = []
    print(f"{'case':10s} {'other ms':>9s} {'this ms':>8s} {'this/other':>11s} {'this faster':>12s}")
    for case in args.cases.split(","):
        times = measure(fits_for(case, packages), args.calls)
        ratio = times["this"] / times["other"]
        row = {
            "case": case,
            "other_median_ms": 1e3 * float(np.median(times["other"])),
            "this_median_ms": 1e3 * float(np.median(times["this"])),
            "paired_ratio_median": float(np.median(ratio)),
            "this_faster_calls": int(np.sum(ratio < 1)),
            "calls": args.calls,
        }
        rows.append(row)
        print(
            f"{case:10s} {row['other_median_ms']:9.1f} {row['this_median_ms']:8.1f} "
            f"{row['paired_ratio_median']:11.3f} {row['this_faster_calls']:>7d}/{args.calls}"
        )
    args.json.parent.mkdir(parents=True, exist_ok=True)
    record = {"this": commit(HERE.parent), "other": commit(args.other) or str(args.other), "sites": N_SITES, "rows": rows}
    args.json.write_text(json.dumps(record, indent=1) + "\n")


if __name__ == "__main__":
    main()

"""The examples at full size: how long each takes, end to end, in a fresh process.

The documentation site runs the examples at a smaller size (POINTAX_DOCS_QUICK=1,
docs/gallery/); this runs each of examples/*.py as a user would, at its default size
(``python examples/NAME.py``), and times it, so that the timings the examples' and
README's texts quote can be checked against a measurement instead of drifting. Each run
is a new process with JAX's compilation cache off (a user's first run).

Prints a table and writes benchmarks/results/examples.json (``--quick``: the
build-time sizes, examples_quick.json).

    .venv/bin/python benchmarks/examples.py [--quick] [--only NAME ...]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

FULL = {
    "new_error_term": "main()",
    "turntable_sun_calibration": "main()",
    "compare_model_families": "main()",
    "plan_pointing_run": "main(skymap={skymap!r})",
    "sun_sensor_calibration": "main()",
}
"""Each example and the call that runs it at its default (full) size."""

QUICK = {**FULL, "turntable_sun_calibration": "main(realisations=1)", "compare_model_families": "main(draws=0)"}
"""The sizes the documentation site runs (docs/gallery/plot_*.py)."""


def run(name: str, call: str) -> float:
    """Seconds to import and run one example in a fresh process."""
    with tempfile.TemporaryDirectory() as tmp:
        code = (
            f"import sys; sys.path.insert(0, {str(REPO / 'examples')!r}); import {name} as m; "
            f"m.{call.format(skymap=str(Path(tmp) / 'skymap.png'))}"
        )
        env = {**os.environ, "POINTAX_JAX_CACHE": "", "MPLBACKEND": "Agg"}
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", code], check=True, env=env, cwd=REPO, stdout=subprocess.DEVNULL)
        return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="the documentation site's sizes")
    parser.add_argument("--only", nargs="+", metavar="NAME", help="only these examples")
    args = parser.parse_args()
    calls = QUICK if args.quick else FULL
    names = args.only or list(calls)
    rows = []
    print(f"{'example':<28s} {'call':<32s} {'seconds':>8s}")
    for name in names:
        seconds = run(name, calls[name])
        rows.append({"example": name, "call": calls[name], "seconds": round(seconds, 2)})
        print(f"{name:<28s} {calls[name][:32]:<32s} {seconds:8.1f}")
    out = REPO / "benchmarks" / "results" / ("examples_quick.json" if args.quick else "examples.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"machine": platform.platform(), "cpus": os.cpu_count(), "rows": rows}, indent=1) + "\n")
    print(f"wrote {out.relative_to(REPO)}")


if __name__ == "__main__":
    main()

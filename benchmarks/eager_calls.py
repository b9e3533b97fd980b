"""A user's calls of a model outside any jit: time and XLA compilations of the first call
and of the next ones, each group in a fresh process (``pointax.core.compiled``).

    python benchmarks/eager_calls.py [--out benchmarks/results/eager_calls.json]

The bundled MMT run (80 observations) and its eight-term model. Prints a table and
writes JSON. Figures and their history: ``benchmarks/interactive_notes.md``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RUN = ROOT / "examples" / "data" / "mmt_20210821.dat"
TERMS = "IA IE NPAE CA AN AW TF TX"
GROUPS = ("residuals", "mount_direction", "call", "simulate")


def _measure(group: str) -> list[dict]:
    """The rows of one group, measured in this process (a fresh one)."""
    import collections

    import jax
    import numpy as np

    import pointax as px

    compilations = collections.Counter()
    jax.monitoring.register_event_duration_secs_listener(
        lambda event, duration, **kw: compilations.update([event.rsplit("/", 1)[-1]])
    )
    run = px.io.read_tpoint(RUN, azimuth="S-E")
    encoder = np.asarray(run.observations.encoder)

    def timed(label, fn, repeat=1):
        compilations.clear()
        start = time.perf_counter()
        for _ in range(repeat):
            jax.block_until_ready(fn())
        seconds = (time.perf_counter() - start) / repeat
        return {"call": label, "seconds": seconds, "compilations": compilations["backend_compile_duration"] / repeat}

    model = px.AltAz(px.terms.tpoint(TERMS), azimuth=run.azimuth)
    if group == "residuals":
        other = px.AltAz(px.terms.tpoint(TERMS.rsplit(" ", 1)[0]), azimuth=run.azimuth)
        return [
            timed("px.residuals, first call", lambda: px.residuals(model, run)),
            timed("px.residuals, again", lambda: px.residuals(model, run), repeat=5),
            timed("px.residuals, a model of other terms", lambda: px.residuals(other, run)),
        ]
    if group == "mount_direction":
        linear = px.AltAz(px.terms.tpoint(TERMS, form="linear"), azimuth=run.azimuth)
        first = timed("mount_direction (linear form), first call", lambda: linear.mount_direction(encoder[0]))
        again = timed("mount_direction (linear form), each further call", lambda: linear.mount_direction(encoder[1]), repeat=5)
        return [first, again]
    if group == "call":
        return [
            timed("model(encoders), 80 rows, first call", lambda: model(encoder)),
            timed("model(encoders), 80 rows, again", lambda: model(encoder), repeat=5),
        ]
    if group == "simulate":
        as_arrays = model.with_values(model.values())
        return [
            timed("px.simulate, first call", lambda: px.simulate(model, encoder).target),
            timed("px.simulate, the same values as arrays", lambda: px.simulate(as_arrays, encoder).target),
        ]
    raise ValueError(group)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "eager_calls.json"))
    parser.add_argument("--group", choices=GROUPS, help=argparse.SUPPRESS)  # one group, in this process
    args = parser.parse_args()
    if args.group:
        print(json.dumps(_measure(args.group)))
        return
    rows = []
    for group in GROUPS:
        proc = subprocess.run(
            [sys.executable, __file__, "--group", group], capture_output=True, text=True, check=True, cwd=ROOT
        )
        rows += json.loads(proc.stdout.strip().splitlines()[-1])
    print(f"{'call':52s} {'time':>10s} {'compilations':>13s}")
    for row in rows:
        print(f"{row['call']:52s} {row['seconds'] * 1e3:8.1f} ms {row['compilations']:13.1f}")
    git = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], capture_output=True, text=True, cwd=ROOT).stdout.strip()
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps({"command": " ".join(["python", *sys.argv]), "git": git, "rows": rows}, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

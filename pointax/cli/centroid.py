"""``pointax centroid FRAME... [--json]``: the sun's centre in sun-sensor frames.

Reads PNG (8 and 16 bit), FITS and ``.npy`` frames and prints, per frame, the centre
``x``, ``y`` in pixels (origin at the centre of the top-left pixel, x to the right, y
down), the disk radius (along x, pixels), the method used (``intensity`` or ``limb``),
``status`` and ``reason``. With ``--json`` it prints a JSON list with one object per
frame with the keys ``frame``, ``x``, ``y``, ``radius``, ``method``, ``status``,
``reason`` (``null`` where there is no value).

Exit status: 0 when every frame gave a centre, 1 when some frames are bad (no sun,
clipped, cloud, saturated ...), 2 for bad input (a file that cannot be read, a bad
option; every frame is still reported) or when torch or kornia is missing (the message
gives the install line, ``pip install 'pointax[vision]'``).

Wired into the ``pointax`` command by :func:`add_centroid_parser` and
:func:`run_centroid` (the frames and centroids: :mod:`pointax.sunsensor`, loaded by
:func:`run_centroid` only, so that the parser imports no torch).
"""

from __future__ import annotations

import argparse
import json
import math
import sys

from . import choices

__all__ = ["add_centroid_parser", "run_centroid", "main", "METHODS"]

METHODS = choices.CENTROID_METHODS
"""``--method`` choices (those of :func:`pointax.sunsensor.centroids.centroid`), a copy
in :mod:`pointax.cli.choices`, so that building the parser does not import torch."""


def add_centroid_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``centroid`` sub-command to an ``argparse`` sub-parsers object."""
    p = subparsers.add_parser(
        "centroid",
        help="find the sun's centre in sun-sensor frames (PNG, FITS, .npy)",
    )
    p.add_argument("frames", nargs="+", metavar="FRAME", help="frame files: .png (8 or 16 bit), .fits, .npy")
    p.add_argument("--json", action="store_true", help="print one JSON list, an object per frame")
    p.set_defaults(run=run_centroid)
    p.add_argument("--method", choices=METHODS, default="auto", help="centroid method (default: auto)")
    p.add_argument("--radius", type=float, default=None, help="expected sun radius along x, pixels (default: measured)")
    p.add_argument("--aspect", type=float, default=1.0, help="pixel aspect fy/fx of the camera (default 1)")
    p.add_argument(
        "--saturation",
        type=float,
        default=None,
        help="saturation level in frame units (default: the integer type's maximum, e.g. 4095 needs giving for 12-bit data in 16-bit files)",
    )
    return p


def _rows(results, names: list[str], unreadable: dict[int, str]) -> list[dict]:
    """One dict per input file, unreadable files included, in input order."""
    rows, k, found = [], 0, results.to_dicts()
    for i, name in enumerate(names):
        if i in unreadable:
            rows.append(dict(frame=name, x=None, y=None, radius=None, method="", status="bad_input", reason=unreadable[i]))
        else:
            rows.append(found[k] | {"frame": name})
            k += 1
    return rows


def _format(rows: list[dict]) -> str:
    def num(v, width, places):
        return f"{v:{width}.{places}f}" if v is not None else f"{'-':>{width}s}"

    lines = [f"{'frame':<30s} {'x':>10s} {'y':>10s} {'radius':>7s} {'method':>9s}  status"]
    for r in rows:
        tail = r["status"] + (f": {r['reason']}" if r["reason"] else "")
        name = r["frame"] if len(r["frame"]) <= 30 else "..." + r["frame"][-27:]
        lines.append(f"{name:<30s} {num(r['x'], 10, 3)} {num(r['y'], 10, 3)} {num(r['radius'], 7, 2)} {r['method'] or '-':>9s}  {tail}")
    return "\n".join(lines)


def run_centroid(args: argparse.Namespace) -> int:
    """Run ``pointax centroid`` for parsed ``args``; returns the exit status (2, with
    the install line, when torch or kornia is missing)."""
    from ..sunsensor import require_vision

    try:
        require_vision()
    except ImportError as err:
        print(f"pointax centroid: error: {err}", file=sys.stderr)
        return 2
    from ..sunsensor.centroids import centroid
    from ..sunsensor.imageio import FrameReadError, read_frame

    for option in ("radius", "aspect", "saturation"):
        value = getattr(args, option)
        if value is not None and not (math.isfinite(value) and value > 0):
            print(f"pointax centroid: --{option} must be a positive number, got {value}", file=sys.stderr)
            return 2
    names = [str(f) for f in args.frames]
    frames, unreadable = [], {}
    for i, path in enumerate(names):
        try:
            frames.append(read_frame(path))
        except FrameReadError as err:
            unreadable[i] = str(err)
            print(f"pointax centroid: {err}", file=sys.stderr)
    readable = [n for i, n in enumerate(names) if i not in unreadable]
    try:
        results = centroid(
            frames,
            method=args.method,
            radius=args.radius,
            aspect=args.aspect,
            saturation=args.saturation,
            names=readable,
        )
    except ValueError as err:
        print(f"pointax centroid: {err}", file=sys.stderr)
        return 2
    rows = _rows(results, names, unreadable)
    if args.json:
        print(json.dumps(rows, indent=1))
    else:
        print(_format(rows))
    if unreadable:
        return 2
    return 0 if all(r["status"] == "ok" for r in rows) else 1


def main(argv: list[str] | None = None) -> int:
    """Stand-alone entry point (``python -m pointax.cli.centroid FRAME...``)."""
    parser = argparse.ArgumentParser(prog="pointax")
    sub = parser.add_subparsers(dest="command", required=True)
    add_centroid_parser(sub)
    args = parser.parse_args(["centroid", *(sys.argv[1:] if argv is None else argv)])
    return run_centroid(args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

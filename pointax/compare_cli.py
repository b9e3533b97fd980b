"""``pointax compare``: fit several model families to one pointing run and compare them.

    pointax compare DATA --families basic,harmonic [--mount altaz|xy] [--format tpoint|gpoint]
                    [--azimuth N-E|S-E|S-W] [--holdout FRACTION | --folds K] [--seed N]
                    [--per-axis angle|sky] [--form linear|rigorous] [--json]

``--per-axis``: the first axis's RMS of its angle residual (the level-mount paper's eqs
21-23; default for ``--mount xy``) or of the offset on the sky (``dA cos E``, TPOINT's;
default for alt-az).

DATA is a TPOINT input file (``--format tpoint``, the default; ``--azimuth`` says how it
counts azimuth), an RTS2 gpoint file (``--format gpoint``) or, with ``--mount xy``, an
X-Y mount run in the text format below.

``--families`` lists the families: family names separated by commas
(``basic,harmonic``), or families separated by ``;``, each a family name, a term list
or ``label=terms`` (``"basic;IA IE CA NPAE AN AW TF TX HACA2"``,
``"tpoint8=basic;mine=basic HACA2 HESE2"``). Names are those of
:func:`pointax.compare.family_model`: alt-az ``basic`` (TPOINT's eight), ``harmonic``
(those and the second azimuth harmonics), TPOINT term names, and with ``--format
gpoint`` gpoint's names (``gpoint`` = gpoint's seven, ``ia``, extras); X-Y ``basic``,
``harmonic``, ``rotation``, ``linearised`` and term names of :mod:`pointax.terms.xy`.
``--family SPEC`` (repeatable) adds one family whose terms may contain ``;`` (gpoint
extras such as ``az:sincos:az;el:2;2``).

Out of sample: ``--folds K`` (k-fold cross-validation, default 5), ``--holdout
FRACTION`` (that fraction held back at random, ``--seed``), or ``--folds 0`` for none.

**X-Y text format** (``--mount xy``): one star per line, four numbers in degrees,
``L B L0 B0``: the encoder readings ``L, B`` and where the star is, ``L0, B0``, as X-Y
angles (the level-mount paper's eq 20 columns; the direction is ``(sin L0 cos B0, sin
B0, cos L0 cos B0)`` in East-North-Up). ``#`` starts a comment; fields may be separated
by spaces, tabs or commas. :func:`write_xy_run` writes it.

Output: the comparison table (:meth:`pointax.compare.Comparison.table`) or, with
``--json``, one object: ``file``, ``mount``, ``format`` and the keys of
:meth:`pointax.compare.Comparison.to_dict` (``scheme``, ``n_fit``, ``n_validation``,
``families``: per family ``label``, ``n_params``, ``in_sample`` and ``out_of_sample``
(``axis1``, ``axis2``, ``total`` in arcsec, ``n``), ``sky_rms``, ``aic``, ``bic``,
``terms`` with ``significance``, ``warnings``, ``converged``). Exit status: 0 when
every fit converged, 1 when some did not, 2 for bad input (the message names the file,
line and field, or the option).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path

import numpy as np

from .compare import Comparison, compare
from .io import (
    FileFormatError,
    GpointFormatError,
    TpointFormatError,
    read_gpoint,
    read_tpoint,
)
from .mounts import AZIMUTH_CONVENTIONS
from .observations import Observations
from .terms import FORMS
from .terms.xy import FAMILIES as XY_FAMILIES

__all__ = ["add_compare_parser", "run_compare", "read_xy_run", "write_xy_run", "parse_families", "XYFormatError"]


class XYFormatError(FileFormatError):
    """An X-Y run file could not be read; the message names file, line and field."""


XY_FIELDS = ("L", "B", "L0", "B0")


def read_xy_run(path: str | os.PathLike) -> Observations:
    """Read an X-Y run in the text format of this module (``L B L0 B0`` in degrees).

    Returns:
        :class:`pointax.Observations` with convention 'xy': encoder ``(L, B)`` radians,
        targets ``(sin L0 cos B0, sin B0, cos L0 cos B0)`` in East-North-Up.

    Raises:
        XYFormatError: naming the file, line and field of the first bad value.
        OSError: the file cannot be read.
    """
    name = os.fspath(path)
    rows = []
    for number, line in enumerate(Path(path).read_text().splitlines(), 1):
        fields = line.split("#", 1)[0].replace(",", " ").split()
        if not fields:
            continue
        if len(fields) != 4:
            raise XYFormatError(name, number, f"expected 4 numbers L B L0 B0 (degrees), got {len(fields)}: {line.strip()!r}")
        values = []
        for field, token in zip(XY_FIELDS, fields):
            try:
                x = float(token)
            except ValueError:
                raise XYFormatError(name, number, f"not a number: {token!r}", f"field {field}") from None
            if not math.isfinite(x):
                raise XYFormatError(name, number, f"not finite: {token!r}", f"field {field}")
            if field == "B0" and abs(x) > 90.0:
                raise XYFormatError(name, number, f"{x} is outside -90..90 deg", f"field {field}")
            values.append(x)
        rows.append(values)
    if not rows:
        raise XYFormatError(name, None, "no observations (expected lines of L B L0 B0 in degrees)")
    a = np.radians(np.asarray(rows, np.float64))
    L0, B0 = a[:, 2], a[:, 3]
    target = np.stack([np.sin(L0) * np.cos(B0), np.sin(B0), np.cos(L0) * np.cos(B0)], axis=1)
    return Observations(a[:, :2], target, convention="xy")


def write_xy_run(path: str | os.PathLike, observations, comments: tuple[str, ...] = ()) -> None:
    """Write X-Y observations (convention 'xy') in the text format of this module."""
    obs = observations if isinstance(observations, Observations) else observations.observations
    if obs.convention != "xy":
        raise ValueError(f"write_xy_run writes X-Y runs; these observations are {obs.convention!r}")
    enc = np.degrees(np.asarray(obs.encoder, np.float64))
    t = np.asarray(obs.target, np.float64)
    L0 = np.degrees(np.arctan2(t[:, 0], t[:, 2]))
    B0 = np.degrees(np.arcsin(np.clip(t[:, 1], -1.0, 1.0)))
    lines = [f"# {c}" for c in comments]
    lines.append("# X-Y pointing run: L B (encoder readings) L0 B0 (the star), degrees")
    lines += [f"{a:.9f} {b:.9f} {c:.9f} {d:.9f}" for (a, b), c, d in zip(enc, L0, B0)]
    Path(path).write_text("\n".join(lines) + "\n")


def _known_names(mount: str, naming: str) -> set[str]:
    if mount == "xy":
        return set(XY_FAMILIES) | {"linearized"}
    names = {"basic", "harmonic"}
    return names | {"gpoint"} if naming == "gpoint" else names


def parse_families(text: str, extra: list[str] | None, mount: str, naming: str) -> dict[str, str]:
    """``--families`` (and ``--family``) to ``{label: spec}`` (see the module docstring)."""
    items: list[str] = []
    text = (text or "").strip()
    if text:
        if ";" in text:
            items = [s.strip() for s in text.split(";")]
            if any(not s for s in items):
                raise ValueError(f"--families: empty family in {text!r}")
        else:
            parts = [s.strip() for s in text.split(",")]
            known = _known_names(mount, naming)
            items = parts if all(p.lower() in known or p in known for p in parts) else [text]
    items += [s.strip() for s in (extra or []) if s.strip()]
    if not items:
        raise ValueError("--families: give at least one family, e.g. --families basic,harmonic")
    out: dict[str, str] = {}
    for item in items:
        label, sep, spec = item.partition("=")
        if sep and label.strip() and ":" not in label:
            label, spec = label.strip(), spec.strip()
        else:
            label, spec = item, item
        if not spec:
            raise ValueError(f"--families: no terms for family {label!r}")
        if label in out:
            raise ValueError(f"--families: family {label!r} given twice")
        out[label] = spec
    return out


def add_compare_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``compare`` subcommand to an ``argparse`` subparsers object."""
    p = subparsers.add_parser(
        "compare",
        help="fit several model families to one pointing run and compare them (in/out-of-sample RMS, AIC, BIC)",
        description="Fit several model families to one pointing run and compare them fairly.",
    )
    p.add_argument(
        "data", help="pointing run: TPOINT file, gpoint file (--format gpoint) or X-Y text file (--mount xy)"
    )
    p.add_argument(
        "--families",
        default="basic,harmonic",
        help="families: names separated by commas (basic,harmonic), or families separated by ';', each a name, "
        "a term list or label=terms (default: %(default)s)",
    )
    p.add_argument(
        "--family", action="append", default=None, metavar="SPEC", help="one more family (may contain ';'); repeatable"
    )
    p.add_argument("--mount", choices=["altaz", "xy"], default="altaz", help="mount kind (default: altaz)")
    p.add_argument(
        "--format", choices=["tpoint", "gpoint"], default="tpoint", help="alt-az input format (default: tpoint)"
    )
    p.add_argument(
        "--azimuth",
        choices=sorted(AZIMUTH_CONVENTIONS),
        default="N-E",
        help="tpoint: how the file counts azimuth (default N-E; the MMT run is S-E)",
    )
    p.add_argument("--form", choices=sorted(FORMS), default="linear", help="alt-az TPOINT term form (default: linear)")
    group = p.add_mutually_exclusive_group()
    group.add_argument(
        "--holdout", type=float, default=None, metavar="FRACTION", help="hold back this fraction of the stars at random"
    )
    group.add_argument(
        "--folds",
        type=int,
        default=None,
        metavar="K",
        help="k-fold cross-validation (default 5; 0: no out-of-sample test)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the holdout or fold assignment (default: 0)")
    p.add_argument(
        "--per-axis",
        choices=["angle", "sky"],
        default=None,
        help="per-axis RMS of the first axis: its angle (the level-mount paper's; default for --mount xy) "
        "or the offset on the sky (TPOINT's dA cos E; default for altaz)",
    )
    p.add_argument("--max-steps", type=int, default=256, help="solver step limit (default: %(default)s)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    return p


def _observations(args):
    if args.mount == "xy":
        if args.format != "tpoint" or args.azimuth != "N-E":
            raise ValueError(
                "--format and --azimuth apply to alt-az runs; --mount xy reads the X-Y text format (L B L0 B0, degrees)"
            )
        return read_xy_run(args.data), "xy", "tpoint"
    if args.format == "gpoint":
        if args.azimuth != "N-E":
            raise ValueError("--azimuth applies to TPOINT runs; gpoint files count azimuth from South through West")
        return read_gpoint(args.data).observations, "gpoint", "gpoint"
    return read_tpoint(args.data, azimuth=args.azimuth).observations, "tpoint", "tpoint"


def _comparison(args) -> tuple[Comparison, str]:
    obs, fmt, naming = _observations(args)
    families = parse_families(args.families, args.family, args.mount, naming)
    if args.holdout is not None:
        scheme = {"holdout": args.holdout}
    else:
        folds = 5 if args.folds is None else args.folds
        if folds < 0 or folds == 1:
            raise ValueError(f"--folds must be 0 (no out-of-sample test) or at least 2, got {folds}")
        scheme = {"folds": folds} if folds else {}
    if args.max_steps < 1:
        raise ValueError(f"--max-steps must be at least 1, got {args.max_steps}")
    result = compare(
        families,
        obs,
        seed=args.seed,
        per_axis=args.per_axis,
        naming=naming,
        form=args.form,
        max_steps=args.max_steps,
        **scheme,
    )
    return result, fmt


def run_compare(args) -> int:
    """Run ``pointax compare`` for parsed ``args``; returns the exit status (0 every fit
    converged, 1 some did not, 2 bad input, with the message on standard error)."""
    try:
        result, fmt = _comparison(args)
    except (TpointFormatError, GpointFormatError, XYFormatError, ValueError, KeyError, TypeError) as err:
        print(f"pointax compare: error: {err}", file=sys.stderr)
        return 2
    except OSError as err:
        print(f"pointax compare: error: {err.filename or args.data}: {err.strerror or err}", file=sys.stderr)
        return 2
    if args.json:
        out = {
            "file": args.data,
            "mount": args.mount,
            "format": fmt if args.mount == "altaz" else "xy",
            **result.to_dict(),
        }
        print(json.dumps(out, indent=2))
    else:
        print(result.table())
    converged = all(row.converged for row in result.rows)
    return 0 if converged else 1


def main(argv: list[str] | None = None) -> int:
    """Stand-alone entry point (``python -m pointax.compare_cli DATA ...``) until the
    subcommand is wired into ``pointax``."""
    parser = argparse.ArgumentParser(prog="pointax")
    sub = parser.add_subparsers(dest="command", required=True)
    add_compare_parser(sub)
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] != "compare":
        argv = ["compare", *argv]
    return run_compare(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())

"""``pointax command``: encoder commands for wanted directions (the model's inverse,
:func:`pointax.command`). See :mod:`pointax.cli` for the input and output."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from . import choices
from .common import guarded_run

__all__ = ["add_command_parser", "run_command", "read_directions", "parse_params"]

_PREFIX = "pointax"


def add_command_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``pointax command`` to an ``argparse`` sub-parser set; returns its parser."""
    c = subparsers.add_parser("command", help="encoder commands for wanted directions (the model's inverse)")
    c.add_argument("directions", help="text file of 'az el' (deg) per line, or '-' for standard input")
    c.add_argument(
        "--mount",
        choices=["turntable", "altaz", "equatorial"],
        default=None,
        help="mount kind (default: altaz with --model, else turntable; equatorial needs --model and --latitude)",
    )
    c.add_argument("--latitude", type=float, default=None, help="equatorial: site latitude (deg)")
    c.add_argument(
        "--params",
        default="",
        help="parameter values name=value, comma separated, in the parameters' display units "
        "(turntable: degrees, e.g. mu0=0.0751,nu0=0.0145,omega0=-0.0947,alpha0=60.5425,beta0=165.8931)",
    )
    c.add_argument("--terms", default=None, help="terms of the model (default: turntable 'full'; altaz: the --model file's)")
    c.add_argument("--model", metavar="FILE", help="TPOINT model file with the fitted terms (altaz or equatorial)")
    c.add_argument("--form", choices=sorted(choices.TERM_FORMS), default=choices.DEFAULT_TERM_FORM, help="TPOINT term form (default: rigorous, as TPOINT applies its model)")
    c.add_argument(
        "--azimuth",
        choices=sorted(choices.AZIMUTH_CONVENTIONS),
        default="N-E",
        help="altaz: azimuth convention of the encoder readings (and of the model's terms); the input "
        "directions are always N-E (North through East); default N-E",
    )
    c.add_argument("--reflect", action="store_true", help="lines hold sun az el and target az el: command the mirror normal")
    c.add_argument(
        "--limits",
        default=None,
        help="axis limits in degrees: a1min,a1max,a2min,a2max (default: turntable 0,360 on axis 1; altaz none)",
    )
    c.add_argument(
        "--near",
        default=None,
        metavar="A1,A2",
        help="readings (deg) to command nearest: the azimuth wrap branch and, with --solution nearest, the "
        "mechanical solution nearest them (default: the middle of the limits, normal solution)",
    )
    c.add_argument(
        "--solution", choices=choices.SOLUTIONS, default="nearest", help="mechanical solution (default: nearest, i.e. normal)"
    )
    c.add_argument("--json", action="store_true", help="print a JSON list instead of a table")
    c.set_defaults(run=run_command)
    return c


def run_command(args: argparse.Namespace) -> int:
    """Run ``pointax command`` for parsed ``args``; returns the exit status (0 every
    direction commanded, 1 some were not, 2 bad input)."""
    return guarded_run(_PREFIX, _command, args, [args.directions, args.model])


def _number(x) -> float | None:
    """A float for JSON, None (null) where it is not finite."""
    x = float(x)
    return x if math.isfinite(x) else None


def read_directions(path: str, columns: int) -> list[list[float]]:
    """Rows of ``columns`` numbers (degrees) from a text file ('-': standard input),
    naming file and line on error."""
    text = sys.stdin.read() if path == "-" else Path(path).read_text()
    name = "<stdin>" if path == "-" else path
    rows = []
    for number, line in enumerate(text.splitlines(), 1):
        fields = line.split("#", 1)[0].replace(",", " ").split()
        if not fields:
            continue
        if len(fields) != columns:
            raise ValueError(f"{name}:{number}: expected {columns} numbers (degrees), got {len(fields)}: {line.strip()!r}")
        try:
            values = [float(f) for f in fields]
        except ValueError:
            raise ValueError(f"{name}:{number}: not a number in {line.strip()!r}") from None
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"{name}:{number}: non-finite value in {line.strip()!r}")
        elevations = values[1::2]
        if any(abs(e) > 90.0 for e in elevations):
            raise ValueError(f"{name}:{number}: elevation outside -90..90 deg in {line.strip()!r}")
        rows.append(values)
    if not rows:
        raise ValueError(f"{name}: no directions")
    return rows


def parse_params(spec: str, model) -> dict:
    """``--params`` text, ``name=value`` pairs separated by commas (each value in its
    parameter's display unit), as ``{name: internal value}`` for ``model.set``.

    Raises:
        ValueError: an item without ``=``, a name the model lacks, or a value that is not
            a number (the message names ``--params``)."""
    from ..core.units import UNITS

    units = {p.name: p.unit for p in model.parameters}
    out = {}
    for item in filter(None, (s.strip() for s in spec.split(","))):
        name, sep, value = item.partition("=")
        if not sep:
            raise ValueError(f"--params: expected name=value, got {item!r}")
        if name not in units:
            raise ValueError(f"--params: no parameter {name!r}; the model has {', '.join(units)}")
        try:
            out[name] = float(value) * UNITS[units[name]]
        except ValueError:
            raise ValueError(f"--params: {name}: not a number: {value!r}") from None
    return out


def _command_model(args):
    import numpy as np

    from .. import terms as term_library
    from ..io.errors import warn_input
    from ..io.tpoint_model import read_model
    from ..terms.model_factories import AltAz, Turntable
    from ..core.units import UNITS

    mount = args.mount or ("altaz" if args.model else "turntable")
    if args.model and mount == "turntable":
        raise ValueError("--model: a TPOINT model is for --mount altaz or equatorial, not turntable")
    if mount != "equatorial" and args.latitude is not None:
        raise ValueError("--latitude is for --mount equatorial")
    if mount == "turntable":
        model = Turntable(args.terms or "full")
        default_limits = ((0.0, 2 * np.pi), None)
    elif mount == "equatorial":
        if not args.model:
            raise ValueError("--mount equatorial needs --model FILE (the TPOINT model) and --latitude DEG")
        if args.latitude is None or not math.isfinite(args.latitude) or abs(args.latitude) > 90.0:
            raise ValueError("--mount equatorial needs the site's --latitude DEG (-90..90): a model file does not record it")
        model = read_model(args.model).model(form=args.form, mount="equatorial", latitude=math.radians(args.latitude))
        default_limits = None
    else:
        if args.model:
            tpoint_model = read_model(args.model)
            if args.mount is None:
                # The mount inferred from the terms: every term must be an alt-az one.
                try:
                    tpoint_model.check_terms(args.form, "altaz")
                except ValueError as err:
                    raise ValueError(
                        f"{err}\n--model {args.model}: its terms are not all alt-az ones, so the mount cannot be "
                        "taken as altaz: give --mount (an equatorial model: --mount equatorial --latitude DEG)"
                    ) from None
            names = args.terms or " ".join(t.name for t in tpoint_model.terms)
            model = AltAz(term_library.tpoint(names, form=args.form), azimuth=args.azimuth)
            known = set(model.parameter_names)
            model = model.set(**{t.name: t.value * UNITS["arcsec"] for t in tpoint_model.terms if t.name in known})
        else:
            model = AltAz(term_library.tpoint(args.terms or term_library.BASIC_ALTAZ, form=args.form), azimuth=args.azimuth)
        default_limits = None
    given = parse_params(args.params, model)
    if not args.model and not given:
        warn_input(
            "--model",
            None,
            f"no --model file and no --params: commanding the nominal model ({model.describe()}, every "
            "parameter 0), i.e. a mount without pointing errors",
        )
    model = model.set(**given)
    if args.limits is None:
        return model, default_limits
    parts = [p.strip() for p in args.limits.split(",")]
    if len(parts) != 4:
        raise ValueError(f"--limits: expected a1min,a1max,a2min,a2max in degrees, got {args.limits!r}")
    try:
        # An empty field leaves that end of the axis open, e.g. "0,360,," limits axis 1 only.
        deg = [float(p) if p else None for p in parts]
    except ValueError:
        raise ValueError(f"--limits: not a number in {args.limits!r} (degrees; leave a field empty for no limit)") from None
    for k, value in enumerate(deg):
        if value is not None and not math.isfinite(value):
            raise ValueError(f"--limits: field {k + 1} is {parts[k]!r}, not a finite number of degrees")
        if value is not None and abs(value) > 720.0:
            raise ValueError(f"--limits: field {k + 1} is {value:g} deg, beyond two turns (limits are in degrees)")
    for axis in (0, 1):
        lo, hi = deg[2 * axis], deg[2 * axis + 1]
        if lo is not None and hi is not None and lo > hi:
            raise ValueError(f"--limits: axis {axis + 1} is inverted: min {lo:g} deg is above max {hi:g} deg")
    lim = [None if v is None else float(np.radians(v)) for v in deg]
    return model, ((lim[0], lim[1]), (lim[2], lim[3]))


def _near(text: str | None):
    """``--near a1,a2`` (degrees) in radians, or None."""
    if text is None:
        return None
    parts = [p.strip() for p in text.split(",")]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise ValueError(f"--near: expected a1,a2 in degrees, got {text!r}") from None
    if len(values) != 2 or not all(math.isfinite(v) for v in values):
        raise ValueError(f"--near: expected two finite numbers a1,a2 in degrees, got {text!r}")
    if any(abs(v) > 720.0 for v in values):
        raise ValueError(f"--near: {text!r} is beyond two turns (degrees expected)")
    return [math.radians(v) for v in values]


def _conventions(args, model) -> dict:
    """Which azimuth convention the input and the readings are in (for headers and JSON)."""
    mount = args.mount or ("altaz" if args.model else "turntable")
    reading = args.azimuth if mount == "altaz" else None
    return {"input_azimuth": "N-E", "reading_azimuth": reading}


def _command(args) -> int:
    from ..fitting.compilation_cache import enable_compilation_cache

    enable_compilation_cache()  # $POINTAX_JAX_CACHE; empty: off
    import numpy as np

    from ..core.inverse import command, command_reflector
    from ..core.rotations import azel_to_enu_numpy

    near = _near(args.near)
    model, limits = _command_model(args)
    rows = np.asarray(read_directions(args.directions, 4 if args.reflect else 2))
    conventions = _conventions(args, model)
    rad = np.radians(rows)

    if args.reflect:
        sun, target = azel_to_enu_numpy(rad[:, 0], rad[:, 1]), azel_to_enu_numpy(rad[:, 2], rad[:, 3])
        cmd = command_reflector(model, sun, target, limits=limits, solution=args.solution, near=near)
    else:
        cmd = command(model, azel_to_enu_numpy(rad[:, 0], rad[:, 1]), limits=limits, solution=args.solution, near=near)
    reading = np.degrees(np.asarray(cmd.reading))
    ok = np.asarray(cmd.ok)
    residual = np.asarray(cmd.residual)
    reasons = cmd.reasons()
    names = cmd.axis_names
    if args.json:
        out = [
            {
                "input_deg": [float(x) for x in row],
                f"{names[0]}_deg": _number(r[0]),
                f"{names[1]}_deg": _number(r[1]),
                "ok": bool(k),
                "residual_rad": _number(res),
                "reason": why,
                **conventions,
            }
            for row, r, k, res, why in zip(rows, reading, ok, residual, reasons)
        ]
        print(json.dumps(out, indent=2))
    else:
        print(f"# {model.describe()}")
        reading_az = conventions["reading_azimuth"]
        print(
            "# input: azimuth N-E (from North through East), elevation; readings: "
            + (f"{names[0]} in the {reading_az} convention" if reading_az else "the mount's raw axis readings")
        )
        print(f"# {'input (deg)':<40s} {names[0] + ' (deg)':>14s} {names[1] + ' (deg)':>14s}  ok  reason")
        for row, r, k, why in zip(rows, reading, ok, reasons):
            text = " ".join(f"{x:9.4f}" for x in row)
            print(f"  {text:<40s} {r[0]:14.6f} {r[1]:14.6f}  {'yes' if k else 'NO ':3s} {why}")
    return 0 if bool(np.all(ok)) else 1

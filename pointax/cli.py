"""The ``pointax`` command: a thin layer over the Python API.

    pointax fit DATA [--terms IA,IE,...] [--form linear|rigorous] [--json]
    pointax fit DIR --format paint [--terms t1n,t1u,t2e,t2n] [--loss cauchy] [--json]
    pointax fit FILE --format gpoint [--terms ia,ie,tn,te,npae,npoa,tf,az:sin:az:2,HACA2] [--json]
    pointax command DIRECTIONS --mount turntable --params mu0=0.0751,... [--reflect] [--json]
    pointax fit-network MANIFEST [--json] [--quiet] [--chunk-size N] [--scheduler ADDRESS]
    pointax centroid FRAME... [--json] [--method auto|intensity|limb]
    pointax compare DATA --families basic,harmonic,... [--holdout F | --folds K] [--json]

``pointax fit`` reads a TPOINT input file, fits the terms (TPOINT's eight basic alt-az
terms by default) and prints the TPOINT-style report, or with ``--json`` one JSON
object with the keys ``n_obs``, ``sky_rms_arcsec``, ``popn_sd_arcsec``, ``converged``,
``terms`` (``name``, ``value_arcsec``, ``sigma_arcsec``) and ``correlation`` (in the
order of ``terms``), plus ``iterations``, ``message``, ``solver``, ``fixed``,
``loss``, ``outliers`` (0-based indices of observations a robust ``--loss`` rejected;
``n_obs`` counts the observations kept) and ``warnings``. Exit status: 0 on a converged fit, 1 if the fit did not converge, 2 for
bad input.

``pointax fit FILE --format gpoint`` reads an RTS2 gpoint ``altaz-manual`` (or ``altaz``)
file (azimuth from South through West, as gpoint counts it) and fits gpoint's terms
(``ia ie tn te npae npoa tf`` by default; lower-case names are gpoint's, ``a:b:c:d``
strings gpoint's extra terms, upper-case names TPOINT's, mixed freely), printing the
same report or JSON as for TPOINT runs.

``pointax fit DIR --format paint`` calibrates one PAINT heliostat folder (robust fit,
outlier flags, leave-one-out; :func:`pointax.calibrate_heliostat`) and prints the report
and a per-sample table, or with ``--json`` the keys ``n_obs``, ``params`` (``name``,
``value``, ``sigma``, ``unit``), ``error_mrad`` (``before``, ``after``, ``loo``: one
value per sample in file order; ``rms`` over the unflagged samples and ``rms_all``),
``samples`` (ids in file order), ``outliers`` (ids of flagged samples), ``n_used``
(samples kept by the fit; ``n_obs`` counts all of them) and more (see
:meth:`pointax.HeliostatCalibration.to_dict`). The "unflagged" samples are those the
fit of all samples kept; each leave-one-out fit re-detects outliers without its sample.

``pointax command`` is the inverse: encoder commands for wanted directions
(:func:`pointax.command`). DIRECTIONS is a text file ('-' for standard input) with one
direction per line, azimuth (North through East) and elevation in degrees, or with
``--reflect`` four columns: sun azimuth and elevation, target azimuth and elevation (the
mirror normal is their bisector). ``#`` starts a comment. The model is a turntable
(``--mount turntable``; ``--params`` in degrees, e.g. from a fit) or an alt-az telescope
(``--mount altaz --model FILE.mod``, a TPOINT model file, or ``--params`` in arcsec with
``--terms``). It prints one line per direction (readings in degrees, ok, reason) or a
JSON list. Exit status 0 when every direction was commanded, 1 when some were not.

``pointax fit-network`` fits every site of a network listed in a CSV manifest (see
:mod:`pointax.network`): one batched fit per model, a progress bar and a summary on
standard error (``--quiet``: none), per-site JSON with ``--json``.

``pointax centroid`` finds the sun in sun-sensor frames (PNG 8/16 bit, FITS, ``.npy``;
:mod:`pointax.sunsensor`) and prints per frame ``x``, ``y`` (pixels, origin at the centre
of the top-left pixel, x right, y down), the disk radius, the method, ``status`` and
``reason``.

``pointax compare`` fits several model families to the same run and prints a table
shaped like the level-mount paper's Table 3 (:func:`pointax.compare`).

Compiled fits are cached on disk (JAX's persistent compilation cache) in
``$POINTAX_JAX_CACHE``, by default ``~/.cache/pointax/jax``: a repeated ``pointax fit``
of the same model then starts in about 2 s instead of 8 s. ``POINTAX_JAX_CACHE=""``
turns the cache off.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from . import terms as term_library
from .command import SOLUTIONS, command, command_reflector
from .compare_cli import add_compare_parser, run_compare
from .compilation_cache import enable_compilation_cache
from .fit import LOSSES, SOLVERS, fit
from .heliostat import calibrate_heliostat
from .io import (
    FOCAL_SPOT_METHODS,
    PaintFormatError,
    TpointFormatError,
    read_gpoint,
    read_model,
    read_paint,
    read_tpoint,
    write_model,
)
from .model import RESIDUAL_FORMS, AltAz, Turntable
from .mounts import AZIMUTH_CONVENTIONS
from .network import add_fit_network_parser, run_fit_network
from .rotations import azel_to_enu_numpy
from .sunsensor.cli import add_centroid_parser, run_centroid
from .terms.heliostat import HELIOSTAT_DEFAULT
from .units import UNITS

__all__ = ["main", "build_parser"]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="pointax", description="Telescope and sun-tracker pointing models in JAX.")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("fit", help="fit a pointing model to a pointing run and print the report")
    p.add_argument("data", help="pointing run (TPOINT input file) or PAINT heliostat folder (--format paint)")
    p.add_argument(
        "--terms",
        default=None,
        help="terms to fit, comma or space separated (default: TPOINT's "
        + ",".join(term_library.BASIC_ALTAZ)
        + "; for paint: "
        + ",".join(HELIOSTAT_DEFAULT)
        + ")",
    )
    p.add_argument("--form", choices=sorted(term_library.FORMS), default="linear", help="term form (default: linear, as TPOINT)")
    p.add_argument("--fix", default="", help="terms to hold fixed at 0, comma separated")
    p.add_argument(
        "--residuals",
        choices=list(RESIDUAL_FORMS),
        default="sky",
        help="what the fit minimises: sky (exact tangent-plane offsets, default) or tpoint (TPOINT's own: "
        "(dA cos E, dE) with the terms at the observed position)",
    )
    p.add_argument(
        "--azimuth",
        choices=sorted(AZIMUTH_CONVENTIONS),
        default="N-E",
        help="how the file counts azimuth (default N-E, TPOINT's standard; the bundled MMT run is S-E). "
        "Fitted TPOINT terms do not depend on it; directions in ENU do",
    )
    p.add_argument(
        "--format",
        choices=["tpoint", "paint", "gpoint"],
        default="tpoint",
        help="input format (default: tpoint; gpoint: an RTS2 gpoint altaz-manual or altaz file)",
    )
    p.add_argument(
        "--loss",
        choices=sorted(LOSSES),
        default=None,
        help="least-squares loss; a robust one flags outliers (default: linear for tpoint, cauchy for paint)",
    )
    p.add_argument("--focal-spot", choices=FOCAL_SPOT_METHODS, default="HeliOS", help="paint: focal-spot method (default: HeliOS)")
    p.add_argument("--solver", choices=sorted(SOLVERS), default="lm", help="least-squares solver (default: lm)")
    p.add_argument("--max-steps", type=int, default=256, help="solver step limit (default: %(default)s)")
    p.add_argument("--write-model", metavar="FILE", help="also write the fitted model as a TPOINT .mod file")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    c = sub.add_parser("command", help="encoder commands for wanted directions (the model's inverse)")
    c.add_argument("directions", help="text file of 'az el' (deg) per line, or '-' for standard input")
    c.add_argument("--mount", choices=["turntable", "altaz"], default="turntable", help="mount kind (default: turntable)")
    c.add_argument(
        "--params",
        default="",
        help="parameter values name=value, comma separated, in the parameters' display units "
        "(turntable: degrees, e.g. mu0=0.0751,nu0=0.0145,omega0=-0.0947,alpha0=60.5425,beta0=165.8931)",
    )
    c.add_argument("--terms", default=None, help="terms of the model (default: turntable 'full'; altaz: the --model file's)")
    c.add_argument("--model", metavar="FILE", help="altaz: TPOINT model file with the fitted terms")
    c.add_argument("--form", choices=sorted(term_library.FORMS), default="linear", help="altaz: term form (default: linear)")
    c.add_argument("--azimuth", choices=sorted(AZIMUTH_CONVENTIONS), default="N-E", help="altaz: encoder azimuth convention")
    c.add_argument("--reflect", action="store_true", help="lines hold sun az el and target az el: command the mirror normal")
    c.add_argument(
        "--limits",
        default=None,
        help="axis limits in degrees: a1min,a1max,a2min,a2max (default: turntable 0,360 on axis 1; altaz none)",
    )
    c.add_argument("--solution", choices=SOLUTIONS, default="nearest", help="mechanical solution (default: nearest, i.e. normal)")
    c.add_argument("--json", action="store_true", help="print a JSON list instead of a table")
    add_fit_network_parser(sub)
    add_centroid_parser(sub)
    add_compare_parser(sub)
    return parser


def _number(x) -> float | None:
    """A float for JSON, None (null) where it is not finite."""
    x = float(x)
    return x if np.isfinite(x) else None


def _read_directions(path: str, columns: int) -> np.ndarray:
    """``(n, columns)`` numbers (degrees) from a text file, naming file and line on error."""
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
        if not all(np.isfinite(values)):
            raise ValueError(f"{name}:{number}: non-finite value in {line.strip()!r}")
        elevations = values[1::2]
        if any(abs(e) > 90.0 for e in elevations):
            raise ValueError(f"{name}:{number}: elevation outside -90..90 deg in {line.strip()!r}")
        rows.append(values)
    if not rows:
        raise ValueError(f"{name}: no directions")
    return np.asarray(rows)


def _parse_params(spec: str, model) -> dict:
    """``name=value`` pairs (display units) to radians for ``model.set``."""
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
    if args.mount == "turntable":
        model = Turntable(args.terms or "full")
        default_limits = ((0.0, 2 * np.pi), None)
    else:
        if args.model:
            tpoint_model = read_model(args.model)
            names = args.terms or " ".join(t.name for t in tpoint_model.terms)
            model = AltAz(term_library.tpoint(names, form=args.form), azimuth=args.azimuth)
            known = set(model.parameter_names)
            model = model.set(**{t.name: t.value * UNITS["arcsec"] for t in tpoint_model.terms if t.name in known})
        else:
            model = AltAz(term_library.tpoint(args.terms or term_library.BASIC_ALTAZ, form=args.form), azimuth=args.azimuth)
        default_limits = None
    model = model.set(**_parse_params(args.params, model))
    if args.limits is None:
        return model, default_limits
    parts = [p.strip() for p in args.limits.split(",")]
    if len(parts) != 4:
        raise ValueError(f"--limits: expected a1min,a1max,a2min,a2max in degrees, got {args.limits!r}")
    try:
        # An empty field leaves that end of the axis open, e.g. "0,360,," limits axis 1 only.
        lim = [np.radians(float(p)) if p else None for p in parts]
    except ValueError:
        raise ValueError(f"--limits: not a number in {args.limits!r} (degrees; leave a field empty for no limit)") from None
    return model, ((lim[0], lim[1]), (lim[2], lim[3]))


def _command_command(args) -> int:
    model, limits = _command_model(args)
    rows = _read_directions(args.directions, 4 if args.reflect else 2)
    rad = np.radians(rows)

    if args.reflect:
        sun, target = azel_to_enu_numpy(rad[:, 0], rad[:, 1]), azel_to_enu_numpy(rad[:, 2], rad[:, 3])
        cmd = command_reflector(model, sun, target, limits=limits, solution=args.solution)
    else:
        cmd = command(model, azel_to_enu_numpy(rad[:, 0], rad[:, 1]), limits=limits, solution=args.solution)
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
            }
            for row, r, k, res, why in zip(rows, reading, ok, residual, reasons)
        ]
        print(json.dumps(out, indent=2))
    else:
        print(f"# {model.describe()}")
        print(f"# {'input (deg)':<40s} {names[0] + ' (deg)':>14s} {names[1] + ' (deg)':>14s}  ok  reason")
        for row, r, k, why in zip(rows, reading, ok, reasons):
            text = " ".join(f"{x:9.4f}" for x in row)
            print(f"  {text:<40s} {r[0]:14.6f} {r[1]:14.6f}  {'yes' if k else 'NO ':3s} {why}")
    return 0 if bool(np.all(ok)) else 1


def _fit_paint(args) -> int:
    for option, value, default in (("--write-model", args.write_model, None), ("--form", args.form, "linear"),
                                   ("--azimuth", args.azimuth, "N-E"), ("--residuals", args.residuals, "sky")):
        if value != default:
            raise ValueError(f"{option} applies to TPOINT runs, not to --format paint")
    run = read_paint(args.data, focal_spot=args.focal_spot)
    terms = args.terms if args.terms is not None else HELIOSTAT_DEFAULT
    fixed = [name.strip() for name in args.fix.split(",") if name.strip()]
    cal = calibrate_heliostat(
        run, terms, loss=args.loss or "cauchy", solver=args.solver, max_steps=args.max_steps, fixed=fixed
    )
    if args.json:
        print(json.dumps({"directory": args.data, **cal.to_dict()}, indent=2))
    else:
        print(cal.report())
    return 0 if bool(cal.result.converged) else 1


def _gpoint_model(args, run):
    if args.azimuth != "N-E":
        raise ValueError("--azimuth applies to TPOINT runs; gpoint files count azimuth from South through West")
    spec = args.terms if args.terms is not None else term_library.GPOINT_ALTAZ_TERMS
    terms = term_library.gpoint_terms(spec, form=args.form)
    if args.write_model and any(t.name != t.name.upper() for t in terms):
        raise ValueError("--write-model writes TPOINT model files; gpoint's lower-case terms have no TPOINT name there")
    # gpoint's names are case-sensitive (ie is not IE): no upper-casing of --fix.
    return AltAz(terms, azimuth=run.azimuth, fixed=term_library.gpoint_names(args.fix), residual_form=args.residuals)


def _fit_command(args) -> int:
    if args.format == "paint":
        return _fit_paint(args)
    if args.format == "gpoint":
        run = read_gpoint(args.data)
        model = _gpoint_model(args, run)
    else:
        run = read_tpoint(args.data, azimuth=args.azimuth)
        terms = term_library.tpoint(args.terms if args.terms is not None else term_library.BASIC_ALTAZ, form=args.form)
        model = AltAz(terms, azimuth=run.azimuth, fixed=term_library.names(args.fix), residual_form=args.residuals)
    result = fit(model, run, solver=args.solver, max_steps=args.max_steps, loss=args.loss or "linear")
    if args.write_model:
        write_model(args.write_model, result)
    if args.json:
        out = {"file": args.data, "caption": run.caption, "form": args.form, "residuals": args.residuals, **result.to_dict()}
        print(json.dumps(out, indent=2))
    else:
        print(result.report())
    return 0 if bool(result.converged) else 1


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    enable_compilation_cache()  # $POINTAX_JAX_CACHE; empty: off
    try:
        if args.command == "fit":
            return _fit_command(args)
        if args.command == "command":
            return _command_command(args)
        if args.command == "fit-network":
            return run_fit_network(args)
        if args.command == "centroid":
            return run_centroid(args)
        if args.command == "compare":
            return run_compare(args)
    except (TpointFormatError, PaintFormatError, ValueError, KeyError) as err:
        print(f"pointax: error: {err}", file=sys.stderr)
        return 2
    except OSError as err:
        where = err.filename or getattr(args, "data", None) or getattr(args, "directions", "")
        print(f"pointax: error: {where}: {err.strerror or err}", file=sys.stderr)
        return 2
    parser.error(f"unknown command {args.command}")
    return 2


if __name__ == "__main__":
    sys.exit(main())

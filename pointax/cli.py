"""The ``pointax`` command: a thin layer over the Python API.

    pointax fit DATA [--terms IA,IE,...] [--form linear|rigorous] [--json]
    pointax fit DIR --format paint [--terms t1n,t1u,t2e,t2n] [--loss cauchy] [--json]

``pointax fit`` reads a TPOINT input file, fits the terms (TPOINT's eight basic alt-az
terms by default) and prints the TPOINT-style report, or with ``--json`` one JSON
object with the keys ``n_obs``, ``sky_rms_arcsec``, ``popn_sd_arcsec``, ``converged``,
``terms`` (``name``, ``value_arcsec``, ``sigma_arcsec``) and ``correlation`` (in the
order of ``terms``), plus ``iterations``, ``message``, ``solver``, ``fixed`` and
``warnings``. Exit status: 0 on a converged fit, 1 if the fit did not converge, 2 for
bad input.

``pointax fit DIR --format paint`` calibrates one PAINT heliostat folder (robust fit,
outlier flags, leave-one-out; :func:`pointax.calibrate_heliostat`) and prints the report
and a per-sample table, or with ``--json`` the keys ``n_obs``, ``params`` (``name``,
``value``, ``sigma``, ``unit``), ``error_mrad`` (``before``, ``after``, ``loo``: one
value per sample in file order; ``rms`` over the unflagged samples and ``rms_all``),
``samples``, ``outliers`` and more (see :meth:`pointax.HeliostatCalibration.to_dict`).

Compiled fits are cached on disk (JAX's persistent compilation cache) in
``$POINTAX_JAX_CACHE``, by default ``~/.cache/pointax/jax``: a repeated ``pointax fit``
of the same model then starts in about 2 s instead of 8 s. ``POINTAX_JAX_CACHE=""``
turns the cache off.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import jax

from . import terms as term_library
from .fit import LOSSES, SOLVERS, fit
from .heliostat import calibrate_heliostat
from .io import FOCAL_SPOT_METHODS, PaintFormatError, TpointFormatError, read_paint, read_tpoint, write_model
from .model import AltAz
from .mounts import AZIMUTH_CONVENTIONS
from .terms.heliostat import HELIOSTAT_DEFAULT

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
        "--azimuth",
        choices=sorted(AZIMUTH_CONVENTIONS),
        default="N-E",
        help="how the file counts azimuth (default N-E, TPOINT's standard; the bundled MMT run is S-E). "
        "Fitted TPOINT terms do not depend on it; directions in ENU do",
    )
    p.add_argument("--format", choices=["tpoint", "paint"], default="tpoint", help="input format (default: tpoint)")
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
    return parser


def _fit_paint(args) -> int:
    run = read_paint(args.data, focal_spot=args.focal_spot)
    terms = args.terms if args.terms is not None else HELIOSTAT_DEFAULT
    cal = calibrate_heliostat(run, terms, loss=args.loss or "cauchy", solver=args.solver)
    if args.json:
        print(json.dumps({"directory": args.data, **cal.to_dict()}, indent=2))
    else:
        print(cal.report())
    return 0 if bool(cal.result.converged) else 1


def _fit_command(args) -> int:
    if args.format == "paint":
        return _fit_paint(args)
    run = read_tpoint(args.data, azimuth=args.azimuth)
    terms = term_library.tpoint(args.terms if args.terms is not None else term_library.BASIC_ALTAZ, form=args.form)
    fixed = term_library.names(args.fix)
    model = AltAz(terms, azimuth=run.azimuth, fixed=fixed)
    result = fit(model, run, solver=args.solver, max_steps=args.max_steps, loss=args.loss or "linear")
    if args.write_model:
        write_model(args.write_model, result)
    if args.json:
        out = {"file": args.data, "caption": run.caption, "form": args.form, **result.to_dict()}
        print(json.dumps(out, indent=2))
    else:
        print(result.report())
    return 0 if bool(result.converged) else 1


def _enable_compilation_cache() -> None:
    default = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "pointax" / "jax"
    cache = os.environ.get("POINTAX_JAX_CACHE", str(default))
    if cache:
        jax.config.update("jax_compilation_cache_dir", cache)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    _enable_compilation_cache()
    try:
        if args.command == "fit":
            return _fit_command(args)
    except (TpointFormatError, PaintFormatError, ValueError, KeyError) as err:
        print(f"pointax: error: {err}", file=sys.stderr)
        return 2
    except OSError as err:
        print(f"pointax: error: {err.filename or args.data}: {err.strerror or err}", file=sys.stderr)
        return 2
    parser.error(f"unknown command {args.command}")
    return 2


if __name__ == "__main__":
    sys.exit(main())

"""``pointax fit``: fit a pointing model to one run and print the report (or JSON).

The run is a TPOINT input file, an RTS2 gpoint alt-az file or a PAINT heliostat folder;
``--format`` names it, or it is told from the file (:func:`pointax.io.detect_format`).
See :mod:`pointax.cli` for the output and exit status.
"""

from __future__ import annotations

import argparse
import json

from . import choices
from .common import error, missing_input, os_error_text

__all__ = ["FIT_FORMATS", "add_fit_parser", "run_fit"]

FIT_FORMATS = ("tpoint", "paint", "gpoint")
"""The run formats ``pointax fit`` fits."""

_PREFIX = "pointax"


def add_fit_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``pointax fit`` to an ``argparse`` sub-parser set; returns its parser."""
    p = subparsers.add_parser("fit", help="fit a pointing model to a pointing run and print the report")
    p.add_argument("data", help="pointing run: TPOINT input file, RTS2 gpoint file or PAINT heliostat folder")
    p.add_argument(
        "--terms",
        default=None,
        help="terms to fit, comma or space separated (default: TPOINT's "
        + ",".join(choices.BASIC_ALTAZ)
        + "; for paint: "
        + ",".join(choices.HELIOSTAT_DEFAULT)
        + ")",
    )
    p.add_argument("--form", choices=sorted(choices.TERM_FORMS), default="linear", help="term form (default: linear, as TPOINT)")
    p.add_argument("--fix", default="", help="terms to hold fixed at 0, comma separated")
    p.add_argument(
        "--residuals",
        choices=list(choices.RESIDUAL_FORMS),
        default="sky",
        help="what the fit minimises: sky (exact tangent-plane offsets, default) or tpoint (TPOINT's own: "
        "(dA cos E, dE) with the terms at the observed position)",
    )
    p.add_argument(
        "--azimuth",
        choices=sorted(choices.AZIMUTH_CONVENTIONS),
        default="N-E",
        help="how the file counts azimuth (default N-E, TPOINT's standard; the bundled MMT run is S-E). "
        "Fitted TPOINT terms do not depend on it; directions in ENU do",
    )
    p.add_argument(
        "--format",
        choices=list(FIT_FORMATS),
        default=None,
        help="input format (default: told from the file: a folder is paint, a file tpoint or gpoint; "
        "gpoint: an RTS2 gpoint altaz-manual or altaz file)",
    )
    p.add_argument(
        "--loss",
        choices=sorted(choices.LOSSES),
        default=None,
        help="least-squares loss; a robust one flags outliers (default: linear for tpoint, cauchy for paint)",
    )
    p.add_argument(
        "--focal-spot", choices=choices.FOCAL_SPOT_METHODS, default="HeliOS", help="paint: focal-spot method (default: HeliOS)"
    )
    p.add_argument("--solver", choices=sorted(choices.SOLVERS), default="lm", help="least-squares solver (default: lm)")
    p.add_argument("--max-steps", type=int, default=256, help="solver step limit (default: %(default)s)")
    p.add_argument("--write-model", metavar="FILE", help="also write the fitted model as a TPOINT .mod file")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    p.set_defaults(run=run_fit)
    return p


def run_fit(args: argparse.Namespace) -> int:
    """Run ``pointax fit`` for parsed ``args``; returns the exit status (0 converged,
    1 not converged, 2 bad input, with the message on standard error)."""
    missing = missing_input([args.data])
    if missing:
        return error(_PREFIX, missing)
    try:
        return _fit(args)
    except (ValueError, KeyError) as err:
        return error(_PREFIX, err)
    except OSError as err:
        return error(_PREFIX, os_error_text(err, args.data))


def _format(args) -> str:
    from ..io.load import detect_format

    fmt = args.format or detect_format(args.data)
    if fmt not in FIT_FORMATS:
        raise ValueError(
            f"{args.data}: a {fmt} run; pointax fit reads {', '.join(FIT_FORMATS)} runs"
            + (" (pointax fit-network fits sun runs)" if fmt == "sun" else "")
            + (" (pointax compare --mount xy fits X-Y runs)" if fmt == "xy" else "")
        )
    return fmt


def _fit(args) -> int:
    fmt = _format(args)
    if fmt == "paint":
        _check_paint_options(args)
    elif fmt == "gpoint" and args.azimuth != "N-E":
        raise ValueError("--azimuth applies to TPOINT runs; gpoint files count azimuth from South through West")

    from ..compilation_cache import enable_compilation_cache

    enable_compilation_cache()  # $POINTAX_JAX_CACHE; empty: off
    if fmt == "paint":
        return _fit_paint(args)

    from .. import terms as term_library
    from ..fitting import fit
    from ..io.load import load_run
    from ..io.tpoint import write_model
    from ..mount_models import AltAz

    if fmt == "gpoint":
        run = load_run(args.data, "gpoint")
        spec = args.terms if args.terms is not None else term_library.GPOINT_ALTAZ_TERMS
        terms = term_library.gpoint_terms(spec, form=args.form)
        if args.write_model and any(t.name != t.name.upper() for t in terms):
            raise ValueError("--write-model writes TPOINT model files; gpoint's lower-case terms have no TPOINT name there")
        # gpoint's names are case-sensitive (ie is not IE): no upper-casing of --fix.
        fixed = term_library.gpoint_names(args.fix)
    else:
        run = load_run(args.data, "tpoint", azimuth=args.azimuth)
        terms = term_library.tpoint(args.terms if args.terms is not None else term_library.BASIC_ALTAZ, form=args.form)
        fixed = term_library.names(args.fix)
    model = AltAz(terms, azimuth=run.azimuth, fixed=fixed, residual_form=args.residuals)
    result = fit(model, run, solver=args.solver, max_steps=args.max_steps, loss=args.loss or "linear")
    if args.write_model:
        write_model(args.write_model, result)
    if args.json:
        out = {"file": args.data, "caption": run.caption, "form": args.form, "residuals": args.residuals, **result.to_dict()}
        print(json.dumps(out, indent=2))
    else:
        print(result.report())
    return 0 if bool(result.converged) else 1


def _check_paint_options(args) -> None:
    for option, value, default in (
        ("--write-model", args.write_model, None),
        ("--form", args.form, "linear"),
        ("--azimuth", args.azimuth, "N-E"),
        ("--residuals", args.residuals, "sky"),
    ):
        if value != default:
            raise ValueError(f"{option} applies to TPOINT runs, not to --format paint")


def _fit_paint(args) -> int:
    from ..heliostat import calibrate_heliostat
    from ..io.load import load_run

    run = load_run(args.data, "paint", focal_spot=args.focal_spot)
    terms = args.terms if args.terms is not None else choices.HELIOSTAT_DEFAULT
    fixed = [name.strip() for name in args.fix.split(",") if name.strip()]
    cal = calibrate_heliostat(run, terms, loss=args.loss or "cauchy", solver=args.solver, max_steps=args.max_steps, fixed=fixed)
    if args.json:
        print(json.dumps({"directory": args.data, **cal.to_dict()}, indent=2))
    else:
        print(cal.report())
    return 0 if bool(cal.result.converged) else 1


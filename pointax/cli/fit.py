"""``pointax fit``: fit a pointing model to one run and print the report (or JSON).

The run is a TPOINT input file, an RTS2 gpoint alt-az file or a PAINT heliostat folder;
``--format`` names it, or it is told from the file (:func:`pointax.io.detect_format`).
See :mod:`pointax.cli` for the output and exit status.

Other subcommands that fit a run the same way (``pointax plot``, ``pointax report``)
reuse the pieces here: :func:`add_fit_options` adds the run and every fit option (not
the output options ``--json``, ``--list``, ``--plot``, ``--write-model``),
:func:`fit_from_args` loads the run and fits it (masks included) into a
:class:`FitOutcome`, and :func:`guarded` turns input errors into exit status 2.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
from collections.abc import Callable
from typing import Any

from . import choices
from .common import error, guarded_run, positive_float

__all__ = [
    "FIT_FORMATS",
    "FitOutcome",
    "add_fit_options",
    "add_fit_parser",
    "fit_from_args",
    "guarded",
    "masked_observations",
    "run_fit",
]

FIT_FORMATS = ("tpoint", "paint", "gpoint", "offsets")
"""The run formats ``pointax fit`` fits."""

_PREFIX = "pointax"


def add_fit_options(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Add the run (positional ``data``) and every option of ``pointax fit`` but the
    output ones (``--json``, ``--list``, ``--plot``, ``--write-model``) to ``parser``;
    returns it. Imports no numerical library."""
    p = parser
    p.add_argument(
        "data", help="pointing run: TPOINT input file, RTS2 gpoint file, table of pointing offsets or PAINT heliostat folder"
    )
    p.add_argument(
        "--terms",
        default=None,
        help="terms to fit, comma or space separated (default: TPOINT's "
        + ",".join(choices.BASIC_ALTAZ)
        + "; for equatorial runs "
        + ",".join(choices.BASIC_EQUATORIAL)
        + "; for paint: "
        + ",".join(choices.HELIOSTAT_DEFAULT)
        + ")",
    )
    p.add_argument(
        "--model",
        metavar="START.mod",
        default=None,
        help="start from a TPOINT model file (TPOINT's INMOD): its terms, their values as start values and its "
        "'=' (fixed) flags; with --terms, --terms chooses the terms and the file gives the start values and "
        "flags of those it holds (the others start at 0). TPOINT runs and offsets tables",
    )
    p.add_argument(
        "--form",
        choices=sorted(choices.TERM_FORMS),
        default=choices.DEFAULT_TERM_FORM,
        help="how the TPOINT terms are applied: rigorous (default: exact rotations and encoder corrections, the model "
        "applied as TPOINT applies it) or linear (TPOINT's formulas as first-order offsets at the sky position, off "
        "TPOINT's fitted values where the corrections are large)",
    )
    p.add_argument(
        "--fix",
        default="",
        help="terms to hold fixed at their start values (from --model; 0, with a warning, for a term with no start "
        "value), comma separated",
    )
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
        "--mount",
        choices=choices.TPOINT_MOUNTS,
        default=None,
        help="mount of a TPOINT run whose file names none (no ': ALTAZ' or ': EQUAT' record; TPOINT's default "
        "is equatorial, but some observatories' files are alt-az)",
    )
    p.add_argument(
        "--format",
        choices=list(FIT_FORMATS),
        default=None,
        help="input format (default: told from the file: a folder is paint, a file tpoint, gpoint or offsets; "
        "gpoint: an RTS2 gpoint file; offsets: a table of pointing offsets az el daz del [errors] (degrees; offsets "
        "in arcsec unless --units or the header says otherwise; cross-elevation dA cos E unless --plain-daz), "
        "with a header naming the columns or --columns)",
    )
    p.add_argument(
        "--columns",
        metavar="SPEC",
        default=None,
        help="offsets tables: which column is which, the roles in column order ('_' skips a column), e.g. "
        "_,az,el,dxel,del,dxel_err,del_err, or ROLE=COLUMN pairs with a 1-based number or a header name, e.g. "
        "az=2,el=3,dxel=6,del=7 (roles: az el dxel|daz del daz_err del_err err)",
    )
    p.add_argument(
        "--units",
        choices=choices.OFFSET_UNITS,
        default=None,
        help="offsets tables: unit of the offsets and errors whose header names none (default: the header's, "
        "e.g. 'dxel [arcmin]', else arcsec); positions are degrees",
    )
    p.add_argument(
        "--plain-daz",
        action="store_true",
        help="offsets tables: the azimuth offset is a plain dA, not the cross-elevation offset dA cos E",
    )
    p.add_argument(
        "--sign",
        choices=choices.OFFSET_SIGNS,
        default=None,
        help="offsets tables: observed-raw (default, TPOINT's: the source was found at raw + offset) or "
        "raw-observed (the table holds corrections)",
    )
    p.add_argument(
        "--loss",
        choices=sorted(choices.LOSSES),
        default=None,
        help="least-squares loss; a robust one flags outliers (default: linear for tpoint, cauchy for paint; "
        "cauchy when --reject is given)",
    )
    p.add_argument(
        "--focal-spot", choices=choices.FOCAL_SPOT_METHODS, default="HeliOS", help="paint: focal-spot method (default: HeliOS)"
    )
    p.add_argument("--solver", choices=sorted(choices.SOLVERS), default="lm", help="least-squares solver (default: lm)")
    p.add_argument("--max-steps", type=int, default=256, help="solver step limit (default: %(default)s)")
    p.add_argument(
        "--mask",
        metavar="ROWS",
        default="",
        help="observations to leave out of the fit (weight 0; they stay in the listing), by row number counted "
        "from 1 in file order as TPOINT numbers them, e.g. 17,19-21",
    )
    p.add_argument(
        "--mask-above",
        metavar="ARCSEC",
        type=positive_float,
        default=None,
        help="TPOINT's MASK R > ARCSEC: fit, mask the observations whose on-sky residual exceeds ARCSEC, refit",
    )
    p.add_argument(
        "--reject",
        metavar="SIGMAS",
        type=positive_float,
        default=None,
        help="robust fit: flag observations whose residual norm exceeds SIGMAS robust standard deviations "
        "(median residual norm / 1.1774) and leave them out of the final least-squares fit "
        "(default 3 with a robust --loss; alone it implies --loss cauchy)",
    )
    p.add_argument(
        "--quiet", action="store_true", help="no progress bar (paint: the leave-one-out folds; drawn only on a terminal)"
    )
    p.add_argument(
        "--loo",
        choices=("auto", "yes", "no"),
        default=None,
        help="paint: leave-one-out fits: auto (default: where the samples allow, else skipped with a note), "
        "yes (required: an error where too few samples) or no",
    )
    return p


def add_fit_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``pointax fit`` to an ``argparse`` sub-parser set; returns its parser."""
    p = subparsers.add_parser("fit", help="fit a pointing model to a pointing run and print the report")
    add_fit_options(p)
    p.add_argument("--write-model", metavar="FILE", help="also write the fitted model as a TPOINT .mod file")
    p.add_argument(
        "--model-layout",
        choices=("lines", "one-line"),
        default="lines",
        help="layout of --write-model's file: a record a line (default) or TPOINT's one-line layout "
        "(with the x and y RMS and the masked observations)",
    )
    p.add_argument(
        "--list",
        action="store_true",
        help="also print the residual listing (TPOINT's SLIST: per observation, angles and residuals)",
    )
    p.add_argument(
        "--json",
        action="store_true",
        help="print one JSON object instead of the report (with per-observation entries under 'observations')",
    )
    p.add_argument(
        "--plot",
        metavar="FILE",
        help="also draw the fit's summary figure (residuals, sky map, histogram) to FILE: .png, .svg, .pdf, "
        ".ps or .eps, by the extension (needs matplotlib: pip install 'pointax[plot]')",
    )
    p.set_defaults(run=run_fit)
    return p


@dataclasses.dataclass
class FitOutcome:
    """What :func:`fit_from_args` loaded and fitted.

    Attributes:
        fmt: the run's format ('tpoint', 'gpoint' or 'paint').
        run: the run as read (:class:`pointax.io.TpointRun`, ``GpointRun`` or
            ``PaintRun``).
        model: the model fitted (before the fit: terms, fixed names, start values).
        result: the final :class:`pointax.FitResult` (for paint, the calibration's fit).
        observations: the run's :class:`pointax.Observations` (file weights, no mask).
        masked: ``(n,)`` bool, observations given weight 0 (``--mask`` and
            ``--mask-above``), or None for paint.
        first: for ``--mask-above``, the fit before masking (None otherwise).
        calibration: for paint, the :class:`pointax.HeliostatCalibration` (else None).
    """

    fmt: str
    run: Any
    model: Any
    result: Any
    observations: Any
    masked: Any = None
    first: Any = None
    calibration: Any = None


def guarded(args: argparse.Namespace, body: Callable[[argparse.Namespace], int], prefix: str = _PREFIX) -> int:
    """Run ``body(args)`` after checking that ``args.data`` exists; a bad input
    (ValueError, KeyError, OSError) prints ``prefix: error: ...`` and gives 2."""
    return guarded_run(prefix, body, args, [args.data, getattr(args, "model", None)])


def run_fit(args: argparse.Namespace) -> int:
    """Run ``pointax fit`` for parsed ``args``; returns the exit status (0 converged,
    1 not converged, 2 bad input, with the message on standard error)."""
    return guarded(args, _fit)


_OFFSETS_OPTIONS = (("--columns", "columns", None), ("--units", "units", None), ("--plain-daz", "plain_daz", False),
                    ("--sign", "sign", None))  # fmt: skip


def _offsets_options_given(args) -> list[str]:
    return [option for option, name, default in _OFFSETS_OPTIONS if getattr(args, name, default) != default]


def _format(args) -> str:
    from ..io.load import FormatDetectionError, detect_format

    given = _offsets_options_given(args)
    fmt = args.format
    if fmt is None:
        try:
            fmt = detect_format(args.data)
        except FormatDetectionError:
            if not given:
                raise
            fmt = "offsets"  # a table with no header: --columns or --units say it is one
    if given and fmt != "offsets":
        how = "is" if args.format else "looks like"
        raise ValueError(
            f"{' and '.join(given)} appl{'ies' if len(given) == 1 else 'y'} to offsets tables; {args.data} {how} a {fmt} run"
            + ("" if args.format else " (give --format offsets to read it as an offsets table)")
        )
    if fmt not in FIT_FORMATS:
        raise ValueError(
            f"{args.data}: a {fmt} run; pointax fit reads {', '.join(FIT_FORMATS)} runs"
            + (" (pointax fit-network fits sun runs)" if fmt == "sun" else "")
            + (" (pointax compare --mount xy fits X-Y runs)" if fmt == "xy" else "")
        )
    return fmt


def _loss(args, fmt: str) -> str:
    if args.loss is not None:
        if args.loss == "linear" and args.reject is not None:
            raise ValueError("--reject flags outliers of a robust fit; it does not apply to --loss linear")
        return args.loss
    if fmt == "paint" or args.reject is not None:
        return "cauchy"
    return "linear"


def fit_from_args(args: argparse.Namespace) -> FitOutcome:
    """Load the run named by ``args`` (from :func:`add_fit_options`) and fit it.

    Masks: ``--mask`` rows get weight 0; with ``--mask-above`` the run is fitted, the
    observations whose on-sky residual exceeds the limit are masked as well and the
    run is refitted (:func:`pointax.fitting.masking.mask_above`).

    Raises:
        ValueError, KeyError, OSError: for bad input (the message names the file, line
            and field, or the option).
    """
    fmt = _format(args)
    output_only = getattr(args, "write_model", None)
    if getattr(args, "model_layout", "lines") != "lines" and not output_only:
        raise ValueError("--model-layout is the layout of --write-model's file: give --write-model FILE too")
    if fmt == "paint":
        _check_paint_options(args)
    elif fmt == "gpoint" and args.azimuth != "N-E":
        raise ValueError("--azimuth applies to TPOINT runs; gpoint files count azimuth from South through West")
    if fmt != "paint" and getattr(args, "loo", None) is not None:
        raise ValueError(f"--loo applies to PAINT heliostat runs (--format paint), not to a {fmt} run")
    if fmt != "tpoint" and getattr(args, "mount", None) is not None:
        raise ValueError(f"--mount applies to TPOINT runs whose files name no mount; this is a {fmt} run")
    if fmt == "gpoint" and getattr(args, "model", None):
        raise ValueError("--model reads TPOINT model files, for TPOINT runs and offsets tables; this is a gpoint run")
    columns = _columns(args)
    loss = _loss(args, fmt)

    from ..fitting.compilation_cache import enable_compilation_cache

    enable_compilation_cache()  # $POINTAX_JAX_CACHE; empty: off
    if fmt == "paint":
        return _fit_paint(args, loss)
    from ..fitting import programs

    # The executable this file's last fit ran starts loading while the rest is imported.
    programs.prefetch(f"fit {os.path.abspath(args.data)}")
    import numpy as np

    from .. import terms as term_library
    from ..fitting import FitOptions, fit
    from ..io.load import load_run
    from ..fitting.masking import mask_above, parse_rows
    from ..terms.model_factories import AltAz, Equatorial

    if fmt == "gpoint":
        run = load_run(args.data, "gpoint")
        gem = run.mount == "gem"
        default = term_library.GPOINT_GEM_TERMS if gem else term_library.GPOINT_ALTAZ_TERMS
        spec = args.terms if args.terms is not None else default
        latitude = run.latitude if gem else None
        terms = term_library.gpoint_terms(spec, form=args.form, mount=run.mount, latitude=latitude)
        if output_only and any(t.name != t.name.upper() for t in terms):
            raise ValueError("--write-model writes TPOINT model files; gpoint's lower-case terms have no TPOINT name there")
        # gpoint's names are case-sensitive (ie is not IE): no upper-casing of --fix.
        fixed = term_library.gpoint_names(args.fix, mount=run.mount)
        if gem:
            model = Equatorial(terms, latitude=run.latitude, fixed=fixed, residual_form=args.residuals)
        else:
            model = AltAz(terms, azimuth=run.azimuth, fixed=fixed, residual_form=args.residuals)
    elif fmt == "offsets":
        run = load_run(
            args.data, "offsets", azimuth=args.azimuth, columns=columns, units=args.units,
            cross_elevation=not args.plain_daz, sign=args.sign or "observed-raw",
        )  # fmt: skip
        terms, fixed = start_terms(args, term_library.BASIC_ALTAZ, {})
        model = AltAz(terms, azimuth=run.azimuth, fixed=fixed, residual_form=args.residuals)
    else:
        run = load_run(args.data, "tpoint", azimuth=args.azimuth, mount=args.mount)
        if run.mount == "equatorial" and args.azimuth != "N-E":
            raise ValueError(f"{args.data}: --azimuth applies to alt-az runs; this run is equatorial")
        default = term_library.BASIC_EQUATORIAL if run.mount == "equatorial" else term_library.BASIC_ALTAZ
        terms, fixed = start_terms(args, default, run.term_options())
        model = run.model(terms, fixed=fixed, residual_form=args.residuals)
    options = FitOptions(
        solver=args.solver,
        max_steps=args.max_steps,
        loss=loss,
        reject=args.reject if args.reject is not None else FitOptions().reject,
    )
    obs = run.observations
    n = len(run)
    masked = np.zeros(n, bool)
    if args.mask:
        masked[parse_rows(args.mask, n, option="--mask")] = True
    base = np.asarray(obs.weight, np.float64)
    weights = np.where(masked, 0.0, base) if masked.any() else None
    result = fit(model, run, weights=weights, options=options)
    first = None
    if args.mask_above is not None:
        first = result
        masked = masked | mask_above(result.model, obs, args.mask_above, masked=masked)
        result = fit(model, run, weights=np.where(masked, 0.0, base), options=options)
    return FitOutcome(fmt=fmt, run=run, model=model, result=result, observations=obs, masked=masked, first=first)


def _columns(args):
    """``--columns`` as the reader's ``columns`` (None when not given)."""
    text = getattr(args, "columns", None)
    if text is None:
        return None
    from ..io.offset_columns import parse_columns_option

    return parse_columns_option(text)


def start_terms(args: argparse.Namespace, default, term_options: dict) -> tuple[tuple, list[str]]:
    """The TPOINT terms and fixed names of a fit from ``--terms``, ``--model`` and
    ``--fix``.

    * the terms: ``--terms``, else the model file's (in its order), else ``default``;
    * start values: the model file's, for the terms it holds; 0 for the others;
    * fixed: the file's ``=`` terms among them, and ``--fix``, each at its start value.
      A ``--fix`` term with no start value (no ``--model``, or not in the file) is
      held at 0 with an :class:`pointax.io.InputWarning`: the other terms then absorb
      what it would have taken up.

    Raises:
        ValueError: an unknown term (:class:`pointax.io.TpointFormatError` naming the
            model file's line when the file holds it), a ``--fix`` term not fitted.
    """
    from .. import terms as term_library
    from ..io.errors import warn_input

    spec_fix = term_library.names(args.fix)
    path = getattr(args, "model", None)
    if not path:
        spec = args.terms if args.terms is not None else default
        terms = term_library.tpoint(spec, form=args.form, **term_options)
        file_terms = {}
        names = [t.name for t in terms]
    else:
        from ..io.tpoint_model import read_model
        from ..io.tpoint_records import TpointFormatError
        from ..core.units import ARCSEC

        start = read_model(path)
        file_terms = {t.name: t for t in start.terms}
        names = term_library.names(args.terms) if args.terms is not None else list(start.names)
        values = {n: file_terms[n].value * ARCSEC for n in names if n in file_terms}
        try:
            terms = term_library.tpoint(names, form=args.form, values=values, **term_options)
        except ValueError:
            for n in names:  # which one: name the model file's line when it holds the term
                try:
                    term_library.tpoint([n], form=args.form, **term_options)
                except ValueError as err:
                    if n in file_terms:
                        raise TpointFormatError(path, file_terms[n].line, f"term record {n}: {err}") from None
                    raise
            raise
    fitted = {p for t in terms for p in _parameter_names(t)}
    unknown = [n for n in spec_fix if n not in fitted]
    if unknown:
        raise ValueError(f"--fix {','.join(unknown)}: not among the terms fitted ({' '.join(names)})")
    fixed = [n for n in names if n in file_terms and file_terms[n].fixed]
    fixed += [n for n in spec_fix if n not in fixed]
    for n in spec_fix:
        if n not in file_terms:
            where = f"{n} is not in {path}" if path else "no --model START.mod"
            warn_input(
                f"--fix {n}",
                None,
                f"no start value ({where}): {n} is held at 0 and the other terms absorb what it would take up; "
                f"give its value with --model START.mod (TPOINT's INMOD), or leave {n} out of --terms",
            )
    return terms, fixed


def _parameter_names(term) -> list[str]:
    """A term's parameter names as :attr:`pointax.Model.parameter_names` gives them."""
    from ..core.term import param_fields

    fields = param_fields(term)
    return [term.name if len(fields) == 1 else f"{term.name}.{f.name}" for f in fields]


def _fit(args) -> int:
    outcome = fit_from_args(args)
    if outcome.fmt == "paint":
        return _print_paint(args, outcome)
    result = outcome.result
    if args.plot:
        from ..plots.save import format_of

        format_of(args.plot)  # an unknown extension fails before the fit is printed
    if args.write_model:
        from ..io.tpoint_model import write_model

        write_model(args.write_model, result, layout=args.model_layout, run=outcome.run)
    if args.json:
        from ..analysis.listing import observation_entries

        out = {
            "file": args.data,
            "caption": getattr(outcome.run, "caption", None),
            "form": args.form,
            "residuals": args.residuals,
            "start_model": args.model,
            **result.to_dict(),
            "masked": [int(i) for i in outcome.masked.nonzero()[0]],  # 0-based indices
            "masked_rows": [int(i) + 1 for i in outcome.masked.nonzero()[0]],  # 1-based, as --mask and the report
            "observations": observation_entries(outcome.run, result, outcome.masked),
        }
        print(json.dumps(out, indent=2))
    else:
        print(result.report())
        if args.list:
            from ..analysis.listing import format_listing

            print()
            print(format_listing(outcome.run, result, outcome.masked))
    if args.plot:
        # After the report, so that a missing matplotlib does not lose the fit.
        try:
            _plot(args.plot, outcome)
        except ImportError as err:
            if "matplotlib" not in str(err):
                raise
            return error(_PREFIX, "--plot needs matplotlib, an optional extra: pip install 'pointax[plot]'")
    return 0 if bool(result.converged) else 1


def masked_observations(outcome: FitOutcome):
    """The run's observations with the masked ones at weight 0 (plots draw them as
    masked)."""
    import numpy as np


    obs = outcome.observations
    weight = np.where(outcome.masked, 0.0, np.asarray(obs.weight, np.float64))
    return obs.with_weight(weight)


def _plot(path: str, outcome: FitOutcome) -> None:
    import sys

    from ..plots import fit_figure, save_figure

    figure = fit_figure(outcome.result, masked_observations(outcome), "summary")
    print(f"{_PREFIX}: wrote {save_figure(figure, path)}", file=sys.stderr)


def _check_paint_options(args) -> None:
    for option, value, default in (
        ("--write-model", getattr(args, "write_model", None), None),
        ("--form", args.form, choices.DEFAULT_TERM_FORM),
        ("--azimuth", args.azimuth, "N-E"),
        ("--residuals", args.residuals, "sky"),
        ("--mask", args.mask, ""),
        ("--mask-above", args.mask_above, None),
        ("--model", getattr(args, "model", None), None),
        ("--list", getattr(args, "list", False), False),
        ("--plot", getattr(args, "plot", None), None),
    ):
        if value != default:
            raise ValueError(f"{option} applies to TPOINT runs and gpoint runs, not to --format paint")


def _fit_paint(args, loss: str) -> FitOutcome:
    from ..analysis.heliostat import calibrate_heliostat
    from ..io.load import load_run

    run = load_run(args.data, "paint", focal_spot=args.focal_spot)
    terms = args.terms if args.terms is not None else choices.HELIOSTAT_DEFAULT
    fixed = [name.strip() for name in args.fix.split(",") if name.strip()]
    reject = {} if args.reject is None else {"reject": args.reject}
    cal = calibrate_heliostat(
        run, terms, loss=loss, solver=args.solver, max_steps=args.max_steps, fixed=fixed,
        progress=not args.quiet, loo={None: None, "auto": None, "yes": True, "no": False}[getattr(args, "loo", None)],
        **reject,
    )  # fmt: skip
    return FitOutcome(
        fmt="paint", run=run, model=cal.result.model, result=cal.result, observations=getattr(run, "observations", None),
        calibration=cal,
    )


def _print_paint(args, outcome: FitOutcome) -> int:
    cal = outcome.calibration
    if args.json:
        print(json.dumps({"directory": args.data, **cal.to_dict()}, indent=2))
    else:
        print(cal.report())
    return 0 if bool(cal.result.converged) else 1

"""``pointax report``: fit a run as ``pointax fit`` does and write one self-contained
HTML page (fit table, statistics, warnings, plots as embedded PNG, residual listing).

    pointax report DATA [fit options] [--kind KIND ...] [--tpoint "G S A" ...] -o report.html

The page loads nothing from elsewhere (:mod:`pointax.plots.report`). A PAINT heliostat folder
gets the calibration report and its per-sample error figure. Prints one line saying
what was written. Exit status 0 for a converged fit, 1 when it did not converge (the
page is still written), 2 for bad input or a missing matplotlib.
"""

from __future__ import annotations

import argparse
import os

from .common import error
from .fit import add_fit_options, guarded
from .plot import add_figure_options

__all__ = ["REPORT_KINDS", "add_report_parser", "run_report"]

REPORT_KINDS = ("summary", "tpoint9", "histogram")
"""Figures in a report by default: :data:`pointax.plots.report.REPORT_FIGURES`."""

_PREFIX = "pointax report"


def add_report_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``pointax report`` to an ``argparse`` sub-parser set; returns its parser."""
    p = subparsers.add_parser(
        "report",
        help="fit a pointing run and write a self-contained HTML report",
    )
    add_fit_options(p)
    add_figure_options(
        p,
        kind_help="figures to include (repeatable; default: " + ", ".join(REPORT_KINDS) + ")",
        tpoint_help="also include a TPOINT graphics command's plot, e.g. 'G S A' (repeatable)",
    )
    p.add_argument("--title", default=None, help="page title (default: the run's caption)")
    p.add_argument("-o", "--output", required=True, metavar="FILE", help="the HTML file to write")
    p.set_defaults(run=run_report)
    return p


def run_report(args: argparse.Namespace) -> int:
    """Run ``pointax report`` for parsed ``args``; returns the exit status."""
    if os.path.splitext(args.output)[1].lower() not in (".html", ".htm"):
        return error(_PREFIX, f"{args.output}: a report is an HTML file; name it .html")
    return guarded(args, _report, _PREFIX)


def _report(args) -> int:
    from .plot import checked_commands, fitted_observations

    try:
        commands = checked_commands(args)
    except ImportError as err:
        return error(_PREFIX, err)
    from ..plots.report import fit_report, heliostat_report, write_report
    from .fit import fit_from_args

    outcome = fit_from_args(args)
    notes = [f"Run: {args.data} ({outcome.fmt})"]
    if outcome.fmt == "paint":
        page = heliostat_report(outcome.calibration, title=args.title, notes=notes)
    else:
        page = fit_report(
            outcome.result,
            fitted_observations(outcome),
            run=outcome.run,
            title=args.title,
            figures=tuple(args.kind) if args.kind else REPORT_KINDS,
            commands=commands,
            notes=notes,
        )
    print(write_report(args.output, page))
    return 0 if bool(outcome.result.converged) else 1

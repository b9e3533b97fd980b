"""``pointax plot``: fit a run as ``pointax fit`` does and draw the fit to a file.

    pointax plot DATA [fit options] [--kind KIND ...] [--tpoint "G S A" ...] -o FILE

The format comes from FILE's extension (png, svg, pdf, ps/eps). One figure goes to
FILE itself; several (``--kind`` or ``--tpoint`` given more than once) go to
``STEM-NAME.EXT`` each, or to the pages of one PDF when FILE ends in ``.pdf``. A PAINT
heliostat folder gets the per-sample error figure (before, after, leave-one-out).
Prints one line per file written. Exit status 0 for a converged fit, 1 when it did not
converge (the figures are still written), 2 for bad input or a missing matplotlib.
"""

from __future__ import annotations

import argparse
import os
import re

from .common import error
from .fit import add_fit_options, guarded

__all__ = ["PLOT_KINDS", "add_plot_parser", "add_figure_options", "run_plot", "figures_from_outcome", "write_figures"]

PLOT_KINDS = ("summary", "residuals", "sky", "scatter", "histogram", "tpoint9")
"""The kinds of :func:`pointax.plots.fit_figure` (a light copy for the parser)."""

_PREFIX = "pointax plot"


def add_plot_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``pointax plot`` to an ``argparse`` sub-parser set; returns its parser."""
    p = subparsers.add_parser(
        "plot",
        help="fit a pointing run and draw the fit (png, svg, pdf or PostScript)",
    )
    add_fit_options(p)
    add_figure_options(
        p,
        kind_help="what to draw (repeatable; default summary): summary, residuals (each component against each axis "
        "angle and against each other), sky (sky map with residual vectors), scatter, histogram, tpoint9 "
        "(TPOINT's nine-panel A9 set)",
        tpoint_help="draw a TPOINT graphics command instead, e.g. 'G S A', 'GZZ', 'GSMAP', 'GHIST', 'A9' (repeatable)",
    )
    p.add_argument("-o", "--output", required=True, metavar="FILE", help="output file: .png, .svg, .pdf, .ps or .eps")
    p.set_defaults(run=run_plot)
    return p


def add_figure_options(parser: argparse.ArgumentParser, *, kind_help: str, tpoint_help: str) -> None:
    """Add the figure options of ``pointax plot`` and ``pointax report`` to ``parser``:
    ``--kind`` (repeatable, one of :data:`PLOT_KINDS`) and ``--tpoint COMMAND``
    (repeatable, a TPOINT graphics command), each with its command's help text."""
    parser.add_argument("--kind", action="append", choices=PLOT_KINDS, default=None, help=kind_help)
    parser.add_argument("--tpoint", action="append", default=None, metavar="COMMAND", help=tpoint_help)


def _check_output(path: str) -> None:
    ext = os.path.splitext(path)[1].lower()
    if ext not in (".png", ".svg", ".pdf", ".ps", ".eps"):
        raise ValueError(f"{path}: cannot tell the graphics format from the extension; use .png, .svg, .pdf, .ps or .eps")


def run_plot(args: argparse.Namespace) -> int:
    """Run ``pointax plot`` for parsed ``args``; returns the exit status."""
    try:
        _check_output(args.output)
    except ValueError as err:
        return error(_PREFIX, err)
    return guarded(args, _plot, _PREFIX)


def fitted_observations(outcome):
    """The observations as fitted: the run's weights with ``outcome.masked`` at 0."""
    import numpy as np


    obs = outcome.observations
    masked = outcome.masked
    if masked is None or not np.any(masked):
        return obs
    weight = np.where(np.asarray(masked, bool), 0.0, np.asarray(obs.weight, float))
    return obs.with_weight(weight)


def figures_from_outcome(outcome, kinds=None, commands=None) -> list[tuple[str, object]]:
    """``[(name, Figure)]`` for a :class:`pointax.cli.fit.FitOutcome`: the heliostat
    figure for PAINT runs, else each of ``kinds`` and TPOINT ``commands``."""
    from .. import plots

    if outcome.fmt == "paint":
        return [("heliostat", plots.heliostat_figure(outcome.calibration))]
    obs = fitted_observations(outcome)
    out = [(kind, plots.fit_figure(outcome.result, obs, kind)) for kind in (kinds or [])]
    for command in commands or []:
        name = re.sub(r"[^A-Za-z0-9]+", "", command).upper() or "G"
        out.append((name, plots.tpoint_graph(command, outcome.result, obs)))
    return out


def write_figures(figures: list[tuple[str, object]], path: str) -> list[str]:
    """Write ``figures`` to ``path`` (one figure), to ``STEM-NAME.EXT`` each, or to the
    pages of one PDF; returns the descriptions of what was written."""
    from ..plots import save_figure

    if len(figures) == 1:
        return [save_figure(figures[0][1], path)]
    stem, ext = os.path.splitext(path)
    if ext.lower() == ".pdf":
        from matplotlib.backends.backend_pdf import PdfPages

        with PdfPages(path) as pdf:
            for _, fig in figures:
                pdf.savefig(fig)
        names = ", ".join(name for name, _ in figures)
        return [f"PDF document, {len(figures)} pages ({names}), {os.path.getsize(path) / 1024:.0f} kB: {path}"]
    return [save_figure(fig, f"{stem}-{name}{ext}") for name, fig in figures]


def checked_commands(args) -> list[str]:
    """``--tpoint`` commands of ``args``, each checked before any fit (ValueError for an
    unknown name); ImportError when matplotlib is missing (``pip install 'pointax[plot]'``)."""
    from ..plots._mpl import require_matplotlib

    require_matplotlib()
    commands = args.tpoint or []
    if commands:
        from ..plots.tpoint_panels import parse_command

        for command in commands:
            parse_command(command)  # an unknown name fails before the fit
    return commands


def _plot(args) -> int:
    try:
        commands = checked_commands(args)
    except ImportError as err:
        return error(_PREFIX, err)
    from .fit import fit_from_args

    outcome = fit_from_args(args)
    kinds = args.kind if args.kind else ([] if commands else ["summary"])
    for line in write_figures(figures_from_outcome(outcome, kinds, commands), args.output):
        print(line)
    return 0 if bool(outcome.result.converged) else 1

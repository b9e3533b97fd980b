"""``pointax tpoint [SCRIPT ...]``: run TPOINT commands from files, or from standard input.

Scripts run in turn in one session (a procedure defined in one is known in the next);
with no script, commands are read from standard input, interactively with a prompt
when it is a terminal. The commands and how each maps to the Python API: the README's
"TPOINT procedures" and :mod:`pointax.procedures`.

Exit status: 0 when every command ran, 2 at the first error of a script or
non-interactive input (the message names the file and line); an interactive session
prints errors and goes on, and exits 0.
"""

from __future__ import annotations

import argparse
import sys

from . import choices
from .common import error, missing_input

__all__ = ["add_tpoint_parser", "run_tpoint"]

_PREFIX = "pointax tpoint"


def add_tpoint_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``pointax tpoint`` to an ``argparse`` sub-parser set; returns its parser."""
    p = subparsers.add_parser(
        "tpoint",
        help="run TPOINT commands (INDAT, USE, FIT, MASK, OUTMOD, PROC, ...) from files or standard input",
    )
    p.add_argument("scripts", nargs="*", metavar="SCRIPT", help="command files; file names in them are relative to their folder")
    p.add_argument(
        "--mount",
        choices=choices.TPOINT_MOUNTS,
        default="altaz",
        help="mount of runs whose files name none (TPOINT's default is equatorial; default here: altaz); "
        "a file with ': ALTAZ' or ': EQUAT' is read as it says",
    )
    p.add_argument(
        "--azimuth",
        choices=sorted(choices.AZIMUTH_CONVENTIONS),
        default="N-E",
        help="how the run files count azimuth (default N-E; the MMT runs are S-E)",
    )
    p.add_argument("--form", choices=sorted(choices.TERM_FORMS), default=choices.DEFAULT_TERM_FORM, help="term form (default: rigorous, as TPOINT applies its model)")
    p.add_argument(
        "--residuals",
        choices=list(choices.RESIDUAL_FORMS),
        default="sky",
        help="what FIT linearises: sky (the model applied rigorously, as TPOINT's FIT; default) or tpoint "
        "(TPOINT's linear residuals: one FIT solves the linear problem)",
    )
    p.set_defaults(run=run_tpoint)
    return p


def _enable_cache() -> None:
    """JAX's compilation cache ($POINTAX_JAX_CACHE; empty: off), turned on before the
    first command that computes (HELP or a bad first word never imports JAX)."""
    from ..fitting.compilation_cache import enable_compilation_cache

    enable_compilation_cache()


def run_tpoint(args: argparse.Namespace) -> int:
    """Run ``pointax tpoint`` for parsed ``args``; returns the exit status."""
    missing = missing_input(args.scripts)
    if missing:
        return error(_PREFIX, missing)
    from ..procedures import ProcedureError, Runner, Session

    session = Session(
        mount=args.mount, azimuth=args.azimuth, form=args.form, residual_form=args.residuals, prepare=_enable_cache
    )
    runner = Runner(session)
    try:
        if args.scripts:
            for script in args.scripts:
                runner.run_file(script)
        else:
            interactive = sys.stdin.isatty()
            if interactive:
                try:
                    import readline  # noqa: F401  (line editing and history for input())
                except ImportError:
                    pass
            runner.run_stream(sys.stdin, interactive=interactive)
    except ProcedureError as err:
        return error(_PREFIX, err)
    return 0

"""``pointax fit-network``: fit every site of a network manifest (:mod:`pointax.analysis.network`)."""

from __future__ import annotations

import argparse
import sys
from typing import TextIO

from . import choices
from .common import missing_input, os_error_text
from .history import add_previous_options, mark_moves, read_previous_option

__all__ = ["add_fit_network_parser", "run_fit_network"]


def add_fit_network_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``pointax fit-network`` to an ``argparse`` sub-parser set; returns its parser."""
    p = subparsers.add_parser(
        "fit-network",
        help="fit every site of a network manifest in batched fits; per-site status and a summary",
    )
    p.add_argument("manifest", help="CSV manifest: one row per site (site, path, format, ...)")
    p.add_argument("--json", action="store_true", help="print a JSON list, one object per site, instead of the table")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no summary on standard error")
    p.add_argument("--chunk-size", type=int, default=1000, help="sites per compiled call (default: %(default)s)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler address (e.g. tcp://host:8786) to fit on a cluster")
    p.add_argument("--solver", choices=sorted(choices.SOLVERS), default="lm", help="least-squares solver (default: lm)")
    p.add_argument("--max-steps", type=int, default=256, help="solver step limit (default: %(default)s)")
    p.add_argument("--pooled", action="store_true", help="partial pooling: the sites of one design share a population "
                   "estimated from them all (pointax.fit_pooled); per site shrinkage and a flag beyond --flag-sigma")
    p.add_argument("--flag-sigma", type=float, default=3.0, metavar="K",
                   help="with --pooled: flag sites beyond K sigma of their population (default: %(default)s)")
    add_previous_options(p)  # --previous FILE.json, --alarm N (pointax.cli.history)
    p.set_defaults(run=run_fit_network)
    return p


def run_fit_network(args: argparse.Namespace, stdout: TextIO | None = None, stderr: TextIO | None = None) -> int:
    """Run ``pointax fit-network`` for parsed ``args``; returns the exit status
    (0 every site converged, 1 some did not, 2 bad manifest or options)."""
    stdout = stdout if stdout is not None else sys.stdout
    stderr = stderr if stderr is not None else sys.stderr

    def fail(message) -> int:
        print(f"pointax fit-network: error: {message}", file=stderr)
        return 2

    if args.chunk_size < 1:
        return fail(f"--chunk-size must be a positive number of sites, got {args.chunk_size}")
    if getattr(args, "pooled", False):
        return _run_pooled(args, stdout, stderr, fail)
    missing = missing_input([args.manifest, getattr(args, "previous", None)])
    if missing:
        return fail(missing)
    try:
        previous = read_previous_option(args)  # a bad --previous fails before any fit
    except (ValueError, OSError) as err:
        return fail(err)

    from ..fitting.compilation_cache import enable_compilation_cache
    from ..analysis.network import ManifestError, fit_network
    from ..fitting.progress import progress_bar

    enable_compilation_cache()  # $POINTAX_JAX_CACHE; empty: off
    client = None
    progress = None
    try:
        if args.scheduler:
            try:
                from distributed import Client
            except ImportError:
                raise ValueError('--scheduler needs Dask distributed: pip install "dask[distributed]"') from None
            client = Client(args.scheduler)
        # A tqdm bar on standard error when it is a terminal (silent in pipes and logs).
        progress = progress_bar(0, "fitting", "site", enabled=not args.quiet, stream=stderr)
        result = fit_network(
            args.manifest,
            solver=args.solver,
            max_steps=args.max_steps,
            chunk_size=args.chunk_size,
            progress=progress if progress.active else False,
            client=client,
            observations=args.json,  # the table and the summary show none of them
        )
    except (ManifestError, ValueError) as err:
        return fail(err)
    except OSError as err:
        return fail(os_error_text(err, args.manifest))
    finally:
        if progress is not None:
            progress.close()
        if client is not None:
            client.close()
    moves = mark_moves(args, result, previous)  # per site 'moved' when --previous is given
    _print_result(args, result, stdout, stderr)
    if moves is not None and not (args.json and args.quiet):
        print(moves, file=stderr if args.json else stdout)
    return 0 if result.all_converged else 1


def _run_pooled(args: argparse.Namespace, stdout: TextIO, stderr: TextIO, fail) -> int:
    """``pointax fit-network --pooled`` (:mod:`pointax.analysis.pooled_report`)."""
    if args.scheduler:
        return fail("--pooled runs in this process: leave out --scheduler")
    if getattr(args, "previous", None):
        return fail("--previous compares independent fits with a previous one: leave out --pooled")
    if not args.flag_sigma > 0:
        return fail(f"--flag-sigma must be positive, got {args.flag_sigma}")
    missing = missing_input([args.manifest])
    if missing:
        return fail(missing)
    from ..analysis.network import ManifestError
    from ..analysis.pooled_report import pooled_network
    from ..fitting.compilation_cache import enable_compilation_cache
    from ..fitting.progress import progress_bar

    enable_compilation_cache()
    # A tqdm bar on standard error when it is a terminal (silent in pipes and logs).
    progress = progress_bar(0, "fitting", "site", enabled=not args.quiet, stream=stderr)
    try:
        result = pooled_network(args.manifest, k=args.flag_sigma, solver=args.solver, max_steps=args.max_steps,
                                chunk_size=args.chunk_size, progress=progress if progress.active else False)  # fmt: skip
    except (ManifestError, ValueError) as err:
        return fail(err)
    except OSError as err:
        return fail(os_error_text(err, args.manifest))
    finally:
        progress.close()
    _print_result(args, result, stdout, stderr)
    return 0 if result.all_converged else 1


def _print_result(args: argparse.Namespace, result, stdout: TextIO, stderr: TextIO) -> None:
    """A network's result (independent or pooled): ``--json`` on standard output with the
    summary on standard error (not with ``--quiet``), else the table and the summary."""
    if args.json:
        print(result.to_json(), file=stdout)
        if not args.quiet:
            print(result.summary(), file=stderr)
    else:
        print(result.table(), file=stdout)
        print("", file=stdout)
        print(result.summary(), file=stdout)

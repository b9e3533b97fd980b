"""``pointax fit-network``: fit every site of a network manifest (:mod:`pointax.analysis.network`)."""

from __future__ import annotations

import argparse
import sys
from typing import TextIO

from . import choices
from .common import missing_input, os_error_text

__all__ = ["add_fit_network_parser", "run_fit_network"]


def add_fit_network_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``pointax fit-network`` to an ``argparse`` sub-parser set; returns its parser."""
    p = subparsers.add_parser(
        "fit-network",
        help="fit every site of a network manifest in batched fits; per-site status and a summary",
        description="Fit every site listed in MANIFEST (CSV: site, path, format[, terms, form, residuals, azimuth, "
        "focal_spot]; see pointax.analysis.network). Exit status 0 when every site converged, 1 when some did "
        "not (degenerate or failed), 2 for a bad manifest.",
    )
    p.add_argument("manifest", help="CSV manifest: one row per site (site, path, format, ...)")
    p.add_argument("--json", action="store_true", help="print a JSON list, one object per site, instead of the table")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no summary on standard error")
    p.add_argument("--chunk-size", type=int, default=1000, help="sites per compiled call (default: %(default)s)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler address (e.g. tcp://host:8786) to fit on a cluster")
    p.add_argument("--solver", choices=sorted(choices.SOLVERS), default="lm", help="least-squares solver (default: lm)")
    p.add_argument("--max-steps", type=int, default=256, help="solver step limit (default: %(default)s)")
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
    missing = missing_input([args.manifest])
    if missing:
        return fail(missing)

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
    if args.json:
        print(result.to_json(), file=stdout)
        if not args.quiet:
            print(result.summary(), file=stderr)
    else:
        print(result.table(), file=stdout)
        print("", file=stdout)
        print(result.summary(), file=stdout)
    return 0 if result.all_converged else 1

"""``pointax history``: several runs of one telescope fitted with the same model, the
coefficients per run in time order, and an alarm for every change beyond ``--alarm``
sigma between consecutive runs (:mod:`pointax.analysis.history`).

    pointax history RUN... [--terms IA,IE,...] [--azimuth S-E] [--alarm 3] [--json] [--plot FILE.png]
                    [--vary TERM:READING[:DEGREE] ...]

Each RUN is a TPOINT input file (or an RTS2 gpoint file, or a table of pointing
offsets: ``--format``, else told from the file), read with the same ``--azimuth`` and
``--mount``. A run's time is the median of its observations' ``time`` reading, else the
date of its file (TPOINT's run-parameters record); the runs are listed in time order
(in the order given when one has no time).

Output: the table (one line per run: date, observations, Sky RMS and each coefficient
as value(sigma) in arcsec), the alarms and notes; or with ``--json`` one object,
``{"runs": [{"file", "time", "n_obs", "sky_rms_arcsec", "terms": [{"name",
"value_arcsec", "sigma_arcsec"}]}], "alarms": [{"file", "term", "change_sigma"}]}``
(``time``: MJD UTC, days, or null), with ``"joint"`` added when ``--vary`` is given.
``--plot FILE`` draws each coefficient against time with its error bars and alarms
(:func:`pointax.plots.history.history_figure`).

``--vary TERM:READING[:DEGREE]`` (repeatable) adds a joint fit of every run together in
which TERM is a smooth function of READING and the other terms are the same in every
run: ``TF:temperature`` (linear in the temperature, :func:`pointax.terms.thermal`),
``IA:time:2`` (a polynomial of degree 2 in time, :func:`pointax.terms.in_time`).

Exit status: 0 when every run's fit converged (alarms are findings, not failures), 1
when some did not, 2 for bad input.
"""

from __future__ import annotations

import argparse
import sys

from . import choices
from .common import error, missing_input, os_error_text, positive_float

__all__ = ["HISTORY_FORMATS", "add_history_parser", "run_history", "parse_vary"]

HISTORY_FORMATS = ("tpoint", "gpoint", "offsets")
"""The run formats ``pointax history`` reads."""

_PREFIX = "pointax history"


def parse_vary(items) -> dict[str, tuple[str, int]]:
    """``--vary`` items ``TERM:READING[:DEGREE]`` as ``{term: (reading, degree)}``.

    Raises:
        ValueError: a malformed item, a degree that is not a positive integer, a
            degree other than 1 for a reading other than time, a term given twice.
    """
    out: dict[str, tuple[str, int]] = {}
    for item in items or ():
        parts = [p.strip() for p in item.split(":")]
        if len(parts) not in (2, 3) or not all(parts):
            raise ValueError(f"--vary {item!r}: expected TERM:READING or TERM:READING:DEGREE, e.g. TF:temperature or IA:time:2")
        term, reading = parts[0], parts[1]
        degree = 1
        if len(parts) == 3:
            try:
                degree = int(parts[2])
            except ValueError:
                raise ValueError(f"--vary {item!r}: degree {parts[2]!r} is not a whole number") from None
            if degree < 1:
                raise ValueError(f"--vary {item!r}: degree must be 1 or more")
            if reading != "time" and degree != 1:
                raise ValueError(f"--vary {item!r}: a coefficient varies linearly with {reading}; degrees are for time")
        if term in out:
            raise ValueError(f"--vary {item!r}: {term} is given twice")
        out[term] = (reading, degree)
    return out


def add_history_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``pointax history`` to an ``argparse`` sub-parser set; returns its parser."""
    p = subparsers.add_parser(
        "history",
        help="fit several runs of one telescope with the same model: coefficients over time, drift alarms",
        description="Fit every RUN with the same model; print the coefficients per run in time order and an alarm "
        "for every change beyond --alarm sigma between consecutive runs. Exit status 0 when every fit converged, "
        "1 when some did not, 2 for bad input.",
    )
    p.add_argument("runs", nargs="+", metavar="RUN", help="pointing runs: TPOINT input files (or gpoint files, offsets tables)")
    p.add_argument(
        "--terms",
        default=None,
        help="terms to fit, comma or space separated (default: TPOINT's " + ",".join(choices.BASIC_ALTAZ) + "; for "
        "equatorial runs " + ",".join(choices.BASIC_EQUATORIAL) + ")",
    )
    p.add_argument("--alarm", type=positive_float, default=3.0, metavar="N",
                   help="alarm for a change beyond N sigma between consecutive runs (default: %(default)s)")  # fmt: skip
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    p.add_argument("--plot", metavar="FILE", help="draw each coefficient against time to FILE (.png, .svg, .pdf, .ps, .eps)")
    p.add_argument(
        "--vary",
        action="append",
        default=[],
        metavar="TERM:READING[:DEGREE]",
        help="also fit every run together with TERM a smooth function of READING (TF:temperature, IA:time, "
        "IA:time:2); repeatable",
    )
    p.add_argument("--format", choices=list(HISTORY_FORMATS), default=None, help="the runs' format (default: told from each file)")
    p.add_argument(
        "--azimuth",
        choices=sorted(choices.AZIMUTH_CONVENTIONS),
        default="N-E",
        help="how the files count azimuth (default N-E; the MMT's files are S-E)",
    )
    p.add_argument("--mount", choices=choices.TPOINT_MOUNTS, default=None, help="mount of TPOINT runs whose files name none")
    p.add_argument("--form", choices=sorted(choices.TERM_FORMS), default=choices.DEFAULT_TERM_FORM,
                   help="how the TPOINT terms are applied (default: %(default)s)")  # fmt: skip
    p.add_argument("--residuals", choices=list(choices.RESIDUAL_FORMS), default="sky",
                   help="what the fits minimise: sky (default) or tpoint")  # fmt: skip
    p.add_argument("--reject", metavar="SIGMAS", type=positive_float, default=None,
                   help="robust fits (Cauchy loss): leave out each run's observations beyond SIGMAS robust standard "
                   "deviations (as pointax fit --reject)")  # fmt: skip
    p.add_argument("--solver", choices=sorted(choices.SOLVERS), default="lm", help="least-squares solver (default: lm)")
    p.add_argument("--max-steps", type=int, default=256, help="solver step limit (default: %(default)s)")
    p.set_defaults(run=run_history)
    return p


def run_history(args: argparse.Namespace, stdout=None, stderr=None) -> int:
    """Run ``pointax history`` for parsed ``args``; returns the exit status."""
    stdout = stdout if stdout is not None else sys.stdout
    stderr = stderr if stderr is not None else sys.stderr

    def fail(message) -> int:
        print(f"{_PREFIX}: error: {message}", file=stderr)
        return 2

    missing = missing_input(args.runs)
    if missing:
        return fail(missing)
    try:
        vary = parse_vary(args.vary)
        if args.plot:
            from ..plots.save import format_of

            format_of(args.plot)  # an unknown extension fails before any fit
        return _history(args, vary, stdout, stderr)
    except (ValueError, KeyError) as err:
        return fail(err)
    except OSError as err:
        return fail(os_error_text(err, err.filename))


def _load(args):
    from ..io.load import load_run, detect_format

    runs = []
    for path in args.runs:
        fmt = args.format or detect_format(path)
        if fmt not in HISTORY_FORMATS:
            raise ValueError(f"{path}: a {fmt} run; pointax history reads {', '.join(HISTORY_FORMATS)} runs")
        if fmt == "tpoint":
            runs.append(load_run(path, "tpoint", azimuth=args.azimuth, mount=args.mount))
        elif fmt == "offsets":
            runs.append(load_run(path, "offsets", azimuth=args.azimuth))
        else:
            runs.append(load_run(path, "gpoint"))
    first = runs[0]
    for path, run in zip(args.runs, runs):
        mount, convention = getattr(run, "mount", "altaz"), run.observations.convention
        if mount != getattr(first, "mount", "altaz") or convention != first.observations.convention:
            raise ValueError(
                f"{path}: a {getattr(run, 'mount', 'altaz')} run with encoder convention {run.observations.convention!r}; "
                f"{args.runs[0]} is {getattr(first, 'mount', 'altaz')}, {first.observations.convention!r}: "
                "every run of a history is fitted with the same model"
            )
    return runs


def _model(args, run):
    from .. import terms as term_library
    from ..terms.model_factories import AltAz

    if type(run).__name__ == "GpointRun":
        if run.mount == "gem":
            raise ValueError(f"{run.path}: a German-equatorial gpoint run; pointax history fits alt-az gpoint runs")
        spec = args.terms if args.terms is not None else term_library.GPOINT_ALTAZ_TERMS
        terms = term_library.gpoint_terms(spec, form=args.form, mount=run.mount)
        return AltAz(terms, azimuth=run.azimuth, residual_form=args.residuals)
    if getattr(run, "mount", "altaz") == "equatorial":
        spec = args.terms if args.terms is not None else term_library.BASIC_EQUATORIAL
    else:
        spec = args.terms if args.terms is not None else term_library.BASIC_ALTAZ
    if hasattr(run, "term_options"):  # a TPOINT run: its mount (alt-az or equatorial at its latitude)
        return run.model(term_library.tpoint(spec, form=args.form, **run.term_options()), residual_form=args.residuals)
    return AltAz(term_library.tpoint(spec, form=args.form), azimuth=run.azimuth, residual_form=args.residuals)


def _resolve(vary: dict, model) -> dict:
    """``--vary`` term names as the model spells them (TPOINT's upper case, gpoint's lower)."""
    names = [t.name for t in model.terms]
    out = {}
    for term, how in vary.items():
        match = [n for n in names if n == term] or [n for n in names if n.lower() == term.lower()]
        if len(match) != 1:
            raise ValueError(f"--vary {term}: not among the terms fitted ({' '.join(names)})")
        out[match[0]] = how
    return out


def _history(args, vary, stdout, stderr) -> int:
    import json

    from ..analysis.history import history
    from ..fitting import FitOptions
    from ..fitting.compilation_cache import enable_compilation_cache

    enable_compilation_cache()  # $POINTAX_JAX_CACHE; empty: off
    runs = _load(args)
    model = _model(args, runs[0])
    vary = _resolve(vary, model)
    robust = {} if args.reject is None else {"loss": "cauchy", "reject": args.reject}
    options = FitOptions(solver=args.solver, max_steps=args.max_steps, **robust)
    h = history(runs, model, alarm=args.alarm, names=list(args.runs), options=options)
    joint = h.joint_fit(vary, options=options) if vary else None
    if args.json:
        out = h.to_dict()
        if joint is not None:
            out["joint"] = joint.to_dict()
        print(json.dumps(out, indent=2), file=stdout)
    else:
        print(h.table(), file=stdout)
        if joint is not None:
            print("", file=stdout)
            print(joint.report(), file=stdout)
    if args.plot:
        try:
            from ..plots.save import save_figure

            print(f"pointax: wrote {save_figure(h.figure(), args.plot)}", file=stderr)
        except ImportError as err:
            if "matplotlib" not in str(err):
                raise
            return error(_PREFIX, "--plot needs matplotlib, an optional extra: pip install 'pointax[plot]'")
    converged = h.all_converged and (joint is None or bool(joint.result.converged))
    return 0 if converged else 1


# --------------------------------------------------------------------------- pointax fit-network --previous


def add_previous_options(p: argparse.ArgumentParser) -> None:
    """``pointax fit-network``'s ``--previous FILE.json`` and ``--alarm N``."""
    p.add_argument("--previous", metavar="FILE.json", default=None,
                   help="a previous 'pointax fit-network --json' output: name the sites and terms that moved beyond "
                   "--alarm sigma since (per site 'moved' in the JSON)")  # fmt: skip
    p.add_argument("--alarm", type=positive_float, default=3.0, metavar="N",
                   help="with --previous: a change beyond N sigma is a move (default: %(default)s)")  # fmt: skip


def read_previous_option(args):
    """The ``--previous`` file's sites (None without the option). Raises ValueError or
    OSError naming the file for one that cannot be used (before anything is fitted)."""
    if not getattr(args, "previous", None):
        return None
    from ..analysis.history import read_previous

    return read_previous(args.previous)


def mark_moves(args, result, previous) -> str | None:
    """Compare a network's fit with the ``--previous`` one: each compared site's dict gets
    ``"moved"`` (``[{"term", "change_sigma"}]``, empty when nothing moved); returns the
    text of the moves and notes (None without ``--previous``)."""
    if previous is None:
        return None
    from ..analysis.history import compare_with_previous, moves_table

    moves, notes = compare_with_previous(result.sites, previous, args.alarm)
    before = {d["site"] for d in previous}
    for d in result.sites:
        if d["site"] in before:
            d["moved"] = [{"term": m.term, "change_sigma": m.change_sigma} for m in moves if m.site == d["site"]]
    return moves_table(moves, notes, args.previous, args.alarm)

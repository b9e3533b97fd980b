"""``pointax compare``: fit several model families to one pointing run and compare them.

    pointax compare DATA --families basic,harmonic,fauto [--mount altaz|equatorial|xy] [--format tpoint|gpoint|xy]
                    [--azimuth N-E|S-E|S-W] [--holdout FRACTION | --folds K] [--seed N]
                    [--per-axis angle|sky] [--form linear|rigorous] [--json]

``--per-axis``: the first axis's RMS of its angle residual (the level-mount paper's eqs
21-23; default for ``--mount xy``) or of the offset on the sky (``dA cos E``, TPOINT's;
default for alt-az).

DATA is a TPOINT input file (``--format tpoint``; ``--azimuth`` says how it counts
azimuth), an RTS2 gpoint file (``--format gpoint``) or an X-Y mount run in the text
format below (``--format xy`` or ``--mount xy``). Without ``--format`` the format is
told from the file (:func:`pointax.io.detect_format`); without ``--mount`` the mount is
``xy`` for an X-Y run, what a TPOINT file's option record says (``: ALTAZ``,
``: EQUAT``; a file that names none needs ``--mount altaz`` or ``--mount
equatorial``) and ``altaz`` for gpoint.

``--families`` lists the families: family names separated by commas
(``basic,harmonic``), or families separated by ``;``, each a family name, a term list
or ``label=terms`` (``"basic;IA IE CA NPAE AN AW TF TX HACA2"``,
``"tpoint8=basic;mine=basic HACA2 HESE2"``). Names are those of
:func:`pointax.analysis.family_model`: alt-az ``basic`` (TPOINT's eight), ``harmonic``
(those and the second azimuth harmonics), TPOINT term names, and with ``--format
gpoint`` gpoint's names (``gpoint`` = gpoint's seven, ``ia``, extras); equatorial
``basic`` (IH ID CH NP MA ME), ``flexure`` (those and TF FO DAF), ``harmonic`` (those
and the second hour-angle harmonics) and TPOINT's equatorial names; X-Y ``basic``,
``harmonic``, ``rotation``, ``linearised`` and term names of :mod:`pointax.terms.xy`.
The family ``fauto`` is the model :func:`pointax.analysis.fauto` builds on the run (the
mount's physical terms and the harmonics, to order ``--fauto-order``, and with
``--fauto-products N`` the product harmonics to order N, it keeps); its step
table is printed before the comparison (``"fauto"`` in the JSON). ``--family SPEC`` (repeatable) adds one family whose terms may contain ``;`` (gpoint
extras such as ``az:sincos:az;el:2;2``).

Out of sample: ``--folds K`` (k-fold cross-validation, default 5), ``--holdout
FRACTION`` (that fraction held back at random, ``--seed``), or ``--folds 0`` for none.

**X-Y text format** (``--mount xy``): one star per line, four numbers in degrees,
``L B L0 B0``: the encoder readings ``L, B`` and where the star is, ``L0, B0``, as X-Y
angles (the level-mount paper's eq 20 columns; the direction is ``(sin L0 cos B0, sin
B0, cos L0 cos B0)`` in East-North-Up). ``#`` starts a comment; fields may be separated
by spaces, tabs or commas. :func:`pointax.io.write_xy_run` writes it,
:func:`pointax.io.read_xy_run` reads it (:mod:`pointax.io.xy`).

Output: the comparison table (:meth:`pointax.analysis.Comparison.table`) or, with
``--json``, one object: ``file``, ``mount``, ``format`` and the keys of
:meth:`pointax.analysis.Comparison.to_dict` (``scheme``, ``n_fit``, ``n_validation``,
``families``: per family ``label``, ``n_params``, ``in_sample`` and ``out_of_sample``
(``axis1``, ``axis2``, ``total`` in arcsec, ``n``), ``sky_rms``, ``aic``, ``bic``,
``terms`` with ``significance``, ``warnings``, ``converged``). Exit status: 0 when
every fit converged, 1 when some did not, 2 for bad input (the message names the file,
line and field, or the option).
"""

from __future__ import annotations

import argparse
import json
import sys

from . import choices
from .common import error, missing_input, os_error_text

__all__ = ["COMPARE_FORMATS", "add_compare_parser", "run_compare", "parse_families", "main"]

COMPARE_FORMATS = ("tpoint", "gpoint", "xy")
"""The run formats ``pointax compare`` reads."""

_PREFIX = "pointax compare"


FAUTO_FAMILY = "fauto"
"""The family name that stands for the model :func:`pointax.analysis.fauto` builds on the run."""


def _known_names(mount: str, naming: str) -> set[str]:
    if mount == "xy":
        return set(choices.XY_FAMILIES) | {"linearized", FAUTO_FAMILY}
    if mount == "equatorial":
        return {"basic", "flexure", "harmonic", FAUTO_FAMILY}
    names = {"basic", "harmonic", FAUTO_FAMILY}
    return names | {"gpoint"} if naming == "gpoint" else names


def _is_term(name: str, mount: str, naming: str) -> bool:
    """Whether ``name`` is a term name for the mount (as :func:`pointax.analysis.family_model` reads it)."""
    from .. import terms

    try:
        if mount == "xy":
            from ..analysis.families import _xy_terms

            _xy_terms([name])
        elif mount == "equatorial":
            terms.tpoint([name], mount="equatorial", latitude=0.5)
        elif naming == "gpoint":
            terms.gpoint_terms([name])
        else:
            terms.tpoint([name])
    except (ValueError, KeyError, TypeError):
        return False
    return True


def _check_comma_list(parts: list[str], mount: str, naming: str) -> None:
    """A comma-separated ``--families`` list names families and terms: an item that is
    neither is answered with the families known for the mount."""
    known = _known_names(mount, naming)
    for p in parts:
        if p.lower() not in known and p not in known and not _is_term(p, mount, naming):
            raise ValueError(
                f"--families: unknown family {p!r} for a {mount} run; families: {', '.join(sorted(known))} "
                "(or term names, or families separated by ';')"
            )


def parse_families(text: str, extra: list[str] | None, mount: str, naming: str) -> dict[str, str]:
    """``--families`` (and ``--family``) to ``{label: spec}`` (see the module docstring)."""
    items: list[str] = []
    text = (text or "").strip()
    if text:
        if ";" in text:
            items = [s.strip() for s in text.split(";")]
            if any(not s for s in items):
                raise ValueError(f"--families: empty family in {text!r}")
        else:
            parts = [s.strip() for s in text.split(",")]
            known = _known_names(mount, naming)
            if all(p.lower() in known or p in known for p in parts):
                items = parts
            else:
                if "," in text and not any(c in text for c in " =:"):
                    _check_comma_list(parts, mount, naming)
                items = [text]
    items += [s.strip() for s in (extra or []) if s.strip()]
    if not items:
        raise ValueError("--families: give at least one family, e.g. --families basic,harmonic")
    out: dict[str, str] = {}
    for item in items:
        label, sep, spec = item.partition("=")
        if sep and label.strip() and ":" not in label:
            label, spec = label.strip(), spec.strip()
        else:
            label, spec = item, item
        if not spec:
            raise ValueError(f"--families: no terms for family {label!r}")
        if label in out:
            raise ValueError(f"--families: family {label!r} given twice")
        out[label] = spec
    return out


def add_compare_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``compare`` subcommand to an ``argparse`` subparsers object."""
    p = subparsers.add_parser(
        "compare",
        help="fit several model families to one pointing run and compare them (in/out-of-sample RMS, AIC, BIC)",
    )
    p.add_argument(
        "data", help="pointing run: TPOINT file, gpoint file or X-Y text file (told from the file, or --format)"
    )
    p.add_argument(
        "--families",
        default="basic,harmonic",
        help="families: names separated by commas (basic,harmonic), or families separated by ';', each a name, "
        "a term list or label=terms (default: %(default)s)",
    )
    p.add_argument(
        "--family", action="append", default=None, metavar="SPEC", help="one more family (may contain ';'); repeatable"
    )
    p.add_argument(
        "--mount",
        choices=["altaz", "equatorial", "xy"],
        default=None,
        help="mount kind (default: xy for an X-Y run, a TPOINT run's own option record (': ALTAZ', ': EQUAT'), "
        "altaz for gpoint); for a TPOINT file that names no mount, altaz or equatorial",
    )
    p.add_argument(
        "--format",
        choices=list(COMPARE_FORMATS),
        default=None,
        help="input format (default: told from the file; --mount xy reads the X-Y format)",
    )
    p.add_argument(
        "--azimuth",
        choices=sorted(choices.AZIMUTH_CONVENTIONS),
        default="N-E",
        help="tpoint: how the file counts azimuth (default N-E; the MMT run is S-E)",
    )
    p.add_argument("--form", choices=sorted(choices.TERM_FORMS), default=choices.DEFAULT_TERM_FORM, help="TPOINT term form (default: rigorous, as TPOINT applies its model)")
    group = p.add_mutually_exclusive_group()
    group.add_argument(
        "--holdout", type=float, default=None, metavar="FRACTION", help="hold back this fraction of the stars at random"
    )
    group.add_argument(
        "--folds",
        type=int,
        default=None,
        metavar="K",
        help="k-fold cross-validation (default 5; 0: no out-of-sample test)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the holdout or fold assignment (default: 0)")
    p.add_argument(
        "--per-axis",
        choices=["angle", "sky"],
        default=None,
        help="per-axis RMS of the first axis: its angle (the level-mount paper's; default for --mount xy) "
        "or the offset on the sky (TPOINT's dA cos E; default for altaz)",
    )
    p.add_argument(
        "--fauto-order",
        type=int,
        default=3,
        metavar="N",
        help="the family 'fauto' (TPOINT-style FAUTO on the run): harmonics up to this order (default: %(default)s)",
    )
    p.add_argument(
        "--fauto-products",
        type=int,
        default=0,
        metavar="N",
        help="the family 'fauto': also try two-coordinate product harmonics, both orders up to N, in a last "
        "stage (alt-az and equatorial; default: %(default)s, none)",
    )
    p.add_argument("--max-steps", type=int, default=256, help="solver step limit (default: %(default)s)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    p.add_argument("--quiet", action="store_true", help="no progress bar (it is drawn only on a terminal)")
    p.set_defaults(run=run_compare)
    return p


def _observations(args):
    """The run's observations, its format, the term naming and the mount."""
    from ..io.load import detect_format, load_run

    if args.mount == "xy":
        if args.format not in (None, "xy") or args.azimuth != "N-E":
            raise ValueError(
                "--format and --azimuth apply to alt-az runs; --mount xy reads the X-Y text format (L B L0 B0, degrees)"
            )
        return load_run(args.data, "xy").observations, "xy", "tpoint", "xy"
    fmt = args.format or detect_format(args.data)
    if fmt == "xy":
        if args.mount == "altaz":
            raise ValueError(f"{args.data}: an X-Y run (L B L0 B0); compare it with --mount xy")
        if args.azimuth != "N-E":
            raise ValueError("--azimuth applies to alt-az runs; an X-Y run counts its own angles (L B L0 B0, degrees)")
        return load_run(args.data, "xy").observations, "xy", "tpoint", "xy"
    if fmt not in COMPARE_FORMATS:
        raise ValueError(f"{args.data}: a {fmt} run; pointax compare reads {', '.join(COMPARE_FORMATS)} runs")
    if fmt == "gpoint":
        if args.azimuth != "N-E":
            raise ValueError("--azimuth applies to TPOINT runs; gpoint files count azimuth from South through West")
        run = load_run(args.data, "gpoint")
        if run.mount == "gem" or args.mount == "equatorial":
            raise ValueError(
                f"{args.data}: pointax compare reads gpoint's alt-az runs"
                + ("; this is a GEM run" if run.mount == "gem" else " (--mount equatorial)")
            )
        return run.observations, "gpoint", "gpoint", "altaz"
    run = load_run(args.data, "tpoint", azimuth=args.azimuth, mount=args.mount)
    if run.mount == "equatorial" and args.azimuth != "N-E":
        raise ValueError(f"{args.data}: --azimuth applies to alt-az runs; this run is equatorial")
    # The run itself, not its observations: an equatorial run's latitude names its families' mount.
    return run, "tpoint", "tpoint", run.mount


def _comparison(args):
    """The comparison, the run's format and the mount."""
    obs, fmt, naming, mount = _observations(args)
    families = parse_families(args.families, args.family, mount, naming)
    if args.holdout is not None:
        scheme = {"holdout": args.holdout}
    else:
        folds = 5 if args.folds is None else args.folds
        if folds < 0 or folds == 1:
            raise ValueError(f"--folds must be 0 (no out-of-sample test) or at least 2, got {folds}")
        scheme = {"folds": folds} if folds else {}
    if args.max_steps < 1:
        raise ValueError(f"--max-steps must be at least 1, got {args.max_steps}")
    from ..analysis import compare
    from ..fitting.compilation_cache import enable_compilation_cache

    enable_compilation_cache()  # $POINTAX_JAX_CACHE; empty: off
    built = _fauto_families(families, obs, args)
    result = compare(
        families,
        obs,
        seed=args.seed,
        per_axis=args.per_axis,
        naming=naming,
        form=args.form,
        max_steps=args.max_steps,
        progress=not getattr(args, "quiet", False),
        **scheme,
    )
    return result, fmt, mount, built


def _fauto_families(families: dict[str, str], obs, args):
    """Replace a ``fauto`` family by the terms :func:`pointax.analysis.fauto` chooses on all
    the run's stars (harmonics to ``--fauto-order``); returns that FAUTO result (or None).
    The folds then refit those terms: the choice itself saw every star."""
    wanted = [label for label, spec in families.items() if spec.strip().lower() == FAUTO_FAMILY]
    if not wanted:
        return None
    from ..analysis.fauto_search import fauto

    built = fauto(obs, max_order=args.fauto_order, max_product_order=args.fauto_products, form=args.form)
    names = " ".join(t.name for t in built.model.terms)
    for label in wanted:
        families[label] = names
    return built


def run_compare(args) -> int:
    """Run ``pointax compare`` for parsed ``args``; returns the exit status (0 every fit
    converged, 1 some did not, 2 bad input, with the message on standard error)."""
    missing = missing_input([args.data])
    if missing:
        return error(_PREFIX, missing)
    try:
        result, fmt, mount, built = _comparison(args)
    except (ValueError, KeyError, TypeError) as err:  # the readers' errors are ValueErrors
        return error(_PREFIX, err)
    except OSError as err:
        return error(_PREFIX, os_error_text(err, args.data))
    if args.json:
        out = {
            "file": args.data,
            "mount": mount,
            "format": fmt,
            **result.to_dict(),
        }
        if built is not None:
            out["fauto"] = built.to_dict()
        print(json.dumps(out, indent=2))
    else:
        if built is not None:
            print(built.report() + "\n")
        print(result.table())
    converged = all(row.converged for row in result.rows)
    return 0 if converged else 1


def main(argv: list[str] | None = None) -> int:
    """Stand-alone entry point (``python -m pointax.cli.compare DATA ...``)."""
    parser = argparse.ArgumentParser(prog="pointax")
    sub = parser.add_subparsers(dest="command", required=True)
    add_compare_parser(sub)
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] != "compare":
        argv = ["compare", *argv]
    return run_compare(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())

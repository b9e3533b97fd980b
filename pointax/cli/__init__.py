"""The ``pointax`` command: a thin layer over the Python API.

    pointax fit DATA [--terms IA,IE,...] [--form linear|rigorous] [--json]
    pointax fit DIR --format paint [--terms t1n,t1u,t2e,t2n] [--loss cauchy] [--json]
    pointax fit FILE --format gpoint [--terms ia,ie,tn,te,npae,npoa,tf,az:sin:az:2,HACA2] [--json]
    pointax command DIRECTIONS --mount turntable --params mu0=0.0751,... [--reflect] [--json]
    pointax fit-network MANIFEST [--json] [--quiet] [--chunk-size N] [--scheduler ADDRESS] [--previous FILE.json]
    pointax history RUN... [--terms ...] [--json] [--plot FILE] [--alarm N] [--vary TERM:READING[:DEGREE] ...]
    pointax centroid FRAME... [--json] [--method auto|intensity|limb]
    pointax compare DATA --families basic,harmonic,... [--holdout F | --folds K] [--json]
    pointax plot DATA [fit options] [--kind summary|residuals|sky|...] [--tpoint 'G S A'] -o FILE.png
    pointax report DATA [fit options] -o report.html
    pointax tpoint [SCRIPT ...] [--mount altaz|equatorial] [--azimuth S-E] [--residuals sky|tpoint]
    pointax plan --site LAT,LON,HEIGHT --time ISO [--terms ...] [-n 40] [--target-rms ARCSEC] [--json]
    pointax plan --sun --site LAT,LON,HEIGHT --time START --days 30 [--params alpha0=...] [--json]

Exit status, the same for every subcommand (:mod:`pointax.cli.common`): **0** success;
**1** the input was good but some item did not succeed (a fit that did not converge, a
direction not commanded, a frame without a usable sun, a site that failed); **2** bad
input (a missing or malformed file, option or value; the message names the file, line
and field). Warnings about input that was accepted but looks wrong (rows written twice,
lines after END, a nominal model used because none was given) go to standard error as
``pointax: warning: ...`` and do not change the exit status. ``pointax --version``
prints the version without importing any numerical library.

``pointax fit`` reads a TPOINT input file, fits the terms (TPOINT's eight basic alt-az
terms by default) and prints the TPOINT-style report, or with ``--json`` one JSON
object with the keys ``n_obs``, ``sky_rms_arcsec``, ``popn_sd_arcsec``, ``converged``,
``terms`` (``name``, ``value_arcsec``, ``sigma_arcsec``) and ``correlation`` (in the
order of ``terms``), plus ``iterations``, ``message``, ``solver``, ``fixed``,
``loss``, ``outliers`` (0-based indices of observations a robust ``--loss`` rejected;
``n_obs`` counts the observations kept) and ``warnings``. Exit status: 0 on a converged fit, 1 if the fit did not converge, 2 for
bad input.

``pointax fit FILE --format gpoint`` reads an RTS2 gpoint ``altaz-manual`` (or ``altaz``)
file (azimuth from South through West, as gpoint counts it) and fits gpoint's terms
(``ia ie tn te npae npoa tf`` by default; lower-case names are gpoint's, ``a:b:c:d``
strings gpoint's extra terms, upper-case names TPOINT's, mixed freely), printing the
same report or JSON as for TPOINT runs.

``pointax fit DIR --format paint`` calibrates one PAINT heliostat folder (robust fit,
outlier flags, leave-one-out; :func:`pointax.calibrate_heliostat`; ``--loo auto|yes|no``:
by default leave-one-out runs where the samples allow and is otherwise skipped with a
note, JSON key ``loo_skipped``, and null ``loo`` values) and prints the report
and a per-sample table, or with ``--json`` the keys ``n_obs``, ``params`` (``name``,
``value``, ``sigma``, ``unit``), ``error_mrad`` (``before``, ``after``, ``loo``: one
value per sample in file order; ``rms`` over the unflagged samples and ``rms_all``),
``samples`` (ids in file order), ``outliers`` (ids of flagged samples), ``n_used``
(samples kept by the fit; ``n_obs`` counts all of them) and more (see
:meth:`pointax.HeliostatCalibration.to_dict`). The "unflagged" samples are those the
fit of all samples kept; each leave-one-out fit re-detects outliers without its sample.

``pointax command`` is the inverse: encoder commands for wanted directions
(:func:`pointax.command`). DIRECTIONS is a text file ('-' for standard input) with one
direction per line, azimuth (North through East) and elevation in degrees, or with
``--reflect`` four columns: sun azimuth and elevation, target azimuth and elevation (the
mirror normal is their bisector). ``#`` starts a comment. The model is a turntable
(``--mount turntable``; ``--params`` in degrees, e.g. from a fit) or an alt-az telescope
(``--mount altaz --model FILE.mod``, a TPOINT model file, or ``--params`` in arcsec with
``--terms``). It prints one line per direction (readings in degrees, ok, reason) or a
JSON list. Exit status 0 when every direction was commanded, 1 when some were not.

``pointax fit-network`` fits every site of a network listed in a CSV manifest (see
:mod:`pointax.analysis.network`): one batched fit per model, a progress bar and a summary on
standard error (``--quiet``: none), per-site JSON with ``--json``.

``pointax centroid`` finds the sun in sun-sensor frames (PNG 8/16 bit, FITS, ``.npy``;
:mod:`pointax.sunsensor`) and prints per frame ``x``, ``y`` (pixels, origin at the centre
of the top-left pixel, x right, y down), the disk radius, the method, ``status`` and
``reason``.

``pointax compare`` fits several model families to the same run and prints a table
shaped like the level-mount paper's Table 3 (:func:`pointax.compare`).

``pointax fit`` masks rows with ``--mask 17,19-21`` (numbers from 1, file order),
``--mask-above ARCSEC`` (TPOINT's MASK R > x: fit, mask, refit) and flags outliers with
``--reject SIGMAS`` (robust fit); ``--list`` prints the residual listing and ``--json``
has per-observation entries (:mod:`pointax.analysis.listing`, :mod:`pointax.fitting.masking`).

``pointax plan`` chooses the stars (or, with ``--sun``, the sun times) of the next
pointing run that pin the model down best and prints them in observing order with the
predicted accuracy of the fit (:mod:`pointax.cli.plan`, :func:`pointax.plan_run`).

``pointax tpoint`` runs TPOINT commands (INDAT, USE, FIT, MASK, OUTMOD, PROC, ...) from
script files in turn or from standard input (:mod:`pointax.cli.tpoint`,
:mod:`pointax.procedures`).

The run's format is told from the file when ``--format`` is not given (a folder is a
PAINT heliostat; :func:`pointax.io.load_run` reads every format). A missing input file,
a mistyped option or an unknown name is reported (exit status 2) before any numerical
library is imported: the parser is built from :mod:`pointax.cli.choices`, and each
subcommand's module imports the library only in its ``run_*`` function.

One module per subcommand: :mod:`pointax.cli.fit`, :mod:`pointax.cli.inverse`,
:mod:`pointax.cli.fit_network`, :mod:`pointax.cli.centroid`, :mod:`pointax.cli.compare`,
:mod:`pointax.cli.plot` (figures of a fit, :mod:`pointax.plots`), :mod:`pointax.cli.plan` (planning a run), :mod:`pointax.cli.report` (an
HTML report, :mod:`pointax.plots.report`), :mod:`pointax.cli.tpoint` (TPOINT procedures).

Compiled fits are cached on disk (JAX's persistent compilation cache) in
``$POINTAX_JAX_CACHE``, by default ``~/.cache/pointax/jax``: a repeated ``pointax fit``
of the same model then loads its compiled fit instead of compiling it. ``POINTAX_JAX_CACHE=""``
turns the cache off.
"""

from __future__ import annotations

import argparse
import sys

from ..core.helptext import HELP_DIR, description
from .centroid import add_centroid_parser
from .inverse import add_command_parser
from .common import print_warnings
from .compare import add_compare_parser
from .fit import add_fit_parser
from .fit_network import add_fit_network_parser
from .history import add_history_parser
from .plan import add_plan_parser
from .plot import add_plot_parser
from .report import add_report_parser
from .tpoint import add_tpoint_parser

__all__ = ["main", "build_parser"]

_PROG = "pointax"

SUBCOMMANDS = (add_fit_parser, add_command_parser, add_fit_network_parser, add_centroid_parser, add_compare_parser, add_tpoint_parser, add_plot_parser, add_report_parser, add_plan_parser, add_history_parser)
"""Each adds its subcommand to the parser, with its ``run`` function as a default."""


def _version() -> str:
    """The installed distribution's version, else the package's (no JAX import)."""
    try:
        from importlib.metadata import version

        return version("pointax")
    except Exception:  # not installed: the source tree's own number
        from .. import __version__

        return __version__


class _VersionAction(argparse.Action):
    """``--version``, looked up only when asked for (reading the installed package's
    metadata would otherwise lengthen every command's start)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS, help="show the version and exit"):
        super().__init__(option_strings=option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"pointax {_version()}")
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    """The ``pointax`` parser (imports no numerical library)."""
    parser = argparse.ArgumentParser(prog="pointax", description="Telescope and sun-tracker pointing models in JAX.")
    parser.add_argument("--version", action=_VersionAction)
    sub = parser.add_subparsers(dest="command", required=True)
    for add in SUBCOMMANDS:
        add(sub)
    for name, subparser in sub.choices.items():  # descriptions: pointax/data/help/NAME.md, the site's text too
        if (HELP_DIR / f"{name}.md").is_file():
            subparser.description = description(name)
            subparser.formatter_class = argparse.RawDescriptionHelpFormatter
    return parser


def main(argv: list[str] | None = None) -> int:
    """The ``pointax`` command; returns the exit status."""
    args = build_parser().parse_args(argv)
    print_warnings(_PROG)  # input warnings (file, line, field) on standard error
    return args.run(args)


if __name__ == "__main__":
    sys.exit(main())

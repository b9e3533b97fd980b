"""``pointax plan``: choose the observations of the next pointing run and predict the
accuracy of its fit (:func:`pointax.plan_run`).

    pointax plan --site LAT,LON,HEIGHT --time ISO [--terms IA,IE,...] [-n 40] [--target-rms ARCSEC]
                 [--noise ARCSEC] [--mount altaz|xy] [--criterion i-optimal|d-optimal]
                 [--min-elevation DEG] [--max-elevation DEG] [--az-limits=MIN,MAX] [--sun-avoid DEG]
                 [--moon-avoid DEG] [--cadence SECONDS] [--max-magnitude MAG] [--pressure HPA]
                 [--skymap FILE.png] [--json]
    pointax plan --sun --site LAT,LON,HEIGHT --time START --days 30 [--step MINUTES]
                 [--terms full|simple] [--params alpha0=60.5,beta0=165.9] [-n 20] [--whole-sky] ...
    pointax plan --grid [--mount altaz|xy|turntable] [--terms ...] [-n 20] ...

Telescopes (default, ``--mount altaz`` or ``xy``): the candidates are the bundled
catalogue's stars (4559 Hipparcos stars, :func:`pointax.planning.star_candidates`)
visible at the site at ``--time`` between the elevation limits, at least
``--sun-avoid`` degrees (default 30) from the Sun and ``--moon-avoid`` degrees (default
15; 0 keeps all) from the Moon (its topocentric place, up or not). The run starts at
``--time`` and each target takes ``--cadence`` seconds (default 60, slew included):
after ordering, target k (from 0) is scheduled at ``--time`` + k x cadence and its
azimuth and elevation are those of the star at that time; targets that by then have
left the elevation or mount limits or come too near the Sun or Moon are dropped (a
warning and the table name them, the later targets moving up), not replaced, and the
predicted accuracy is that of the targets as scheduled. ``--cadence 0``: a snapshot,
every star where it is at ``--time``. ``--terms``: TPOINT names for
``altaz`` (default TPOINT's eight basic terms), a family name or term names for ``xy``
(default ``basic``). Sun trackers (``--sun``: ``--mount turntable``): the Sun's
positions every ``--step`` minutes over ``--days`` days from ``--time``
(:func:`pointax.planning.sun_candidates`); ``--terms full`` (the sun-vector paper's five
parameters, default) or ``simple``; ``--params`` name=value in degrees sets where to
linearise (the encoder zeros matter: default 0). Heliostats (``--sun --mount heliostat
--paint DIR``): the actuator geometry of a PAINT heliostat folder
(:func:`pointax.heliostat_model`, terms ``t1n,t1u,t2e,t2n`` by default), the candidates
the mirror normals that send the sun to the receiver, whose direction from the mirror
is ``--receiver AZ,EL`` (degrees) or, by default, the mean of the folder's measured
reflected rays; readings are actuator counts. A sun tracker only ever points along the
sun's path, so sun plans are chosen and judged over it by default: the predicted
figures average over the candidates within the limits (the sun, or the mirror normals,
every ``--step`` minutes over ``--days``: weighted by tracking time); ``--whole-sky``
uses the visible sky's grid instead (512 equal-area points, 20-85 deg), as telescope
plans do. ``--grid``: an azimuth-elevation grid every 15 deg in azimuth and 5 deg in
elevation (mechanical tests).

``--az-limits=MIN,MAX`` (degrees of the axis-1 reading, e.g. ``--az-limits=-270,270``
for a cable wrap: with ``=``, since the value starts with a minus sign) puts each target on its wrap branch and drops those outside; ``--el-limits``
likewise for axis 2. The plan stops at ``-n`` targets or as soon as the predicted
pointing RMS over the plan's sky reaches ``--target-rms`` arcsec.

Output: the targets in observing order (label: HIP number, time or grid index; the
time, UTC, the target is scheduled for (stars) or seen at (sun); azimuth and elevation
in degrees at that time; the axis readings; the predicted pointing error of the fitted
model there, arcsec), the predicted RMS, maximum and median-run RMS over the plan's sky
(the visible sky 20-85 deg, or the sun's path), and the targets dropped; with
``--json`` one object with the keys ``site``, ``time``, ``model``, ``n``,
``criterion``, ``noise_arcsec``, ``n_candidates``, ``stopped``, ``slew_deg``,
``readings_unit``, ``seconds_per_target`` (null for a snapshot), ``dropped`` (``label``,
``time``, ``reason``), ``predicted`` (``rms_arcsec``, ``max_arcsec``,
``median_rms_arcsec``, ``n_sky``, ``sky``: 'grid' or 'path'), ``rms_after_arcsec`` and
``targets`` (``order``, ``label``, ``azimuth_deg``, ``elevation_deg``, ``readings``,
``predicted_sigma_arcsec``, ``time``, ``magnitude``). ``--skymap FILE.png`` also saves
the predicted-accuracy sky map, titled with the figures of the table (over the plan's
sky: for ``--sun``, the sun's path). Exit status: 0 success, 1 when ``--target-rms`` was
not reached (or reached only before the stars moved), 2 bad input: options that
contradict (a minimum elevation or axis limit not below its maximum, ``--max-magnitude``
or ``--cadence`` for a sun or grid plan, a ``--step`` longer than ``--days``) or lie out
of range are refused before any numerical library is imported (:func:`check_options`);
a ``--max-magnitude`` brighter than every catalogue star names the brightest.
"""

from __future__ import annotations

import argparse
import json
import math

from .common import error, missing_input

__all__ = ["add_plan_parser", "run_plan", "check_options", "PLAN_MOUNTS", "PLAN_CRITERIA"]

PLAN_MOUNTS = ("altaz", "xy", "turntable", "heliostat")
"""Mounts ``pointax plan`` plans for."""

PLAN_CRITERIA = ("i-optimal", "d-optimal")
"""Design criteria: :data:`pointax.planning.CRITERIA`."""

_PREFIX = "pointax plan"


def add_plan_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``plan`` subcommand to an ``argparse`` subparsers object."""
    p = subparsers.add_parser(
        "plan",
        help="choose the observations of the next pointing run and predict the accuracy of its fit",
    )
    source = p.add_mutually_exclusive_group()
    source.add_argument("--sun", action="store_true", help="sun tracker: candidates are sun positions over --days")
    source.add_argument("--grid", action="store_true", help="a plain azimuth-elevation grid (mechanical tests)")
    p.add_argument("--site", metavar="LAT,LON,HEIGHT", help="site: latitude and longitude (deg, East +), height (m)")
    p.add_argument("--time", metavar="ISO", help="UTC start of the run (stars: targets are scheduled from it) or time of the first sun position (--sun)")
    p.add_argument("--days", type=float, default=30.0, help="--sun: span of days (default: %(default)s)")
    p.add_argument("--step", type=float, default=10.0, metavar="MINUTES", help="--sun: minutes between sun positions (default: %(default)s)")
    p.add_argument("--mount", choices=list(PLAN_MOUNTS), default=None, help="mount (default: altaz; turntable with --sun)")
    p.add_argument("--terms", default=None, help="model terms (altaz: TPOINT names, default the basic eight; xy: a family or "
                   "term names, default basic; turntable: full or simple)")  # fmt: skip
    p.add_argument("--paint", default=None, metavar="DIR", help="--mount heliostat: PAINT heliostat folder (geometry)")
    p.add_argument("--receiver", default=None, metavar="AZ,EL", help="--mount heliostat: direction of the receiver, deg")
    p.add_argument("--params", default="", help="where to linearise: name=value,... (arcsec for altaz/xy, deg for turntable)")
    p.add_argument("-n", type=int, default=40, help="most targets (default: %(default)s)")
    p.add_argument("--target-rms", type=float, default=None, metavar="ARCSEC", help="stop once the predicted RMS over the plan's sky (the whole sky; --sun: the sun's path) is this")
    p.add_argument("--noise", type=float, default=2.0, metavar="ARCSEC", help="expected measurement noise per axis (default: %(default)s)")
    p.add_argument("--criterion", choices=list(PLAN_CRITERIA), default="i-optimal", help="design criterion (default: %(default)s)")
    p.add_argument("--min-elevation", type=float, default=None, metavar="DEG", help="lowest elevation (default 20; --sun 15)")
    p.add_argument("--max-elevation", type=float, default=None, metavar="DEG", help="highest elevation (default 85; --sun 90)")
    p.add_argument("--az-limits", default=None, metavar="MIN,MAX", help="axis-1 reading limits, degrees (cable wrap; write --az-limits=-270,270)")
    p.add_argument("--el-limits", default=None, metavar="MIN,MAX", help="axis-2 reading limits, degrees (write --el-limits=MIN,MAX)")
    p.add_argument("--flipped", action="store_true", help="the flipped (over the top) mechanical solution")
    p.add_argument("--sun-avoid", type=float, default=30.0, metavar="DEG", help="stars: keep this far from the Sun (default: %(default)s)")
    p.add_argument("--moon-avoid", type=float, default=15.0, metavar="DEG",
                   help="stars: keep this far from the Moon, up or not (default: %(default)s; 0 keeps all)")  # fmt: skip
    p.add_argument("--cadence", type=float, default=None, metavar="SECONDS",
                   help="stars: seconds per target, slew included; each target is placed where it is at its scheduled "
                   "time, --time + k x cadence, and dropped if it has left the limits (default 60; 0: a snapshot at --time)")  # fmt: skip
    p.add_argument("--whole-sky", action="store_true",
                   help="--sun: choose and judge over the whole visible sky (20-85 deg) instead of the sun's path over --days")  # fmt: skip
    p.add_argument("--max-magnitude", type=float, default=None, metavar="MAG", help="stars: only this bright or brighter")
    p.add_argument("--pressure", type=float, default=None, metavar="HPA", help="air pressure for refraction (none without it)")
    p.add_argument("--skymap", default=None, metavar="FILE.png", help="save the predicted-accuracy sky map")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    p.set_defaults(run=run_plan)
    return p


def _floats(text: str, count: int, option: str) -> list[float]:
    parts = [s.strip() for s in text.split(",")]
    try:
        values = [float(s) for s in parts]
    except ValueError:
        raise ValueError(f"{option}: expected {count} numbers separated by commas, got {text!r}") from None
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise ValueError(f"{option}: expected {count} finite numbers separated by commas, got {text!r}")
    return values


def _model(args, mount: str):
    from .. import terms as term_library
    from ..terms.model_factories import AltAz, Turntable, XY
    from .inverse import parse_params

    if mount == "heliostat":
        from ..analysis.heliostat import heliostat_model
        from ..io.load import load_run

        if not args.paint:
            raise ValueError("--mount heliostat needs --paint DIR (a PAINT heliostat folder: its actuator geometry)")
        run = load_run(args.paint, "paint")
        names = args.terms.replace(",", " ").split() if args.terms else None
        model = heliostat_model(run, names) if names else heliostat_model(run)
        args._paint_run = run
    elif mount == "turntable":
        model = Turntable(args.terms or "full")
    elif mount == "xy":
        from ..terms.model_factories import XY_FAMILIES, xy_family

        spec = (args.terms or "basic").strip()
        if spec in XY_FAMILIES or spec == "linearized":
            model = XY(spec)
        else:
            known = {t.name: t for family in XY_FAMILIES for t in xy_family(family)}
            names = spec.replace(",", " ").split()
            unknown = [n for n in names if n not in known]
            if unknown:
                raise ValueError(f"--terms: unknown X-Y terms {', '.join(unknown)}; families: {', '.join(XY_FAMILIES)}")
            model = XY([known[n] for n in names])
    else:
        model = AltAz(term_library.tpoint(args.terms.replace(",", " ") if args.terms else term_library.BASIC_ALTAZ))
    return model.set(**parse_params(args.params, model))


def _finite(option: str, value, *, positive: bool = False, low=None, high=None) -> None:
    """ValueError naming ``option`` unless ``value`` (None: not given) is finite and in range."""
    if value is None:
        return
    if not math.isfinite(value) or (positive and not value > 0):
        raise ValueError(f"{option} must be a {'positive' if positive else 'finite'} number, got {value}")
    if (low is not None and value < low) or (high is not None and value > high):
        raise ValueError(f"{option} must be between {low:g} and {high:g}, got {value:g}")


def _ordered(option: str, text: str | None, count: int = 2) -> None:
    """ValueError unless ``text`` (MIN,MAX) has MIN below MAX."""
    if text:
        lo, hi = _floats(text, count, option)
        if not lo < hi:
            raise ValueError(f"{option}: the minimum ({lo:g}) must be below the maximum ({hi:g}), got {text!r}")


def check_options(args) -> tuple[str, float, float]:
    """Every check of the options that needs no numerical library: one option out of
    range or two that contradict (a minimum above its maximum, an option of another
    kind of plan). Returns ``(mount, min elevation, max elevation)`` (degrees, the
    defaults filled in); ValueError naming the options otherwise."""
    mount = args.mount or ("turntable" if args.sun else "altaz")
    if args.sun and mount not in ("turntable", "heliostat"):
        raise ValueError(f"--sun plans sun trackers: use --mount turntable or heliostat (not {mount})")
    if mount in ("turntable", "heliostat") and not (args.sun or (args.grid and mount == "turntable")):
        raise ValueError(f"--mount {mount}: plan over sun positions (--sun)" + (" or a grid (--grid)" if mount == "turntable" else ""))
    if args.n < 1:
        raise ValueError(f"-n must be at least 1, got {args.n}")
    if not (math.isfinite(args.noise) and args.noise > 0):
        raise ValueError(f"--noise must be positive, got {args.noise}")
    _finite("--target-rms", args.target_rms, positive=True)
    for option, value in (("--sun-avoid", args.sun_avoid), ("--moon-avoid", args.moon_avoid)):
        if not (0.0 <= value <= 180.0):
            raise ValueError(f"{option} must be between 0 and 180 degrees, got {value}")
    if args.cadence is not None and not (math.isfinite(args.cadence) and args.cadence >= 0):
        raise ValueError(f"--cadence must be a number of seconds >= 0, got {args.cadence}")
    if args.cadence and (args.sun or args.grid):
        raise ValueError("--cadence schedules stars: sun positions are at their own times, and a grid has none")
    if args.whole_sky and not args.sun:
        raise ValueError("--whole-sky is for sun plans (--sun): star and grid plans are judged over the whole sky already")
    if args.max_magnitude is not None and (args.sun or args.grid):
        raise ValueError("--max-magnitude selects stars: a sun or grid plan has none")
    _finite("--max-magnitude", args.max_magnitude)
    _finite("--pressure", args.pressure, low=0.0, high=1100.0)
    _finite("--min-elevation", args.min_elevation, low=-90.0, high=90.0)
    _finite("--max-elevation", args.max_elevation, low=-90.0, high=90.0)
    lo = args.min_elevation if args.min_elevation is not None else (15.0 if args.sun else 20.0)
    hi = args.max_elevation if args.max_elevation is not None else (90.0 if args.sun else 85.0)
    if not lo < hi:
        given = " and ".join(f"{o} {v:g}" for o, v in (("--min-elevation", args.min_elevation), ("--max-elevation", args.max_elevation))
                             if v is not None)  # fmt: skip
        raise ValueError(f"the minimum elevation ({lo:g} deg) must be below the maximum ({hi:g} deg): {given}")
    _ordered("--az-limits", args.az_limits)
    _ordered("--el-limits", args.el_limits)
    if args.sun:
        _finite("--days", args.days, positive=True)
        _finite("--step", args.step, positive=True)
        if args.step > args.days * 1440.0:
            raise ValueError(f"--step {args.step:g} minutes is longer than --days {args.days:g} ({args.days * 1440.0:g} minutes): one sun position")
    if args.site:
        lat, lon, height = _floats(args.site, 3, "--site")
        if not -90.0 <= lat <= 90.0:
            raise ValueError(f"--site: latitude must be between -90 and 90 degrees, got {lat:g}")
    return mount, lo, hi


def _plan(args):
    mount, lo, hi = check_options(args)
    site = time = None
    if not args.grid:
        if not args.site or not args.time:
            raise ValueError("give --site LAT,LON,HEIGHT and --time ISO (or --grid for a plain grid)")
        lat, lon, height = _floats(args.site, 3, "--site")
        from ..sky.sun import as_time, site as make_site

        site = make_site(lat, lon, height)
        time = as_time(args.time)
    limits = None
    if args.az_limits or args.el_limits:
        az = tuple(math.radians(v) for v in _floats(args.az_limits, 2, "--az-limits")) if args.az_limits else None
        el = tuple(math.radians(v) for v in _floats(args.el_limits, 2, "--el-limits")) if args.el_limits else None
        limits = (az, el)
    # The options are checked: now the numerical libraries (an error above imports none).
    from ..planning import grid_candidates, plan_run, star_candidates, sun_candidates
    from ..core.units import ARCSEC

    model = _model(args, mount)
    if args.grid:
        cand = grid_candidates()
    elif args.sun:
        target = None
        if mount == "heliostat":
            import numpy as np

            from ..core.rotations import azel_to_enu_numpy

            if args.receiver:
                az, el = _floats(args.receiver, 2, "--receiver")
                target = azel_to_enu_numpy(math.radians(az), math.radians(el))
            else:
                rays = np.asarray(args._paint_run.reflected, np.float64)
                rays = rays[np.all(np.isfinite(rays), axis=1)]
                if not len(rays):
                    raise ValueError(f"{args.paint}: no reflected rays to take the receiver's direction from: give --receiver AZ,EL")
                target = rays.mean(axis=0)
        cand = sun_candidates(site, time, args.days, step_minutes=args.step, min_elevation_deg=lo, max_elevation_deg=hi,
                              pressure_hpa=args.pressure, target=target)  # fmt: skip
    else:
        cand = star_candidates(site, time, min_elevation_deg=lo, max_elevation_deg=hi, max_magnitude=args.max_magnitude,
                               sun_avoid_deg=args.sun_avoid, moon_avoid_deg=args.moon_avoid or None,
                               pressure_hpa=args.pressure)  # fmt: skip
    if len(cand) == 0:
        raise ValueError("no candidate lies within the elevation limits (and away from the Sun and Moon) at that time")
    cadence = None if args.sun or args.grid else (60.0 if args.cadence is None else args.cadence)
    plan = plan_run(
        model, cand, args.n, noise=args.noise * ARCSEC, criterion=args.criterion,
        target_rms=None if args.target_rms is None else args.target_rms * ARCSEC, limits=limits,
        solution="flipped" if args.flipped else "normal",
        # (sun positions were cut by the sun's elevation; a heliostat's candidates are normals)
        min_elevation_deg=None if args.sun else lo, max_elevation_deg=None if args.sun else hi,
        seconds_per_target=cadence, sky="grid" if args.whole_sky else None,
    )  # fmt: skip
    meta = {
        "site": None if site is None else [float(x) for x in _floats(args.site, 3, "--site")],
        "time": None if time is None else time.isot,
        "model": model.describe(),
        "mount": mount,
        "candidates": "grid" if args.grid else ("sun" if args.sun else "stars"),
    }
    return plan, meta


def run_plan(args) -> int:
    """Run ``pointax plan`` for parsed ``args``; returns the exit status (0 success, 1
    the target RMS not reached, 2 bad input)."""
    missing = missing_input([args.paint])
    if missing:
        return error(_PREFIX, missing)
    try:
        plan, meta = _plan(args)
    except (ValueError, KeyError, TypeError) as err:
        return error(_PREFIX, err)
    if args.skymap:
        try:
            plan.accuracy.skymap().savefig(args.skymap, dpi=110)
        except OSError as err:
            return error(_PREFIX, f"{args.skymap}: {err.strerror or err}")
    if args.json:
        print(json.dumps({**meta, **plan.to_dict()}, indent=2))
    else:
        print(f"{meta['model']}; candidates: {meta['candidates']}" + (f" at {meta['time']} UTC" if meta["time"] else ""))
        print(plan.table())
    missed = args.target_rms is not None and plan.stopped != "target"
    if missed and not args.json:
        print(f"{_PREFIX}: the predicted RMS did not reach {args.target_rms}\" with {len(plan)} targets"
              + (" as scheduled (it did with the stars where they were at --time)" if plan.stopped == "moved" else ""))  # fmt: skip
    return 1 if missed else 0


def main(argv: list[str] | None = None) -> int:
    """``pointax plan`` on its own."""
    parser = argparse.ArgumentParser(prog="pointax")
    add_plan_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["plan", *(argv or [])])
    return args.run(args)

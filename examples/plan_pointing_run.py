"""Plan the next pointing run of an alt-az telescope and map its predicted accuracy.

Chooses 40 of the bundled catalogue's stars visible from Mt Hopkins on 2026-03-01 at
05:00 UTC (20-85 deg elevation, 30 deg from the Sun, a +-270 deg cable wrap) for
TPOINT's eight basic terms with 2" noise per axis, prints them in observing order and
writes the predicted-accuracy sky map to ``--skymap FILE`` (default
``plan_skymap.png`` in the system's temporary folder, so that a run never overwrites
the repository's ``examples/plan_skymap.png``, the README's figure).

    .venv/bin/python examples/plan_pointing_run.py [--skymap FILE.png]
"""

import argparse
import tempfile
from pathlib import Path

import pointax as px
from pointax import planning

DEFAULT_SKYMAP = Path(tempfile.gettempdir()) / "pointax-examples" / "plan_skymap.png"


def main(skymap=DEFAULT_SKYMAP) -> Path:
    model = px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"))
    where = px.sky.site(31.96, -111.60, 2100)
    stars = planning.star_candidates(where, "2026-03-01T05:00", min_elevation_deg=20, max_elevation_deg=85)
    plan = px.plan_run(model, stars, 40, noise=px.arcsec(2), limits=((px.deg(-270), px.deg(270)), None))
    print(plan.table())

    fig = plan.accuracy.skymap()
    out = Path(skymap)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    print(f"wrote {out}")
    return out


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skymap", default=str(DEFAULT_SKYMAP), metavar="FILE.png", help="where to write the sky map (default: %(default)s)")
    main(parser.parse_args().skymap)

"""Plan the next pointing run of an alt-az telescope and map its predicted accuracy.

Chooses 40 of the bundled catalogue's stars visible from Mt Hopkins on 2026-03-01 at
05:00 UTC (20-85 deg elevation, 30 deg from the Sun, a +-270 deg cable wrap) for
TPOINT's eight basic terms with 2" noise per axis, prints them in observing order and
writes the predicted-accuracy sky map to examples/plan_skymap.png.

    .venv/bin/python examples/plan_pointing_run.py
"""

from pathlib import Path

import pointax as px
from pointax import planning

model = px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"))
where = px.sky.site(31.96, -111.60, 2100)
stars = planning.star_candidates(where, "2026-03-01T05:00", min_elevation_deg=20, max_elevation_deg=85)
plan = px.plan_run(model, stars, 40, noise=px.arcsec(2), limits=((px.deg(-270), px.deg(270)), None))
print(plan.table())

fig = plan.accuracy.skymap()
out = Path(__file__).resolve().parent / "plan_skymap.png"
fig.savefig(out, dpi=100)
print(f"wrote {out}")

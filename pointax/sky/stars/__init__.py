"""Simulated star runs: a bright-star catalogue, apparent places, a planner, a simulator.

This is an edge module (NumPy and astropy; it calls the JAX core through
:func:`pointax.command`). A pointing run is simulated in four steps::

    import pointax as px
    from pointax import stars

    cat = stars.bright_stars()                                # 4559 Hipparcos stars, Hp <= 6
    where = px.sky.site(31.96, -111.60, 2100)
    plan = stars.plan_star_run(cat, where, "2026-03-01T03:00", 146,
                               min_elevation_deg=25, pressure_hpa=790)
    run = stars.simulate_star_run(true_model, plan, noise_arcsec=(4.1, 2.0), seed=1)
    fitting, validation = run.split(68, seed=2)               # the paper's 68 + 78 stars
    px.fit(model, fitting.observations)

Catalogue. :func:`bright_stars` reads ``pointax/data/bright_stars.csv``: every star of
the Hipparcos new reduction (van Leeuwen 2007, CDS I/311) with Hipparcos magnitude
``Hp <= 6.0`` (4559 stars, about one per 9 square degrees), fields copied verbatim from
``hip2.dat`` (provenance and extraction in ``pointax/data/PROVENANCE.txt``). Positions
are ICRS at epoch J1991.25 with parallaxes and proper motions. :data:`STAR_NAMES` gives
the HIP numbers of 52 named bright stars (``cat.find("Vega")``).

Apparent places. :func:`apparent_altaz` is astropy's: the catalogue place is carried to
the time of observation with ``SkyCoord.apply_space_motion`` (ERFA ``pmsafe``: proper
motion and parallax as straight-line space motion; radial velocity taken as 0, since
the catalogue has none: the perspective acceleration left out amounts by 2026 to about
0.1 arcsec for the nearest fast stars, 61 Cygni and alpha Centauri, far below a pointing
run's noise) and transformed to
``AltAz`` (precession-nutation, annual and diurnal aberration, light deflection, annual
parallax, UT1 and polar motion from the IERS tables). Refraction, when a pressure is
given, is :func:`pointax.sky.refraction` applied to the geometric elevation, exactly as
ERFA's ``atioq`` and astropy apply it. Stars with a parallax below 0.01 mas (18 have a
zero or negative Hipparcos parallax) are placed at 100 kpc. Checked against ERFA's
all-in-one ``atco13`` (0.03 mas apart; the test allows 1 mas) and against Meeus's
worked apparent place of theta Persei (0.5 arcsec apart, the size of the diurnal
aberration and polar motion the textbook leaves out; ``tests/test_stars.py``). IERS data are never downloaded (see
:mod:`pointax.sky`).

Planner. :func:`plan_star_run` spreads ``n`` aim points evenly (a Fibonacci lattice,
equal area) over the band of sky between two elevations, orders them like a real run
(rings of elevation from low to high, each ring swept in azimuth alternately up and
down, so an alt-az mount never winds more than a turn), and at each aim point's time
(one star every ``cadence_s`` seconds) takes the unused catalogue star nearest to it
that keeps at least half the aim points' spacing from the stars already taken (where
they were seen). For 146 stars above 25 deg (aim points 9 deg apart) this gave stars
at least 4.6-4.8 deg apart at two sites (random visible stars: 0.5 deg typical), each
within 6 deg of its aim point, with 12-13 deg slews on average (random order: 52 deg).

Simulator. :func:`simulate_star_run` asks a *true* :class:`pointax.Model` (any mount)
for the encoder readings that centre each planned star (:func:`pointax.command`, the
model's exact inverse) and adds Gaussian noise, per axis, to the readings (or on the
sky). The result's :class:`pointax.Observations` pair the noisy readings with the
apparent directions, ready for :func:`pointax.fit`.

Conventions: radians, azimuth from North through East, East-North-Up unit vectors
``(sin A cos E, cos A cos E, sin E)``; elevations are observed (refracted) when a
pressure is given and geometric otherwise.

One module per job: :mod:`~pointax.sky.stars.catalogue`, :mod:`~pointax.sky.stars.apparent`,
:mod:`~pointax.sky.stars.planner`, :mod:`~pointax.sky.stars.simulator`; every name is
importable from :mod:`pointax.sky.stars`.
"""

from __future__ import annotations

from ...core.units import ARCSEC  # noqa: F401  (pointax.sky.stars.ARCSEC, as before the split)
from .apparent import apparent_altaz, apparent_direction
from .apparent import fast_altaz as _fast_altaz  # noqa: F401  (tests/test_stars.py)
from .catalogue import (
    CATALOGUE_FILE,
    HIPPARCOS_EPOCH,
    MIN_PARALLAX_MAS,
    STAR_NAMES,
    Catalogue,
    bright_stars,
    read_catalogue,
)
from .planner import StarPlan, _aim_spacing, plan_star_run  # noqa: F401  (_aim_spacing: tests/test_stars.py)
from .simulator import NOISE_ON, StarRun, simulate_star_run

__all__ = [
    "CATALOGUE_FILE",
    "HIPPARCOS_EPOCH",
    "MIN_PARALLAX_MAS",
    "NOISE_ON",
    "STAR_NAMES",
    "Catalogue",
    "StarPlan",
    "StarRun",
    "apparent_altaz",
    "apparent_direction",
    "bright_stars",
    "plan_star_run",
    "read_catalogue",
    "simulate_star_run",
]

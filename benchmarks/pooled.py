"""Partial pooling of a network (``px.fit_pooled``) against independent fits
(``px.fit_batch``): held-out pointing error by site size, and fits per second.

The network: alt-az mounts of one design, TPOINT's linear terms IA IE AN AW TF
fitted in TPOINT's residual form (affine in the parameters), each site's true
coefficients drawn from one population (``POPULATIONS``: mean, spread and noise per
axis for each geometry; the gain of pooling grows with the noise against the spread).
Sites have 3, 5, 10 or 60 observations (a quarter each, padded to 60 rows in one
batch). Two geometries, each its own network and table:

* ``sun`` (the JSON's ``by_size``): sun trackers, the issue's case. A new installation
  (3, 5 or 10 observations) has seen the sun on one day, so its observations lie on
  one arc; a site with 60 has seen it on 60 days of a year. The held-out places are
  the sun's over a year (the places the site will point at).
* ``sky`` (``by_size_sky``): telescopes, stars and held-out places at random on the
  sky for every size.

A site's held-out pointing error is the RMS, over 100 held-out places, of the on-sky
difference between its fitted model and its true one; the table gives the RMS of that
over the sites of each size. Timing (sun network): both fits of the whole network,
warm (the first call's compilation excluded), best of ``--repeat``.

    .venv/bin/python benchmarks/pooled.py [--sites 10000] [--repeat 3]

Prints the tables and writes ``benchmarks/results/pooled.json``:
``{"by_size": [{"n_obs", "pooled_error_arcsec", "independent_error_arcsec"}, ...],
"by_size_sky": [...], "pooled_fits_per_s", "independent_fits_per_s"}``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import pointax as px

HERE = Path(__file__).resolve().parent
NAMES = ("IA", "IE", "AN", "AW", "TF")
ARCSEC = np.pi / 180 / 3600
# Each geometry's population (mean, spread) and noise per axis, arcsec. Telescopes: a
# spread of a few arcseconds, comparable to the noise of a star's centroid. Sun trackers:
# mounts installed to arcminutes, a sun sensor that resolves ten arcseconds.
POPULATIONS = {
    "sky": (np.array([0.0, 0.0, 0.0, 0.0, 15.0]), np.array([5.0, 5.0, 2.0, 2.0, 2.0]), 5.0),
    "sun": (np.array([0.0, 0.0, 0.0, 0.0, 30.0]), np.array([60.0, 60.0, 30.0, 30.0, 20.0]), 10.0),
}
SIZES = (3, 5, 10, 60)
HELD_OUT = 100


def basis(A, E):
    """``(5, 2, n)``: each term's (dA cos E, dE) per unit coefficient (DESIGN.md's
    TPOINT basis; azimuth A from North through East)."""
    zero, one = np.zeros_like(A), np.ones_like(A)
    fa = [-one, zero, -np.sin(A) * np.tan(E), -np.cos(A) * np.tan(E), zero]
    fe = [zero, one, -np.cos(A), np.sin(A), -np.cos(E)]
    return np.stack([np.stack([a * np.cos(E), e]) for a, e in zip(fa, fe)])


def sky(rng, shape):
    return rng.uniform(0, 2 * np.pi, shape), np.arcsin(rng.uniform(np.sin(np.radians(15)), np.sin(np.radians(85)), shape))



LATITUDE = np.radians(35.0)


def sun(rng, days, hours_per_day):
    """The sun's azimuth (from North through East) and elevation, ``days`` of shape
    ``(S, D)`` (day of the year), ``hours_per_day`` places a day at random times with the
    sun above 15 degrees: ``(S, D * hours_per_day)`` each. A circular orbit and
    declination (23.44 degrees of obliquity) at latitude 35 degrees: the geometry of a
    sun tracker, not an ephemeris."""
    dec = -np.radians(23.44) * np.cos(2 * np.pi * (days + 10) / 365.25)
    dec = np.repeat(dec, hours_per_day, axis=-1)
    lo = np.sin(np.radians(15.0))
    # the hour angle at which the sun crosses 15 degrees (|cos h| <= 1 at this latitude)
    cos_h = (lo - np.sin(LATITUDE) * np.sin(dec)) / (np.cos(LATITUDE) * np.cos(dec))
    h_max = np.arccos(np.clip(cos_h, -1.0, 1.0))
    h = h_max * rng.uniform(-1.0, 1.0, dec.shape)
    sin_e = np.sin(LATITUDE) * np.sin(dec) + np.cos(LATITUDE) * np.cos(dec) * np.cos(h)
    az = np.arctan2(-np.cos(dec) * np.sin(h), np.sin(dec) * np.cos(LATITUDE) - np.cos(dec) * np.cos(h) * np.sin(LATITUDE))
    return np.mod(az, 2 * np.pi), np.arcsin(sin_e)


def places(rng, sizes, n_max: int, geometry: str):
    """``(A, E)``, ``(S, n_max)`` each: where each site observed (see the module)."""
    if geometry == "sky":
        return sky(rng, (len(sizes), n_max))
    one_day = sun(rng, rng.uniform(0, 365.25, (len(sizes), 1)), n_max)
    year = sun(rng, rng.uniform(0, 365.25, (len(sizes), n_max)), 1)
    new = (sizes < n_max)[:, None]
    return np.where(new, one_day[0], year[0]), np.where(new, one_day[1], year[1])

def network(n_sites: int, seed: int = 1, geometry: str = "sun", noise: float | None = None):
    """``(batch, truth (S, 5), sizes (S,), held-out (A, E) (S, HELD_OUT))``; ``noise``
    (radians) replaces the geometry's."""
    mean, spread, default_noise = POPULATIONS[geometry]
    noise = default_noise * ARCSEC if noise is None else noise
    rng = np.random.default_rng(seed)
    sizes = np.array([SIZES[k % len(SIZES)] for k in range(n_sites)])
    truth = (mean + spread * rng.normal(size=(n_sites, len(NAMES)))) * ARCSEC
    n_max = max(SIZES)
    A, E = places(rng, sizes, n_max, geometry)
    f = basis(A, E)  # (5, 2, S, N)
    offsets = np.einsum("sk,kjsn->sjn", truth, f)  # (S, 2, N): (dA cos E, dE)
    noise = noise * rng.normal(size=offsets.shape)
    raw_a = A - (offsets[:, 0] + noise[:, 0]) / np.cos(E)
    raw_e = E - (offsets[:, 1] + noise[:, 1])
    encoder = np.stack([raw_a, raw_e], axis=-1)
    target = np.stack([np.sin(A) * np.cos(E), np.cos(A) * np.cos(E), np.sin(E)], axis=-1)
    weight = (np.arange(n_max)[None, :] < sizes[:, None]).astype(float)
    encoder = np.where(weight[..., None] > 0, encoder, 0.0)
    target = np.where(weight[..., None] > 0, target, np.array([0.0, 0.0, 1.0]))
    from pointax.fitting.batch import batched_observations

    batch = batched_observations(encoder, target, weight, "N-E")
    held = sky(rng, (n_sites, HELD_OUT)) if geometry == "sky" else sun(rng, rng.uniform(0, 365.25, (n_sites, HELD_OUT)), 1)
    return batch, truth, sizes, held


def held_out_error(values, truth, held) -> np.ndarray:
    """``(S,)`` RMS on-sky error (radians) of each site's fitted model at its held-out places."""
    f = basis(*held)  # (5, 2, S, H)
    diff = np.einsum("sk,kjsh->sjh", np.asarray(values) - truth, f)
    return np.sqrt(np.mean(np.sum(diff**2, axis=1), axis=-1))


def timed(fn, repeat: int):
    out = fn()  # compiles
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return out, best


def table(model, geometry: str, args, time_it: bool):
    """Fit one network both ways, print its table; ``(by_size rows, seconds pooled,
    seconds independent)`` (the seconds None unless ``time_it``)."""
    noise = None if args.noise is None else args.noise * ARCSEC
    batch, truth, sizes, held = network(args.sites, geometry=geometry, noise=noise)
    repeat = args.repeat if time_it else 0
    pooled, t_pooled = timed(lambda: px.fit_pooled(model, batch), repeat)
    independent, t_independent = timed(lambda: px.fit_batch(model, batch), repeat)
    err_p = held_out_error(pooled.sites.values, truth, held) / ARCSEC
    err_i = held_out_error(independent.values, truth, held) / ARCSEC
    ok_i = np.asarray(independent.converged) & np.all(np.isfinite(np.asarray(independent.values)), axis=-1)
    where = {"sun": "sun trackers: 3-10 observations on one day, 60 over a year; held out: the sun over a year",
             "sky": "telescopes: stars and held-out places at random on the sky"}[geometry]  # fmt: skip
    mean, spread, noise = POPULATIONS[geometry]
    noise = noise if args.noise is None else args.noise
    print(f"{geometry}: {where}")
    print(f"noise {noise:g}\" per axis; population mean, spread (arcsec): "
          + ", ".join(f"{n} {m:g}, {s:g}" for n, m, s in zip(NAMES, mean, spread)))
    print(f"pooled fit: converged {bool(pooled.converged)}, {int(pooled.iterations)} EM updates, "
          f"{int(np.sum(np.asarray(pooled.disagrees)))} sites flagged at {pooled.k:g} sigma")  # fmt: skip
    head = ("n_obs", "sites", 'pooled (")', 'independent (")', "change", "indep. not converged")
    print("{:>5}  {:>6}  {:>11}  {:>16}  {:>7}  {:>20}".format(*head))
    rows = []
    for n in SIZES:
        here = sizes == n
        use = here & ok_i
        row = {
            "n_obs": int(n),
            "pooled_error_arcsec": float(np.sqrt(np.mean(err_p[here] ** 2))),
            "independent_error_arcsec": float(np.sqrt(np.mean(err_i[use] ** 2))),
        }
        rows.append(row)
        change = row["pooled_error_arcsec"] / row["independent_error_arcsec"] - 1
        print(f"{n:>5}  {int(here.sum()):>6}  {row['pooled_error_arcsec']:>11.3f}  {row['independent_error_arcsec']:>16.3f}  "
              f"{change:>+7.1%}  {int((here & ~ok_i).sum()):>20}")  # fmt: skip
    print()
    return rows, (t_pooled if time_it else None), (t_independent if time_it else None)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sites", type=int, default=10000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--noise", type=float, help="noise per axis, arcsec, for both networks (default: each its own)")
    parser.add_argument("--out", default=str(HERE / "results" / "pooled.json"))
    args = parser.parse_args(argv)
    model = px.AltAz(px.terms.tpoint(" ".join(NAMES), form="linear"), residual_form="tpoint")
    print(f"{args.sites} sites, TPOINT IA IE AN AW TF (TPOINT form)\n")
    by_size, t_pooled, t_independent = table(model, "sun", args, time_it=True)
    by_size_sky, _, _ = table(model, "sky", args, time_it=False)
    out = {
        "by_size": by_size,
        "by_size_sky": by_size_sky,
        "pooled_fits_per_s": args.sites / t_pooled,
        "independent_fits_per_s": args.sites / t_independent,
    }
    print(f"pooled      {t_pooled:8.3f} s  {out['pooled_fits_per_s']:10.0f} fits/s")
    print(f"independent {t_independent:8.3f} s  {out['independent_fits_per_s']:10.0f} fits/s  "
          f"(pooled at {out['pooled_fits_per_s'] / out['independent_fits_per_s']:.2f} of it)")  # fmt: skip
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()

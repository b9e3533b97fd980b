"""Partial pooling of a network (``px.fit_pooled``) against independent fits
(``px.fit_batch``): held-out pointing error by site size, and fits per second.

The network: alt-az telescopes of one design, TPOINT's linear terms IA IE AN AW TF
fitted in TPOINT's residual form (affine in the parameters), each site's true
coefficients drawn from one population (mean and spread below), 5" noise per axis
(``--noise``: the gain of pooling grows with the noise against the population's spread).
Sites have 3, 5, 10 or 60 stars at random places on the sky (a quarter each, padded
to 60 rows in one batch). A site's held-out pointing error is the RMS, over 100 other
random places on the sky, of the on-sky difference between its fitted model and its
true one; the table gives the RMS of that over the sites of each size. Timing: both
fits of the whole network, warm (the first call's compilation excluded), best of
``--repeat``.

    .venv/bin/python benchmarks/pooled.py [--sites 10000] [--repeat 3]

Prints a table and writes ``benchmarks/results/pooled.json``:
``{"by_size": [{"n_obs", "pooled_error_arcsec", "independent_error_arcsec"}, ...],
"pooled_fits_per_s", "independent_fits_per_s"}``.
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
MEAN = np.array([0.0, 0.0, 0.0, 0.0, 15.0]) * ARCSEC
SPREAD = np.array([5.0, 5.0, 2.0, 2.0, 2.0]) * ARCSEC
NOISE = 5.0 * ARCSEC
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


def network(n_sites: int, seed: int = 1, noise: float = NOISE):
    """``(batch, truth (S, 5), sizes (S,), held-out (A, E) (S, HELD_OUT))``."""
    rng = np.random.default_rng(seed)
    sizes = np.array([SIZES[k % len(SIZES)] for k in range(n_sites)])
    truth = MEAN + SPREAD * rng.normal(size=(n_sites, len(NAMES)))
    n_max = max(SIZES)
    A, E = sky(rng, (n_sites, n_max))
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
    held = sky(rng, (n_sites, HELD_OUT))
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


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sites", type=int, default=10000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--noise", type=float, default=NOISE / ARCSEC, help="noise per axis, arcsec (default 5)")
    parser.add_argument("--out", default=str(HERE / "results" / "pooled.json"))
    args = parser.parse_args(argv)
    model = px.AltAz(px.terms.tpoint(" ".join(NAMES), form="linear"), residual_form="tpoint")
    batch, truth, sizes, held = network(args.sites, noise=args.noise * ARCSEC)
    pooled, t_pooled = timed(lambda: px.fit_pooled(model, batch), args.repeat)
    independent, t_independent = timed(lambda: px.fit_batch(model, batch), args.repeat)
    err_p = held_out_error(pooled.sites.values, truth, held) / ARCSEC
    err_i = held_out_error(independent.values, truth, held) / ARCSEC
    ok_i = np.asarray(independent.converged) & np.all(np.isfinite(np.asarray(independent.values)), axis=-1)
    by_size = []
    print(f"{args.sites} sites, TPOINT IA IE AN AW TF (TPOINT form), noise {args.noise:g}\" per axis, "
          f"population spread {', '.join(f'{n} {s / ARCSEC:g}' for n, s in zip(NAMES, SPREAD))} arcsec")  # fmt: skip
    print(f"pooled fit: converged {bool(pooled.converged)}, {int(pooled.iterations)} EM updates, "
          f"{int(np.sum(np.asarray(pooled.disagrees)))} sites flagged at {pooled.k:g} sigma")  # fmt: skip
    print()
    head = ("n_obs", "sites", 'pooled (")', 'independent (")', "change", "indep. not converged")
    print("{:>5}  {:>6}  {:>11}  {:>16}  {:>7}  {:>20}".format(*head))
    for n in SIZES:
        here = sizes == n
        use = here & ok_i
        row = {
            "n_obs": int(n),
            "pooled_error_arcsec": float(np.sqrt(np.mean(err_p[here] ** 2))),
            "independent_error_arcsec": float(np.sqrt(np.mean(err_i[use] ** 2))),
        }
        by_size.append(row)
        change = row["pooled_error_arcsec"] / row["independent_error_arcsec"] - 1
        print(f"{n:>5}  {int(here.sum()):>6}  {row['pooled_error_arcsec']:>11.3f}  {row['independent_error_arcsec']:>16.3f}  "
              f"{change:>+7.1%}  {int((here & ~ok_i).sum()):>20}")  # fmt: skip
    out = {
        "by_size": by_size,
        "pooled_fits_per_s": args.sites / t_pooled,
        "independent_fits_per_s": args.sites / t_independent,
    }
    print()
    print(f"pooled      {t_pooled:8.3f} s  {out['pooled_fits_per_s']:10.0f} fits/s")
    print(f"independent {t_independent:8.3f} s  {out['independent_fits_per_s']:10.0f} fits/s  "
          f"(pooled at {out['pooled_fits_per_s'] / out['independent_fits_per_s']:.2f} of it)")  # fmt: skip
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()

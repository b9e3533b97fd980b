"""Write the small example network in examples/data/network/: six simulated sun-tracking
turntables and the bundled MMT pointing run, listed in manifest.csv.

* ts-01 .. ts-04: turntables near the sun-vector paper's geometry (mu0 0.0751, nu0
  0.0145, omega0 -0.0947, alpha0 60.5425, beta0 165.8931 deg, each site a little
  different), following the sun for a day above 10 deg elevation, 0.02 deg noise.
* ts-05: a turntable whose azimuth axis never moved (every observation at one
  encoder azimuth): the data cannot separate the tilts from the pitch zero; the fit
  says so ("degenerate").
* ts-06: a file with a typing error on one line: the site is reported "failed" with
  the file, line and column, and the others go on.
* mmt: the bundled TPOINT run (examples/data/mmt_20210821.dat, azimuth from South).

Then try:

    .venv/bin/pointax fit-network examples/data/network/manifest.csv
    .venv/bin/pointax fit-network examples/data/network/manifest.csv --json --quiet

Run:  .venv/bin/python examples/make_network_data.py  (rewrites the files; seeded)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import pointax as px
from pointax.io.sun import write_sun_observations

OUT = Path(__file__).resolve().parent / "data" / "network"
PAPER = {"mu0": 0.0751, "nu0": 0.0145, "omega0": -0.0947, "alpha0": 60.5425, "beta0": 165.8931}  # deg
SITES = {  # name: (observations, latitude deg, declination deg)
    "ts-01": (60, 40.1, 20.0),
    "ts-02": (48, 35.0, -10.0),
    "ts-03": (55, 28.5, 5.0),
    "ts-04": (60, 45.0, 23.0),
    "ts-05": (40, 40.1, 20.0),
}


def sun_day(n: int, latitude_deg: float, declination_deg: float, rng) -> np.ndarray:
    """``(n, 2)`` sun azimuth (North through East) and elevation, radians, at ``n``
    random times of a day when the sun is above 10 deg (a plain spherical-astronomy
    sun, no refraction: enough for a simulation)."""
    lat, dec = np.radians(latitude_deg), np.radians(declination_deg)
    cos_hmax = (np.sin(np.radians(10)) - np.sin(lat) * np.sin(dec)) / (np.cos(lat) * np.cos(dec))
    hour = np.sort(rng.uniform(-1, 1, n)) * np.arccos(np.clip(cos_hmax, -1, 1))
    el = np.arcsin(np.sin(lat) * np.sin(dec) + np.cos(lat) * np.cos(dec) * np.cos(hour))
    az = np.arctan2(-np.cos(dec) * np.sin(hour), np.sin(dec) * np.cos(lat) - np.cos(dec) * np.sin(lat) * np.cos(hour))
    return np.stack([az % (2 * np.pi), el], axis=1)


def simulate_site(name: str, seed: int):
    """Encoder readings and observed sun (az, el) of one simulated turntable, radians."""
    n, latitude, declination = SITES[name]
    rng = np.random.default_rng(seed)
    jitter = {"mu0": 0.02, "nu0": 0.02, "omega0": 0.03, "alpha0": 3.0, "beta0": 1.0}
    truth_deg = {k: v + rng.normal(0, jitter[k]) for k, v in PAPER.items()}
    truth = px.Turntable("full").set(**{k: px.deg(v) for k, v in truth_deg.items()})
    sun = sun_day(n, latitude, declination, rng)
    # The servo centres the sun: nominally alpha - alpha0 = -azimuth, beta - beta0 = elevation.
    alpha = np.radians(truth_deg["alpha0"]) - sun[:, 0]
    if name == "ts-05":
        alpha = np.full(n, np.radians(truth_deg["alpha0"]) - 2.8)  # the azimuth axis stuck
    encoder = np.stack([alpha % (2 * np.pi), np.radians(truth_deg["beta0"]) + sun[:, 1]], axis=1)
    obs = px.simulate(truth, encoder, noise=px.deg(0.02), seed=seed)
    t = np.asarray(obs.target)
    observed = np.stack([np.arctan2(t[:, 0], t[:, 1]) % (2 * np.pi), np.arcsin(t[:, 2])], axis=1)
    return encoder, observed, truth_deg


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    rows = []
    for seed, name in enumerate(SITES, 1):
        encoder, sun, truth = simulate_site(name, seed)
        comments = [
            f"{name}: simulated sun-tracking turntable (examples/make_network_data.py, seed {seed})",
            "truth (deg): " + " ".join(f"{k} {v:.4f}" for k, v in truth.items()),
        ]
        write_sun_observations(OUT / f"{name}.txt", encoder, sun, comments=comments)
        rows.append(f"{name}, {name}.txt, sun, full,")
    # ts-06: ts-01's observations with a typing error on one line.
    text = (OUT / "ts-01.txt").read_text().splitlines()
    text[0] = "# ts-06: ts-01's file with a typing error in the tenth observation"
    fields = text[12].split()
    fields[2] = fields[2].replace(".", ";", 1)  # e.g. '141.022' -> '141;022': a typing error
    text[12] = " ".join(fields)
    (OUT / "ts-06.txt").write_text("\n".join(text) + "\n")
    rows.append("ts-06, ts-06.txt, sun, full,")
    rows.append("mmt, ../mmt_20210821.dat, tpoint, IA IE NPAE CA AN AW TF TX, S-E")
    manifest = [
        "# An example network (examples/make_network_data.py): one row per site.",
        "# path is relative to this file; format: sun | tpoint | paint; terms: names separated by spaces.",
        "site, path, format, terms, azimuth",
        *rows,
    ]
    (OUT / "manifest.csv").write_text("\n".join(manifest) + "\n")
    print(f"wrote {len(rows)} sites to {OUT / 'manifest.csv'}")


if __name__ == "__main__":
    main()

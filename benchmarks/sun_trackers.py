"""Sun trackers: the figures behind the turntable and heliostat features, in one run.

* the paper's Table 1 fitted with the five-parameter turntable model, next to the
  paper's values;
* astropy sun directions (pointax.sky) against NREL's SPA (pvlib) at three sites over
  a year, unrefracted;
* the inverse (pointax.command): round-trip error and directions per second for a
  turntable with random small errors;
* the PAINT heliostat AA39: errors before, after and leave-one-out (mrad), outliers
  and the time of the calibration.

Prints a table and writes benchmarks/results/sun_trackers.json.

    .venv/bin/python benchmarks/sun_trackers.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from astropy.time import Time

import pointax as px

HERE = Path(__file__).resolve().parent
PAINT = HERE.parent.parent / "shared" / "data" / "paint" / "AA39"

TABLE1 = {  # the paper's Table 1: sun altitude, azimuth; encoder pitch, azimuth (deg)
    "altitude": [50.469, 52.704, 53.210, 53.704, 53.965, 54.187, 49.208, 46.623],
    "azimuth": [141.022, 147.820, 148.951, 150.703, 151.689, 152.562, 222.086, 227.280],
    "pitch": [216.460, 218.653, 219.173, 219.656, 219.964, 220.118, 215.150, 212.557],
    "az_encoder": [279.436, 272.655, 271.506, 269.764, 268.775, 267.830, 198.259, 193.104],
}
PAPER = {"mu0": 0.0751, "nu0": 0.0145, "omega0": -0.0947, "alpha0": 60.5425, "beta0": 165.8931}
SITES = {"Juelich": (50.913, 6.388, 88.0), "Alice Springs": (-23.698, 133.881, 546.0), "Mauna Kea": (19.8207, -155.4681, 4205.0)}


def enu(az_deg, el_deg):
    return px.rotations.azel_to_enu_numpy(np.radians(az_deg), np.radians(el_deg))


def angle(a, b):
    return 2.0 * np.arcsin(np.clip(np.linalg.norm(a - b, axis=-1) / 2.0, 0.0, 1.0))


def table1() -> dict:
    encoder = np.radians(np.stack([TABLE1["az_encoder"], TABLE1["pitch"]], axis=1))
    obs = px.Observations(encoder, enu(TABLE1["azimuth"], TABLE1["altitude"]), convention="turntable")
    result = px.fit(px.Turntable("full", start=obs), obs)
    values = {n: result.value(n, "deg") for n in PAPER}
    corr = np.asarray(result.correlation)
    return {
        "values_deg": values,
        "paper_deg": PAPER,
        "max_deviation_deg": max(abs(values[n] - PAPER[n]) for n in PAPER),
        "rms_deg": float(np.degrees(float(result.sky_rms))),
        "corr_omega0_alpha0": float(corr[result.names.index("omega0"), result.names.index("alpha0")]),
        "converged": bool(result.converged),
    }


def spa(days_step: int) -> dict:
    from pvlib import spa as pvlib_spa

    out = {}
    for name, (lat, lon, h) in SITES.items():
        hours = np.array([6.5, 8.0, 10.0, 11.5, 12.5, 14.0, 16.0, 17.5]) - lon / 15.0
        mjd = Time("2025-01-01T00:00:00").mjd + np.arange(0, 365, days_step)[:, None] + hours[None, :] / 24.0
        times = Time(mjd.ravel(), format="mjd", scale="utc")
        ours = px.sky.sun_direction(times, px.sky.site(lat, lon, h))
        # SPA is given the UT1 and TT - UT1 astropy uses: only ephemeris and reduction differ.
        ut1_unix = times.unix + times.delta_ut1_utc
        delta_t = ((times.tt.jd1 - times.ut1.jd1) + (times.tt.jd2 - times.ut1.jd2)) * 86400.0
        res = pvlib_spa.solar_position(ut1_unix, lat, lon, h, 1010.0, 10.0, delta_t, 0.5667)
        theirs = enu(res[4], res[3])  # index 3: topocentric elevation without refraction; 4: azimuth
        up = theirs[:, 2] > 0
        out[name] = {"n": int(up.sum()), "max_arcsec": float(np.degrees(angle(ours[up], theirs[up]).max()) * 3600)}
    return out


def inverse(n: int) -> dict:
    rng = np.random.default_rng(0)
    model = px.Turntable("full").set(
        mu0=px.deg(0.08), nu0=px.deg(-0.03), omega0=px.deg(-0.09), alpha0=px.deg(60.54), beta0=px.deg(165.89)
    )
    az = rng.uniform(0, 360, n)
    el = np.degrees(np.arcsin(rng.uniform(np.sin(np.radians(5)), 1, n)))
    wanted = enu(az, el)
    limits = ((0.0, 2 * np.pi), None)
    t0 = time.perf_counter()
    cmd = px.command(model, wanted, limits=limits)
    cmd.reading.block_until_ready()
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    cmd = px.command(model, wanted, limits=limits)
    cmd.reading.block_until_ready()
    steady = time.perf_counter() - t0
    back = np.asarray(model(np.asarray(cmd.reading)))
    return {
        "n": n,
        "all_ok": bool(np.all(cmd.ok)),
        "max_roundtrip_rad": float(angle(back, wanted).max()),
        "first_call_s": first,
        "directions_per_s": n / steady,
        "max_newton_steps": int(np.asarray(cmd.iterations).max()),
    }


def heliostat() -> dict | None:
    if not PAINT.is_dir():
        return None
    t0 = time.perf_counter()
    cal = px.calibrate_heliostat(PAINT)
    seconds = time.perf_counter() - t0
    d = cal.to_dict()
    return {
        "rms_mrad": d["error_mrad"]["rms"],
        "rms_all_mrad": d["error_mrad"]["rms_all"],
        "outliers": d["outliers"],
        "n_unflagged": d["n_used"],
        "params_mrad": {p["name"]: [p["value"], p["sigma"]] for p in d["params"]},
        "seconds_first_call": seconds,
    }


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer sun times and directions")
    parser.add_argument("--out", default=str(HERE / "results" / "sun_trackers.json"))
    args = parser.parse_args()

    out = {
        "table1": table1(),
        "spa": spa(days_step=15 if args.quick else 5),
        "inverse": inverse(1_000 if args.quick else 100_000),
        "heliostat_AA39": heliostat(),
    }
    t = out["table1"]
    print("Paper's Table 1, five-parameter turntable model (deg)")
    for name, want in PAPER.items():
        print(f"  {name:<7s} pointax {t['values_deg'][name]:+10.4f}   paper {want:+10.4f}")
    print(f"  max deviation {t['max_deviation_deg']:.1e} deg, RMS {t['rms_deg']:.4f} deg, r(omega0, alpha0) {t['corr_omega0_alpha0']:+.4f}")
    print("\nSun direction, astropy (pointax.sky) vs NREL SPA (pvlib), unrefracted")
    for name, row in out["spa"].items():
        print(f"  {name:<14s} {row['n']:5d} times   max {row['max_arcsec']:.2f} arcsec")
    inv = out["inverse"]
    print(f"\nInverse (pointax.command), turntable with errors, {inv['n']} directions above 5 deg")
    print(f"  all ok {inv['all_ok']}, max |forward(inverse(d)) - d| {inv['max_roundtrip_rad']:.1e} rad, "
          f"<= {inv['max_newton_steps']} Newton steps")
    print(f"  first call {inv['first_call_s']:.1f} s, then {inv['directions_per_s']:,.0f} directions/s")
    hel = out["heliostat_AA39"]
    if hel is None:
        print("\nPAINT AA39: ../shared/data/paint/AA39 not found, skipped")
    else:
        r, a = hel["rms_mrad"], hel["rms_all_mrad"]
        print(f"\nPAINT heliostat AA39 (normal errors, mrad; {hel['n_unflagged']} unflagged of 18)")
        print(f"  unflagged: before {r['before']:.2f}  after {r['after']:.2f}  leave-one-out {r['loo']:.2f}")
        print(f"  all:       before {a['before']:.2f}  after {a['after']:.2f}  leave-one-out {a['loo']:.2f}")
        print(f"  outliers: {', '.join(hel['outliers'])}; calibration incl. compilation {hel['seconds_first_call']:.1f} s")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=2) + "\n")
    print(f"\nwrote {args.out}")
    return out


if __name__ == "__main__":
    main()

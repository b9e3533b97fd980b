"""Writes ``altaz_manual.txt``: a synthetic RTS2 gpoint ``altaz-manual`` run (test data).

Not real data. The layout follows RTS2's writer of such files (``TPVP`` in
``python/rts2/tpvp.py``: line 1 '# model file created on ...', line 2
'# altaz-manual LONGITUDE LATITUDE ALTITUDE', then per star
``id <TAB> JD <TAB> RA <TAB> Dec <TAB> alt offset <TAB> az offset <TAB> alt <TAB> az``)
and gpoint's reader (``GPoint.process_files`` in ``python/rts2/gpoint.py``, RTS2/rts2
commit 6480a7eb549d3158ee178ce557fab6d75de8eba9), which takes (az, alt) as the mount
position and (az + az offset, alt + alt offset) as the real one. Azimuth counts from
South through West (libnova). The offsets are gpoint's own model (``model_az_hadec``,
``model_el_hadec``) with the coefficients in TRUE_ARCSEC, evaluated at the mount
position, plus Gaussian noise of NOISE_ARCSEC on the sky. RA and Dec are the real
position converted with the standard formulas at an assumed sidereal time; gpoint's
fit does not use them.

Run from the repository root: ``.venv/bin/python tests/data/gpoint/make_sample.py``.
"""

from pathlib import Path

import numpy as np

TRUE_ARCSEC = {"ia": 120.0, "ie": -45.0, "tn": 15.0, "te": -22.0, "npae": 8.0, "npoa": -30.0, "tf": 35.0,
               "az:sincos:az;el:2;2": 12.0}
NOISE_ARCSEC = 1.5
LONGITUDE, LATITUDE, ALTITUDE = -20.8, -32.53, 1850.0
N = 36
SEED = 5


def gpoint_offsets(p, az, el):
    """gpoint's model_az / model_el (radians in, radians out), az from South through West."""
    tan_el = np.tan(el)
    d_az = (-p["ia"] + p["tn"] * np.sin(az) * tan_el - p["te"] * np.cos(az) * tan_el - p["npae"] * tan_el
            + p["npoa"] / np.cos(el) + p["az:sincos:az;el:2;2"] * np.sin(2 * az) * np.cos(2 * el))
    d_el = -p["ie"] + p["tn"] * np.cos(az) + p["te"] * np.sin(az) + p["tf"] * np.cos(el)
    return d_az, d_el


def main():
    rng = np.random.default_rng(SEED)
    arcsec = np.pi / 648000
    p = {k: v * arcsec for k, v in TRUE_ARCSEC.items()}
    az = np.round(np.sort(rng.uniform(0.0, 360.0, N)), 4)
    alt = np.round(rng.uniform(15.0, 85.0, N), 4)
    d_az, d_el = gpoint_offsets(p, np.radians(az), np.radians(alt))
    noise = rng.normal(size=(N, 2)) * NOISE_ARCSEC * arcsec
    e_alt = np.degrees(d_el + noise[:, 1])
    e_az = np.degrees(d_az + noise[:, 0] / np.cos(np.radians(alt) + d_el))
    # Target RA/Dec of the real position (standard formulas, A from South through West).
    real_az, real_alt = np.radians(az + e_az), np.radians(alt + e_alt)
    lat = np.radians(LATITUDE)
    ha = np.arctan2(np.sin(real_az), np.cos(real_az) * np.sin(lat) + np.tan(real_alt) * np.cos(lat))
    dec = np.arcsin(np.sin(lat) * np.sin(real_alt) - np.cos(lat) * np.cos(real_alt) * np.cos(real_az))
    jd = 2457000.5 + 0.004 * np.arange(N)
    lst = 100.0 + 360.98564736629 * (jd - jd[0])
    ra = (lst - np.degrees(ha)) % 360.0
    lines = ["# model file created on Sat Dec 13 00:00:00 2014 (synthetic test data, see make_sample.py)",
             f"# altaz-manual {LONGITUDE} {LATITUDE} {ALTITUDE}"]
    for k in range(N):
        fields = [f"{jd[k]:.6f}", f"{ra[k]:.6f}", f"{np.degrees(dec[k]):.6f}", f"{e_alt[k]:.8f}", f"{e_az[k]:.8f}",
                  f"{alt[k]:.4f}", f"{az[k]:.4f}"]
        lines.append(f"{k + 1}\t" + "\t".join(fields))
    Path(__file__).with_name("altaz_manual.txt").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()

"""Writes ``gem.txt``: a synthetic RTS2 gpoint German-equatorial run (test data).

Not real data: no real gpoint GEM input file was found (RTS2's repository has only the
man page's ten-row example, whose real positions are 1 deg off in RA and Dec). The
layout follows RTS2's writer of such files (``python/rts2/fits2model.py``: a column
caption on line 1, '# observatory LONGITUDE LATITUDE ALTITUDE' on line 2, then per
image ``IMGID <TAB> JD <TAB> LST <TAB> TAR_TELRA <TAB> TAR_TELDEC <TAB> AXRA <TAB>
AXDEC <TAB> RA <TAB> DEC``) and gpoint's reader (``GPoint.process_files`` in
``python/rts2/gpoint.py``, RTS2/rts2 commit 6480a7eb549d3158ee178ce557fab6d75de8eba9):
the mount's RA/Dec are in telescope coordinates, on the flipped side of the pier the Dec
beyond +-90 deg and the RA 180 deg from the sky's, the real RA/Dec on the sky.

Half the stars (those East of the meridian) are observed with the mount flipped. The
mount readings are drawn first; the real positions are gpoint's own model
(``model_ha``, ``model_dec``) with the coefficients in TRUE_ARCSEC added to them,
plus Gaussian noise of NOISE_ARCSEC on the sky, and turned back to the sky side.
Axis counts are the readings times 10000 counts per degree.

Run from the repository root: ``.venv/bin/python tests/data/gpoint/make_gem_sample.py``.
"""

from pathlib import Path

import numpy as np

TRUE_ARCSEC = {"ih": 150.0, "id": -80.0, "ch": 40.0, "np": -25.0, "ma": 30.0, "me": -45.0, "tf": 20.0,
               "fo": 12.0, "daf": 15.0, "ha:sin:dec:2": 9.0}
NOISE_ARCSEC = 1.0
LONGITUDE, LATITUDE, ALTITUDE = 14.7817, 49.9092, 530.0
N = 60
SEED = 7


def gpoint_offsets(p, ha, dec, lat):
    """gpoint's model_ha / model_dec (radians), at the mount readings."""
    d_ha = (-p["ih"] - p["ch"] / np.cos(dec) - p["np"] * np.tan(dec)
            - (p["me"] * np.sin(ha) - p["ma"] * np.cos(ha)) * np.tan(dec)
            - p["tf"] * np.cos(lat) * np.sin(ha) / np.cos(dec)
            - p["daf"] * (np.sin(lat) * np.tan(dec) + np.cos(lat) * np.cos(ha))
            + p["ha:sin:dec:2"] * np.sin(2 * dec))
    d_dec = (-p["id"] - p["me"] * np.cos(ha) - p["ma"] * np.sin(ha)
             - p["tf"] * (np.cos(lat) * np.sin(dec) * np.cos(ha) - np.sin(lat) * np.cos(dec))
             - p["fo"] * np.cos(ha))
    return d_ha, d_dec


def main():
    rng = np.random.default_rng(SEED)
    arcsec = np.pi / 648000
    lat = np.radians(LATITUDE)
    p = {k: v * arcsec for k, v in TRUE_ARCSEC.items()}
    # Sky positions above 20 deg elevation, hour angles -6h..+6h.
    ha_sky, dec_sky = [], []
    while len(ha_sky) < N:
        h, d = rng.uniform(-90.0, 90.0), rng.uniform(-25.0, 85.0)
        alt = np.degrees(np.arcsin(np.sin(lat) * np.sin(np.radians(d))
                                   + np.cos(lat) * np.cos(np.radians(d)) * np.cos(np.radians(h))))
        if alt > 20.0:
            ha_sky.append(h)
            dec_sky.append(d)
    ha_sky, dec_sky = np.round(np.array(ha_sky), 4), np.round(np.array(dec_sky), 4)
    flipped = ha_sky < 0.0  # East of the meridian: the other side of the pier
    jd = 2457222.760012 + 0.0035 * np.arange(N)
    lst = np.round((233.8937 + 360.98564736629 * (jd - jd[0])) % 360.0, 4)
    # Mount readings (telescope coordinates): flipped = (H + 180, 180 - dec); the hour
    # angle as gpoint reads it, LST - RA, from the RA as written.
    ra_m = np.round((lst - np.where(flipped, ha_sky + 180.0, ha_sky)) % 360.0, 4)
    ha_m = lst - ra_m
    dec_m = np.where(flipped, 180.0 - dec_sky, dec_sky)
    d_ha, d_dec = gpoint_offsets(p, np.radians(ha_m), np.radians(dec_m), lat)
    noise = rng.normal(size=(N, 2)) * NOISE_ARCSEC * arcsec
    ha_r = np.degrees(np.radians(ha_m) + d_ha + noise[:, 0] / np.abs(np.cos(np.radians(dec_m))))
    dec_r = np.degrees(np.radians(dec_m) + d_dec + noise[:, 1])
    # Real position back on the sky.
    ha_true = np.where(flipped, ha_r - 180.0, ha_r)
    dec_true = np.where(flipped, 180.0 - dec_r, dec_r)
    ra_true = (lst - ha_true) % 360.0
    lines = ["#  Observation      MJD    MNT-LST   RA-MNT   DEC-MNT       AXRA      AXDEC   RA-TRUE  DEC-TRUE",
             f"# observatory {LONGITUDE} {LATITUDE} {ALTITUDE}"]
    for k in range(N):
        fields = [f"02a57222e{k:04d}o", f"{jd[k]:.6f}", f"{lst[k]:.4f}", f"{ra_m[k]:.4f}", f"{dec_m[k]:.4f}",
                  str(int(round(-ha_m[k] * 10000))), str(int(round(dec_m[k] * 10000))),
                  f"{ra_true[k]:.8f}", f"{dec_true[k]:.8f}"]
        lines.append("\t".join(fields))
    Path(__file__).with_name("gem.txt").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()

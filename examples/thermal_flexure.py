"""Prototype a thermal flexure term on simulated runs, fit it, recover it.

A telescope tube sags more when it is warm: its tube flexure ``TF`` (``dE = -TF cos E``)
follows the temperature. Four simulated pointing runs, each at its own temperature
(a cold winter night to a warm summer one) with the temperature drifting through the
night, carry the temperature as an auxiliary reading. A new term reads it by name
(``self.reading("temperature")``) and the fit finds its thermal coefficient jointly
with the physical terms; the library's ``px.terms.thermal("TF")`` is the same term,
ready-made. The inverse takes the temperature at the time of the command.

Run:  python examples/thermal_flexure.py
"""

from typing import ClassVar

import jax.numpy as jnp
import numpy as np

import pointax as px


# ---------------------------------------------------------------- the new term (9 lines)
class ThermalTF(px.Term):
    """Tube flexure ``TF0 + TF_T (T - 10 C)``: ``dE = -TF(T) cos E``."""

    readings: ClassVar[tuple[str, ...]] = ("temperature",)
    TF0: float = px.param(0.0)  # radians at 10 deg C, reported in arcsec
    TF_T: float = px.param(0.0)  # radians per deg C, reported in arcsec (per deg C)

    def sky_offset(self, angles):
        tf = self.TF0 + self.TF_T * (self.reading("temperature") - 10.0)
        return jnp.stack([0.0 * tf, -tf * jnp.cos(angles[1])])


# ---------------------------------------------------------------- simulate, fit, check
PHYSICAL = "IA IE NPAE CA AN AW"
TRUE = {"IA": 30.0, "IE": -12.0, "NPAE": 4.0, "CA": -9.0, "AN": 3.0, "AW": -5.0, "ThermalTF.TF0": 11.0, "ThermalTF.TF_T": 0.6}
NIGHTS = (-6.0, 3.0, 14.0, 24.0)  # deg C at the start of each run


def simulated_runs(truth: px.Model, seed: int = 0) -> px.Observations:
    """One Observations for the four runs: 80 stars a night, the temperature falling
    by 3 deg C through each night."""
    rng = np.random.default_rng(seed)
    encoder, temperature = [], []
    for start in NIGHTS:
        n = 80
        az = rng.uniform(0, 2 * np.pi, n)
        el = np.arcsin(rng.uniform(np.sin(0.3), np.sin(1.45), n))
        encoder.append(np.stack([az, el], -1))
        temperature.append(start - 3.0 * np.linspace(0, 1, n))
    encoder, temperature = np.concatenate(encoder), np.concatenate(temperature)
    return px.simulate(truth, encoder, noise=px.arcsec(1.0), seed=seed, readings={"temperature": temperature})


def main(seed: int = 0, verbose: bool = True) -> dict:
    terms = px.terms.tpoint(PHYSICAL) + (ThermalTF(),)
    truth = px.AltAz(terms).set(**{name: px.arcsec(v) for name, v in TRUE.items()})
    observations = simulated_runs(truth, seed)

    result = px.fit(px.AltAz(terms), observations)  # every coefficient from 0
    rows = []
    for name, true in TRUE.items():
        value, sigma = result.value(name), result.sigma(name)
        rows.append((name, true, value, sigma, (value - true) / sigma))

    # The library's thermal wrapper of TPOINT's TF is the same term.
    library = px.fit(px.AltAz(px.terms.tpoint(PHYSICAL) + (px.terms.thermal("TF", reference=10.0),)), observations)
    same = abs(library.value("TF@temperature.slope") - result.value("ThermalTF.TF_T"))

    # The inverse at the temperature of the command: a round trip to the sky.
    wanted = np.asarray(truth(np.array([[1.0, 0.7], [4.0, 1.2]]), readings={"temperature": 18.0}))
    command = px.command(result.model, wanted, readings={"temperature": 18.0})
    back = np.asarray(result.model(np.asarray(command.reading), readings={"temperature": 18.0}))
    cross, dot = np.linalg.norm(np.cross(back, wanted), axis=-1), np.sum(back * wanted, -1)
    round_trip = float(np.max(np.arctan2(cross, dot)))

    if verbose:
        print(f"{len(NIGHTS)} simulated runs, {len(observations)} observations, temperatures "
              f"{min(NIGHTS) - 3:.0f} to {max(NIGHTS):.0f} deg C, noise 1.0\"")
        print(f"{'parameter':<16}{'unit':<9}{'true':>8}{'fitted':>9}{'sigma':>8}{'dev/sigma':>11}")
        for name, true, value, sigma, dev in rows:
            unit = "arcsec/C" if name.endswith("TF_T") else "arcsec"
            print(f"{name:<16}{unit:<9}{true:>8.3f}{value:>9.3f}{sigma:>8.3f}{dev:>+11.2f}")
        print(f"thermal coefficient recovered within 2 sigma: {abs(rows[-1][4]) <= 2}")
        print(f"px.terms.thermal('TF') gives the same slope (difference {same:.1e}\"/C)")
        print(f"inverse at 18 C, then the model at 18 C: back within {round_trip:.1e} rad")
    return {
        "rows": rows,
        "converged": bool(result.converged),
        "slope_deviation": rows[-1][4],
        "library_difference": same,
        "round_trip_rad": round_trip,
    }


if __name__ == "__main__":
    main()

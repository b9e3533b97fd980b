"""A new error term in a few lines of JAX: azimuth-axis wobble.

The azimuth axis of a real mount can wobble as it turns (an uneven azimuth track or
bearing): the axis tilts by an amplitude whose direction turns twice per azimuth
revolution. That is a rotation in the chain between the local frame and the azimuth
axis, so the term overrides ``base_rotation``. Nothing else in pointax changes and no
derivative is written: the fit differentiates the term with JAX.

Run:  python examples/new_error_term.py
"""

import jax.numpy as jnp
import numpy as np

import pointax as px


# ---------------------------------------------------------------- the new term (12 lines)
class AzWobble(px.Term):
    """Azimuth axis tilted by ``amp`` towards a direction that turns at twice the
    azimuth: tilt about x = amp cos(2A + phase), about y = amp sin(2A + phase)."""

    amp: float = px.param(0.0)  # radians, reported in arcsec
    phase: float = px.param(0.0, unit="deg")  # radians, reported in degrees

    def base_rotation(self, angles):
        turn = 2.0 * angles[0] + self.phase
        return px.rotations.small_tilt(self.amp * jnp.cos(turn), self.amp * jnp.sin(turn))


# ---------------------------------------------------------------- simulate, fit, check
TRUE_AMP, TRUE_PHASE = px.arcsec(6.0), px.deg(35.0)


def main(seed: int = 0, verbose: bool = True) -> dict:
    basic = px.terms.tpoint("IA IE NPAE CA AN AW TF", form="rigorous")
    truth = px.AltAz(basic + (AzWobble(amp=TRUE_AMP, phase=TRUE_PHASE),))
    truth = truth.set(IA=px.arcsec(30), IE=px.arcsec(-12), NPAE=px.arcsec(4), CA=px.arcsec(-9),
                      AN=px.arcsec(3), AW=px.arcsec(-5), TF=px.arcsec(7))
    rng = np.random.default_rng(seed)
    encoder = np.stack([rng.uniform(0, 2 * np.pi, 120), np.arcsin(rng.uniform(np.sin(0.3), np.sin(1.45), 120))], -1)
    observations = px.simulate(truth, encoder, noise=px.arcsec(1.0), seed=seed)

    # Start the wobble at a small amplitude: at exactly zero its phase has no gradient.
    start = px.AltAz(basic + (AzWobble(amp=px.arcsec(1.0)),))
    result = px.fit(start, observations, caption="Simulated run with azimuth-axis wobble")
    amp, phase = result.value("AzWobble.amp"), result.value("AzWobble.phase")
    if amp < 0:  # (amp, phase) and (-amp, phase + 180 deg) are the same wobble
        amp, phase = -amp, phase + 180.0
    phase = (phase + 180.0) % 360.0 - 180.0
    sigma = result.sigma("AzWobble.amp")
    deviation = (amp - 6.0) / sigma
    if verbose:
        print(result.report())
        print()
        print(f"wobble amplitude: true 6.000\"  fitted {amp:.3f}\" +- {sigma:.3f}\"  ({deviation:+.2f} sigma)")
        print(f"wobble phase:     true 35.00 deg  fitted {phase:.2f} +- {result.sigma('AzWobble.phase'):.2f} deg")
        print("recovered within 1 sigma" if abs(deviation) <= 1 else "NOT within 1 sigma")
    return {"amp": amp, "sigma": sigma, "phase": phase, "deviation": deviation, "converged": bool(result.converged)}


if __name__ == "__main__":
    main()

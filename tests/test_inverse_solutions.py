"""The inverse picks the normal solution (issue 20, item 4): for every reachable
direction, near the horizon and near the zenith, ``command`` returns the normal
mechanical solution (elevation reading within [-90, 90] deg) unless the flipped one is
asked for; a normal solve that fails is reported, never replaced by the over-the-top
reading.

References: the forward model (``model(reading)`` must point at the direction: the
definition of the inverse) and the elevation range of each solution.
"""

from __future__ import annotations

import numpy as np
import pytest

import pointax as px
from pointax.core.rotations import azel_to_enu_numpy

from numpy_rotations import angle_between
from conftest import MMT_MOD

VALUES = {"IA": 120.0, "IE": -45.0, "CA": 20.0, "NPAE": -8.0, "AN": 15.0, "AW": -12.0, "TF": 30.0}


def _model():
    return px.AltAz(px.terms.tpoint(" ".join(VALUES), values={k: px.arcsec(v) for k, v in VALUES.items()}))



@pytest.mark.parametrize(
    "elevations",
    [[0.05, 0.2, 0.5, 0.99, -0.3, 0.7, 0.01, 0.9], [89.0, 89.5, 89.9, 89.95, 88.0, 85.0, 89.7, 89.8]],
    ids=["horizon", "zenith"],
)
def test_normal_solution_near_horizon_and_zenith(elevations):
    model = _model()
    az = np.radians(np.linspace(0.0, 315.0, len(elevations)))
    d = azel_to_enu_numpy(az, np.radians(elevations))
    c = px.command(model, d)
    assert bool(np.all(np.asarray(c.ok))), c.reasons()
    assert np.all(np.asarray(c.solution) == 0)
    reading_el = np.degrees(np.asarray(c.reading)[:, 1])
    assert np.all(np.abs(reading_el) <= 90.0 + 0.1)
    assert np.max(angle_between(np.asarray(model(np.asarray(c.reading))), d)) < 1e-10
    # The flipped solution, asked for, is over the top and points there too.
    f = px.command(model, d, solution="flipped")
    assert bool(np.all(np.asarray(f.ok))) and np.all(np.asarray(f.solution) == 1)
    assert np.all(np.degrees(np.asarray(f.reading)[:, 1]) > 89.9)
    assert np.max(angle_between(np.asarray(model(np.asarray(f.reading))), d)) < 1e-10


def test_failed_normal_solve_is_reported_not_flipped():
    # The MMT model's TX term (cot E) makes elevations below ~0.34 deg unreachable by the
    # normal solution (the model turns back towards the horizon: checked here on the
    # forward model). Without `near`, "nearest" must report that, not go over the top.
    model = px.io.read_model(MMT_MOD).model(azimuth="S-E")
    reading_el = np.radians(np.linspace(0.05, 1.0, 200))
    forward = np.asarray(model(np.stack([np.full_like(reading_el, np.radians(80.33)), reading_el], -1)))
    assert np.degrees(np.arcsin(forward[:, 2])).min() > 0.3
    d = azel_to_enu_numpy(np.radians([100.0]), np.radians([0.2]))
    c = px.command(model, d)
    assert int(np.asarray(c.solution)[0]) == 0
    assert not bool(np.asarray(c.ok)[0])
    assert c.reasons()[0].startswith("did not converge")


def test_at_the_zenith_the_reading_stays_on_its_branch():
    # Within a few arcsec of the zenith the normal Newton solve meets a singular
    # Jacobian; the reading returned must point there and keep axis 1 within one turn
    # (it had wandered to -12070 deg), with an elevation reading of about 90 deg.
    # The linear form reaches every direction there; the rigorous form (CA, NPAE as
    # rotations) cannot reach some directions within a few arcsec of the zenith.
    model = px.io.read_model(MMT_MOD).model(azimuth="S-E", form="linear")
    az = np.radians(np.arange(0.0, 360.0, 45.0))
    d = azel_to_enu_numpy(az, np.radians(np.full(az.shape, 89.999)))
    c = px.command(model, d)
    assert bool(np.all(np.asarray(c.ok))), c.reasons()
    reading = np.degrees(np.asarray(c.reading))
    assert np.all(np.abs(reading[:, 0]) <= 360.0)
    assert np.all(np.abs(reading[:, 1] - 90.0) < 0.01)
    assert np.max(angle_between(np.asarray(model(np.asarray(c.reading))), d)) < 1e-10

"""Property tests of the inverse (issue 30): over the whole sky, 0-1 deg elevation
included, with models whose terms are of realistic size and with cable-wrap limits.

For every direction that has a solution inside the limits (built here from a reading
inside the limits through the forward model, so that one exists), ``command`` is ok,
the forward model of its reading hits the direction within 1e-9 rad, and its reading
is the one nearest ``near`` among the equivalent readings: the generating reading and
its over-the-top twin, each shifted by whole turns, kept where inside the limits.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pointax as px
from numpy_rotations import angle_between

N = 64
DEG = np.pi / 180
ARCSEC = DEG / 3600
HIT = 1e-9
TERMS = ("IA", "IE", "NPAE", "CA", "AN", "AW", "TF")
WRAPS = {"-270..270": (-270.0, 270.0), "0..360": (0.0, 360.0), "-180..540": (-180.0, 540.0)}
ELEVATION = {"normal only": (0.0, 90.0), "over the top": (0.0, 180.0)}
SHIFTS = np.array(list(itertools.product(range(-3, 4), range(-1, 2))), float) * 2 * np.pi



def _altaz(values):
    return px.AltAz(px.terms.tpoint(" ".join(TERMS), values={k: v * ARCSEC for k, v in zip(TERMS, values)}))


def _turntable(values):
    tilts = np.asarray(values[:3]) * ARCSEC
    return px.Turntable("full").with_values(np.concatenate([tilts, np.radians(values[3:5])]))


def _readings(seed, limits):
    """Readings inside the limits: axis 1 anywhere in its range, axis 2 a quarter in
    0-1 deg (the horizon), the rest up to 89 deg."""
    rng = np.random.default_rng(seed)
    (lo1, hi1), _ = limits
    a1 = rng.uniform(lo1, hi1, N)
    el = np.where(np.arange(N) % 4 == 0, rng.uniform(0.0, 1.0, N), rng.uniform(1.0, 89.0, N)) * DEG
    return np.stack([a1, el], -1)


def _check(model, limits, seed, near_mode):
    reading0 = _readings(seed, limits)
    target = np.asarray(model(reading0))
    rng = np.random.default_rng(seed + 1)
    (lo1, hi1), (lo2, hi2) = limits
    near = np.stack([rng.uniform(lo1, hi1, N), rng.uniform(lo2, hi2, N)], -1)
    c = px.command(model, target, limits=limits, near=near if near_mode else None)
    ok = np.asarray(c.ok)
    assert ok.all(), [r for r in c.reasons() if r][:5]
    reading = np.asarray(c.reading)
    assert np.max(angle_between(np.asarray(model(reading)), target)) < HIT
    lim = np.asarray(limits)
    assert np.all((reading >= lim[:, 0]) & (reading <= lim[:, 1]))
    # The equivalent readings: the generator and its twin (solved without limits and
    # checked here on the forward model), each shifted by whole turns.
    twin = np.asarray(px.command(model, target, solution="flipped").reading)
    twin_hits = angle_between(np.asarray(model(twin)), target) < HIT
    cands = [reading0[:, None, :] + SHIFTS, np.where(twin_hits[:, None, None], twin[:, None, :] + SHIFTS, np.nan)]
    cands = np.concatenate(cands, axis=1)
    inside = np.all((cands >= lim[:, 0]) & (cands <= lim[:, 1]), axis=-1)
    if near_mode:
        dist = np.sum(np.abs(cands - near[:, None, :]), axis=-1)
        best = np.min(np.where(inside, dist, np.inf), axis=1)
        got = np.sum(np.abs(reading - near), axis=-1)
        assert np.all(got <= best + 1e-6), np.max(got - best)
    else:
        # Without near: the normal solution where it is inside the limits, on the axis-1
        # branch nearest the middle of the limits.
        normal = cands[:, : len(SHIFTS)]
        inside_n = inside[:, : len(SHIFTS)]
        middle = 0.5 * (lo1 + hi1)
        best = np.min(np.where(inside_n, np.abs(normal[..., 0] - middle), np.inf), axis=1)
        assert np.all(np.abs(reading[:, 0] - middle) <= best + 1e-6)
        assert np.all(np.asarray(c.solution) == 0)


coef = st.floats(-60.0, 60.0)  # arcsec: terms of realistic size


@pytest.mark.slow
@pytest.mark.parametrize("elevation", list(ELEVATION), ids=list(ELEVATION))
@pytest.mark.parametrize("wrap", list(WRAPS), ids=list(WRAPS))
@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(values=st.tuples(*[coef] * len(TERMS)), seed=st.integers(0, 2**31), near_mode=st.booleans())
def test_altaz_inverse_is_ok_hits_and_is_nearest(wrap, elevation, values, seed, near_mode):
    limits = (np.radians(WRAPS[wrap]), np.radians(ELEVATION[elevation]))
    _check(_altaz(values), limits, seed, near_mode)


@pytest.mark.slow
@pytest.mark.parametrize("wrap", list(WRAPS), ids=list(WRAPS))
@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    values=st.tuples(coef, coef, coef, st.floats(-180.0, 180.0), st.floats(-2.0, 2.0)),
    seed=st.integers(0, 2**31),
    near_mode=st.booleans(),
)
def test_turntable_inverse_is_ok_hits_and_is_nearest(wrap, values, seed, near_mode):
    limits = (np.radians(WRAPS[wrap]), np.radians(ELEVATION["normal only"]))
    _check(_turntable(values), limits, seed, near_mode)

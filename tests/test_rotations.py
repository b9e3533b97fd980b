"""Tests for pointax.core.rotations and pointax.core.mounts.AltAzMount.

Every expected value comes from an independent source: scipy's Rotation, astropy's
AltAz frame, numpy closed forms (gnomonic projection and its inverse, Snyder 1987),
hand-worked cardinal directions, or central finite differences of those references.

Conventions: ENU (x East, y North, z Up), azimuth from North through East, radians.
"""

from __future__ import annotations

import math

import jax

jax.config.update("jax_enable_x64", True)

import astropy.units as u  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from astropy.coordinates import AltAz, CartesianRepresentation  # noqa: E402
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

from pointax import rotations as rot  # noqa: E402
from pointax.core.mounts import AZIMUTH_CONVENTIONS, AltAzMount  # noqa: E402

PI = math.pi
DEG = PI / 180.0
S = math.sqrt(0.5)
SETTINGS = settings(max_examples=50, deadline=None)


# --------------------------------------------------------------------------- references
def np_azel_to_enu(az, el):
    az, el = np.asarray(az, float), np.asarray(el, float)
    return np.stack([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)], axis=-1)


def np_enu_to_azel(v):
    v = np.asarray(v, float)
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    return np.arctan2(x, y), np.arctan2(z, np.hypot(x, y))


def np_gnomonic(v, ref):
    """Forward gnomonic projection of v about ref (longitude = azimuth, latitude = el)."""
    az, el = np_enu_to_azel(v)
    az0, el0 = np_enu_to_azel(ref)
    da = az - az0
    cos_c = np.sin(el0) * np.sin(el) + np.cos(el0) * np.cos(el) * np.cos(da)
    x = np.cos(el) * np.sin(da) / cos_c
    y = (np.cos(el0) * np.sin(el) - np.sin(el0) * np.cos(el) * np.cos(da)) / cos_c
    return np.stack([x, y], axis=-1)


def np_inverse_gnomonic(ref, off):
    """Inverse gnomonic projection (Snyder, Map Projections, eqs. 20-14, 20-15)."""
    az0, el0 = np_enu_to_azel(ref)
    off = np.asarray(off, float)
    x, y = off[..., 0], off[..., 1]
    rho = np.hypot(x, y)
    c = np.arctan(rho)
    el = np.arcsin(np.cos(c) * np.sin(el0) + y * np.sin(c) * np.cos(el0) / rho)
    az = az0 + np.arctan2(x * np.sin(c), rho * np.cos(el0) * np.cos(c) - y * np.sin(el0) * np.sin(c))
    return np_azel_to_enu(az, el)


def euler(axis, angles):
    """scipy Rotation about one principal axis, for a scalar or a 1-D array of angles."""
    return Rotation.from_euler(axis, np.asarray(angles, float)[..., None])


def astropy_azel_to_enu(az, el):
    """ENU unit vector from astropy's AltAz frame (astropy's x is North, y is East)."""
    cart = AltAz(az=np.asarray(az) * u.rad, alt=np.asarray(el) * u.rad).cartesian
    return np.stack([cart.y.value, cart.x.value, cart.z.value], axis=-1)


def astropy_enu_to_azel(v):
    v = np.asarray(v, float)
    frame = AltAz(CartesianRepresentation(x=v[..., 1] * u.one, y=v[..., 0] * u.one, z=v[..., 2] * u.one))
    return frame.az.to_value(u.rad), frame.alt.to_value(u.rad)


def central_fd(f, x, h=1e-6):
    """Central finite-difference Jacobian of numpy function f at x: shape out + in."""
    x = np.asarray(x, float)
    f0 = np.asarray(f(x))
    jac = np.zeros(f0.shape + x.shape)
    for idx in np.ndindex(x.shape):
        dx = np.zeros_like(x)
        dx[idx] = h
        jac[(...,) + idx] = (np.asarray(f(x + dx)) - np.asarray(f(x - dx))) / (2 * h)
    return jac


def ang_diff(a, b):
    """Signed smallest difference a - b of angles (numpy)."""
    return np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b))))


@pytest.fixture
def rng():
    return np.random.default_rng(20240821)


def random_unit_vectors(rng, n):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


# ------------------------------------------------------------------ 1. rotation matrices
PRINCIPAL = [("x", rot.rot_x, 0), ("y", rot.rot_y, 1), ("z", rot.rot_z, 2)]


@pytest.mark.parametrize("name, fn, _", PRINCIPAL)
def test_principal_rotation_matches_scipy_scalar_and_batched(rng, name, fn, _):
    angles = rng.uniform(-2 * PI, 2 * PI, size=40)
    expected = euler(name, angles).as_matrix()
    for a, e in zip(angles[:5], expected[:5]):
        got = fn(a)
        assert got.shape == (3, 3)
        np.testing.assert_allclose(got, e, atol=1e-14)
    batched = fn(jnp.asarray(angles))
    assert batched.shape == (40, 3, 3)
    np.testing.assert_allclose(batched, expected, atol=1e-14)
    # leading batch dimensions of any rank
    np.testing.assert_allclose(fn(jnp.asarray(angles).reshape(5, 8)), expected.reshape(5, 8, 3, 3), atol=1e-14)


@pytest.mark.parametrize(
    "fn, v, expected",
    [
        (rot.rot_z, (1, 0, 0), (0, 1, 0)),  # +x towards +y
        (rot.rot_x, (0, 1, 0), (0, 0, 1)),  # +y towards +z
        (rot.rot_y, (0, 0, 1), (1, 0, 0)),  # +z towards +x
    ],
)
def test_principal_rotation_is_right_handed_active(fn, v, expected):
    np.testing.assert_allclose(fn(PI / 2) @ jnp.asarray(v, float), expected, atol=1e-15)


def test_rot_axis_matches_scipy_rotvec(rng):
    n = 60
    axes = rng.normal(size=(n, 3)) * rng.uniform(0.01, 100.0, size=(n, 1))  # un-normalised
    angles = rng.uniform(-2 * PI, 2 * PI, size=n)
    unit = axes / np.linalg.norm(axes, axis=-1, keepdims=True)
    expected = Rotation.from_rotvec(unit * angles[:, None]).as_matrix()
    np.testing.assert_allclose(rot.rot_axis(axes, angles), expected, atol=1e-13)
    for k in range(5):
        got = rot.rot_axis(axes[k], angles[k])
        assert got.shape == (3, 3)
        np.testing.assert_allclose(got, expected[k], atol=1e-13)


def test_rot_axis_broadcasts_one_axis_over_many_angles(rng):
    axis = np.array([0.3, -1.2, 0.5])
    angles = rng.uniform(-PI, PI, size=7)
    expected = Rotation.from_rotvec(np.outer(angles, axis / np.linalg.norm(axis))).as_matrix()
    got = rot.rot_axis(axis, angles)
    assert got.shape == (7, 3, 3)
    np.testing.assert_allclose(got, expected, atol=1e-14)


@SETTINGS
@given(
    axis=st.tuples(*[st.floats(-10, 10)] * 3).filter(lambda a: np.linalg.norm(a) > 1e-3),
    angle=st.floats(-10, 10),
)
def test_rot_axis_property_matches_scipy(axis, angle):
    axis = np.asarray(axis)
    expected = Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_matrix()
    np.testing.assert_allclose(rot.rot_axis(axis, angle), expected, atol=1e-13)


def _all_rotations(rng):
    angles = rng.uniform(-2 * PI, 2 * PI, size=30)
    axes = rng.normal(size=(30, 3))
    return {
        "rot_x": rot.rot_x(angles),
        "rot_y": rot.rot_y(angles),
        "rot_z": rot.rot_z(angles),
        "rot_axis": rot.rot_axis(axes, angles),
        "small_tilt": rot.small_tilt(angles, angles[::-1]),
    }


@pytest.mark.parametrize("name", ["rot_x", "rot_y", "rot_z", "rot_axis", "small_tilt"])
def test_rotations_are_orthogonal_with_unit_determinant(rng, name):
    mats = np.asarray(_all_rotations(rng)[name])
    eye = np.broadcast_to(np.eye(3), mats.shape)
    np.testing.assert_allclose(np.swapaxes(mats, -1, -2) @ mats, eye, atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(mats), 1.0, atol=1e-14)


@pytest.mark.parametrize("name, fn, i", PRINCIPAL)
def test_rot_axis_along_unit_axes_equals_principal(rng, name, fn, i):
    angles = rng.uniform(-2 * PI, 2 * PI, size=20)
    axis = np.eye(3)[i]
    np.testing.assert_allclose(rot.rot_axis(axis, angles), fn(angles), atol=1e-15)
    np.testing.assert_allclose(rot.rot_axis(3.5 * axis, angles), euler(name, angles).as_matrix(), atol=1e-14)


def test_small_tilt_equals_rot_x_times_rot_y(rng):
    ax = rng.uniform(-0.5, 0.5, size=25)
    ay = rng.uniform(-0.5, 0.5, size=25)
    # scipy composition p * q applies q first, so its matrix is P @ Q.
    expected = (euler("x", ax) * euler("y", ay)).as_matrix()
    np.testing.assert_allclose(rot.small_tilt(ax, ay), expected, atol=1e-14)
    np.testing.assert_allclose(rot.small_tilt(ax, ay), rot.rot_x(ax) @ rot.rot_y(ay), atol=1e-15)


def test_small_tilt_documented_directions():
    up = jnp.array([0.0, 0.0, 1.0])
    t = 1e-3
    tipped_x = rot.small_tilt(t, 0.0) @ up  # tips +z towards -y
    tipped_y = rot.small_tilt(0.0, t) @ up  # tips +z towards +x
    np.testing.assert_allclose(tipped_x, [0.0, -math.sin(t), math.cos(t)], atol=1e-16)
    np.testing.assert_allclose(tipped_y, [math.sin(t), 0.0, math.cos(t)], atol=1e-16)


# ----------------------------------------------------------- 2. azimuth/elevation <-> ENU
CARDINALS = [
    # az_deg, el_deg, ENU
    (0, 0, (0, 1, 0)),  # North
    (90, 0, (1, 0, 0)),  # East
    (180, 0, (0, -1, 0)),  # South
    (-90, 0, (-1, 0, 0)),  # West
    (45, 0, (S, S, 0)),  # North-East
    (0, 45, (0, S, S)),
    (-135, -45, (-0.5, -0.5, -S)),
    (37, 90, (0, 0, 1)),  # zenith, any azimuth
    (-120, -90, (0, 0, -1)),  # nadir, any azimuth
]


@pytest.mark.parametrize("az_deg, el_deg, expected", CARDINALS)
def test_azel_to_enu_cardinal_directions(az_deg, el_deg, expected):
    np.testing.assert_allclose(rot.azel_to_enu(az_deg * DEG, el_deg * DEG), expected, atol=1e-15)


@pytest.mark.parametrize(
    "v, az_deg, el_deg",
    [
        ((1, 0, 0), 90, 0),
        ((0, 1, 0), 0, 0),
        ((0, -1, 0), 180, 0),
        ((-1, 0, 0), -90, 0),
        ((3, 3, 0), 45, 0),  # un-normalised
        ((0, 2, 2), 0, 45),
        ((-5, -5, -math.sqrt(50)), -135, -45),
        ((0, 0, 1), 0, 90),  # zenith: azimuth taken as 0
        ((0, 0, 7), 0, 90),
        ((0, 0, -2), 0, -90),  # nadir: azimuth taken as 0
    ],
)
def test_enu_to_azel_cardinal_directions(v, az_deg, el_deg):
    az, el = rot.enu_to_azel(jnp.asarray(v, float))
    assert az == pytest.approx(az_deg * DEG, abs=1e-15)
    assert el == pytest.approx(el_deg * DEG, abs=1e-15)


def test_azel_to_enu_matches_astropy(rng):
    az = rng.uniform(-PI, PI, size=200)
    el = rng.uniform(-PI / 2, PI / 2, size=200)
    expected = astropy_azel_to_enu(az, el)
    np.testing.assert_allclose(rot.azel_to_enu(az, el), expected, atol=1e-15)
    # and against the closed form, in a 2-D batch
    np.testing.assert_allclose(rot.azel_to_enu(az.reshape(20, 10), el.reshape(20, 10)), np_azel_to_enu(az, el).reshape(20, 10, 3), atol=1e-15)


def test_enu_to_azel_matches_astropy_for_unnormalised_vectors(rng):
    v = rng.normal(size=(200, 3)) * 10.0 ** rng.uniform(-100, 100, size=(200, 1))
    az, el = rot.enu_to_azel(v)
    az_ref, el_ref = astropy_enu_to_azel(v)  # astropy returns az in [0, 2 pi)
    np.testing.assert_allclose(ang_diff(az, az_ref), 0.0, atol=1e-13)
    np.testing.assert_allclose(el, el_ref, atol=1e-13)
    assert np.all(np.asarray(az) > -PI) and np.all(np.asarray(az) <= PI)
    assert np.all(np.abs(np.asarray(el)) <= PI / 2)


def test_azel_round_trip(rng):
    az = np.concatenate([rng.uniform(-PI, PI, size=300), [PI, PI - 1e-12, -PI + 1e-12, 0.0]])
    el = np.concatenate([rng.uniform(-PI / 2 + 1e-6, PI / 2 - 1e-6, size=300), [0.3, -1.2, 1.5, -0.2]])
    az2, el2 = rot.enu_to_azel(rot.azel_to_enu(az, el))
    np.testing.assert_allclose(az2, az, atol=1e-9)  # within ~eps/cos(el) near the poles
    np.testing.assert_allclose(el2, el, atol=1e-12)
    # away from the poles the round trip is at the rounding level
    mid = np.abs(el) < 1.4
    np.testing.assert_allclose(np.asarray(az2)[mid], az[mid], atol=1e-13)
    assert float(az2[300]) == pytest.approx(PI, abs=1e-15)  # az = pi stays +pi


def test_enu_round_trip_unnormalised(rng):
    v = rng.normal(size=(100, 3)) * rng.uniform(1e-3, 1e3, size=(100, 1))
    back = rot.azel_to_enu(*rot.enu_to_azel(v))
    np.testing.assert_allclose(back, v / np.linalg.norm(v, axis=-1, keepdims=True), atol=1e-15)


@SETTINGS
@given(
    az=st.floats(-PI, PI, exclude_min=True),
    el=st.floats(-PI / 2 + 1e-3, PI / 2 - 1e-3),
    scale=st.floats(1e-6, 1e6),
)
def test_enu_to_azel_property_scale_invariant_round_trip(az, el, scale):
    az2, el2 = rot.enu_to_azel(scale * np_azel_to_enu(az, el))
    assert float(ang_diff(az2, az)) == pytest.approx(0.0, abs=1e-11)
    assert float(el2) == pytest.approx(el, abs=1e-12)


# ----------------------------------------------------------------- 3. tangent-plane offsets
def _ref_and_targets(rng, n, max_sep):
    az0 = rng.uniform(-PI, PI, size=n)
    el0 = rng.uniform(-80 * DEG, 80 * DEG, size=n)
    ref = np_azel_to_enu(az0, el0)
    # targets within max_sep of ref (random direction)
    axes = np.cross(ref, rng.normal(size=(n, 3)))
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    seps = rng.uniform(0, max_sep, size=n)
    v = np.einsum("nij,nj->ni", Rotation.from_rotvec(axes * seps[:, None]).as_matrix(), ref)
    return ref, v


def test_tangent_offset_matches_gnomonic_closed_form(rng):
    ref, v = _ref_and_targets(rng, 200, 60 * DEG)
    np.testing.assert_allclose(rot.tangent_offset(v, ref), np_gnomonic(v, ref), atol=1e-12)
    # un-normalised v projects the same way
    np.testing.assert_allclose(rot.tangent_offset(7.5 * v, ref), np_gnomonic(v, ref), atol=1e-12)


def test_offset_direction_matches_inverse_gnomonic_closed_form(rng):
    az0 = rng.uniform(-PI, PI, size=200)
    el0 = rng.uniform(-80 * DEG, 80 * DEG, size=200)
    ref = np_azel_to_enu(az0, el0)
    off = rng.uniform(-1.0, 1.0, size=(200, 2))
    np.testing.assert_allclose(rot.offset_direction(ref, off), np_inverse_gnomonic(ref, off), atol=1e-12)


def test_tangent_offset_small_offsets_are_daz_cos_el_and_del(rng):
    az0 = rng.uniform(-PI, PI, size=100)
    el0 = rng.uniform(-70 * DEG, 70 * DEG, size=100)
    d_az = rng.uniform(-1e-6, 1e-6, size=100)
    d_el = rng.uniform(-1e-6, 1e-6, size=100)
    got = rot.tangent_offset(np_azel_to_enu(az0 + d_az, el0 + d_el), np_azel_to_enu(az0, el0))
    expected = np.stack([d_az * np.cos(el0), d_el], axis=-1)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-11)  # second-order terms ~1e-12


@pytest.mark.parametrize("t", [1e-9, 1e-4, 0.1, 0.5, -0.3, 1.0])
@pytest.mark.parametrize("az0_deg", [0.0, 123.0, -77.0])
def test_gnomonic_pure_elevation_offset_is_tan(t, az0_deg):
    el0 = 30 * DEG
    ref = np_azel_to_enu(az0_deg * DEG, el0)
    v = np_azel_to_enu(az0_deg * DEG, el0 + t)
    got = np.asarray(rot.tangent_offset(v, ref))
    assert got[0] == pytest.approx(0.0, abs=1e-15)
    assert got[1] == pytest.approx(math.tan(t), rel=1e-12)
    # and back
    np.testing.assert_allclose(rot.offset_direction(ref, jnp.array([0.0, math.tan(t)])), v, atol=1e-15)


@pytest.mark.parametrize("t", [1e-7, 0.2, -0.7])
def test_gnomonic_pure_azimuth_on_horizon_is_tan(t):
    ref = np_azel_to_enu(0.4, 0.0)
    got = np.asarray(rot.tangent_offset(np_azel_to_enu(0.4 + t, 0.0), ref))
    assert got[0] == pytest.approx(math.tan(t), rel=1e-12)
    assert got[1] == pytest.approx(0.0, abs=1e-15)


def test_offset_direction_then_tangent_offset_round_trip(rng):
    az0 = rng.uniform(-PI, PI, size=150)
    el0 = rng.uniform(-89 * DEG, 89 * DEG, size=150)
    ref = np_azel_to_enu(az0, el0)
    off = rng.uniform(-2.0, 2.0, size=(150, 2)) * 10.0 ** rng.uniform(-8, 0, size=(150, 1))
    back = rot.tangent_offset(rot.offset_direction(ref, off), ref)
    np.testing.assert_allclose(back, off, rtol=1e-12, atol=1e-14)


def test_tangent_offset_then_offset_direction_round_trip(rng):
    ref, v = _ref_and_targets(rng, 150, 80 * DEG)
    back = rot.offset_direction(ref, rot.tangent_offset(v, ref))
    np.testing.assert_allclose(back, v, atol=1e-13)


@SETTINGS
@given(
    az0=st.floats(-PI, PI),
    el0=st.floats(-PI / 2, PI / 2),
    dx=st.floats(-3.0, 3.0),
    dy=st.floats(-3.0, 3.0),
)
def test_offset_round_trip_property(az0, el0, dx, dy):
    ref = np_azel_to_enu(az0, el0)  # includes the poles
    back = rot.tangent_offset(rot.offset_direction(ref, jnp.array([dx, dy])), ref)
    np.testing.assert_allclose(back, [dx, dy], rtol=1e-10, atol=1e-12)


def test_tangent_basis_at_zenith_is_azimuth_zero_basis():
    e_az, e_el = rot.tangent_basis(jnp.array([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(e_az, [1.0, 0.0, 0.0], atol=1e-16)  # East
    np.testing.assert_allclose(e_el, [0.0, -1.0, 0.0], atol=1e-16)  # South


def test_tangent_basis_generic_matches_derivatives_of_azel(rng):
    az0, el0 = 0.7, 0.4
    ref = np_azel_to_enu(az0, el0)
    e_az, e_el = rot.tangent_basis(ref)
    d_daz = central_fd(lambda p: np_azel_to_enu(p[0], p[1]), [az0, el0])[:, 0]
    d_del = central_fd(lambda p: np_azel_to_enu(p[0], p[1]), [az0, el0])[:, 1]
    np.testing.assert_allclose(e_az, d_daz / np.linalg.norm(d_daz), atol=1e-9)
    np.testing.assert_allclose(e_el, d_del / np.linalg.norm(d_del), atol=1e-9)


@pytest.mark.parametrize("az_deg", [0.0, 90.0, 180.0, -90.0, 33.0])
@pytest.mark.parametrize("t", [1e-6, 0.1, 0.6])
def test_tangent_offset_with_ref_at_zenith(az_deg, t):
    zenith = jnp.array([0.0, 0.0, 1.0])
    v = np_azel_to_enu(az_deg * DEG, PI / 2 - t)
    # basis of azimuth 0: x along East, y along South; radius tan t
    expected = math.tan(t) * np.array([math.sin(az_deg * DEG), -math.cos(az_deg * DEG)])
    np.testing.assert_allclose(rot.tangent_offset(v, zenith), expected, rtol=1e-12, atol=1e-16)
    np.testing.assert_allclose(rot.offset_direction(zenith, expected), v, atol=1e-15)


def test_offset_direction_at_zenith_moves_east_and_south():
    zenith = jnp.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(rot.offset_direction(zenith, jnp.array([0.01, 0.0])), np.array([0.01, 0, 1]) / math.hypot(0.01, 1), atol=1e-16)
    np.testing.assert_allclose(rot.offset_direction(zenith, jnp.array([0.0, 0.01])), np.array([0, -0.01, 1]) / math.hypot(0.01, 1), atol=1e-16)


# ------------------------------------------------------------- 4. jit, vmap, grad
def _gen_point():
    """A generic point and batched inputs for each function, and numpy references."""
    ref = np_azel_to_enu(0.7, 0.4)
    v = np.array([0.35, 0.8, 0.5])
    a = np.array([0.3, -0.5, 0.8])
    b = np.array([-0.2, 0.6, 0.4])
    return ref, v, a, b


JV_CASES = {
    # name: (pointax fn, numpy reference, args for one call)
    "rot_x": (rot.rot_x, lambda t: euler("x", t).as_matrix(), (0.3,)),
    "rot_y": (rot.rot_y, lambda t: euler("y", t).as_matrix(), (-1.1,)),
    "rot_z": (rot.rot_z, lambda t: euler("z", t).as_matrix(), (2.2,)),
    "rot_axis": (
        rot.rot_axis,
        lambda k, t: Rotation.from_rotvec(np.asarray(k) / np.linalg.norm(k) * t).as_matrix(),
        (np.array([0.2, -0.7, 1.3]), 0.9),
    ),
    "small_tilt": (
        rot.small_tilt,
        lambda x, y: (euler("x", x) * euler("y", y)).as_matrix(),
        (0.01, -0.02),
    ),
    "azel_to_enu": (rot.azel_to_enu, np_azel_to_enu, (0.7, 0.4)),
    "enu_to_azel": (rot.enu_to_azel, np_enu_to_azel, (np.array([0.35, 0.8, 0.5]),)),
    "tangent_offset": (rot.tangent_offset, np_gnomonic, (np.array([0.35, 0.8, 0.5]), np_azel_to_enu(0.7, 0.4))),
    "offset_direction": (rot.offset_direction, np_inverse_gnomonic, (np_azel_to_enu(0.7, 0.4), np.array([0.05, -0.02]))),
    "angle_between": (
        rot.angle_between,
        lambda a, b: np.arccos(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b)),
        (np.array([0.3, -0.5, 0.8]), np.array([-0.2, 0.6, 0.4])),
    ),
    "wrap_pi": (rot.wrap_pi, lambda t: np.arctan2(np.sin(t), np.cos(t)), (7.0,)),
}


UNIT_ARGS = {"tangent_offset": (1,), "offset_direction": (0,)}  # documented unit `ref`


def _assert_tree_close(got, expected, atol=1e-12):
    if isinstance(expected, tuple):
        for g, e in zip(got, expected):
            np.testing.assert_allclose(g, e, atol=atol)
    else:
        np.testing.assert_allclose(got, expected, atol=atol)


@pytest.mark.parametrize("name", sorted(JV_CASES))
def test_jit_matches_reference(name):
    fn, ref, args = JV_CASES[name]
    _assert_tree_close(jax.jit(fn)(*args), ref(*args))


@pytest.mark.parametrize("name", sorted(JV_CASES))
def test_vmap_matches_reference(name, rng):
    fn, ref, args = JV_CASES[name]
    n = 4
    batched = [np.asarray(a, float) + rng.normal(scale=0.05, size=(n,) + np.shape(a)) for a in args]
    for i in UNIT_ARGS.get(name, ()):
        batched[i] /= np.linalg.norm(batched[i], axis=-1, keepdims=True)
    got = jax.jit(jax.vmap(fn))(*batched)
    for i in range(n):
        one = jax.tree_util.tree_map(lambda g: g[i], got)
        _assert_tree_close(one, ref(*[b[i] for b in batched]))


# Scalar outputs of each function for grad, expressed over parameters p, with the numpy
# reference over the same parameters (for central finite differences).
def _grad_cases():
    ref_az, ref_el = 0.7, 0.4
    v = np.array([0.35, 0.8, 0.5])
    return {
        "rot_x": (lambda p: rot.rot_x(p[0]), lambda p: euler("x", p[0]).as_matrix(), [0.3]),
        "rot_y": (lambda p: rot.rot_y(p[0]), lambda p: euler("y", p[0]).as_matrix(), [-1.1]),
        "rot_z": (lambda p: rot.rot_z(p[0]), lambda p: euler("z", p[0]).as_matrix(), [2.2]),
        "rot_axis": (
            lambda p: rot.rot_axis(p[:3], p[3]),
            lambda p: Rotation.from_rotvec(p[:3] / np.linalg.norm(p[:3]) * p[3]).as_matrix(),
            [0.2, -0.7, 1.3, 0.9],
        ),
        "small_tilt": (
            lambda p: rot.small_tilt(p[0], p[1]),
            lambda p: (euler("x", p[0]) * euler("y", p[1])).as_matrix(),
            [0.01, -0.02],
        ),
        "azel_to_enu": (lambda p: rot.azel_to_enu(p[0], p[1]), lambda p: np_azel_to_enu(p[0], p[1]), [0.7, 0.4]),
        "enu_to_azel": (lambda p: jnp.stack(rot.enu_to_azel(p)), lambda p: np.stack(np_enu_to_azel(p)), list(v)),
        "tangent_offset_v": (
            lambda p: rot.tangent_offset(p, rot.azel_to_enu(ref_az, ref_el)),
            lambda p: np_gnomonic(p, np_azel_to_enu(ref_az, ref_el)),
            list(v),
        ),
        "tangent_offset_ref": (
            lambda p: rot.tangent_offset(jnp.asarray(v), rot.azel_to_enu(p[0], p[1])),
            lambda p: np_gnomonic(v, np_azel_to_enu(p[0], p[1])),
            [ref_az, ref_el],
        ),
        "offset_direction_offset": (
            lambda p: rot.offset_direction(rot.azel_to_enu(ref_az, ref_el), p),
            lambda p: np_inverse_gnomonic(np_azel_to_enu(ref_az, ref_el), p),
            [0.05, -0.02],
        ),
        "offset_direction_ref": (
            lambda p: rot.offset_direction(rot.azel_to_enu(p[0], p[1]), jnp.array([0.05, -0.02])),
            lambda p: np_inverse_gnomonic(np_azel_to_enu(p[0], p[1]), np.array([0.05, -0.02])),
            [ref_az, ref_el],
        ),
        "angle_between": (
            lambda p: rot.angle_between(p[:3], p[3:]),
            lambda p: np.arccos(np.dot(p[:3], p[3:]) / np.linalg.norm(p[:3]) / np.linalg.norm(p[3:])),
            [0.3, -0.5, 0.8, -0.2, 0.6, 0.4],
        ),
        "wrap_pi": (lambda p: rot.wrap_pi(p[0]), lambda p: np.arctan2(np.sin(p[0]), np.cos(p[0])), [7.0]),
        "mount_direction": (
            lambda p: AltAzMount().direction(p),
            lambda p: np_azel_to_enu(p[0], p[1]),
            [0.7, 0.4],
        ),
        "mount_angles_of": (
            lambda p: AltAzMount().angles_of(p, jnp.array([0.4, 0.5])),
            lambda p: np.stack(np_enu_to_azel(p)),
            list(v),
        ),
    }


GRAD_CASES = _grad_cases()


@pytest.mark.parametrize("name", sorted(GRAD_CASES))
def test_jacobian_matches_central_finite_differences(name):
    fn, ref, p0 = GRAD_CASES[name]
    p0 = np.asarray(p0, float)
    jac = np.asarray(jax.jit(jax.jacobian(fn))(jnp.asarray(p0)))  # jit: compiles faster than eager
    fd = central_fd(ref, p0, h=1e-6)
    assert np.all(np.isfinite(jac))
    np.testing.assert_allclose(jac, fd, rtol=1e-6, atol=1e-9)


def test_grad_of_scalar_loss_matches_finite_differences():
    # a scalar pipeline through several functions, with jax.grad (not jacobian)
    target = np_azel_to_enu(0.2, 0.9)

    def loss(p):
        d = rot.rot_axis(jnp.array([0.1, 0.2, 1.0]), p[2]) @ rot.azel_to_enu(p[0], p[1])
        return jnp.sum(rot.tangent_offset(d, jnp.asarray(target)) ** 2)

    def loss_np(p):
        m = Rotation.from_rotvec(np.array([0.1, 0.2, 1.0]) / np.linalg.norm([0.1, 0.2, 1.0]) * p[2]).as_matrix()
        return np.sum(np_gnomonic(m @ np_azel_to_enu(p[0], p[1]), target) ** 2)

    p0 = np.array([0.3, 0.8, 0.05])
    g = jax.jit(jax.grad(loss))(jnp.asarray(p0))
    np.testing.assert_allclose(g, central_fd(loss_np, p0), rtol=1e-6, atol=1e-10)


ZENITH = np.array([0.0, 0.0, 1.0])
NADIR = np.array([0.0, 0.0, -1.0])


@pytest.mark.parametrize(
    "name, fn, x",
    [
        ("azel_to_enu el=+90", lambda p: rot.azel_to_enu(p[0], p[1]), [0.3, PI / 2]),
        ("azel_to_enu el=-90", lambda p: rot.azel_to_enu(p[0], p[1]), [0.3, -PI / 2]),
        ("enu_to_azel zenith", lambda v: jnp.stack(rot.enu_to_azel(v)), ZENITH),
        ("enu_to_azel nadir", lambda v: jnp.stack(rot.enu_to_azel(v)), NADIR),
        ("enu_to_azel scaled zenith", lambda v: jnp.stack(rot.enu_to_azel(v)), 5 * ZENITH),
        ("tangent_basis zenith", lambda r: jnp.concatenate(rot.tangent_basis(r)), ZENITH),
        ("tangent_basis nadir", lambda r: jnp.concatenate(rot.tangent_basis(r)), NADIR),
        ("tangent_offset wrt ref at zenith", lambda r: rot.tangent_offset(jnp.array([0.1, 0.2, 0.9]), r), ZENITH),
        ("tangent_offset wrt v, ref at zenith", lambda v: rot.tangent_offset(v, jnp.asarray(ZENITH)), [0.1, 0.2, 0.9]),
        ("tangent_offset wrt v at zenith, ref at zenith", lambda v: rot.tangent_offset(v, jnp.asarray(ZENITH)), ZENITH),
        ("offset_direction wrt ref at zenith", lambda r: rot.offset_direction(r, jnp.array([0.01, 0.02])), ZENITH),
        ("offset_direction wrt offset, ref at zenith", lambda o: rot.offset_direction(jnp.asarray(ZENITH), o), [0.0, 0.0]),
        ("angle_between zenith/north", lambda a: rot.angle_between(a, jnp.array([0.0, 1.0, 0.0])), ZENITH),
        ("angles_of zenith", lambda d: AltAzMount().angles_of(d, jnp.array([0.3, 0.4])), ZENITH),
    ],
)
def test_jacobian_finite_at_singular_points(name, fn, x):
    jac = jax.jit(jax.jacobian(fn))(jnp.asarray(x, float))
    assert np.all(np.isfinite(np.asarray(jac))), name


def test_enu_to_azel_elevation_gradient_at_zenith_along_z_is_zero():
    # el = atan2(z, hypot(x, y)): scaling along z at the zenith does not change el.
    jac = jax.jit(jax.jacobian(lambda v: rot.enu_to_azel(v)[1]))(jnp.asarray(ZENITH))
    assert float(jac[2]) == 0.0


def test_vmap_of_grad_over_batch_including_zenith():
    pts = np.array([ZENITH, NADIR, [0.3, 0.4, 0.5], [1.0, 0.0, 0.0]])
    g = jax.jit(jax.vmap(jax.grad(lambda v: rot.enu_to_azel(v)[1])))(jnp.asarray(pts))
    assert np.all(np.isfinite(np.asarray(g)))
    # generic row against finite differences of the numpy reference
    np.testing.assert_allclose(g[2], central_fd(lambda v: np_enu_to_azel(v)[1], pts[2]), rtol=1e-6, atol=1e-9)


# ------------------------------------------------------------------- 5. angle_between
def test_angle_between_matches_arccos_for_separated_vectors(rng):
    a = random_unit_vectors(rng, 300)
    b = random_unit_vectors(rng, 300)
    expected = np.arccos(np.clip(np.sum(a * b, axis=-1), -1, 1))
    keep = (expected > 0.05) & (expected < PI - 0.05)
    np.testing.assert_allclose(np.asarray(rot.angle_between(a, b))[keep], expected[keep], atol=1e-13)


@pytest.mark.parametrize("t", [1e-12, 1e-9, 1e-7, 1e-5])
def test_angle_between_small_angles_where_arccos_fails(rng, t):
    a = random_unit_vectors(rng, 1)[0]
    perp = np.cross(a, rng.normal(size=3))
    perp /= np.linalg.norm(perp)
    b = Rotation.from_rotvec(perp * t).apply(a)  # exactly t away (to rounding)
    got = float(rot.angle_between(a, b))
    assert got == pytest.approx(t, rel=1e-6)
    if t <= 1e-9:
        # the naive arccos(dot) loses the answer entirely at this scale
        assert abs(np.arccos(np.clip(a @ b, -1, 1)) - t) > 0.5 * t


def test_angle_between_simple_small_angle_closed_form():
    t = 1e-9
    got = rot.angle_between(jnp.array([1.0, 0.0, 0.0]), jnp.array([math.cos(t), math.sin(t), 0.0]))
    assert float(got) == pytest.approx(t, rel=1e-12)


@pytest.mark.parametrize(
    "a, b, expected",
    [
        ((1, 0, 0), (1, 0, 0), 0.0),
        ((1, 0, 0), (-1, 0, 0), PI),
        ((1, 0, 0), (0, 1, 0), PI / 2),
        ((0, 0, 1), (S, 0, S), PI / 4),
        ((1, 0, 0), (-math.cos(1e-9), math.sin(1e-9), 0), PI - 1e-9),
    ],
)
def test_angle_between_known_values(a, b, expected):
    assert float(rot.angle_between(jnp.asarray(a, float), jnp.asarray(b, float))) == pytest.approx(expected, abs=1e-15)


def test_angle_between_broadcasts(rng):
    a = random_unit_vectors(rng, 1)[0]
    b = random_unit_vectors(rng, 12).reshape(3, 4, 3)
    got = rot.angle_between(a, b)
    assert got.shape == (3, 4)
    np.testing.assert_allclose(got, np.arccos(np.clip(b @ a, -1, 1)), atol=1e-7)


# ------------------------------------------------------------------------- 6. wrap_pi
@pytest.mark.parametrize(
    "x, expected",
    [
        (0.0, 0.0),
        (1.0, 1.0),
        (-1.0, -1.0),
        (PI, -PI),  # [-pi, pi): +pi maps to -pi
        (-PI, -PI),
        (3 * PI / 2, -PI / 2),
        (-3 * PI / 2, PI / 2),
        (2 * PI + 0.1, 0.1),
        (-7.0, -7.0 + 2 * PI),
        (100.0, 100.0 - 32 * PI),
    ],
)
def test_wrap_pi_known_values(x, expected):
    assert float(rot.wrap_pi(x)) == pytest.approx(expected, abs=1e-13)


def test_wrap_pi_matches_numpy_and_stays_in_range(rng):
    x = rng.uniform(-1e3, 1e3, size=2000)
    got = np.asarray(rot.wrap_pi(x))
    assert np.all(got >= -PI) and np.all(got < PI)
    np.testing.assert_allclose(got, np.arctan2(np.sin(x), np.cos(x)), atol=1e-12)
    # differs from x by a whole number of turns
    turns = (x - got) / (2 * PI)
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-12)


def test_wrap_pi_grad_is_one():
    g = jax.vmap(jax.grad(rot.wrap_pi))(jnp.array([-10.0, -1.0, 0.5, 4.0, 50.0]))
    np.testing.assert_allclose(g, 1.0)


# ------------------------------------------------------------------ 7. AltAzMount
def test_mount_direction_ne_equals_azel_to_enu(rng):
    mount = AltAzMount()
    assert mount.azimuth == "N-E"
    for az, el in zip(rng.uniform(-2 * PI, 2 * PI, 20), rng.uniform(-PI / 2, PI, 20)):
        d = mount.direction(jnp.array([az, el]))
        np.testing.assert_allclose(d, np_azel_to_enu(az, el), atol=1e-15)
        np.testing.assert_allclose(d, rot.azel_to_enu(az, el), atol=1e-15)
        if abs(el) <= PI / 2:  # astropy only takes |alt| <= 90 deg
            np.testing.assert_allclose(mount.frame @ d, astropy_azel_to_enu(az, el), atol=1e-15)


def test_mount_axis_chain_equals_direction(rng):
    mount = AltAzMount()
    for az, el in zip(rng.uniform(-PI, PI, 10), rng.uniform(-PI / 2, PI / 2, 10)):
        chain = mount.axis1(az) @ mount.axis2(el) @ mount.boresight
        np.testing.assert_allclose(chain, np_azel_to_enu(az, el), atol=1e-15)


@pytest.mark.parametrize(
    "convention, to_ne",
    [
        ("N-E", lambda a: a),
        ("S-E", lambda a: PI - a),
        ("S-W", lambda a: a + PI),
    ],
)
def test_mount_conventions_frame_times_direction(rng, convention, to_ne):
    mount = AltAzMount(azimuth=convention)
    assert mount.convention == convention
    frame = np.asarray(mount.frame)
    np.testing.assert_allclose(frame.T @ frame, np.eye(3), atol=0)
    for a, e in zip(rng.uniform(-PI, PI, 20), rng.uniform(-PI / 2, PI / 2, 20)):
        enu = frame @ np.asarray(mount.direction(jnp.array([a, e])))
        np.testing.assert_allclose(enu, np_azel_to_enu(to_ne(a), e), atol=1e-15)
        np.testing.assert_allclose(enu, astropy_azel_to_enu(to_ne(a), e), atol=1e-15)


@pytest.mark.parametrize(
    "convention, enc_az_deg",
    [
        # a star due East (A_NE = 90) at el 40: S-E counts 180 - 90 = 90, S-W counts 90 - 180 = -90
        ("N-E", 90.0),
        ("S-E", 90.0),
        ("S-W", -90.0),
        # a star at A_NE = 30: S-E 150, S-W -150
    ],
)
def test_mount_angles_of_enu_star_in_each_convention(convention, enc_az_deg):
    mount = AltAzMount(azimuth=convention)
    enu = np_azel_to_enu(90 * DEG, 40 * DEG)
    mount_dir = np.asarray(mount.frame).T @ enu
    got = np.asarray(mount.angles_of(jnp.asarray(mount_dir), jnp.array([enc_az_deg * DEG + 0.1, 0.6])))
    np.testing.assert_allclose(got, [enc_az_deg * DEG, 40 * DEG], atol=1e-13)


@pytest.mark.parametrize("convention", sorted(AZIMUTH_CONVENTIONS))
def test_mount_angles_of_round_trip(rng, convention):
    mount = AltAzMount(azimuth=convention)
    az = rng.uniform(-PI, PI, size=40)
    el = rng.uniform(-10 * DEG, 89 * DEG, size=40)
    for a, e in zip(az, el):
        angles = jnp.array([a, e])
        near = angles + jnp.array(rng.normal(scale=0.05, size=2))
        got = mount.angles_of(mount.direction(angles), near)
        np.testing.assert_allclose(got, [a, e], atol=1e-12)


def test_mount_angles_of_over_the_top(rng):
    mount = AltAzMount()
    for a, e in zip(rng.uniform(-PI, PI, 20), rng.uniform(5 * DEG, 85 * DEG, 20)):
        d = mount.direction(jnp.array([a, e]))
        near = jnp.array([a + PI + 0.05, PI - e - 0.03])  # encoders are "over the top"
        got = np.asarray(mount.angles_of(d, near))
        # the over-the-top solution on the encoder's azimuth branch
        expected_az = float(near[0]) + float(ang_diff(a + PI, float(near[0])))
        np.testing.assert_allclose(got, [expected_az, PI - e], atol=1e-12)
        assert abs(got[0] - float(near[0])) < PI
        np.testing.assert_allclose(mount.direction(jnp.asarray(got)), d, atol=1e-13)
        # and the normal solution when the encoders are not over the top
        got_a = np.asarray(mount.angles_of(d, jnp.array([a - 0.05, e + 0.03])))
        np.testing.assert_allclose(got_a, [a, e], atol=1e-12)


@pytest.mark.parametrize(
    "star_az_deg, near_deg, expected_az_deg",
    [
        (-170.0, (-170.0, 40.0), -170.0),  # not +190
        (190.0, (-170.0, 40.0), -170.0),  # same star, given as +190
        (-170.0, (190.0, 40.0), 190.0),  # encoder past +180 stays past +180
        (10.0, (365.0, 40.0), 370.0),  # wound a full turn
        (10.0, (-345.0, 40.0), -350.0),
        (179.0, (-179.0, 40.0), 179.0 - 360.0),  # across the +-180 seam
    ],
)
def test_mount_angles_of_stays_on_encoder_branch(star_az_deg, near_deg, expected_az_deg):
    mount = AltAzMount()
    d = np_azel_to_enu(star_az_deg * DEG, 40 * DEG)
    got = np.asarray(mount.angles_of(jnp.asarray(d), jnp.asarray(near_deg) * DEG))
    np.testing.assert_allclose(got / DEG, [expected_az_deg, 40.0], atol=1e-10)


def test_mount_angles_of_jit_and_vmap(rng):
    mount = AltAzMount()
    az = rng.uniform(-PI, PI, size=16)
    el = rng.uniform(0, 80 * DEG, size=16)
    dirs = np_azel_to_enu(az, el)
    near = np.stack([az + 2 * PI, el], axis=-1)  # one turn wound up
    got = jax.jit(jax.vmap(mount.angles_of))(jnp.asarray(dirs), jnp.asarray(near))
    np.testing.assert_allclose(got, np.stack([az + 2 * PI, el], axis=-1), atol=1e-12)
    np.testing.assert_allclose(jax.jit(jax.vmap(mount.direction))(jnp.asarray(near)), dirs, atol=1e-14)


def test_mount_unknown_convention_raises():
    with pytest.raises(ValueError, match="unknown azimuth convention"):
        AltAzMount(azimuth="N-W")


def test_mount_angles_of_at_zenith_keeps_encoder_azimuth():
    # Every (A, 90 deg) points at the zenith; the documented choice is the solution
    # closest to `near`, i.e. (near_az, 90 deg).
    mount = AltAzMount()
    near = jnp.array([30.0, 89.0]) * DEG
    got = np.asarray(mount.angles_of(jnp.array([0.0, 0.0, 1.0]), near))
    np.testing.assert_allclose(got / DEG, [30.0, 90.0], atol=1e-9)


def test_azel_to_enu_numpy_is_the_float64_twin():
    rng = np.random.default_rng(11)
    az, el = rng.uniform(-4, 4, (3, 7)), rng.uniform(-1.5, 1.5, (3, 7))
    got = rot.azel_to_enu_numpy(az, el)
    assert isinstance(got, np.ndarray) and got.dtype == np.float64 and got.shape == (3, 7, 3)
    np.testing.assert_allclose(got, np_azel_to_enu(az, el), rtol=0, atol=1e-15)


def test_offset_angle_is_the_angle_to_the_offset_direction():
    rng = np.random.default_rng(12)
    ref = np_azel_to_enu(rng.uniform(0, 6, 50), rng.uniform(-1.4, 1.4, 50))
    off = rng.normal(0, 0.3, (50, 2))
    moved = np_inverse_gnomonic(ref, off)
    # Independent: the great-circle angle by atan2(|a x b|, a . b).
    want = np.arctan2(np.linalg.norm(np.cross(ref, moved), axis=-1), np.sum(ref * moved, axis=-1))
    np.testing.assert_allclose(np.asarray(rot.offset_angle(off)), want, rtol=0, atol=1e-13)


def test_azel_trig_is_cos_and_sin_of_the_numpy_angles(rng):
    """Against numpy's cos and sin of arctan2 angles, with non-unit directions, the
    zenith and nadir (azimuth 0 there, as enu_to_azel) and a direction next to the pole."""
    v = rng.normal(size=(500, 3)) * rng.uniform(0.01, 100.0, (500, 1))
    v[:3] = [[0.0, 0.0, 2.0], [0.0, 0.0, -0.5], [1e-140, 0.0, 1.0]]  # (1e-140: just off the pole)
    az = np.arctan2(v[:, 0], v[:, 1])
    az[:2] = 0.0
    el = np.arctan2(v[:, 2], np.hypot(v[:, 0], v[:, 1]))
    ours = [np.asarray(x) for x in rot.azel_trig(jnp.asarray(v))]
    for name, got, want in zip(("cos az", "sin az", "cos el", "sin el"), ours, (np.cos(az), np.sin(az), np.cos(el), np.sin(el))):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-15, err_msg=name)

"""Quaternion helpers against scipy's Rotation (Hamilton, scalar first, body -> world)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from quad_wrench_env import rotations as r

unit_quaternions = (
    st.lists(st.floats(-1, 1, allow_nan=False), min_size=4, max_size=4)
    .filter(lambda q: np.linalg.norm(q) > 0.1)
    .map(lambda q: r.quat_normalize(np.array(q)))
)
angles = st.floats(-math.pi, math.pi, allow_nan=False)


def _scipy(q: np.ndarray) -> Rotation:
    return Rotation.from_quat([q[1], q[2], q[3], q[0]])


@given(unit_quaternions)
def test_rotation_matrix_matches_scipy(q):
    np.testing.assert_allclose(r.rotation_matrix(q), _scipy(q).as_matrix(), atol=1e-12)


@given(unit_quaternions, unit_quaternions)
def test_product_composes_rotations(a, b):
    np.testing.assert_allclose(
        r.rotation_matrix(r.quat_multiply(a, b)), r.rotation_matrix(a) @ r.rotation_matrix(b), atol=1e-12
    )


@given(unit_quaternions)
def test_conjugate_inverts_and_pybullet_order_round_trips(q):
    identity = r.quat_multiply(q, r.quat_conjugate(q))
    np.testing.assert_allclose(identity, (1.0, 0.0, 0.0, 0.0), atol=1e-12)
    np.testing.assert_array_equal(r.from_pybullet(r.to_pybullet(q)), q)


@given(angles, st.floats(-1.5, 1.5), angles)
def test_euler_yaw_and_tilt(roll, pitch, yaw):
    q = r.quat_from_euler_zyx(roll, pitch, yaw)
    expected = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix()
    np.testing.assert_allclose(r.rotation_matrix(q), expected, atol=1e-12)
    assert math.isclose(r.yaw_of(q), yaw, abs_tol=1e-9) or abs(abs(yaw) - math.pi) < 1e-9
    assert math.isclose(math.cos(r.tilt_angle(q)), math.cos(roll) * math.cos(pitch), abs_tol=1e-9)


@given(unit_quaternions)
def test_matrix_to_quaternion_round_trip(q):
    back = r.quat_from_matrix(r.rotation_matrix(q))
    assert min(np.abs(back - q).max(), np.abs(back + q).max()) < 1e-9  # q and -q: one rotation


def test_skew_is_cross_product():
    a, b = np.array((1.0, -2.0, 0.5)), np.array((0.3, 0.2, -4.0))
    np.testing.assert_allclose(r.skew(a) @ b, np.cross(a, b))


def test_zero_quaternion_is_refused():
    import pytest

    with pytest.raises(ValueError, match="norm"):
        r.quat_normalize(np.zeros(4))


def test_cross_matches_numpy_for_vectors_and_rows():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(5, 3)), rng.normal(size=(5, 3))
    np.testing.assert_allclose(r.cross(a, b), np.cross(a, b))
    np.testing.assert_allclose(r.cross(a[0], b), np.cross(a[0], b))
    np.testing.assert_allclose(r.cross(a[0], b[0]), np.cross(a[0], b[0]))

"""Quaternion helpers against scipy's Rotation (Hamilton, scalar first, body -> world)."""

from __future__ import annotations

import math

import numpy as np
import pytest
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
    with pytest.raises(ValueError, match="norm"):
        r.quat_normalize(np.zeros(4))


def test_cross_matches_numpy_for_vectors_and_rows():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(5, 3)), rng.normal(size=(5, 3))
    np.testing.assert_allclose(r.cross(a, b), np.cross(a, b))
    np.testing.assert_allclose(r.cross(a[0], b), np.cross(a[0], b))
    np.testing.assert_allclose(r.cross(a[0], b[0]), np.cross(a[0], b[0]))


small_vectors = st.lists(st.floats(-1.8, 1.8, allow_nan=False), min_size=3, max_size=3).map(np.array)


@given(unit_quaternions)
def test_mrp_round_trip_is_the_same_rotation(q):
    rho = r.mrp_from_quat(q)
    assert np.linalg.norm(rho) <= 1.0 + 1e-12
    back = r.quat_from_mrp(rho)
    assert min(np.abs(back - q).max(), np.abs(back + q).max()) < 1e-9


@given(small_vectors)
def test_mrp_is_tan_quarter_angle(v):
    angle = np.linalg.norm(v)
    rho = r.mrp_from_quat(r.quat_exp(v))
    assert np.linalg.norm(rho) == pytest.approx(math.tan(angle / 4.0), abs=1e-12)
    np.testing.assert_allclose(
        r.quat_exp(v), _scipy_quat(Rotation.from_rotvec(v)), atol=1e-12
    )  # |v| < π: w > 0


@given(unit_quaternions, small_vectors)
def test_error_quaternion_composition_is_the_identity(q, v):
    """q_i = q ⊗ δq, δq = q⁻¹ ⊗ q_i, and back through MRPs (``docs/physics.md``, "The unscented filter":
    Hamilton body error)."""
    dq = r.quat_from_mrp(r.mrp_from_quat(r.quat_exp(v)))
    qi = r.quat_multiply(q, dq)
    recovered = r.quat_multiply(r.quat_conjugate(q), qi)
    np.testing.assert_allclose(r.mrp_from_quat(recovered), r.mrp_from_quat(dq), atol=1e-9)


def test_row_wise_helpers_match_single_ones():
    rng = np.random.default_rng(0)
    qs = np.array([r.quat_normalize(x) for x in rng.normal(size=(6, 4))])
    np.testing.assert_allclose(r.rotation_matrices(qs), [r.rotation_matrix(q) for q in qs], atol=1e-14)
    np.testing.assert_allclose(r.mrp_from_quat(qs), [r.mrp_from_quat(q) for q in qs])


def _scipy_quat(rotation: Rotation) -> np.ndarray:
    x, y, z, w = rotation.as_quat()
    return r.quat_normalize(np.array((w, x, y, z)))


@given(angles, st.floats(-1.5, 1.5), angles)
def test_euler_round_trip(roll, pitch, yaw):
    euler = r.euler_zyx_from_quat(r.quat_from_euler_zyx(roll, pitch, yaw))
    np.testing.assert_allclose(r.wrap_angle(euler - (roll, pitch, yaw)), 0.0, atol=1e-9)

"""The unscented wrench estimator of McKinnon & Schoellig 2016: its algebra, its shortcuts and its
accuracy."""

from __future__ import annotations

import numpy as np
import pytest

from quad_wrench_env.estimators.noise import FilterNoise
from quad_wrench_env.estimators.ukf import (
    ATT,
    POS,
    STATE_DIM,
    UnscentedFilterBank,
    UnscentedWrenchEstimator,
)
from quad_wrench_env.rotations import mrp_from_quat, quat_conjugate, quat_from_euler_zyx, quat_multiply
from quad_wrench_env.vehicle import GRAVITY, make_vehicle

DT = 0.005


def _filter_in_motion(steps: int = 40) -> UnscentedWrenchEstimator:
    """A filter some steps into a manoeuvre, so that its covariance is full and its attitude tilted."""
    vehicle = make_vehicle("ardrone2")
    ukf = UnscentedWrenchEstimator(vehicle, DT)
    q = quat_from_euler_zyx(0.1, -0.2, 2.0)
    ukf.reset(np.array((1.0, 2.0, 1.0)), q)
    rng = np.random.default_rng(0)
    for k in range(steps):
        ukf.step(
            vehicle.mass * GRAVITY * 1.02,
            np.array((1e-3, -2e-3, 5e-4)),
            np.array((1.0, 2.0, 1.0)) + 1e-3 * rng.standard_normal(3) + 1e-4 * k,
            q,
        )
    return ukf


def test_weights_sum_to_one():
    ukf = UnscentedWrenchEstimator(make_vehicle("ardrone2"), DT)
    assert ukf.L == 30
    assert ukf.weight_centre + 2 * ukf.L * ukf.weight_other == pytest.approx(1.0, abs=1e-15)
    assert ukf.weight_centre == pytest.approx(0.0625) and ukf.weight_other == pytest.approx(0.015625)


def test_closed_form_noise_points_equal_the_plain_61_point_transform():
    ukf = _filter_in_motion()
    thrust, torque = 4.3, np.array((2e-3, -1e-3, 4e-4))
    # plain form: 2L + 1 = 61 sigma points of the extended state (eqs. 18-22), all through the model
    extended = np.zeros((ukf.L, ukf.L))
    extended[:STATE_DIM, :STATE_DIM] = ukf.covariance
    extended[STATE_DIM:, STATE_DIM:] = ukf.Q
    offsets = ukf.spread * np.linalg.cholesky(extended).T
    points = np.vstack((np.zeros(ukf.L), offsets, -offsets))
    weights = np.full(len(points), ukf.weight_other)
    weights[0] = ukf.weight_centre
    q_points, rest_points = ukf.propagate(points[:, :STATE_DIM], thrust, torque, noise=points[:, STATE_DIM:])
    q_plain, rest_plain, P_plain = ukf.recombine(q_points, rest_points, weights)

    ukf.predict(thrust, torque)
    np.testing.assert_allclose(ukf.quaternion, q_plain, atol=1e-13)
    np.testing.assert_allclose(ukf.rest, rest_plain, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(ukf.covariance, P_plain, rtol=1e-9, atol=1e-16)


def test_kalman_form_correction_equals_the_unscented_correction():
    ukf = _filter_in_motion()
    ukf.predict(4.1, np.zeros(3))
    P, G = ukf.covariance.copy(), ukf.G
    position = ukf.rest[3:6] + np.array((2e-3, -1e-3, 5e-4))
    measured_q = quat_multiply(ukf.quaternion, quat_from_euler_zyx(0.004, -0.002, 0.003))
    # eqs. (32)-(34): sigma points of (P̌, G), measurement [x + η_x, δρ + η_ρ]
    extended = np.zeros((STATE_DIM + 6, STATE_DIM + 6))
    extended[:STATE_DIM, :STATE_DIM] = P
    extended[STATE_DIM:, STATE_DIM:] = G
    lam = STATE_DIM + 6 + ukf.noise.kappa
    offsets = np.sqrt(lam) * np.linalg.cholesky(extended).T
    points = np.vstack((np.zeros(STATE_DIM + 6), offsets, -offsets))
    weights = np.full(len(points), 1.0 / (2.0 * lam))
    weights[0] = ukf.noise.kappa / lam
    y = np.hstack(
        (points[:, POS] + points[:, STATE_DIM : STATE_DIM + 3], points[:, ATT] + points[:, STATE_DIM + 3 :])
    )
    y_mean = weights @ y
    dy, dx = y - y_mean, points[:, :STATE_DIM]
    S = (dy * weights[:, None]).T @ dy
    C = (dx * weights[:, None]).T @ dy
    K = C @ np.linalg.inv(S)
    innovation = np.concatenate(
        (position - ukf.rest[3:6], mrp_from_quat(quat_multiply(quat_conjugate(ukf.quaternion), measured_q)))
    )
    delta = K @ (innovation - y_mean)
    P_unscented = P - K @ C.T
    rest_before = ukf.rest.copy()

    ukf.correct(position, measured_q)
    np.testing.assert_allclose(ukf.covariance, P_unscented, rtol=1e-8, atol=1e-15)
    np.testing.assert_allclose(ukf.rest, rest_before + delta[3:], rtol=1e-9, atol=1e-14)


def test_non_finite_input_is_refused_and_never_enters_the_filter():
    ukf = _filter_in_motion(5)
    before = ukf.rest.copy()
    with pytest.raises(ValueError, match="non-finite"):
        ukf.step(4.0, np.zeros(3), np.array((np.nan, 0.0, 1.0)), np.array((1.0, 0.0, 0.0, 0.0)))
    np.testing.assert_array_equal(ukf.rest, before)


def test_a_broken_covariance_is_reinitialised_and_reported():
    ukf = _filter_in_motion(5)
    ukf.covariance[0, 0] = -1.0
    ukf.step(4.12, np.zeros(3), ukf.rest[3:6].copy(), ukf.quaternion.copy())
    assert ukf.status == "reinitialised" and ukf.reinitialisations == 1
    assert np.all(np.linalg.eigvalsh(ukf.covariance) > 0)


def test_noise_settings_are_validated():
    with pytest.raises(ValueError, match="force_walk=-1"):
        FilterNoise(force_walk=-1.0)


def _hover_measurements(ukf: UnscentedWrenchEstimator, seconds: float, seed: int) -> list[np.ndarray]:
    """Feed a hovering vehicle's noisy pose (0.5 mm, 2 mrad) for ``seconds``; return the estimates."""
    rng = np.random.default_rng(seed)
    position, q = np.array((0.0, 0.0, 1.0)), np.array((1.0, 0.0, 0.0, 0.0))
    ukf.reset(position, q)
    weight = ukf.mass * GRAVITY
    out = []
    for _ in range(round(seconds / DT)):
        noise_q = quat_from_euler_zyx(*(2e-3 * rng.standard_normal(3)))
        est = ukf.step(
            weight, np.zeros(3), position + 5e-4 * rng.standard_normal(3), quat_multiply(q, noise_q)
        )
        out.append(np.concatenate((est.force, est.torque)))
    return out


def test_covariance_stays_positive_definite_and_the_quaternion_unit():
    ukf = UnscentedWrenchEstimator(make_vehicle("ardrone2"), DT)
    _hover_measurements(ukf, 120.0, seed=1)
    assert ukf.status == "ok"
    np.testing.assert_allclose(ukf.covariance, ukf.covariance.T, atol=0)
    assert np.linalg.eigvalsh(ukf.covariance).min() > 0
    assert np.linalg.norm(ukf.quaternion) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.slow
def test_one_hour_of_flight_keeps_the_filter_sound():
    ukf = UnscentedWrenchEstimator(make_vehicle("ardrone2"), DT)
    estimates = np.array(_hover_measurements(ukf, 3600.0, seed=2))
    assert ukf.status == "ok" and np.all(np.isfinite(estimates))
    assert np.linalg.eigvalsh(ukf.covariance).min() > 0
    assert np.abs(estimates[-20000:].mean(axis=0)[:3]).max() < 0.01


def test_zero_wrench_in_hover_is_estimated_without_bias():
    """Tolerances: a fifth of McKinnon & Schoellig's (2016) static accuracy (0.05 N, 0.02 N·m)."""
    ukf = UnscentedWrenchEstimator(make_vehicle("ardrone2"), DT)
    estimates = np.array(_hover_measurements(ukf, 30.0, seed=3))[2000:]
    assert np.abs(estimates[:, :3].mean(axis=0)).max() < 0.01
    assert np.abs(estimates[:, 3:].mean(axis=0)).max() < 0.004


def test_a_bank_of_filters_equals_the_filters_run_one_by_one():
    """The batched computation (issue 6) gives each filter what it would get alone."""
    vehicle = make_vehicle("ardrone2")
    n, rng = 5, np.random.default_rng(4)
    bank = UnscentedFilterBank(vehicle, DT, None, n)
    singles = [UnscentedWrenchEstimator(vehicle, DT) for _ in range(n)]
    positions = rng.normal(size=(n, 3))
    quaternions = np.array([quat_from_euler_zyx(*rng.uniform(-0.3, 0.3, 3)) for _ in range(n)])
    bank.reset(slice(None), positions, quaternions)
    for k, single in enumerate(singles):
        single.reset(positions[k], quaternions[k])
    for _ in range(50):
        thrusts = 4.1 + 0.1 * rng.standard_normal(n)
        torques = 1e-3 * rng.standard_normal((n, 3))
        positions = positions + 1e-3 * rng.standard_normal((n, 3))
        bank.step(thrusts, torques, positions, quaternions)
        for k, single in enumerate(singles):
            single.step(thrusts[k], torques[k], positions[k], quaternions[k])
    for k, single in enumerate(singles):
        np.testing.assert_allclose(bank.rests[k], single.rest, rtol=1e-10, atol=1e-13)
        np.testing.assert_allclose(bank.covariances[k], single.covariance, rtol=1e-9, atol=1e-16)
        np.testing.assert_allclose(bank.quaternions[k], single.quaternion, atol=1e-13)

"""The EKF of Hentzen et al. 2019 and the nonlinear observer of Yüksel et al. 2014."""

from __future__ import annotations

import math

import numpy as np
import pytest

from quad_wrench_env.estimators.ekf_kernel import ekf_transition, ekf_transition_jacobian
from quad_wrench_env.estimators.observer import NonlinearWrenchObserver, ObserverGains
from quad_wrench_env.vehicle import GRAVITY, make_vehicle

DT = 0.005


@pytest.mark.parametrize("seed", range(5))
def test_ekf_jacobian_matches_finite_differences(seed):
    """The kernel's analytic Jacobian of Hentzen et al.'s (2019) transition against central
    differences of the kernel's transition (step 1e-6: truncation ~1e-12, rounding ~1e-9, against
    atol 1e-8)."""
    rng = np.random.default_rng(seed)
    vehicle = make_vehicle("hummingbird")
    inertia = np.array(vehicle.inertia)
    x = rng.normal(size=18)
    x[6:9] = rng.uniform((-0.6, -0.6, -3.0), (0.6, 0.6, 3.0))
    x[9:12] *= 2.0
    thrust, torque = 7.0, np.array((0.02, -0.01, 0.005))
    analytic = np.empty((18, 18))
    ekf_transition_jacobian(x, thrust, DT, vehicle.mass, inertia, analytic)

    def transition(state: np.ndarray) -> np.ndarray:
        state = state.copy()
        ekf_transition(state, thrust, torque, DT, vehicle.mass, inertia, GRAVITY, np.empty((3, 3)))
        return state

    h = 1e-6
    numeric = np.column_stack([(transition(x + h * e) - transition(x - h * e)) / (2 * h) for e in np.eye(18)])
    np.testing.assert_allclose(analytic, numeric, rtol=1e-6, atol=1e-8)


def test_observer_force_error_decays_as_exp_minus_c_t_over_m():
    """Eq. (8) with L = c/m: constant force, exact velocities, level vehicle holding its weight."""
    vehicle = make_vehicle("yuksel1kg")
    observer = NonlinearWrenchObserver(vehicle, DT, ObserverGains(c_force=5.0))
    force = np.array((1.0, 0.0, -1.0))
    q = np.array((1.0, 0.0, 0.0, 0.0))
    observer.reset(np.zeros(3), q)
    thrust = vehicle.mass * GRAVITY
    for k in range(1, 201):
        t = k * DT
        velocity = force / vehicle.mass * t
        position = 0.5 * force / vehicle.mass * t * t
        estimate = observer.step(thrust, np.zeros(3), position, q, velocity=velocity, body_rates=np.zeros(3))
        if k % 40 == 0:
            expected = force * (1.0 - math.exp(-5.0 * t / vehicle.mass))
            np.testing.assert_allclose(estimate.force, expected, atol=0.01 * np.linalg.norm(force))


def test_observer_torque_error_decays_as_exp_minus_c_t_over_j():
    vehicle = make_vehicle("yuksel1kg")
    observer = NonlinearWrenchObserver(vehicle, DT, ObserverGains(c_torque=0.5))
    torque, jx = 0.01, vehicle.inertia[0]
    observer.reset(np.zeros(3), np.array((1.0, 0.0, 0.0, 0.0)))
    for k in range(1, 201):
        t = k * DT
        rate, angle = torque / jx * t, 0.5 * torque / jx * t * t
        q = np.array((math.cos(angle / 2), math.sin(angle / 2), 0.0, 0.0))
        estimate = observer.step(
            vehicle.mass * GRAVITY,
            np.zeros(3),
            np.zeros(3),
            q,
            velocity=np.zeros(3),
            body_rates=np.array((rate, 0.0, 0.0)),
        )
        if k % 40 == 0:
            expected = torque * (1.0 - math.exp(-0.5 * t / jx))
            assert estimate.torque[0] == pytest.approx(expected, abs=0.02 * torque)


@pytest.mark.parametrize("estimator", ["ukf", "ekf", "observer"])
def test_recovers_a_constant_wrench_in_a_noise_free_run(make_env, estimator):
    env = make_env(
        fan={"enabled": False},
        kf_spread=0.0,
        estimator=estimator,
        sensors={"position_noise": 0.0, "attitude_noise": 0.0, "motor_speed_bits": 32},
        payload={"mass": 0.053, "point": (0.129, 0.129, 0.0)},
    )
    env.reset(seed=0, options={"offset_y": 0.0})
    est, true = [], []
    for _ in range(250):
        _, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
        est.append(info["wrench_est"])
        true.append(info["wrench_true"])
    est, true = np.mean(est[-50:], axis=0), np.mean(true[-50:], axis=0)
    np.testing.assert_allclose(est[2:5], true[2:5], rtol=0.01)
    assert np.abs(est[[0, 1, 5]]).max() < 0.01 * np.abs(true).max()


@pytest.mark.parametrize("estimator", ["ekf", "observer"])
def test_uses_state_estimator_measurements_when_provided(make_env, estimator):
    env = make_env(fan={"motion": "static"}, estimator=estimator, sensors={"state_estimator": True})
    env.reset(seed=0, options={"offset_y": 0.5})
    for _ in range(100):
        _, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
    assert info["estimator_status"] == "ok"
    np.testing.assert_allclose(info["wrench_est"][0], info["wrench_true"][0], atol=0.15)

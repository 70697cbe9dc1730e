"""The unscented wrench estimator of McKinnon & Schoellig 2016: its algebra, its shortcuts (against a plain
unscented filter, ``tests/reference_ukf.py``) and its accuracy."""

from __future__ import annotations

import numpy as np
import pytest

from quad_wrench_env.estimators import make_estimator
from quad_wrench_env.estimators.bank import EstimatorInputs
from quad_wrench_env.estimators.noise import FilterNoise
from quad_wrench_env.estimators.ukf import UnscentedFilterBank, UnscentedWrenchEstimator
from quad_wrench_env.rotations import (
    mrp_from_quat,
    quat_conjugate,
    quat_exp,
    quat_from_euler_zyx,
    quat_multiply,
)
from quad_wrench_env.vehicle import GRAVITY, make_vehicle
from tests.reference_ukf import ReferenceUKF
from tests.test_reference_estimators import ATTITUDE_NOISE, DT, POSITION_NOISE, VEHICLE, reference_flight


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


REFERENCE_STEPS = 200
"""Steps (1 s) of the reference flight on which the filter is held to the plain one."""
ROUNDING = 1e-9
"""Tolerance of the filter against the plain one, in units of the filter's own standard deviations:
the two compute the same numbers in real arithmetic (the kernel's shortcuts are exact, module
docstrings of ``estimators/ukf.py`` and ``estimators/ukf_kernel.py``) in other orders, so they part by
rounding only: each step's ~1e-16 relative, grown by the conditioning of the gain (``Σ_yy`` against
the much larger predicted covariance) and carried from step to step (seen: at most 3e-11 σ for the
means and 3e-12 σ_i σ_j for the covariance over 400 steps). A mistake moves them far more: the
kernel's pairs of linear sigma points weighted 0.5 % light part them by 8e-6 σ in the first step."""


@pytest.mark.parametrize("settings", [{}, {"adaptive_walks": True}], ids=["fixed walks", "matched walks"])
def test_the_filter_is_the_plain_unscented_filter_step_by_step(settings):
    """The filter's kernel (``make_estimator("ukf")``: 13 sigma points through the model, the other
    pairs as their linear map, the noise-only points as ``B Q Bᵀ``, the correction as a Kalman update)
    against ``tests/reference_ukf.py`` (all 61 sigma points of the extended state through the model,
    the unscented correction with measurement sigma points) on the first second of the manoeuvring
    reference flight of ``tests/test_reference_estimators.py`` (body rates of 1.5-2.5 rad/s about every
    axis, a constant external wrench), with its motion-capture noise: after every step the means
    (the external wrench among them, and the attitude as the MRPs between the two quaternions) and
    the covariance agree within ROUNDING of the filter's standard deviations; with the walks fixed and
    matched to the corrections (the reference's own form of the rule)."""
    states, inputs = reference_flight()
    estimator = make_estimator("ukf", VEHICLE, DT, **settings)
    reference = ReferenceUKF(
        VEHICLE.mass, np.array(VEHICLE.inertia), DT, GRAVITY, FilterNoise(**settings).for_vehicle(VEHICLE)
    )
    for filter_ in (estimator, reference):
        filter_.reset(states[0, 4:7], states[0, :4])
    rng = np.random.default_rng(0)
    for k in range(REFERENCE_STEPS):
        pose, (thrust, *torque) = states[k + 1], inputs[k]
        position = pose[4:7] + POSITION_NOISE * rng.standard_normal(3)
        attitude = quat_multiply(pose[:4], quat_exp(ATTITUDE_NOISE * rng.standard_normal(3)))
        estimator.step(thrust, np.array(torque), position, attitude)
        reference.step(thrust, np.array(torque), position, attitude)
        sigma = np.sqrt(np.diag(reference.P))
        attitude_error = mrp_from_quat(quat_multiply(quat_conjugate(reference.q), estimator.quaternion))
        where = f"step {k}, in the filter's standard deviations"
        np.testing.assert_array_less(np.abs(attitude_error) / sigma[:3], ROUNDING, err_msg=where)
        np.testing.assert_array_less(np.abs(estimator.rest - reference.rest) / sigma[3:], ROUNDING, where)
        covariance_error = np.abs(estimator.covariance - reference.P) / np.outer(sigma, sigma)
        np.testing.assert_array_less(covariance_error, ROUNDING, err_msg=where)
    wrench = np.concatenate((estimator.estimate.force, estimator.estimate.torque))
    assert np.abs(wrench).max() > 0.1  # the comparison saw a wrench


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
    with pytest.raises(ValueError, match="kappa=None"):  # only the vehicle-sized settings may be None
        FilterNoise(kappa=None)


def test_default_noise_is_sized_to_the_vehicle():
    """The defaults are the ardrone2's (0.42 kg, arm 0.129 m: thrust 0.05 N, force walk 4e-3 N, motor
    torque 3e-3 N·m, torque walk 2e-4 N·m) times the weight ratio (forces) and the weight x arm ratio
    (torques), worked by hand here for the crazyflie2 (0.027 kg, arm 0.0397/√2 m); on the ardrone2 they
    are its own numbers to the bit, given values are kept, and the measurement noise is not scaled."""
    ardrone2 = FilterNoise().for_vehicle(make_vehicle("ardrone2"))
    assert (ardrone2.thrust, ardrone2.force_walk, ardrone2.motor_torque, ardrone2.torque_walk) == (
        0.05,
        4e-3,
        3e-3,
        2e-4,
    )
    crazyflie2 = FilterNoise(torque_walk=1e-6).for_vehicle(make_vehicle("crazyflie2"))
    force_ratio, torque_ratio = 0.027 / 0.42, 0.027 * 0.0397 / 2**0.5 / (0.42 * 0.129)
    assert crazyflie2.force_walk == pytest.approx(4e-3 * force_ratio, rel=1e-12)
    assert crazyflie2.initial_force == pytest.approx(0.2 * force_ratio, rel=1e-12)
    assert crazyflie2.motor_torque == pytest.approx(3e-3 * torque_ratio, rel=1e-12)
    assert crazyflie2.torque_walk == 1e-6
    assert (crazyflie2.position, crazyflie2.attitude) == (FilterNoise().position, FilterNoise().attitude)


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
        bank.step(EstimatorInputs(thrusts, torques, positions, quaternions))
        for k, single in enumerate(singles):
            single.step(thrusts[k], torques[k], positions[k], quaternions[k])
    for k, single in enumerate(singles):
        np.testing.assert_allclose(bank.rests[k], single.rest, rtol=1e-10, atol=1e-13)
        np.testing.assert_allclose(bank.covariances[k], single.covariance, rtol=1e-9, atol=1e-16)
        np.testing.assert_allclose(bank.quaternions[k], single.quaternion, atol=1e-13)

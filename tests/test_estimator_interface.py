"""Every estimator honours the interface of ``docs/architecture.md``, "Contracts" (one conformance test
for all)."""

from __future__ import annotations

import numpy as np
import pytest

from quad_wrench_env.estimators import (
    ESTIMATORS,
    Estimator,
    EstimatorBank,
    TruthFed,
    make_estimator,
    make_estimator_bank,
)
from quad_wrench_env.estimators.bank import EstimatorInputs
from quad_wrench_env.rotations import quat_from_euler_zyx, rotation_matrix
from quad_wrench_env.vehicle import GRAVITY, make_vehicle

NO_COVARIANCE = ("observer",)
"""Estimators that carry no covariance: they report NaN (the oracle, the truth, reports zeros)."""


def _check_covariance(name: str, covariance: np.ndarray) -> None:
    """A filter's wrench covariance is symmetric positive semi-definite; the observer's NaN, the oracle's
    zero."""
    if name in NO_COVARIANCE:
        assert np.isnan(covariance).all()
    elif name == "oracle":
        assert not covariance.any()
    else:
        np.testing.assert_allclose(covariance, covariance.T)
        assert np.all(np.linalg.eigvalsh(covariance) >= -1e-15)
        assert np.all(np.diag(covariance) > 0)


@pytest.mark.parametrize("name", ESTIMATORS)
def test_estimator_conforms(name):
    vehicle = make_vehicle("ardrone2")
    est = make_estimator(name, vehicle, 0.005)
    assert isinstance(est, Estimator) and est.name == name
    position, q = np.array((0.0, 0.0, 1.0)), np.array((1.0, 0.0, 0.0, 0.0))
    est.reset(position, q)
    assert np.array_equal(est.estimate.force, np.zeros(3)) and np.array_equal(
        est.estimate.torque, np.zeros(3)
    )
    if isinstance(est, TruthFed):
        est.observe_truth(est.state, np.zeros(3), np.zeros(3))
    for _ in range(20):
        out = est.step(vehicle.mass * GRAVITY, np.zeros(3), position, q)
    assert out.force.shape == (3,) and out.torque.shape == (3,) and out.covariance.shape == (6, 6)
    _check_covariance(name, out.covariance)
    bank = make_estimator_bank(name, vehicle, 0.005, 2)
    for i in range(2):
        bank.reset(i, position, q)
    covariances = bank.wrench_covariances()
    assert covariances.shape == (2, 6, 6)
    for covariance in covariances:
        _check_covariance(name, covariance)
    state = est.state
    assert state.position.shape == state.velocity.shape == state.body_rates.shape == (3,)
    assert np.linalg.norm(state.quaternion) == pytest.approx(1.0)
    assert est.status == "ok"
    np.testing.assert_allclose(state.position, position, atol=1e-3)
    assert np.abs(out.force).max() < 0.05 and np.abs(out.torque).max() < 0.01


def test_unknown_estimator_and_settings_are_named():
    vehicle = make_vehicle("ardrone2")
    assert isinstance(make_estimator_bank("oracle", vehicle, 0.005, 2), EstimatorBank)
    with pytest.raises(ValueError, match="count=0"):
        make_estimator_bank("ukf", vehicle, 0.005, 0)
    with pytest.raises(ValueError, match="'kalman'"):
        make_estimator("kalman", vehicle, 0.005)
    with pytest.raises(ValueError, match="'estimator_params.sigma'"):
        make_estimator("ukf", vehicle, 0.005, sigma=1.0)
    with pytest.raises(ValueError, match="dt=0"):
        make_estimator("ukf", vehicle, 0.0)


# Not the learned estimator: fitted, not derived from these equations, it meets them to a few percent of
# the weight (tests/test_learned_estimator.py, held still tilted), not to 1e-3 N.
@pytest.mark.parametrize("name", [n for n in ESTIMATORS if n not in ("oracle", "learned")])
@pytest.mark.parametrize("euler", [(0.0, 0.0, np.pi), (0.1, -0.2, 2.0), (0.0, 0.24, np.pi)])
def test_a_vehicle_held_still_gives_the_wrench_that_balances_its_inputs(name, euler):
    """At rest at any attitude, the external wrench must cancel gravity, thrust and motor torque:
    f = m g e_z - R c_t e_z and tau = -R tau_m (zero accelerations in McKinnon & Schoellig 2016,
    eqs. 4 and 12)."""
    vehicle = make_vehicle("ardrone2")
    est = make_estimator(name, vehicle, 0.005)
    q = quat_from_euler_zyx(*euler)
    R = rotation_matrix(q)
    position, thrust, torque = np.array((2.3, 0.4, 1.0)), 4.2, np.array((0.008, 0.001, -0.03))
    est.reset(position, q)
    for _ in range(1000):
        estimate = est.step(thrust, torque, position, q)
    assert est.status == "ok"
    expected_force = vehicle.mass * GRAVITY * np.array((0.0, 0.0, 1.0)) - thrust * R[:, 2]
    np.testing.assert_allclose(estimate.force, expected_force, atol=1e-3)
    np.testing.assert_allclose(estimate.torque, -R @ torque, atol=1e-4)


@pytest.mark.parametrize("name", [n for n in ESTIMATORS if n != "oracle"])
def test_a_bank_gives_each_vehicle_what_its_single_estimator_gives(name):
    """The envs' estimator banks (one batched computation over N) against N single estimators fed
    the same noisy poses at different attitudes, one of them restarted half-way."""
    vehicle, count, dt = make_vehicle("ardrone2"), 3, 0.005
    bank = make_estimator_bank(name, vehicle, dt, count)
    singles = [make_estimator(name, vehicle, dt) for _ in range(count)]
    assert isinstance(bank, EstimatorBank) and bank.name == name and bank.count == count
    rng = np.random.default_rng(1)
    positions = rng.normal(size=(count, 3))
    quaternions = np.array([quat_from_euler_zyx(*angles) for angles in rng.uniform(-0.3, 0.3, (count, 3))])
    thrusts, torques = np.array((4.0, 4.1, 4.2)), 1e-3 * rng.normal(size=(count, 3))
    for i in range(count):
        bank.reset(i, positions[i], quaternions[i])
        singles[i].reset(positions[i], quaternions[i])
    for k in range(200):
        measured = positions + 5e-4 * rng.normal(size=(count, 3))
        if k == 100:
            bank.reset(1, measured[1], quaternions[1])
            singles[1].reset(measured[1], quaternions[1])
        bank.step(EstimatorInputs(thrusts, torques, measured, quaternions))
        for i, single in enumerate(singles):
            single.step(thrusts[i], torques[i], measured[i], quaternions[i])
    for i, single in enumerate(singles):
        s = single.state
        np.testing.assert_allclose(
            bank.wrenches()[i], np.concatenate((single.estimate.force, single.estimate.torque)), atol=1e-10
        )
        np.testing.assert_allclose(
            bank.states()[i], np.concatenate((s.position, s.velocity, s.quaternion, s.body_rates)), atol=1e-10
        )
    assert bank.statuses() == ["ok"] * count
    with pytest.raises(ValueError, match="non-finite"):
        bank.step(EstimatorInputs(thrusts, torques, measured * np.nan, quaternions))
    states, wrenches = bank.estimates()  # what the envs read: both at once, from one kernel call
    np.testing.assert_array_equal(states, bank.states())
    np.testing.assert_array_equal(wrenches, bank.wrenches())


def _euler_kinematics(roll: float, pitch: float) -> np.ndarray:
    """``T(η)`` with ``ω = T η̇`` for ZYX Euler angles (Yüksel et al. 2014, Sec. II), written here."""
    sr, cr, sp, cp = np.sin(roll), np.cos(roll), np.sin(pitch), np.cos(pitch)
    return np.array(((1.0, 0.0, -sp), (0.0, cr, sr * cp), (0.0, -sr, cr * cp)))


@pytest.mark.parametrize("name", ["ekf", "observer"])
def test_the_euler_angle_banks_report_in_the_world_frame_at_any_attitude(name):
    """The banks that hold ZYX Euler angles (Hentzen et al.'s 2019 EKF, Yüksel et al.'s 2014
    observer) turn them into the reported quaternion, body rates, world-frame torque and (EKF) its
    covariance, over the whole angle range (pitch short of ±90°): against the package's numpy
    rotations and ``T(η)`` written here, to rounding."""
    count = 50
    settings = {"rotor_spread": 0.0} if name == "ekf" else {}  # the filter's own covariance alone
    bank = make_estimator_bank(name, make_vehicle("ardrone2"), 0.005, count, **settings)
    rng = np.random.default_rng(1)
    angles = rng.uniform(-np.pi, np.pi, (count, 3))
    angles[:, 1] = rng.uniform(-1.5, 1.5, count)
    values = rng.normal(size=(count, 18))
    quaternions = quat_from_euler_zyx(angles[:, 0], angles[:, 1], angles[:, 2])
    rotations = [rotation_matrix(q) for q in quaternions]
    if name == "ekf":
        bank.x[:] = values
        bank.x[:, 6:9] = angles
        body_rates, body_torques = values[:, 9:12], values[:, 15:18]
    else:
        for state, column in zip(
            (bank.positions, bank.velocities, bank.euler_rates, bank.forces, bank.torques_generalised),
            range(0, 15, 3),
            strict=True,
        ):
            state[:] = values[:, column : column + 3]
        bank.eulers[:] = angles
        kinematics = [_euler_kinematics(roll, pitch) for roll, pitch, _ in angles]
        body_rates = np.array([t @ rate for t, rate in zip(kinematics, values[:, 6:9], strict=True)])
        body_torques = np.array(
            [np.linalg.solve(t.T, torque) for t, torque in zip(kinematics, values[:, 12:15], strict=True)]
        )
    torques = np.array([r @ torque for r, torque in zip(rotations, body_torques, strict=True)])
    states, wrenches = bank.estimates()
    np.testing.assert_allclose(states[:, 6:10], quaternions, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(states[:, 10:13], body_rates, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(wrenches[:, 3:], torques, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(states, bank.states())
    np.testing.assert_array_equal(wrenches, bank.wrenches())
    if name == "ekf":
        covariance = rng.normal(size=(count, 18, 18))
        bank.P[:] = covariance @ covariance.transpose(0, 2, 1)
        rotate = np.tile(np.eye(6), (count, 1, 1))
        rotate[:, 3:, 3:] = rotations
        expected = rotate @ bank.P[:, 12:18, 12:18] @ rotate.transpose(0, 2, 1)
        np.testing.assert_allclose(bank.wrench_covariances(), expected, rtol=1e-12, atol=1e-12)

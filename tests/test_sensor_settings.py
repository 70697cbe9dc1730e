"""Every numeric sensor and rotor setting does what its docstring says, measured end to end on what the
estimator is handed (issue 51, item 3): each noise's sd from samples against the truth, the motor
speeds' bit depth, the rotors' spread (the latency: tests/test_compiled_step.py). Each setting gets a
value of its own, so that one setting read in place of another shows."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from quad_wrench_env.rotations import quat_conjugate, quat_multiply
from quad_wrench_env.vehicle import Mixer
from tests.conftest import FAN_TRACKING, EstimatorSpy

SENSORS = {
    "position_noise": 0.003,
    "attitude_noise": 0.02,
    "velocity_noise": 0.05,
    "body_rate_noise": 0.002,
    "state_estimator": True,
}


def _fly(steps: int, **settings):
    """The spy's calls over ``steps`` control steps of zero actions (four physics steps each)."""
    env = gym.make(FAN_TRACKING, estimator="ekf", fan={"enabled": False}, **settings)
    try:
        env.reset(seed=3)
        fleet = env.unwrapped.fleet
        fleet.estimator = spy = EstimatorSpy(fleet.estimator, fleet)
        for _ in range(steps):
            env.step(np.zeros(4, dtype=np.float32))
    finally:
        env.close()
    return fleet, spy.calls


def test_each_noise_has_the_sd_it_is_given():
    """1000 physics steps, 3000 samples per setting: each sample sd within 8 % of its own setting (3 %
    is one sd of the estimate), and far from every other setting."""
    _, calls = _fly(250, sensors=SENSORS)
    errors = {name: [] for name in SENSORS if name != "state_estimator"}
    for (_, _, position, quaternion, velocity, rates), _, truth in calls:
        errors["position_noise"].append(position[0] - truth.position[0])
        turn = quat_multiply(quat_conjugate(truth.quaternion[0]), quaternion[0])
        errors["attitude_noise"].append(2.0 * turn[1:] * np.sign(turn[0]))
        errors["velocity_noise"].append(velocity[0] - truth.velocity[0])
        errors["body_rate_noise"].append(rates[0] - truth.body_rates[0])
    for name, samples in errors.items():
        sd = float(np.std(np.ravel(samples)))
        assert sd == pytest.approx(SENSORS[name], rel=0.08), (name, sd)


@pytest.mark.parametrize("bits", [6, 10])
def test_the_motor_speeds_are_read_at_their_bit_depth(bits):
    """The thrust and torque the estimator gets are the nominal mixer of the speeds rounded to 2^bits - 1
    steps over [0, max]; at the other depth they are not."""
    fleet, calls = _fly(5, sensors={"motor_speed_bits": bits})
    top, mixer = fleet.vehicle.max_rotor_speed, Mixer(fleet.vehicle)
    for (thrusts, torques, *_), speeds, _ in calls:
        for depth, match in ((bits, True), (8 if bits != 8 else 12, False)):
            step = top / (2**depth - 1)
            expected = mixer.wrench(np.clip(np.round(speeds[0] / step), 0, 2**depth - 1) * step)
            same = np.allclose(thrusts[0], expected[0], rtol=1e-12) and np.allclose(
                torques[0], expected[1:], atol=1e-12
            )
            assert same == match, (depth, thrusts[0], expected)


def test_the_rotors_spread_has_the_sd_it_is_given():
    """``kf_spread``: over 128 vehicles (512 rotors) the true coefficients' relative errors scatter with
    the sd set (within 15 %, about 2.4 sd of the estimate), about a mean of 0."""
    env = gym.make_vec(FAN_TRACKING, num_envs=128, vectorization_mode="vector_entry_point", kf_spread=0.07)
    try:
        env.reset(seed=0)
        fleet = env.unwrapped.fleet
        nominal = Mixer(fleet.vehicle).allocation[0]
        errors = fleet.rotors.allocations[:, 0, :] / nominal - 1.0
    finally:
        env.close()
    assert np.std(errors) == pytest.approx(0.07, rel=0.15)
    assert abs(np.mean(errors)) < 4.0 * 0.07 / np.sqrt(errors.size)

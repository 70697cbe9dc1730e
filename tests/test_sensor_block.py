"""The observation's ``sensors`` block (``sensor_history``): the estimators' own inputs of the last K physics
steps, checked against what the filter was handed each step (issue 47, item 1)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from quad_wrench_env.rotations import rotation_matrices
from tests.conftest import FAN_TRACKING, EstimatorSpy

K = 6  # more than one control period of physics steps (four)


def _expected(call, fleet) -> np.ndarray:
    """The reading a physics step's spied call stands for, computed here: the speeds rounded to the
    motor sensor's levels over the top speed, the measured position, the first two columns of the
    measured attitude's rotation matrix, and the measured velocity and body rates where made."""
    (_, _, position, quaternion, velocity, rates), speeds, _ = call
    sensor = fleet.motor_sensor
    reported = np.clip(np.round(speeds / sensor.step), 0.0, sensor.levels) * sensor.step
    r = rotation_matrices(quaternion)
    parts = [reported / (sensor.levels * sensor.step), position, r[:, :, 0], r[:, :, 1]]
    if velocity is not None:
        parts += [velocity, rates]
    return np.concatenate(parts, axis=1)


@pytest.mark.parametrize("state_estimator", [False, True])
@pytest.mark.parametrize("count", [1, 3])
def test_the_sensor_block_holds_what_the_estimators_were_handed(count, state_estimator):
    """Every value of ``sensors_1`` ... ``sensors_K`` after each control step is the reading of the
    physics step k - 1 steps before the last (newest first), for the single env and every vehicle of
    a vector env, and zeros before the episode's first physics step."""
    settings = {"sensor_history": K, "sensors": {"state_estimator": state_estimator}}
    if count == 1:
        env = gym.make(FAN_TRACKING, **settings)
    else:
        env = gym.make_vec(FAN_TRACKING, num_envs=count, vectorization_mode="vector_entry_point", **settings)
    try:
        observations, _ = env.reset(seed=4)
        base = env.unwrapped
        layout, fleet = base.obs_layout, base.fleet
        observations = np.atleast_2d(observations)
        assert layout["sensors"].stop - layout["sensors"].start == K * (19 if state_estimator else 13)
        np.testing.assert_array_equal(observations[:, layout["sensors"]], 0.0)
        fleet.estimator = spy = EstimatorSpy(fleet.estimator, fleet)
        rng = np.random.default_rng(0)
        for step in range(5):
            action = rng.uniform(-0.5, 0.5, (count, 4)).astype(np.float32)
            observations = np.atleast_2d(env.step(action[0] if count == 1 else action)[0])
            readings = [_expected(call, fleet) for call in spy.calls]
            for k in range(1, K + 1):
                block = observations[:, layout[f"sensors_{k}"]]
                if k <= len(readings):
                    np.testing.assert_array_equal(
                        block, readings[-k].astype(np.float32), err_msg=f"{step}, {k}"
                    )
                else:
                    np.testing.assert_array_equal(block, 0.0)
    finally:
        env.close()


def test_an_autoreset_starts_the_sensor_block_at_zeros():
    """A vehicle whose episode ends restarts in the same step with an empty block; the others keep
    theirs."""
    env = gym.make_vec(
        FAN_TRACKING,
        num_envs=2,
        vectorization_mode="vector_entry_point",
        sensor_history=K,
        episode_seconds=0.1,
    )
    try:
        env.reset(seed=0)
        block = env.unwrapped.obs_layout["sensors"]
        for _ in range(5):
            observations, _, terminated, truncated, _ = env.step(np.zeros((2, 4), dtype=np.float32))
            if np.any(terminated | truncated):
                break
        ended = terminated | truncated
        assert ended.all()  # both reach the 0.1 s limit together
        np.testing.assert_array_equal(observations[:, block], 0.0)
        observations = env.step(np.zeros((2, 4), dtype=np.float32))[0]
        assert np.all(observations[:, block][:, :13] != 0.0)  # the new episode's first readings
    finally:
        env.close()


@pytest.mark.parametrize("value", [-1, 2.5, True, "8"])
def test_a_bad_sensor_history_is_refused_by_name(value):
    with pytest.raises(ValueError, match="sensor_history="):
        gym.make(FAN_TRACKING, sensor_history=value)

"""Named estimator settings (``estimator_params="paper"``): McKinnon & Schoellig's (2016) UKF rises
in about 1 s to a 53 g mass hung under a rotor (their Fig. 4, Sec. V), the observer takes Yüksel et
al.'s (2014) gains as they are, and a name an estimator does not have is refused."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from quad_wrench_env.agents import make_agent
from quad_wrench_env.estimators import estimator_settings
from tests.conftest import FAN_TRACKING

ATTACH = 7.0  # s: the mass is hung under rotor 1 (its hub, l = 0.129 m on ardrone2) at this time


def _rise_times(estimator_params) -> np.ndarray:
    """10-90 % rise times (s) of the UKF's f_z, tau_x and tau_y after the mass is hung, the vehicle
    holding its position in still air (the paper's experiment), from the recorded ``info``."""
    env = gym.make(
        FAN_TRACKING,
        estimator="ukf",
        estimator_params=estimator_params,
        fan={"enabled": False},
        payload={"mass": 0.053, "point": [0.129, 0.129, 0.0], "attach_time": ATTACH},
        episode_seconds=12.0,
    )
    policy = make_agent("hold", k_xy=1.0, k_z=1.0, k_yaw=1.0)
    try:
        observation, info = env.reset(seed=1, options={"offset_y": 0.0, "fan_motion": "static"})
        policy.reset(env)
        times, estimates, truths = [], [], []
        done = False
        while not done:
            observation, _, terminated, truncated, info = env.step(policy.act(observation))
            times.append(info["time"])
            estimates.append(info["wrench_est"][2:5])
            truths.append(info["wrench_true"][2:5])
            done = terminated or truncated
    finally:
        env.close()
    t, est, true = np.array(times), np.array(estimates), np.array(truths)
    before = est[(t > ATTACH - 2.0) & (t < ATTACH)].mean(axis=0)
    step = true[-1] - true[0]
    after = t[t >= ATTACH]
    rises = []
    for axis in range(3):
        progress = (est[t >= ATTACH, axis] - before[axis]) / step[axis]
        rises.append(after[np.argmax(progress >= 0.9)] - after[np.argmax(progress >= 0.1)])
    return np.array(rises)


def test_the_papers_ukf_rises_in_about_a_second_and_the_default_faster():
    paper, default = _rise_times("paper"), _rise_times({})
    assert np.all((paper >= 0.7) & (paper <= 1.5)), paper  # "a rise time of about 1 second"
    assert np.all(default < 0.5), default


def test_the_observers_paper_gains_and_unknown_names():
    assert estimator_settings("observer", "paper") == {"c_force": 5.0, "c_torque": 0.5}
    gym.make(FAN_TRACKING, vehicle="yuksel1kg", estimator="observer", estimator_params="paper").close()
    no_sets = r"estimator_params='paper': the ekf has no settings of that name; allowed: \[\]"
    with pytest.raises(ValueError, match=no_sets):
        gym.make(FAN_TRACKING, estimator="ekf", estimator_params="paper")
    with pytest.raises(ValueError, match=r"estimator_params='fast'.*allowed: \['paper'\]"):
        gym.make(FAN_TRACKING, estimator="ukf", estimator_params="fast")

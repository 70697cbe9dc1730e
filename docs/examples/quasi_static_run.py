"""Fly the quasi-static estimator in the fan (run from this folder: python quasi_static_run.py)."""

import gymnasium as gym
import numpy as np
import pytest
import quasi_static  # noqa: F401  (registers "quasi_static")

env = gym.make(
    "quad_wrench_env:QuadWrench/FanTracking-v1",
    estimator="quasi_static",
    estimator_params={"time_constant": 0.2},
)
layout = env.unwrapped.obs_layout
obs, info = env.reset(seed=0, options={"fan_motion": "static", "offset_y": 0.5})
for _ in range(100):
    obs, reward, terminated, truncated, info = env.step(np.zeros(4, dtype=np.float32))
env.close()
np.testing.assert_allclose(info["wrench_true"][:3], [0.592, 0.101, 0.084], atol=0.002)  # the fan's push
np.testing.assert_allclose(obs[layout["force"]], [0.618, -0.017, -0.007], atol=0.002)  # its estimate

with pytest.raises(ValueError, match=r"unknown config key\(s\) 'estimator_params.tau'"):
    gym.make("QuadWrench/FanTracking-v1", estimator="quasi_static", estimator_params={"tau": 1})

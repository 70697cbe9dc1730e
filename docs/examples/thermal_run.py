"""Fly through the thermal (run from this folder: python thermal_run.py)."""

import gymnasium as gym
import numpy as np
import thermal  # noqa: F401  (registers "thermal" before the env reads its config)

env = gym.make(
    "quad_wrench_env:QuadWrench/FanTracking-v1",
    estimator="oracle",
    fan={"enabled": False},
    wind=[{"model": "thermal", "center": [2.3, 0.0], "speed": 2.0}],
)
_, at_start = env.reset(seed=0, options={"fan_motion": "static", "offset_y": 0.0})
for _ in range(50):
    obs, reward, terminated, truncated, info = env.step(np.zeros(4, dtype=np.float32))
env.close()
np.testing.assert_allclose(info["wind_velocity"], [0.0, 0.0, 2.0], atol=0.01)  # on the column's axis
np.testing.assert_allclose(info["wrench_true"][2], 0.0618, atol=0.0005)  # N: the drag of the rising air
np.testing.assert_allclose(at_start["wrench_true"][2], info["wrench_true"][2], rtol=0.01)  # and at the start

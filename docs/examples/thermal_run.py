"""Fly through the thermal (run from this folder: python thermal_run.py)."""

import gymnasium as gym
import numpy as np
import thermal  # noqa: F401  (registers "thermal" before the env reads its config)

lift = []
for backend in ("numpy", "numba"):
    env = gym.make(
        "quad_wrench_env:QuadWrench/FanTracking-v1",
        estimator="oracle",
        backend=backend,
        fan={"enabled": False},
        wind=[{"model": "thermal", "center": [2.3, 0.0], "speed": 2.0}],
    )
    env.reset(seed=0, options={"fan_motion": "static", "offset_y": 0.0})
    for _ in range(50):
        obs, reward, terminated, truncated, info = env.step(np.zeros(4, dtype=np.float32))
    np.testing.assert_allclose(info["wind_velocity"], [0.0, 0.0, 2.0], atol=0.01)  # on the column's axis
    assert (env.unwrapped.fleet.compiled is not None) == (backend == "numba")  # its kernel is composed in
    env.close()
    lift.append(info["wrench_true"][2])
np.testing.assert_allclose(lift, 0.0618, atol=0.0005)  # N: the drag of the rising air
np.testing.assert_allclose(lift[0], lift[1], rtol=1e-9)  # the same on both backends

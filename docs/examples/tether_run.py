"""Fly on the tether (run from this folder: python tether_run.py)."""

import gymnasium as gym
import numpy as np
import tether  # noqa: F401  (registers "tether" before the env reads its config)

# Hover 0.9 m above the anchor on a 0.8 m line, the attachment 5 cm below the centre: stretched by
# 0.05 m, it pulls down with k·0.05 = 1 N at rest. Then climb: the line pulls k·stretch + c·(the
# attachment's speed along it), read from the vehicle's position and velocity.
k, c = 20.0, 2.0
env = gym.make(
    "quad_wrench_env:QuadWrench/FanTracking-v1",
    estimator="oracle",
    fan={"enabled": False},
    loads=[{"load": "tether", "anchor": [2.3, 0.0, 0.1], "length": 0.8, "stiffness": k, "damping": c}],
)
_, info = env.reset(seed=0, options={"fan_motion": "static", "offset_y": 0.0})
np.testing.assert_allclose(info["position"], [2.3, 0.0, 1.0], atol=1e-9)
np.testing.assert_allclose(info["wrench_true"][:3], [0.0, 0.0, -1.0], atol=1e-6)  # at rest: k·stretch
for _ in range(50):
    _, _, terminated, _, info = env.step(np.array((0.0, 0.0, 1.0, 0.0), dtype=np.float32))  # climb
    assert not terminated
env.close()
stretch = info["position"][2] - 0.05 - 0.1 - 0.8  # the line is nearly vertical
expected = k * stretch + c * info["velocity"][2]
assert info["velocity"][2] > 0.02  # still climbing: damping adds to the pull
np.testing.assert_allclose(-info["wrench_true"][2], expected, atol=0.01)

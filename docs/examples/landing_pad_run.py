"""Land on the pad (run from this folder: python landing_pad_run.py)."""

import gymnasium as gym
import landing_pad  # noqa: F401  (registers "pad" before the env reads its config)
import numpy as np

descend = np.array((0.0, 0.0, -1.0, 0.0), dtype=np.float32)  # -0.5 m/s
for touch in ("report", "crash"):
    env = gym.make(
        "quad_wrench_env:QuadWrench/FanTracking-v1",
        fan={"enabled": False},
        scene=[{"kind": "pad", "center": [2.3, 0.0], "touch": touch}],
    )
    _, info = env.reset(seed=0, options={"fan_motion": "static", "offset_y": 0.0})  # 0.7 m above the pad
    touched, terminated = None, False
    for step in range(150):  # 3 s
        _, _, terminated, _, info = env.step(descend)
        if terminated:
            break
        if touched is None and "contacts" in info and info["contacts"][0]:
            touched = step
    env.close()
    if touch == "report":  # it lands, the touch is reported and flying on is up to the task
        assert touched is not None and 60 < touched < 100 and not terminated
        assert info["contacts"].tolist() == [True] and 0.3 < info["position"][2] < 0.4
    else:  # the same touch ends the episode as a crash, and nothing is reported
        assert terminated and info["termination_reason"] == "crash" and "contacts" not in info

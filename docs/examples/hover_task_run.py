"""Fly the new task (run from this folder: python hover_task_run.py)."""

import gymnasium as gym
import numpy as np
from hover_task import HoldPoint  # registers its env id, entry points and metrics

from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents.evaluate import evaluate

env = gym.make(HoldPoint.env_id, estimator="oracle")
obs, info = env.reset(seed=0, options={"push": 0.4})
assert env.observation_space.shape == (28,)
assert env.unwrapped.obs_layout["reference_position"] == slice(25, 28)
for _ in range(25):
    obs, reward, terminated, truncated, info = env.step(np.zeros(4, dtype=np.float32))
# the 0.4 N push along body y at 0.1 m ahead: tau_z = 0.04 N·m
np.testing.assert_allclose(info["wrench_true"], [0, 0.398, 0.039, 0, -0.004, 0.040], atol=0.001)
assert set(info["reward_terms"]) == {"distance", "crash"}
env.close()

venv = gym.make_vec(HoldPoint.env_id, num_envs=4, vectorization_mode="vector_entry_point")
assert venv.reset(seed=0)[0].shape == (4, 28)
venv.close()

scores = evaluate(make_agent("hold"), HoldPoint.env_id, seeds=[0, 1], episode_seconds=5.0).per_seed
assert scores[0]["max_distance"] < 0.01 and scores[0]["terminated_early"] == 0.0  # the task's own metric
pushed = evaluate(make_agent("hold"), HoldPoint.env_id, seeds=[0], options={"push": 3.0}, episode_seconds=5.0)
assert pushed.episodes[0].termination_reason == "drifted"

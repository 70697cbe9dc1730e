"""Fly the new task (run from this folder: python hover_task_run.py)."""

import gymnasium as gym
import numpy as np
from hover_task import HoldPoint, HoldPointConfig  # registers its env id, entry points and metrics

from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents.evaluate import evaluate
from quad_wrench_env.engine.fleet_view import FleetView
from quad_wrench_env.engine.world import RigidBodyState
from quad_wrench_env.vehicle import make_vehicle

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

# the task's step on a view built by hand (no PyBullet): two vehicles, 0.3 m and 0.6 m from the target
task = HoldPoint(HoldPointConfig(), make_vehicle("hummingbird"), count=2)
positions = np.array(((2.3, 0.0, 1.0), (2.0, 0.6, 1.0)))
level, still = np.tile(np.eye(3), (2, 1, 1)), np.zeros((2, 3))
state = RigidBodyState(positions, np.tile((1.0, 0.0, 0.0, 0.0), (2, 1)), still, still, level, still)
view = FleetView(np.full(2, 1.0), state, still, np.zeros((2, 6)), np.zeros((2, 13)), np.zeros((2, 6)))
record = task.step(view, np.zeros((2, 4)), ended=np.array((False, False)))
np.testing.assert_allclose(record.reward_terms["distance"], [-0.3, -0.6])
assert record.codes.tolist() == [0, 1] and record.reward_terms["crash"].tolist() == [0.0, -10.0]  # drifted

"""quad-wrench-env: wrench-aware quadrotor control in PyBullet, as Gymnasium environments.

Importing the package registers every task's env id (:data:`quad_wrench_env.tasks.TASKS`, the tasks of
:mod:`quad_wrench_env.registry`) under the ``QuadWrench`` namespace, so
``gym.make("quad_wrench_env:QuadWrench/FanTracking-v1")`` works without a prior import, and each id has
a batched form: ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``.
"""

from quad_wrench_env.registry import env_entry_points
from quad_wrench_env.tasks import TASKS

ENV_IDS = {env_id: env_entry_points(task) for env_id, task in TASKS.items()}
"""The package's env ids -> (entry point of the single env, entry point of the vector env)."""

__version__ = "0.1.0"
__all__ = ["ENV_IDS"]

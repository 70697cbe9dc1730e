"""quad-wrench-env: wrench-aware quadrotor control in PyBullet, as Gymnasium environments.

Importing the package registers every task's env id (:data:`quad_wrench_env.tasks.TASKS`) under the
``QuadWrench`` namespace, so ``gym.make("quad_wrench_env:QuadWrench/FanTracking-v1")`` works without a
prior import, and each id has a batched form:
``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``.
"""

from gymnasium.envs.registration import register, registry

from quad_wrench_env.tasks import TASKS

ENV_IDS = {
    task.env_id: (
        f"quad_wrench_env.envs.registry:{task.__name__}Env",
        f"quad_wrench_env.envs.registry:{task.__name__}VectorEnv",
    )
    for task in TASKS
}
"""Env id -> (entry point of the single env, entry point of the vector env), generated from the tasks
(:func:`quad_wrench_env.envs.registry.entry_points` makes the same strings)."""

for _env_id, (_entry_point, _vector_entry_point) in ENV_IDS.items():
    if _env_id not in registry:
        register(id=_env_id, entry_point=_entry_point, vector_entry_point=_vector_entry_point)

__version__ = "0.1.0"
__all__ = ["ENV_IDS"]

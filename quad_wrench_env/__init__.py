"""quad-wrench-env: wrench-aware quadrotor control in PyBullet, as Gymnasium environments.

Importing the package registers the environments under the ``QuadWrench`` namespace, so
``gym.make("quad_wrench_env:QuadWrench/FanTracking-v0")`` works without a prior import.
"""

from gymnasium.envs.registration import register, registry

ENV_IDS = {"QuadWrench/FanTracking-v0": "quad_wrench_env.envs.fan_tracking:FanTrackingEnv"}

for _env_id, _entry_point in ENV_IDS.items():
    if _env_id not in registry:
        register(id=_env_id, entry_point=_entry_point)

__version__ = "0.1.0"
__all__ = ["ENV_IDS"]

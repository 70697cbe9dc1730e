"""The tasks, one file each (its config dataclass and task class); :data:`TASKS` is the one list the
env ids, both entry points and the harness's metrics are generated from."""

from quad_wrench_env.tasks.disturbance_rejection import DisturbanceRejection
from quad_wrench_env.tasks.fan_tracking import FanTracking
from quad_wrench_env.tasks.force_exertion import ForceExertion

TASKS = (FanTracking, DisturbanceRejection, ForceExertion)
"""Every task; its ``env_id`` is registered on ``import quad_wrench_env``."""

__all__ = ["TASKS", "DisturbanceRejection", "FanTracking", "ForceExertion"]

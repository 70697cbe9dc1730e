"""The tasks, one file each (its config dataclass and task class, registered as ``@register("task")``
under its env id); :data:`TASKS` is the registry's view of them, from which the env ids, both entry
points and the harness's metrics come."""

from quad_wrench_env.registry import registered
from quad_wrench_env.tasks.disturbance_rejection import DisturbanceRejection
from quad_wrench_env.tasks.fan_tracking import FanTracking
from quad_wrench_env.tasks.force_exertion import ForceExertion

TASKS = registered("task")
"""Env id -> task class, every registered task (a live, read-only view); each id is registered with
Gymnasium when its task is."""

__all__ = ["TASKS", "DisturbanceRejection", "FanTracking", "ForceExertion"]

"""Gymnasium environments of quad-wrench-env."""

from quad_wrench_env.envs.base import QuadWrenchEnv
from quad_wrench_env.envs.fan_tracking import FanTrackingEnv

__all__ = ["FanTrackingEnv", "QuadWrenchEnv"]

"""What makes an environment a task: its wind fields, where episodes start, its reward and info.

A task serves N vehicles (a :class:`~quad_wrench_env.envs.fleet.Fleet`) at once, so the single env
(N = 1) and the vector env use the same task code.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar, Protocol

import numpy as np

from quad_wrench_env.disturbances.base import WindField
from quad_wrench_env.envs.config import EnvConfig
from quad_wrench_env.envs.fleet import Fleet
from quad_wrench_env.vehicle import VehicleParams


class Task(Protocol):
    """The task of one env id; built as ``Task(config, vehicle, count)``."""

    config_class: ClassVar[type[EnvConfig]]
    reset_options: ClassVar[tuple[str, ...]]

    def __init__(self, cfg: Any, vehicle: VehicleParams, count: int) -> None: ...

    def wind_fields(self) -> list[WindField]:
        """The task's wind fields (each with a copy per vehicle)."""

    def reset_vehicle(
        self, index: int, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> tuple[np.ndarray, float]:
        """Prepare vehicle ``index``'s new episode; return its initial position (3,) and yaw."""

    def reward_terms(self, fleet: Fleet, actions: np.ndarray, ended: np.ndarray) -> dict[str, np.ndarray]:
        """(N,) reward terms, summed into the reward, after a step with (N, 4) ``actions``;
        ``ended`` (N,) marks the episodes that ended early on this step."""

    def info(self, fleet: Fleet) -> dict[str, np.ndarray]:
        """The task's own ``info`` entries, each with a leading vehicle axis."""

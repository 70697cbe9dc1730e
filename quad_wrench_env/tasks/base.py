"""What makes an environment a task (Isaac Lab's term-based task configs, Gymnasium's env tables).

A task serves N vehicles (a :class:`~quad_wrench_env.engine.fleet.Fleet`) at once, so the single env
(N = 1) and the vector env run the same task code. It names its env id and config; brings its own
components (wind fields, point loads, rotor modifiers, scene parts) besides those every env takes
from its config; says where each episode starts; returns its reward terms, its own terminations,
observation blocks and ``info``; and scores an episode's trace for the evaluation harness. The env
classes and their registration are generated from the task (:mod:`quad_wrench_env.envs.registry`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

from quad_wrench_env.engine.components import Components
from quad_wrench_env.engine.config import EnvConfig
from quad_wrench_env.vehicle import VehicleParams

if TYPE_CHECKING:
    from quad_wrench_env.engine.fleet import Fleet


class Task(Protocol):
    """The task of one env id; built as ``Task(config, vehicle, count)``."""

    env_id: ClassVar[str]
    """``"QuadWrench/<Name>-v<k>"``."""
    config_class: ClassVar[type[EnvConfig]]
    reset_options: ClassVar[tuple[str, ...]]
    observation_blocks: tuple[tuple[str, int, float], ...]
    """The task's own observation blocks ``(name, width, bound)``, after the engine's (may be empty;
    a task may choose them by its config)."""
    termination_reasons: ClassVar[tuple[str, ...]]
    """The task's own reasons to end an episode (may be empty), after the engine's."""
    trace_keys: ClassVar[tuple[str, ...]]
    """``info`` keys of its own that the evaluation harness records at every step."""
    metric_columns: ClassVar[tuple[tuple[str, str, str], ...]]
    """``(metric, title with units, format)`` of the comparison tables: which of :meth:`metrics` a
    table shows, in order (may be empty: the harness's own scores only)."""

    def __init__(self, cfg: Any, vehicle: VehicleParams, count: int) -> None: ...

    def components(self) -> Components:
        """The task's own components (each with a copy per vehicle)."""

    def reset_vehicle(
        self, index: int, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> tuple[np.ndarray, float]:
        """Prepare vehicle ``index``'s new episode; return its initial position (3,) and yaw."""

    def reward_terms(self, fleet: Fleet, actions: np.ndarray, ended: np.ndarray) -> dict[str, np.ndarray]:
        """(N,) reward terms, summed into the reward, after a step with (N, 4) ``actions``;
        ``ended`` (N,) marks the episodes that ended early on this step."""

    def terminations(self, fleet: Fleet) -> np.ndarray | None:
        """(N,) codes: 0, or k for the task's ``termination_reasons[k - 1]``; None when it has none."""

    def observe(self, fleet: Fleet, out: np.ndarray) -> None:
        """Fill the task's observation blocks, ``out`` (N, their width)."""

    def info(self, fleet: Fleet) -> dict[str, np.ndarray]:
        """The task's own ``info`` entries, each with a leading vehicle axis."""

    @staticmethod
    def metrics(trace: Mapping[str, np.ndarray]) -> dict[str, float]:
        """The task's scores of one episode's trace (arrays over steps, keyed as in ``info``)."""

    def render_marks(self, fleet: Fleet, vehicle: int) -> dict[str, Any]:
        """What a frame of ``vehicle`` shows besides the scene (:mod:`quad_wrench_env.envs.render`): any
        of ``label`` (a line of the panel), ``reference`` ((3,) where the vehicle should be now) and
        ``path`` ((K, 3) the reference path over the episode)."""


class TaskDefaults:
    """What a task without its own terminations, observation blocks or metrics inherits."""

    observation_blocks: ClassVar[tuple[tuple[str, int, float], ...]] = ()
    termination_reasons: ClassVar[tuple[str, ...]] = ()
    trace_keys: ClassVar[tuple[str, ...]] = ()
    metric_columns: ClassVar[tuple[tuple[str, str, str], ...]] = ()

    def terminations(self, fleet: Fleet) -> np.ndarray | None:
        return None

    def observe(self, fleet: Fleet, out: np.ndarray) -> None:
        """No blocks of its own."""

    @staticmethod
    def metrics(trace: Mapping[str, np.ndarray]) -> dict[str, float]:
        return {}

    def render_marks(self, fleet: Fleet, vehicle: int) -> dict[str, Any]:
        """Nothing but the scene."""
        return {}

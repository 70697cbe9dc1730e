"""What makes an environment a task (Isaac Lab's term-based task configs, Gymnasium's env tables).

A task serves N vehicles (a :class:`~quad_wrench_env.engine.fleet.Fleet`) at once, so the single env
(N = 1) and the vector env run the same task code. It names its env id and config; brings its own
components (wind fields, point loads, rotor modifiers, scene parts) besides those every env takes
from its config; says where each episode starts; answers each control step with one call,
:meth:`Task.step`, returning a :class:`TaskStep` (its reward terms and its own terminations); fills its
observation blocks and ``info`` from the fleet's state (reads, at a reset as after a step); and scores
an episode's trace for the evaluation harness. The env
classes and their registration are generated from the task (:mod:`quad_wrench_env.envs.env_classes`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

from quad_wrench_env.engine.components import Components
from quad_wrench_env.engine.env_config import EnvConfig
from quad_wrench_env.vehicle import VehicleParams

if TYPE_CHECKING:
    from quad_wrench_env.engine.fleet import Fleet


@dataclass(frozen=True)
class TaskStep:
    """What one control step of N vehicles means to a task."""

    reward_terms: dict[str, np.ndarray]
    """(N,) each term, summed into the reward (reported in ``info["reward_terms"]``)."""
    codes: np.ndarray | None = None
    """(N,) the task's own terminations: 0, or k for ``termination_reasons[k - 1]``; None when it
    has none. The engine's (crash, flip, out of the arena) come first."""


def ended_early(ended: np.ndarray, codes: np.ndarray) -> np.ndarray:
    """(N,) bool: the engine ended the episode (``ended``) or the task's own ``codes`` do."""
    return ended | (codes > 0)


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

    def read_start(self, fleet: Fleet, index: np.ndarray) -> None:
        """Read the start of the vehicles ``index`` once the fleet has placed them (after
        :meth:`reset_vehicle`: trimmed, so tilted against a steady push), e.g. a shaping potential."""

    def step(self, fleet: Fleet, actions: np.ndarray, ended: np.ndarray) -> TaskStep:
        """What the step just flown with (N, 4) ``actions`` means: the reward terms and the task's own
        terminations, in one call (the only one that may change the task's state, e.g. a potential);
        ``ended`` (N,) marks the episodes the engine ended on this step. The terms see the task's own
        terminations too (:func:`ended_early`)."""

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
    """What a task without its own termination reasons, observation blocks or metrics inherits."""

    observation_blocks: ClassVar[tuple[tuple[str, int, float], ...]] = ()
    termination_reasons: ClassVar[tuple[str, ...]] = ()
    trace_keys: ClassVar[tuple[str, ...]] = ()
    metric_columns: ClassVar[tuple[tuple[str, str, str], ...]] = ()

    def read_start(self, fleet: Fleet, index: np.ndarray) -> None:
        """Nothing to read (:meth:`Task.read_start`)."""

    def observe(self, fleet: Fleet, out: np.ndarray) -> None:
        """No blocks of its own."""

    @staticmethod
    def metrics(trace: Mapping[str, np.ndarray]) -> dict[str, float]:
        return {}

    def render_marks(self, fleet: Fleet, vehicle: int) -> dict[str, Any]:
        """Nothing but the scene."""
        return {}

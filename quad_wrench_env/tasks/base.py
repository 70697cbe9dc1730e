"""What makes an environment a task (Isaac Lab's term-based task configs, Gymnasium's env tables,
MuJoCo Playground's one record per step).

A task serves N vehicles (a :class:`~quad_wrench_env.engine.fleet.Fleet`) at once, so the single env
(N = 1) and the vector env run the same task code. It names its env id and config; brings its own
components (wind fields, point loads, rotor modifiers, scene parts) besides those every env takes
from its config; says where each episode starts; answers each control step and each start with one
call on a read-only :class:`~quad_wrench_env.engine.fleet_view.FleetView` (:meth:`Task.step`,
:meth:`Task.start`), returning one :class:`TaskRecord`: its reward terms, its own terminations, its
observation blocks and its ``info`` entries; and scores an episode's trace for the evaluation harness.
The env classes and their registration are generated from the task
(:mod:`quad_wrench_env.envs.env_classes`).
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any, ClassVar, NamedTuple, Protocol

import numpy as np

from quad_wrench_env.engine.components import Components
from quad_wrench_env.engine.env_config import EnvConfig
from quad_wrench_env.engine.fleet_view import FleetView
from quad_wrench_env.vehicle import VehicleParams


class TaskRecord(NamedTuple):
    """What a control step (or a start) of N vehicles means to a task, every array with a leading
    vehicle axis and new on each call."""

    reward_terms: dict[str, np.ndarray]
    """(N,) each term, summed into the reward (reported in ``info["reward_terms"]``); empty at a start."""
    codes: np.ndarray | None = None
    """(N,) the task's own terminations: 0, or k for ``termination_reasons[k - 1]``; None when it
    has none (and at a start). The engine's (crash, flip, out of the arena) come first."""
    blocks: np.ndarray | None = None
    """(N, width) the task's observation blocks in order (:attr:`Task.observation_blocks`); None when
    it has none."""
    info: Mapping[str, np.ndarray] = MappingProxyType({})
    """The task's own ``info`` entries."""


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

    def start(self, view: FleetView, index: np.ndarray) -> TaskRecord:
        """Read the start of the vehicles ``index`` once the fleet has placed them (after
        :meth:`reset_vehicle`: trimmed, so tilted against a steady push), e.g. a shaping potential,
        and return every vehicle's observation blocks and ``info`` now (no reward terms)."""

    def step(self, view: FleetView, actions: np.ndarray, ended: np.ndarray) -> TaskRecord:
        """What the step just flown with (N, 4) ``actions`` means, in one call (the only one besides
        :meth:`start` that may change the task's state, e.g. a potential): the reward terms, the
        task's own terminations, its observation blocks and ``info``; ``ended`` (N,) marks the
        episodes the engine ended on this step. The terms see the task's own terminations too
        (:func:`ended_early`)."""

    @staticmethod
    def metrics(trace: Mapping[str, np.ndarray]) -> dict[str, float]:
        """The task's scores of one episode's trace (arrays over steps, keyed as in ``info``)."""

    def render_marks(self, vehicle: int) -> dict[str, Any]:
        """What a frame of ``vehicle`` shows besides the scene (:mod:`quad_wrench_env.envs.render`): any
        of ``label`` (a line of the panel), ``reference`` ((3,) where the vehicle should be now) and
        ``path`` ((K, 3) the reference path over the episode)."""


class TaskDefaults:
    """What a task without its own termination reasons, observation blocks or metrics inherits."""

    observation_blocks: ClassVar[tuple[tuple[str, int, float], ...]] = ()
    termination_reasons: ClassVar[tuple[str, ...]] = ()
    trace_keys: ClassVar[tuple[str, ...]] = ()
    metric_columns: ClassVar[tuple[tuple[str, str, str], ...]] = ()

    @staticmethod
    def metrics(trace: Mapping[str, np.ndarray]) -> dict[str, float]:
        return {}

    def render_marks(self, vehicle: int) -> dict[str, Any]:
        """Nothing but the scene."""
        return {}

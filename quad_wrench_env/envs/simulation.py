"""N vehicles of one task, stepped by one call: what the single env (N = 1) and the vector env adapt.

``Simulation(task_class, cfg, count).step(actions)`` flies every vehicle one control step (the
fleet's physics, :class:`~quad_wrench_env.engine.fleet.Fleet`), asks the task what the step means
in one call on a read-only view of the fleet (:meth:`~quad_wrench_env.tasks.base.Task.step`: its reward
terms, its own terminations, told which episodes the engine ended, its observation blocks and ``info``),
then assembles the observations. It returns a
:class:`StepResult` of arrays over vehicles, before any restart; the envs turn it into Gymnasium's
tuples (a single env's Python floats, the vector env's arrays and autoresets). Restarts go through
:meth:`Simulation.start` (one vehicle, its generator and task options) and :meth:`Simulation.restarted`
(the vehicles just started, read back at once).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np
from numba import literal_unroll

from quad_wrench_env.control.residual import ResidualActions
from quad_wrench_env.engine.actions import RESIDUAL
from quad_wrench_env.engine.components import assemble
from quad_wrench_env.engine.fleet import ENGINE_TERMINATIONS, Fleet
from quad_wrench_env.engine.fleet_view import FleetView
from quad_wrench_env.engine.kernels import MOTION_READING_WIDTH, SENSOR_READING_WIDTH
from quad_wrench_env.engine.observation import ObservationHistory, ObservationLayout
from quad_wrench_env.numerics import njit
from quad_wrench_env.tasks.base import Task
from quad_wrench_env.vehicle import make_vehicle


def termination_reasons(task: Task) -> tuple[str, ...]:
    """Every code's reason: ``""`` (goes on), the engine's, then the task's own."""
    return ("", *ENGINE_TERMINATIONS, *task.termination_reasons)


@njit
def step_outcome(engine, own, steps, max_steps, terms, rewards, codes, terminated, truncated):
    """Each vehicle's outcome of a control step into the last four (N,) arrays: ``steps`` counted one up,
    the reward ``((0 + t₀) + t₁) + …`` of the task's ``terms`` in order, the termination code (the
    ``engine``'s first, then the task's ``own`` (empty: none) after the engine's), ``terminated``
    (a code) and ``truncated`` (no code, ``steps`` reached ``max_steps``)."""
    for n in range(engine.shape[0]):
        steps[n] += 1
        total = 0.0
        for term in literal_unroll(terms):
            total += term[n]
        rewards[n] = total
        code = engine[n]
        if code == 0 and own.shape[0] > 0 and own[n] > 0:
            code = _FIRST_OWN + own[n]
        codes[n] = code
        terminated[n] = code > 0
        truncated[n] = code == 0 and steps[n] >= max_steps


_FIRST_OWN = len(ENGINE_TERMINATIONS)
"""A task's own code ``k`` is ``_FIRST_OWN + k`` among :func:`termination_reasons`."""
_NO_CODES = np.zeros(0, dtype=np.int64)
"""A task's own codes when it has none."""


def observations(
    fleet: Fleet, view: FleetView, blocks: np.ndarray | None, last_actions: np.ndarray
) -> np.ndarray:
    """(N, width) float32 observations: the engine's blocks, then the task's ``blocks``."""
    out = fleet.observations(view, last_actions)
    if blocks is not None:
        out[:, fleet.layout.task_columns] = blocks
    if fleet.layout.sensor_history:
        out[:, fleet.layout.slices["sensors"]] = fleet.sensor_frames.reshape(fleet.count, -1)
    return out


def build_fleet(task_class: type[Task], cfg: Any, count: int, gui: bool = False) -> tuple[Task, Fleet]:
    """The task for ``count`` vehicles and the fleet that flies it: its components and the config's."""
    vehicle = make_vehicle(cfg.vehicle, **cfg.vehicle_params)
    task = task_class(cfg, vehicle, count)
    components = assemble(cfg, vehicle, count, task.components())
    width = SENSOR_READING_WIDTH + (MOTION_READING_WIDTH if cfg.sensors.state_estimator else 0)
    layout = ObservationLayout(
        task.observation_blocks, cfg.history, cfg.sensor_history, width, privileged=cfg.privileged
    )
    return task, Fleet(cfg, vehicle, count, components, layout, gui=gui)


def info_entries(
    fleet: Fleet, view: FleetView, task_info: Mapping[str, np.ndarray], vehicle: int | None = None
) -> dict[str, Any]:
    """The info of every vehicle, each entry with a leading vehicle axis (the keys of
    ``docs/architecture.md``, "Contracts"; ``docs/tasks.md`` has them in full): the engine's from
    ``view``, then the task's ``task_info``; with ``vehicle``, that vehicle's entries alone (Python
    floats for its scalars). Copies, never views of the fleet's state. ``wrench_cov`` is the
    estimator's 6x6 covariance of ``wrench_est``, in its frame (the world's; zeros for the oracle); an
    estimator that carries none (NaN: the observer) leaves it out, as a NaN in ``info`` would break
    Gymnasium's determinism check. ``contacts`` (K,) bool per vehicle: which of the scene's K parts
    with ``touch="report"`` it touches, only in a scene that has such parts."""
    state = view.state
    covariance = fleet.estimator.wrench_covariances()
    entries = {
        "time": view.time,
        "position": state.position,
        "velocity": state.velocity,
        "wrench_true": view.wrench_true,
        "wrench_est": view.wrench_est,
    }
    if not math.isnan(covariance[0, 0, 0]):
        entries["wrench_cov"] = covariance
    entries["wind_velocity"] = fleet.wind_velocity
    if fleet.world.reported_parts:
        entries["contacts"] = fleet.world.touches()
    entries.update(task_info)
    statuses = fleet.estimator.statuses()
    if vehicle is None:
        info = {key: value.copy() for key, value in entries.items()}
        info["estimator_status"] = np.array(statuses, dtype=object)
    else:
        info = {k: v[vehicle].copy() if v.ndim > 1 else v.item(vehicle) for k, v in entries.items()}
        info["estimator_status"] = statuses[vehicle]
    return info


class StepResult(NamedTuple):
    """One control step of N vehicles, before any restart."""

    observations: np.ndarray
    """(N, width) float32, every vehicle's observation after the step."""
    reward_terms: dict[str, np.ndarray]
    """Each term (N,), as the task returned them."""
    rewards: np.ndarray
    """(N,) the terms' sum."""
    codes: np.ndarray
    """(N,) termination codes into :attr:`Simulation.termination_reasons` (0: goes on)."""
    terminated: np.ndarray
    """(N,) the episode ended early (``codes > 0``)."""
    truncated: np.ndarray
    """(N,) the episode reached ``episode_seconds`` without ending early."""
    task_info: Mapping[str, np.ndarray]
    """The task's own ``info`` entries after the step (new arrays: a restart leaves them)."""


class Simulation:
    """The fleet of ``count`` vehicles flying ``task_class`` per ``cfg``, with each vehicle's step
    count, last action and observation (see the module docstring)."""

    def __init__(self, task_class: type[Task], cfg: Any, count: int, gui: bool = False) -> None:
        self.task, self.fleet = build_fleet(task_class, cfg, count, gui=gui)
        self.count = count
        self.termination_reasons = termination_reasons(self.task)
        """Every code's reason: ``""`` (goes on), the engine's, then the task's own."""
        self.max_steps = round(cfg.episode_seconds * cfg.policy_hz)
        self.steps = np.zeros(count, dtype=int)
        """Control steps flown in each vehicle's episode."""
        self.last_actions = np.zeros((count, 4))
        self.history = ObservationHistory(self.fleet.layout, count)
        self.observations = np.zeros((count, self.fleet.layout.size), dtype=np.float32)
        """Each vehicle's last observation (what a restart of others leaves it)."""
        self.view: FleetView | None = None
        """The fleet as the task last read it (after the last step or start)."""
        self.task_info: Mapping[str, np.ndarray] = {}
        """The task's ``info`` entries of :attr:`view`."""
        self.residual: ResidualActions | None = None
        """``action_type: residual``: every vehicle's base controller under the policy's correction."""
        if cfg.action_type == RESIDUAL:
            fleet, tilt = self.fleet, math.radians(cfg.action_limits.max_tilt_deg)
            self.residual = ResidualActions(
                cfg.residual,
                count,
                fleet.layout.slices,
                fleet.vehicle,
                1.0 / cfg.policy_hz,
                fleet.action_scaling,
                tilt,
            )
        self._wrench_hidden = not cfg.observe_wrench
        """The policy's observation leaves the wrench out: the residual's base reads it all the same."""

    def start(self, index: int, rng: np.random.Generator, options: Mapping[str, Any]) -> None:
        """Begin vehicle ``index``'s next episode with the (checked) task ``options``, its draws from
        ``rng``; call :meth:`restarted` once every restarted vehicle has been started."""
        position, yaw = self.task.reset_vehicle(index, rng, options)
        self.fleet.reset_vehicle(index, rng, position, yaw)
        self.steps[index] = 0
        self.last_actions[index] = 0.0
        if self.residual is not None:
            self.residual.restart(index)

    def restarted(self, index: np.ndarray) -> np.ndarray:
        """Read the vehicles ``index`` back after their :meth:`start` (the others keep their bits) and
        return every vehicle's observation, new for them, their history begun afresh."""
        self.fleet.refresh(index)
        self.view = self.fleet.view()
        record = self.task.start(self.view, index)
        self.task_info = record.info
        self.history.restart(index)
        return self._observe(record.blocks, index)

    def step(self, actions: np.ndarray) -> StepResult:
        """Fly every vehicle one control step with its (N, 4) action, already clipped to [-1, 1] (with
        the ``residual`` action type, the correction to its base controller's action)."""
        fleet = self.fleet
        fleet.step(
            actions if self.residual is None else self.residual.flown(self._base_observations(), actions)
        )
        self.last_actions = actions
        self.view = view = fleet.view()
        engine = fleet.terminations()
        record = self.task.step(view, actions, engine > 0)
        self.task_info = record.info
        terms = record.reward_terms
        rewards, codes = np.empty(self.count), np.empty(self.count, dtype=np.int64)
        terminated, truncated = np.empty(self.count, dtype=bool), np.empty(self.count, dtype=bool)
        own = _NO_CODES if record.codes is None else record.codes
        summed = tuple(terms.values()) or (np.zeros(self.count),)  # a task without terms: rewards of 0
        step_outcome(engine, own, self.steps, self.max_steps, summed, rewards, codes, terminated, truncated)
        observations = self._observe(record.blocks, slice(None))
        return StepResult(observations, terms, rewards, codes, terminated, truncated, record.info)

    def _base_observations(self) -> np.ndarray:
        """What the residual's base controllers read: the observations, with the estimated wrench of
        :attr:`view` even where the policy's observation leaves it out (the base runs on board, beside
        the estimator; ``observe_wrench`` is the policy's)."""
        if not self._wrench_hidden:
            return self.observations
        observed = self.observations.copy()
        observed[:, self.fleet.layout.slices["wrench"]] = self.view.wrench_est
        return observed

    def _observe(self, blocks: np.ndarray | None, index: np.ndarray | slice) -> np.ndarray:
        """Every vehicle's observation: new for the vehicles ``index`` (their history filled and
        recorded), as it was for the others."""
        fresh = observations(self.fleet, self.view, blocks, self.last_actions)
        self.history.record(fresh, index)
        if isinstance(index, slice):  # every vehicle
            self.observations = fresh
        else:
            self.observations[index] = fresh[index]
        return self.observations.copy()

    def info(self, vehicle: int | None = None) -> dict[str, Any]:
        """Every vehicle's ``info`` entries (arrays over vehicles) after the last step or start, or
        ``vehicle``'s alone."""
        return info_entries(self.fleet, self.view, self.task_info, vehicle)

    def close(self) -> None:
        """Release the PyBullet client; safe to call more than once."""
        self.fleet.close()

"""The single-vehicle environment every QuadWrench task shares.

One control step (ARCHITECTURE.md): the normalised action is clipped to [-1, 1] and turned into
motor-speed commands by the autopilot at every physics step; the true rotors, the wind fields and
the body's drag give forces at body points whose resultant PyBullet integrates; the estimator is
stepped at the physics (motion-capture) rate; the observation holds the estimator's belief, never the
truth, which goes to ``info``. The physics is a :class:`~quad_wrench_env.envs.fleet.Fleet` of one
vehicle, the same code the vector env runs for N.

Subclasses name their task (:class:`~quad_wrench_env.envs.task.Task`): the wind fields, the initial
pose, the reward and the task's ``info``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import EzPickle

from quad_wrench_env.config import build, merged, section
from quad_wrench_env.envs.config import EnvConfig
from quad_wrench_env.envs.fleet import OBSERVATION_FIELDS, TERMINATION_REASONS, Fleet
from quad_wrench_env.envs.task import Task
from quad_wrench_env.vehicle import GRAVITY, VehicleParams, make_vehicle

_ENDED = (np.zeros(1, dtype=bool), np.ones(1, dtype=bool))
"""A single env's ``ended`` for its task's reward terms: not ended, ended (read, never written)."""


def observation_layout() -> dict[str, slice]:
    layout, start = {}, 0
    for name, size in OBSERVATION_FIELDS:
        layout[name] = slice(start, start + size)
        start += size
    layout["wrench"] = slice(layout["force"].start, layout["torque"].stop)
    return layout


def observation_space(vehicle: VehicleParams) -> spaces.Box:
    """Finite bounds far outside anything a flight that has not ended can reach (SI units)."""
    weight = vehicle.mass * GRAVITY
    bound = {
        "position": 100.0,
        "velocity": 100.0,
        "attitude": 1.0,
        "body_rates": 100.0,
        "force": 100.0 * weight,
        "torque": 100.0 * weight * vehicle.hull_radius,
        "last_action": 1.0,
    }
    high = np.concatenate([np.full(n, bound[name]) for name, n in OBSERVATION_FIELDS]).astype(np.float32)
    return spaces.Box(-high, high, dtype=np.float32)


def build_config(
    config_class: type[EnvConfig], config: str | Path | Mapping[str, Any] | None, overrides: dict
) -> Any:
    """The env's config from a YAML path or mapping (its ``env`` section) and keyword overrides."""
    return build(config_class, merged(section(config, "env"), overrides))


def check_options(options: Mapping[str, Any] | None, allowed: tuple[str, ...]) -> dict[str, Any]:
    options = dict(options or {})
    unknown = sorted(set(options) - set(allowed))
    if unknown:
        raise ValueError(f"unknown reset option(s) {unknown}; allowed: {list(allowed)}")
    return options


def clip_actions(action: Any, shape: tuple[int, ...]) -> np.ndarray:
    """Actions as a new float array of ``shape`` (a flat action of the right size is accepted for
    one vehicle), clipped to [-1, 1]; other shapes and non-finite values are refused."""
    a = np.array(action, dtype=float)
    if len(shape) == 1 and a.ndim != 1:
        a = a.reshape(-1)
    if a.shape != shape:
        raise ValueError(f"action {action!r} must have shape {shape}, got {a.shape}")
    values = a.ravel().tolist()
    if not math.isfinite(sum(values)) and not all(map(math.isfinite, values)):  # the sum: NaN, ±inf
        raise ValueError(f"action {action!r} contains NaN or infinity; allowed: finite values in [-1, 1]")
    if max(values) > 1.0 or min(values) < -1.0:
        np.clip(a, -1.0, 1.0, out=a)
    return a


def info_entries(fleet: Fleet, task: Task, vehicle: int | None = None) -> dict[str, Any]:
    """The info of every vehicle, each entry with a leading vehicle axis (ARCHITECTURE.md keys); with
    ``vehicle``, that vehicle's entries alone (Python floats for its scalars). Copies, never views
    of the fleet's state."""
    state = fleet.state
    entries = {
        "time": fleet.time, "position": state.position, "velocity": state.velocity,
        "wrench_true": fleet.wrench_true, "wrench_est": fleet.estimates()[1], **task.info(fleet),
    }  # fmt: skip
    statuses = fleet.estimator.statuses()
    if vehicle is None:
        info = {key: value.copy() for key, value in entries.items()}
        info["estimator_status"] = np.array(statuses, dtype=object)
    else:
        info = {k: v[vehicle].copy() if v.ndim > 1 else v.item(vehicle) for k, v in entries.items()}
        info["estimator_status"] = statuses[vehicle]
    return info


class QuadWrenchEnv(gym.Env, EzPickle):
    """Base class; see the task subclasses for the observation/action/reward tables."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"], "render_fps": 50}
    task_class: ClassVar[type[Task]]

    def __init__(
        self,
        config: str | Path | Mapping[str, Any] | None = None,
        render_mode: str | None = None,
        **overrides: Any,
    ) -> None:
        EzPickle.__init__(self, config=config, render_mode=render_mode, **overrides)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"unknown render_mode {render_mode!r}; allowed: {self.metadata['render_modes']}")
        self.render_mode = render_mode
        self.cfg = build_config(self.task_class.config_class, config, overrides)
        cfg = self.cfg
        self.vehicle = make_vehicle(cfg.vehicle, **cfg.vehicle_params)
        self.task = self.task_class(cfg, self.vehicle, 1)
        self.reset_options = self.task_class.reset_options
        self.max_steps = round(cfg.episode_seconds * cfg.policy_hz)
        self.metadata = {**self.metadata, "render_fps": cfg.policy_hz}
        self.obs_layout = observation_layout()
        self.observation_space = observation_space(self.vehicle)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32)
        self.fleet = Fleet(cfg, self.vehicle, 1, self.task.wind_fields(), gui=render_mode == "human")
        self.dt = self.fleet.dt
        self._renderer = None
        self._started = False
        self._last_action = np.zeros((1, 4))
        self._steps = 0

    @property
    def time(self) -> float:
        return float(self.fleet.time[0])

    @property
    def world(self):
        return self.fleet.world

    @property
    def estimator(self):
        return self.fleet.estimator

    # -- Gymnasium API -----------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        options = check_options(options, self.reset_options)
        rng = self.np_random
        position, yaw = self.task.reset_vehicle(0, rng, options)
        self.fleet.reset_vehicle(0, rng, position, yaw)
        self.fleet.refresh(np.zeros(1, dtype=int))
        self._started = True
        self._steps = 0
        self._last_action = np.zeros((1, 4))
        if self._renderer is not None:
            self._renderer.build()
        return self.fleet.observations(self._last_action)[0], self._info()

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if not self._started:
            raise RuntimeError("call reset() before step()")
        a = clip_actions(action, (4,)).reshape(1, 4)
        fleet = self.fleet
        fleet.step(a)
        self._steps += 1
        self._last_action = a
        code = fleet.terminations().item(0)
        terminated = code > 0
        terms = {k: v.item(0) for k, v in self.task.reward_terms(fleet, a, _ENDED[terminated]).items()}
        truncated = not terminated and self._steps >= self.max_steps
        info = self._info()
        info["reward_terms"] = terms
        if terminated:
            info["termination_reason"] = TERMINATION_REASONS[code]
        if self.render_mode == "human":
            self.render()
        return fleet.observations(a)[0], float(sum(terms.values())), terminated, truncated, info

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode= to gym.make")
            return None
        if self._renderer is None:
            from quad_wrench_env.envs.render import SceneRenderer

            self._renderer = SceneRenderer(self)
            if self._started:
                self._renderer.build()
        return self._renderer.render()

    def close(self) -> None:
        """Release the PyBullet client; safe to call more than once."""
        self.fleet.close()
        self._renderer = None
        super().close()

    def _info(self) -> dict[str, Any]:
        return info_entries(self.fleet, self.task, vehicle=0)

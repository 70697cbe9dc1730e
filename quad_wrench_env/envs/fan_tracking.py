"""``QuadWrench/FanTracking-v0``: stay in the centre of a fan's jet while the fan moves along y.

The task of paper 000 Sec. V (Figs. 6-7). A fan at the origin blows along +x; the vehicle starts
``start_distance`` (2.3 m) in front of it at the fan's height, facing it (yaw = π), up to
``max_initial_offset`` (0.8 m) to one side of the jet axis. The fan then moves along y (config
``fan.motion`` or the ``fan_motion`` reset option). The agent never observes the fan: only the
estimated external force and torque tell it where the jet is.

Observation (float32, 23; ``env.unwrapped.obs_layout`` names the slices; SI units, world frame unless
noted; everything is the estimator's belief, and with ``estimator="oracle"`` it is the truth):

=====  ==============  ====================================================================
index  name            meaning
=====  ==============  ====================================================================
0-2    position        estimated position (m)
3-5    velocity        estimated velocity (m/s)
6-9    quaternion      estimated attitude ``[w, x, y, z]``, body -> world, ``w >= 0``
10-12  body_rates      estimated angular velocity in the body frame (rad/s)
13-15  force           estimated external force (N)
16-18  torque          estimated external torque (N·m)
19-22  last_action     the previous (clipped) action
=====  ==============  ====================================================================

Action: ``Box(-1, 1, (4,), float32)``, meaning set by ``action_type`` (see
:mod:`quad_wrench_env.envs.actions`); default ``velocity``: ``(v_x, v_y, v_z, yaw rate)``.

Reward per step (terms in ``info["reward_terms"]``):
``tracking = exp(-(d/axis_scale)²)`` with ``d`` the distance in the y-z plane from the jet axis at
the vehicle's x (the retarded axis, PHYSICS.md), ``effort = -effort_weight·mean(a²)``, and
``crash = -crash_penalty`` on the step that ends the episode early (0 otherwise).

Episode end: terminated on ``crash`` (below ``crash_height`` or touching the ground), ``flip`` (tilt
above ``flip_tilt_deg``) or ``out_of_arena``, named in ``info["termination_reason"]``; truncated
after ``episode_seconds`` (30 s at 50 Hz: 1500 steps; physics at 200 Hz).

Reset options: ``offset_y`` (initial offset from the jet axis, m), ``fan_motion`` (a motion name,
or a mapping ``{"name": ..., **parameters}``).

``info``: ``time``, ``position``, ``velocity``, ``wrench_true``, ``wrench_est``, ``fan_position``
(the fan itself, now), ``jet_axis_y`` (the axis at the vehicle's x), ``axis_error`` (signed
``y - jet_axis_y``), ``reward_terms``, ``termination_reason``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from quad_wrench_env.disturbances.base import WindField
from quad_wrench_env.disturbances.fan import FanConfig, FanJet
from quad_wrench_env.envs.base import QuadWrenchEnv
from quad_wrench_env.envs.config import EnvConfig
from quad_wrench_env.envs.fleet import Fleet
from quad_wrench_env.envs.vector import QuadWrenchVectorEnv
from quad_wrench_env.kernels import resolve_backend
from quad_wrench_env.kernels.physics import fan_tracking_terms
from quad_wrench_env.vehicle import VehicleParams


@dataclass
class FanTrackingReward:
    axis_scale: float = 0.3
    effort_weight: float = 0.01
    crash_penalty: float = 10.0


@dataclass
class FanTrackingConfig(EnvConfig):
    fan: FanConfig = field(default_factory=FanConfig)
    start_distance: float = 2.3
    max_initial_offset: float = 0.8
    reward: FanTrackingReward = field(default_factory=FanTrackingReward)


class FanTracking:
    """The task (see the module docstring) for N vehicles, each in front of a fan of its own."""

    config_class: ClassVar[type[EnvConfig]] = FanTrackingConfig
    reset_options: ClassVar[tuple[str, ...]] = ("offset_y", "fan_motion")

    def __init__(self, cfg: FanTrackingConfig, vehicle: VehicleParams, count: int) -> None:
        arena = cfg.arena
        if not (arena.x_min < cfg.start_distance < arena.x_max):
            raise ValueError(
                f"start_distance={cfg.start_distance} must lie inside the arena "
                f"({arena.x_min}, {arena.x_max})"
            )
        self.cfg = cfg
        self.vehicle = vehicle
        self.fan = FanJet(cfg.fan, count, cfg.backend)
        self._default_motion = self.fan.motion(0)
        self._compiled = resolve_backend(cfg.backend) == "numba"
        r = cfg.reward
        jet = self.fan.kernel_parameters()
        self._terms_constants = np.array(
            (jet[1], jet[2], cfg.fan.height, r.axis_scale, r.effort_weight, r.crash_penalty)
        )
        """What ``fan_tracking_terms`` reads (see its docstring)."""
        self._cache: tuple[int, np.ndarray] = (-1, np.zeros((count, 8)))

    def wind_fields(self) -> list[WindField]:
        return [self.fan] if self.cfg.fan.enabled else []

    def _motion(self, option: Any):
        if option is None:
            return self._default_motion
        if isinstance(option, Mapping):
            params = dict(option)
            if "name" not in params:
                raise ValueError(f"fan_motion={option!r} needs a 'name' key")
            return self.cfg.fan.make_motion(params.pop("name"), **params)
        if isinstance(option, str):
            return self.cfg.fan.make_motion(option)
        raise ValueError(f"fan_motion={option!r} must be a motion name or a mapping")

    def reset_vehicle(
        self, index: int, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> tuple[np.ndarray, float]:
        cfg = self.cfg
        motion = self._motion(options.get("fan_motion"))
        fan_y0 = float(motion.y(np.asarray(0.0)))
        if "offset_y" in options:
            offset = float(options["offset_y"])
        else:
            offset = float(rng.uniform(-cfg.max_initial_offset, cfg.max_initial_offset))
        start_y = fan_y0 + offset
        margin = cfg.arena.y_half_width - self.vehicle.hull_radius
        if not (math.isfinite(offset) and abs(start_y) < margin):
            raise ValueError(
                f"offset_y={options.get('offset_y', offset)!r} puts the vehicle at y={start_y:.3g} m; "
                f"allowed: |fan y0 + offset_y| < {margin:.3g} m (arena half-width minus hull radius)"
            )
        self.fan.set_motion(index, motion)
        return np.array((cfg.start_distance, start_y, cfg.fan.height)), math.pi

    def _numbers(self, fleet: Fleet, actions: np.ndarray | None, ended: np.ndarray | None) -> np.ndarray:
        """(N, 8): reward terms tracking, effort, crash; axis error, jet axis y, fan position (3).
        Computed once per state of the fleet (the reward's call, with the step's actions, comes first)."""
        revision, numbers = self._cache
        if revision == fleet.revision:
            return numbers
        count = fleet.count
        actions = np.zeros((count, 4)) if actions is None else actions
        ended = np.zeros(count, dtype=bool) if ended is None else ended
        r, fan = self.cfg.reward, self.fan
        position, time = fleet.state.position, fleet.time
        numbers = np.empty((count, 8))
        if self._compiled:
            fan_tracking_terms(
                position, time, actions, ended, fan.motion_tables, self._terms_constants, numbers
            )
        else:
            dy = position[:, 1] - fan.axis_y(position[:, 0], time)
            dz = position[:, 2] - self.cfg.fan.height
            numbers[:, 0] = np.exp(-(dy * dy + dz * dz) / r.axis_scale**2)
            numbers[:, 1] = (-r.effort_weight / actions.shape[1]) * (actions * actions).sum(axis=1)
            numbers[:, 2] = -r.crash_penalty * ended
            numbers[:, 3] = dy
            numbers[:, 4] = position[:, 1] - dy
            numbers[:, 5] = 0.0
            numbers[:, 6] = fan.fan_y(time)
            numbers[:, 7] = self.cfg.fan.height
        self._cache = (fleet.revision, numbers)
        return numbers

    def reward_terms(self, fleet: Fleet, actions: np.ndarray, ended: np.ndarray) -> dict[str, np.ndarray]:
        numbers = self._numbers(fleet, actions, ended)
        return {"tracking": numbers[:, 0], "effort": numbers[:, 1], "crash": numbers[:, 2]}

    def info(self, fleet: Fleet) -> dict[str, np.ndarray]:
        numbers = self._numbers(fleet, None, None)
        return {"fan_position": numbers[:, 5:8], "jet_axis_y": numbers[:, 4], "axis_error": numbers[:, 3]}


class FanTrackingEnv(QuadWrenchEnv):
    """Track the centre of a moving fan's jet from the estimated wrench (see the module docstring)."""

    task_class: ClassVar[type] = FanTracking
    cfg: FanTrackingConfig

    @property
    def fan(self) -> FanJet:
        return self.task.fan


class FanTrackingVectorEnv(QuadWrenchVectorEnv):
    """N vehicles tracking their fans' jets, flown together (``gym.make_vec``'s vector entry point)."""

    env_class: ClassVar[type[QuadWrenchEnv]] = FanTrackingEnv

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
``crash = -crash_penalty`` on the step that ends the episode early.

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
from quad_wrench_env.world import RigidBodyState


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


class FanTrackingEnv(QuadWrenchEnv):
    """Track the centre of a moving fan's jet from the estimated wrench (see the module docstring)."""

    config_class: ClassVar[type[EnvConfig]] = FanTrackingConfig
    reset_options: ClassVar[tuple[str, ...]] = ("offset_y", "fan_motion")
    cfg: FanTrackingConfig

    def _make_wind_fields(self) -> list[WindField]:
        cfg = self.cfg
        arena = cfg.arena
        if not (arena.x_min < cfg.start_distance < arena.x_max):
            raise ValueError(
                f"start_distance={cfg.start_distance} must lie inside the arena "
                f"({arena.x_min}, {arena.x_max})"
            )
        self.fan = FanJet(cfg.fan)
        return [self.fan] if cfg.fan.enabled else []

    def _reset_task(self, options: Mapping[str, Any]) -> tuple[np.ndarray, float]:
        cfg = self.cfg
        motion_option = options.get("fan_motion", cfg.fan.motion)
        if isinstance(motion_option, Mapping):
            params = dict(motion_option)
            if "name" not in params:
                raise ValueError(f"fan_motion={motion_option!r} needs a 'name' key")
            motion = cfg.fan.make_motion(params.pop("name"), **params)
        elif isinstance(motion_option, str):
            motion = cfg.fan.make_motion(motion_option)
        else:
            raise ValueError(f"fan_motion={motion_option!r} must be a motion name or a mapping")
        fan_y0 = float(motion.y(np.asarray(0.0)))
        if "offset_y" in options:
            offset = float(options["offset_y"])
        else:
            offset = float(self.np_random.uniform(-cfg.max_initial_offset, cfg.max_initial_offset))
        start_y = fan_y0 + offset
        margin = cfg.arena.y_half_width - self.vehicle.hull_radius
        if not (math.isfinite(offset) and abs(start_y) < margin):
            raise ValueError(
                f"offset_y={options.get('offset_y', offset)!r} puts the vehicle at y={start_y:.3g} m; "
                f"allowed: |fan y0 + offset_y| < {margin:.3g} m (arena half-width minus hull radius)"
            )
        self.fan.motion = motion
        return np.array((cfg.start_distance, start_y, cfg.fan.height)), math.pi

    def _axis_error(self, state: RigidBodyState) -> tuple[float, float]:
        x, y, z = state.position
        axis_y = float(self.fan.axis_y(x, self.time))
        return y - axis_y, z - self.cfg.fan.height

    def _task_reward(
        self, state: RigidBodyState, action: np.ndarray, termination: str | None
    ) -> dict[str, float]:
        r = self.cfg.reward
        dy, dz = self._axis_error(state)
        terms = {
            "tracking": math.exp(-(dy * dy + dz * dz) / r.axis_scale**2),
            "effort": -r.effort_weight * float(np.mean(action * action)),
        }
        if termination is not None:
            terms["crash"] = -r.crash_penalty
        return terms

    def _task_info(self, state: RigidBodyState) -> dict[str, Any]:
        axis_error = self._axis_error(state)[0]
        return {
            "fan_position": np.array((0.0, self.fan.fan_y(self.time), self.cfg.fan.height)),
            "jet_axis_y": float(state.position[1] - axis_error),
            "axis_error": axis_error,
        }

"""The common core of every QuadWrench environment.

One control step (ARCHITECTURE.md): the normalised action is clipped to [-1, 1] and turned into
motor-speed commands by the autopilot at every physics step; the true rotors, the wind fields and
the body's drag give forces at body points whose resultant PyBullet integrates; the estimator is
stepped at the physics (motion-capture) rate; the observation holds the estimator's belief, never the
truth, which goes to ``info``.

Subclasses define the task: the wind fields, the initial pose, the reward and the task's ``info``.
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

from quad_wrench_env.autopilot import Autopilot, attitude_from_thrust
from quad_wrench_env.config import build, merged, section
from quad_wrench_env.disturbances.base import WindField, resultant
from quad_wrench_env.disturbances.drag import QuadraticDrag
from quad_wrench_env.disturbances.payload import Payload
from quad_wrench_env.disturbances.wrench_profile import WrenchProfile
from quad_wrench_env.envs.actions import ActionMap
from quad_wrench_env.envs.config import EnvConfig
from quad_wrench_env.estimators import StateEstimate, TruthFed, WrenchEstimate, make_estimator
from quad_wrench_env.rotations import cross, quat_from_matrix
from quad_wrench_env.rotors import Rotors
from quad_wrench_env.sensors import MotionCapture, MotorSpeedSensor
from quad_wrench_env.vehicle import GRAVITY, make_vehicle
from quad_wrench_env.world import RigidBodyState, World

OBSERVATION_FIELDS: tuple[tuple[str, int], ...] = (
    ("position", 3),
    ("velocity", 3),
    ("quaternion", 4),
    ("body_rates", 3),
    ("force", 3),
    ("torque", 3),
    ("last_action", 4),
)
"""Observation blocks in order: the estimator's state and wrench, and the previous action."""


def _layout() -> dict[str, slice]:
    layout, start = {}, 0
    for name, size in OBSERVATION_FIELDS:
        layout[name] = slice(start, start + size)
        start += size
    layout["wrench"] = slice(layout["force"].start, layout["torque"].stop)
    return layout


class QuadWrenchEnv(gym.Env, EzPickle):
    """Base class; see the task subclasses for the observation/action/reward tables."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"], "render_fps": 50}
    config_class: ClassVar[type[EnvConfig]] = EnvConfig
    reset_options: ClassVar[tuple[str, ...]] = ()

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
        self.cfg = build(self.config_class, merged(section(config, "env"), overrides))
        cfg = self.cfg
        self.vehicle = make_vehicle(cfg.vehicle, **cfg.vehicle_params)
        self.dt = 1.0 / cfg.physics_hz
        self.substeps = cfg.physics_hz // cfg.policy_hz
        self.max_steps = round(cfg.episode_seconds * cfg.policy_hz)
        self.metadata = {**self.metadata, "render_fps": cfg.policy_hz}
        # The estimator's measurement noise defaults to the motion capture's; a noise-free capture
        # leaves the estimator's own default (a filter needs G > 0 to stay well conditioned).
        sensors = cfg.sensors
        measured = [("position", sensors.position_noise), ("attitude", sensors.attitude_noise)]
        if sensors.state_estimator:
            measured += [("velocity", sensors.velocity_noise), ("body_rate", sensors.body_rate_noise)]
        measurement_noise = {key: value for key, value in measured if value > 0}
        self.estimator = make_estimator(
            cfg.estimator, self.vehicle, self.dt, **{**measurement_noise, **cfg.estimator_params}
        )
        self._truth_fed = isinstance(self.estimator, TruthFed)
        self.mocap = MotionCapture(cfg.sensors)
        self.motor_sensor = MotorSpeedSensor(self.vehicle.max_rotor_speed, cfg.sensors.motor_speed_bits)
        self.point_loads = [Payload(cfg.payload), WrenchProfile(cfg.external_wrench)]
        self.autopilot = Autopilot(self.vehicle, self.dt)
        self.actions = ActionMap(cfg.action_type, self.autopilot, cfg.action_limits)
        self.rotors = Rotors(self.vehicle, self.dt)
        self.drag_points = self.vehicle.drag_points()
        self.drag = QuadraticDrag(self.vehicle.drag_area, len(self.drag_points))
        self.wind_fields: list[WindField] = self._make_wind_fields()
        self.obs_layout = _layout()
        self.observation_space = self._observation_space()
        self.action_space = spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32)
        self._flip_cos = math.cos(math.radians(cfg.flip_tilt_deg))
        self.world = World(self.vehicle, self.dt, gui=render_mode == "human")
        self._renderer = None
        self._state: RigidBodyState | None = None
        self._last_action = np.zeros(4)
        self._wrench_true = np.zeros(6)
        self._steps = 0
        self.time = 0.0

    def _observation_space(self) -> spaces.Box:
        """Finite bounds far outside anything a flight that has not ended can reach (SI units)."""
        weight = self.vehicle.mass * GRAVITY
        bound = {
            "position": 100.0,
            "velocity": 100.0,
            "quaternion": 1.0,
            "body_rates": 100.0,
            "force": 100.0 * weight,
            "torque": 100.0 * weight * self.vehicle.hull_radius,
            "last_action": 1.0,
        }
        high = np.concatenate([np.full(n, bound[name]) for name, n in OBSERVATION_FIELDS]).astype(np.float32)
        return spaces.Box(-high, high, dtype=np.float32)

    # -- task hooks ------------------------------------------------------------------------------
    def _make_wind_fields(self) -> list[WindField]:
        return []

    def _reset_task(self, options: Mapping[str, Any]) -> tuple[np.ndarray, float]:
        """Prepare the task for a new episode; return the initial position and yaw."""
        raise NotImplementedError

    def _task_reward(
        self, state: RigidBodyState, action: np.ndarray, termination: str | None
    ) -> dict[str, float]:
        """Reward terms (summed into the reward) for the state after a step."""
        raise NotImplementedError

    def _task_info(self, state: RigidBodyState) -> dict[str, Any]:
        return {}

    # -- Gymnasium API -----------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = sorted(set(options) - set(self.reset_options))
        if unknown:
            raise ValueError(f"unknown reset option(s) {unknown}; allowed: {list(self.reset_options)}")
        rng = self.np_random
        position, yaw = self._reset_task(options)
        self.rotors.reset(rng, self.cfg.kf_spread, self.vehicle.hover_rotor_speed)
        for wind in self.wind_fields:
            wind.reset(rng)
        self.time = 0.0
        rotation, rotor_speeds = self._equilibrium(position, yaw)
        quaternion = quat_from_matrix(rotation)
        self.world.build(position, quaternion)
        self.rotors.speeds = rotor_speeds
        self.autopilot.reset(yaw)
        self.autopilot.trim(rotation, rotor_speeds)
        self.estimator.reset(position, quaternion)
        self.mocap.reset(rng, position, quaternion)
        self._steps = 0
        self._last_action = np.zeros(4)
        self._state = self.world.state()
        self._wrench_true = np.concatenate(self._external_loads(self._state))
        self._feed_truth(self._state)
        if self._renderer is not None:
            self._renderer.build()
        estimate = self.estimator.estimate
        return self._observation(estimate), self._info(self._state, estimate)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self._state is None:
            raise RuntimeError("call reset() before step()")
        a = np.asarray(action, dtype=float).reshape(-1)
        if a.shape != (4,):
            raise ValueError(f"action {action!r} must have shape (4,), got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"action {action!r} contains NaN or infinity; allowed: finite values in [-1, 1]")
        a = np.clip(a, -1.0, 1.0)
        state = self._state
        for _ in range(self.substeps):
            state = self._physics_step(a, state)
        self._state = state
        self._steps += 1
        self._last_action = a

        reason = self._termination_reason(state)
        terms = self._task_reward(state, a, reason)
        reward = float(sum(terms.values()))
        truncated = reason is None and self._steps >= self.max_steps
        estimate = self.estimator.estimate
        info = self._info(state, estimate)
        info["reward_terms"] = terms
        if reason is not None:
            info["termination_reason"] = reason
        if self.render_mode == "human":
            self.render()
        return self._observation(estimate), reward, reason is not None, bool(truncated), info

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode= to gym.make")
            return None
        if self._renderer is None:
            from quad_wrench_env.envs.render import SceneRenderer

            self._renderer = SceneRenderer(self)
            if self._state is not None:
                self._renderer.build()
        return self._renderer.render()

    def close(self) -> None:
        """Release the PyBullet client; safe to call more than once."""
        self.world.close()
        self._renderer = None
        super().close()

    # -- one physics step --------------------------------------------------------------------------
    def _physics_step(self, action: np.ndarray, state: RigidBodyState) -> RigidBodyState:
        command = self.actions.motor_command(action, state)
        self.rotors.step(command)
        thrust_torque = self.rotors.thrust_and_torque()
        rotation = state.rotation
        external_force, external_torque = self._external_loads(state)
        force = rotation[:, 2] * thrust_torque[0] + external_force
        torque = rotation @ thrust_torque[1:] + external_torque
        self.world.step(force, torque, state.position)
        self.time += self.dt
        after = self.world.state()
        for wind in self.wind_fields:
            wind.advance(self.dt, after.position)
        self._wrench_true = np.concatenate((external_force, external_torque))
        self._feed_truth(after)
        nominal = self.autopilot.mixer.wrench(self.motor_sensor.measure(self.rotors.speeds))
        position, quaternion = self.mocap.measure(after.position, after.quaternion)
        velocity, body_rates = self.mocap.measure_motion(after.velocity, after.body_rates)
        self.estimator.step(nominal[0], nominal[1:], position, quaternion, velocity, body_rates)
        return after

    def _equilibrium(self, position: np.ndarray, yaw: float) -> tuple[np.ndarray, np.ndarray]:
        """Attitude and true rotor speeds that hold the vehicle at rest at ``position`` with heading
        ``yaw`` against gravity and the mean external loads there (the vehicle starts trimmed, as
        one that has been hovering in place; turbulence is left out of the balance)."""
        v = self.vehicle
        weight = v.mass * GRAVITY * np.array((0.0, 0.0, 1.0))
        rotation = attitude_from_thrust(weight, yaw)
        for _ in range(3):  # the loads depend weakly on the tilt and the rotor speeds: fixed point
            rest = RigidBodyState(position, quat_from_matrix(rotation), np.zeros(3), np.zeros(3), rotation)
            force, torque = self._external_loads(rest, mean=True)
            thrust_vector = weight - force
            rotation = attitude_from_thrust(thrust_vector, yaw)
            body_torque = -rotation.T @ torque
            squared = self.rotors.mixer.squared_speeds(
                np.array((np.linalg.norm(thrust_vector), *body_torque))
            )
            self.rotors.speeds = np.sqrt(np.clip(squared, v.min_rotor_speed**2, v.max_rotor_speed**2))
        return rotation, self.rotors.speeds

    def _external_loads(self, state: RigidBodyState, mean: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Everything but gravity, thrust and rotor reaction torque, about the centre of mass (world)."""
        offsets = self.drag_points @ state.rotation.T
        point_velocity = state.velocity + cross(state.angular_velocity, offsets)
        wind = np.zeros_like(offsets)
        for field in self.wind_fields:
            wind += field.velocity_at(state.position + offsets, self.time, mean)
        relative_air = wind - point_velocity
        forces = self.drag.forces(relative_air)
        forces[:4] += self.rotors.drag_forces(-relative_air[:4], state.rotation[:, 2])
        for load in self.point_loads:
            extra = load.point_load(self.time, state.rotation)
            if extra is not None:
                offsets = np.vstack((offsets, extra[0]))
                forces = np.vstack((forces, extra[1]))
        return resultant(offsets, forces)

    def _feed_truth(self, state: RigidBodyState) -> None:
        if self._truth_fed:
            self.estimator.observe_truth(
                StateEstimate(state.position, state.velocity, state.quaternion, state.body_rates),
                self._wrench_true[:3],
                self._wrench_true[3:],
            )

    # -- observation, info, termination ------------------------------------------------------------
    def _observation(self, wrench: WrenchEstimate) -> np.ndarray:
        est = self.estimator.state
        quaternion = est.quaternion if est.quaternion[0] >= 0 else -est.quaternion
        return np.concatenate(
            (
                est.position,
                est.velocity,
                quaternion,
                est.body_rates,
                wrench.force,
                wrench.torque,
                self._last_action,
            )
        ).astype(np.float32)

    def _info(self, state: RigidBodyState, estimate: WrenchEstimate) -> dict[str, Any]:
        info = {
            "time": self.time,
            "position": state.position.copy(),
            "velocity": state.velocity.copy(),
            "wrench_true": self._wrench_true.copy(),
            "wrench_est": np.concatenate((estimate.force, estimate.torque)),
            "estimator_status": self.estimator.status,
        }
        info.update(self._task_info(state))
        return info

    def _termination_reason(self, state: RigidBodyState) -> str | None:
        x, y, z = state.position
        arena = self.cfg.arena
        if z < self.cfg.crash_height or self.world.ground_contact():
            return "crash"
        if state.rotation[2, 2] < self._flip_cos:
            return "flip"
        if not (arena.x_min <= x <= arena.x_max and abs(y) <= arena.y_half_width and z <= arena.z_max):
            return "out_of_arena"
        return None

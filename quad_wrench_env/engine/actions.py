"""Action types: how a normalised action in [-1, 1]⁴ becomes motor-speed commands.

==========  ==========================================================================================
type        meaning of ``a = (a0, a1, a2, a3)``
==========  ==========================================================================================
velocity    world velocity ``(a0, a1)·max_speed_xy``, ``a2·max_speed_z`` and yaw rate ``a3·max_yaw_rate``,
            flown by the autopilot's full cascade (default)
attitude    roll ``a0`` and pitch ``a1`` times ``max_tilt_deg``, yaw rate ``a2·max_yaw_rate``, collective
            thrust ``(1 + a3)·hover thrust``; the autopilot's attitude and rate loops fly it
wrench      collective thrust ``(1 + a0)·hover thrust`` and body torques ``(a1, a2, a3)`` times
            ``(l, l, p/k)·hover thrust / 2``, through the mixer
motors      rotor speed commands ``(a + 1)/2·max rotor speed`` (the motor lag still applies)
==========  ==========================================================================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from quad_wrench_env.autopilot import Autopilot
from quad_wrench_env.config import check_numbers
from quad_wrench_env.engine.world import RigidBodyState
from quad_wrench_env.vehicle import GRAVITY

ACTION_TYPES = ("velocity", "attitude", "wrench", "motors")


@dataclass
class ActionLimits:
    """Physical ranges that the normalised actions span."""

    max_speed_xy: float = 1.0
    max_speed_z: float = 0.5
    max_yaw_rate: float = 1.0
    max_tilt_deg: float = 30.0

    def __post_init__(self) -> None:
        check_numbers("action_limits", self, ("max_speed_xy", "max_speed_z", "max_yaw_rate", "max_tilt_deg"))
        if self.max_tilt_deg >= 90.0:
            raise ValueError(f"action_limits.max_tilt_deg={self.max_tilt_deg} must be below 90")


class ActionMap:
    """Turns clipped normalised actions of N vehicles into motor-speed commands through the autopilot."""

    def __init__(self, action_type: str, autopilot: Autopilot, limits: ActionLimits) -> None:
        if action_type not in ACTION_TYPES:
            raise ValueError(f"unknown action_type {action_type!r}; allowed: {list(ACTION_TYPES)}")
        self.action_type = action_type
        self.autopilot = autopilot
        vehicle = autopilot.vehicle
        self._hover_thrust = vehicle.mass * GRAVITY
        self._velocity_scale = np.array((limits.max_speed_xy, limits.max_speed_xy, limits.max_speed_z))
        self._yaw_rate_scale = limits.max_yaw_rate
        self._tilt_scale = math.radians(limits.max_tilt_deg)
        self._torque_scale = (
            0.5 * self._hover_thrust * np.array((vehicle.arm, vehicle.arm, vehicle.km_over_kf))
        )
        self._max_speed = vehicle.max_rotor_speed

    def kernel_parameters(self) -> tuple[int, np.ndarray]:
        """The action type's index in :data:`ACTION_TYPES` and the scales as the compiled kernel
        reads them: velocity (3), yaw rate, tilt, hover thrust, torque (3), max rotor speed."""
        scales = np.concatenate(
            (
                self._velocity_scale, (self._yaw_rate_scale, self._tilt_scale, self._hover_thrust),
                self._torque_scale, (self._max_speed,),
            )
        )  # fmt: skip
        return ACTION_TYPES.index(self.action_type), scales

    def motor_command(self, action: np.ndarray, state: RigidBodyState) -> np.ndarray:
        """(N, 4) rotor speed commands (rad/s) for one physics step of N vehicles, actions (N, 4)."""
        a = action
        if self.action_type == "velocity":
            return self.autopilot.velocity_command(
                state, a[:, :3] * self._velocity_scale, a[:, 3] * self._yaw_rate_scale
            )
        if self.action_type == "attitude":
            return self.autopilot.attitude_command(
                state,
                a[:, 0] * self._tilt_scale,
                a[:, 1] * self._tilt_scale,
                a[:, 2] * self._yaw_rate_scale,
                (1.0 + a[:, 3]) * self._hover_thrust,
            )
        if self.action_type == "wrench":
            return self.autopilot.wrench_command(
                (1.0 + a[:, 0]) * self._hover_thrust, a[:, 1:] * self._torque_scale
            )
        return 0.5 * (a + 1.0) * self._max_speed

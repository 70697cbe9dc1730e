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
residual    a correction: the vehicle flies ``clip(b + s·a, -1, 1)`` as an ``attitude`` action, ``b`` its base
            controller's action (``residual.base``, e.g. the PID), ``s`` = ``residual.scale``
            (:mod:`quad_wrench_env.control.residual`)
==========  ==========================================================================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.vehicle import GRAVITY, VehicleParams

ACTION_TYPES = ("velocity", "attitude", "wrench", "motors")
"""The action types the engine flies (its ``controls`` kernel's order)."""
RESIDUAL = "residual"
"""The action type of a correction to a base controller, which flies :data:`RESIDUAL_FLOWN`."""
RESIDUAL_FLOWN = "attitude"


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


RESIDUAL_LEVELS = ("attitude", "acceleration")
"""Where a residual policy's correction enters the base controller (:class:`ResidualSettings`)."""


@dataclass
class ResidualSettings:
    """The ``residual`` action type's base controller and the size of the policy's correction."""

    base: str | None = None
    """The controller the policy corrects (``pid``); needed by ``action_type: residual``, refused by the
    others."""
    scale: float = 0.25
    """The correction's bound: the policy's action times this is added to the base's normalised action."""
    params: dict[str, Any] = field(default_factory=dict)
    """The base controller's settings, as its agent takes them (e.g. ``{compensation: true}``)."""
    level: str = "attitude"
    """Where the correction enters: ``attitude``, added to the base's attitude action; ``acceleration``,
    ``scale·g`` times the policy's first three components added to the PID's desired acceleration
    before its conversion to tilt and thrust (the fourth to its yaw-rate action, as ``attitude``)."""

    def __post_init__(self) -> None:
        if not (self.base is None or (isinstance(self.base, str) and self.base)):
            raise ValueError(f"residual.base={self.base!r} must be a base controller's name, e.g. 'pid'")
        if self.level not in RESIDUAL_LEVELS:
            raise ValueError(
                f"residual.level={self.level!r} is not a level; allowed: {list(RESIDUAL_LEVELS)}"
            )
        check_numbers("residual", self, ("scale",))
        if not isinstance(self.params, dict):
            raise ValueError(f"residual.params={self.params!r} must be a mapping of the base's settings")


@dataclass(frozen=True)
class ActionScaling:
    """The public map between an env's normalised actions and the physical commands they stand for (the
    table above), for agents that compute a command in SI units: ``env.unwrapped.action_scaling``.

    ``to_action`` gives the action the env takes, clipped to [-1, 1] and float32; ``to_command`` the
    command an action stands for. The scales are those the engine flies (its ``controls`` kernel reads
    them from here, :meth:`kernel_parameters`), so an agent never rebuilds them from the config.
    """

    action_type: str
    velocity: tuple[float, float, float]
    """m/s of ``(v_x, v_y, v_z)`` per unit action (``velocity``)."""
    yaw_rate: float
    """rad/s per unit action (``velocity``, ``attitude``)."""
    tilt: float
    """rad of roll and pitch per unit action (``attitude``)."""
    hover_thrust: float
    """N: the collective thrust ``m g`` of action 0 (``attitude``, ``wrench``)."""
    torque: tuple[float, float, float]
    """N·m of body torque per unit action: ``(l, l, k_m/k_f)·m g / 2`` (``wrench``)."""
    max_rotor_speed: float
    """rad/s of action 1 (``motors``)."""

    @classmethod
    def for_vehicle(cls, action_type: str, vehicle: VehicleParams, limits: ActionLimits) -> ActionScaling:
        if action_type not in ACTION_TYPES:
            raise ValueError(f"unknown action_type {action_type!r}; allowed: {list(ACTION_TYPES)}")
        hover_thrust = vehicle.mass * GRAVITY
        torque = 0.5 * hover_thrust * np.array((vehicle.arm, vehicle.arm, vehicle.km_over_kf))
        return cls(
            action_type,
            (limits.max_speed_xy, limits.max_speed_xy, limits.max_speed_z),
            limits.max_yaw_rate,
            math.radians(limits.max_tilt_deg),
            hover_thrust,
            tuple(float(t) for t in torque),
            vehicle.max_rotor_speed,
        )

    def kernel_parameters(self) -> tuple[int, np.ndarray]:
        """The action type's index in :data:`ACTION_TYPES` and the scales as the ``controls`` kernel
        reads them: velocity (3), yaw rate, tilt, hover thrust, torque (3), max rotor speed."""
        scales = np.array(
            (*self.velocity, self.yaw_rate, self.tilt, self.hover_thrust, *self.torque, self.max_rotor_speed)
        )
        return ACTION_TYPES.index(self.action_type), scales

    def to_action(self, command: np.ndarray | tuple[float, ...]) -> np.ndarray:
        """The (4,) float32 action in [-1, 1] for a command in SI units: ``(v_x, v_y, v_z, yaw rate)``
        (velocity), ``(roll, pitch, yaw rate, thrust)`` (attitude), ``(thrust, τ_x, τ_y, τ_z)`` body frame
        (wrench), four rotor speeds (motors); beyond the range it is clipped."""
        c = np.asarray(command, dtype=float)
        if c.shape != (4,):
            raise ValueError(f"command {command!r} must have 4 entries, got shape {c.shape}")
        if self.action_type == "velocity":
            action = c / np.array((*self.velocity, self.yaw_rate))
        elif self.action_type == "attitude":
            action = np.array(
                (c[0] / self.tilt, c[1] / self.tilt, c[2] / self.yaw_rate, c[3] / self.hover_thrust - 1.0)
            )
        elif self.action_type == "wrench":
            action = np.concatenate(((c[0] / self.hover_thrust - 1.0,), c[1:] / np.array(self.torque)))
        else:
            action = 2.0 * c / self.max_rotor_speed - 1.0
        return np.clip(action, -1.0, 1.0).astype(np.float32)

    def to_command(self, action: np.ndarray) -> np.ndarray:
        """The (4,) command in SI units (the order of :meth:`to_action`) that ``action`` stands for."""
        a = np.asarray(action, dtype=float)
        if self.action_type == "velocity":
            return a * np.array((*self.velocity, self.yaw_rate))
        if self.action_type == "attitude":
            thrust = (1.0 + a[3]) * self.hover_thrust
            return np.array((a[0] * self.tilt, a[1] * self.tilt, a[2] * self.yaw_rate, thrust))
        if self.action_type == "wrench":
            return np.concatenate((((1.0 + a[0]) * self.hover_thrust,), a[1:] * np.array(self.torque)))
        return 0.5 * (a + 1.0) * self.max_rotor_speed

"""Settings shared by every QuadWrench environment (the physical defaults: ``docs/physics.md``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from quad_wrench_env.config import check_numbers
from quad_wrench_env.disturbances.base import load_config, wind_config
from quad_wrench_env.disturbances.payload import PayloadConfig
from quad_wrench_env.disturbances.wrench_profile import validate_segments
from quad_wrench_env.engine.actions import (
    ACTION_TYPES,
    RESIDUAL,
    RESIDUAL_FLOWN,
    ActionLimits,
    ResidualSettings,
)
from quad_wrench_env.scene import make_scene_part
from quad_wrench_env.sensors import SensorConfig
from quad_wrench_env.vehicle import CALIBRATED_ROTORS


@dataclass
class ArenaConfig:
    """Box the vehicle must stay in (m, world frame); leaving it ends the episode."""

    x_min: float = 0.5
    x_max: float = 6.0
    y_half_width: float = 4.0
    z_max: float = 3.0

    def __post_init__(self) -> None:
        if not (self.x_min < self.x_max and self.y_half_width > 0 and self.z_max > 0):
            raise ValueError(
                f"arena x_min={self.x_min}, x_max={self.x_max}, y_half_width={self.y_half_width}, "
                f"z_max={self.z_max}: need x_min < x_max and positive width and height"
            )


@dataclass
class ToolConfig:
    """A rigid, massless tool fixed to the body: a rod from the centre of mass to a spherical tip, the
    one part of the vehicle allowed to touch the scene (Yüksel et al. 2014 Sec. V, Fig. 5)."""

    enabled: bool = False
    offset: tuple[float, float, float] | None = None
    """The tip's centre in the body frame (m); None puts it 0.1 m beyond the hull ahead and above,
    ``(half length + 0.1, 0, half height + 0.1)``, so that it touches a wall ahead or a ceiling above
    before the hull does. The ceiling tool of Yüksel et al. 2014 is ``(0.2, 0, 0.2)`` (its NED
    d read with z up)."""
    tip_radius: float = 0.015
    friction: float = 0.5
    """The tip's friction coefficient (Bullet multiplies it with the surface's)."""

    def __post_init__(self) -> None:
        check_numbers("tool", self, ("tip_radius", "friction"))
        if self.offset is not None:
            self.offset = tuple(self.offset)
            if len(self.offset) != 3 or not all(
                isinstance(v, (int, float)) and math.isfinite(v) for v in self.offset
            ):
                raise ValueError(f"tool.offset={list(self.offset)!r} must be 3 finite numbers (m)")


@dataclass
class EnvConfig:
    """What every environment is built from; each key may be overridden in ``gym.make``."""

    vehicle: str = "ardrone2"
    vehicle_params: dict[str, Any] = field(default_factory=dict)
    """Fields of the vehicle preset to override, e.g. ``{"mass": 0.45}``."""
    estimator: str = "ukf"
    estimator_params: dict[str, Any] | str = field(default_factory=dict)
    """The estimator's settings by key (its noise or gains), or the name of a set of them:
    ``"paper"`` (:data:`quad_wrench_env.estimators.NAMED_SETTINGS`)."""
    action_type: str = "velocity"
    action_limits: ActionLimits = field(default_factory=ActionLimits)
    residual: ResidualSettings = field(default_factory=ResidualSettings)
    """``action_type: residual``: the base controller the policy corrects and the correction's size."""
    physics_hz: int = 200
    policy_hz: int = 50
    episode_seconds: float = 30.0
    kf_spread: float = 0.02
    """Standard deviation of the per-rotor thrust-coefficient error ``ε_i`` (``docs/physics.md``,
    "Rotors")."""
    rotor_calibration: float | str | None = "preset"
    """None: the estimators turn the reported motor speeds into thrust and torque through the nominal
    mixer (the rotors' errors look like an external wrench). A number σ: the vehicle's rotors were
    calibrated (e.g. on a thrust stand) to a relative residual of sd σ: the estimators' mixer uses
    ``k·(1 + ε_i + δ_i)``, ``δ_i ~ N(0, σ²)`` drawn per episode from a generator of their own (0: the true
    coefficients; no other random number of the episode moves), and the UKF and the EKF report that
    residual (``estimator_params.rotor_spread``, unless given). ``"preset"``: the preset's own
    (:data:`~quad_wrench_env.vehicle.CALIBRATED_ROTORS`: the 27 g ``crazyflie2`` is calibrated, the others
    fly the nominal mixer)."""
    sensors: SensorConfig = field(default_factory=SensorConfig)
    payload: PayloadConfig = field(default_factory=PayloadConfig)
    external_wrench: list[list[float]] = field(default_factory=list)
    """Scheduled wrench segments ``[start, end, fx, fy, fz, tx, ty, tz]`` (world frame)."""
    wind: list[dict[str, Any]] = field(default_factory=list)
    """Extra wind fields, each ``{"model": name, **settings}``: ``dryden`` (``w20``, ``altitude``,
    ``mean``), ``one_cosine`` (``peak``, ``start``, ``duration``, ``hold``), ``jet`` (``position``,
    ``direction``, ``speed``, ``diameter``, ``spread``); see :mod:`quad_wrench_env.disturbances`."""
    loads: list[dict[str, Any]] = field(default_factory=list)
    """Extra point loads, each ``{"load": name, **settings}``, of the registry's ``"load"`` kind (a
    user's own, e.g. ``{"load": "my_lab.loads:tether"}``); the package's payload and scheduled wrench
    have keys of their own."""
    ground_effect: bool = False
    """Cheeseman-Bennett ground effect on each rotor over the ground and the scene's tops."""
    scene: list[dict[str, Any]] = field(default_factory=list)
    """Static parts, each ``{"kind": "table"|"wall"|"ceiling", ...}`` (:mod:`quad_wrench_env.scene`)."""
    tool: ToolConfig = field(default_factory=ToolConfig)
    """An optional tool whose tip may press on the scene; its contact forces (PyBullet's solver) are
    in ``wrench_true``."""
    arena: ArenaConfig = field(default_factory=ArenaConfig)
    observe_wrench: bool = True
    """False zeroes the force and torque blocks of the observation (the ablation that asks whether
    the estimated wrench is what makes a task solvable); ``info`` keeps them."""
    history: int = 0
    """Observation frames of the ``history`` previous steps after the current one (each frame the
    observation without its history: the estimated state and wrench, the action before it, the task's
    blocks), ``history_1`` the last; zeros before the episode's first step. 0: none."""
    sensor_history: int = 0
    """The estimators' sensor readings of the last ``sensor_history`` physics steps, appended to the
    observation (``sensors_1`` the newest ... ``sensors_K``, all of them ``sensors``; ``docs/tasks.md``):
    per step the motor speeds as reported over the top speed, the measured position and attitude (the
    ``attitude`` block's form), and the measured velocity and body rates with ``sensors.state_estimator``;
    zeros before the episode's first physics step. 0: none."""
    privileged: bool = False
    """Appends the truth (``privileged``: the true position, velocity, attitude, body rates, force and
    torque in the form of the engine's blocks, ``docs/tasks.md``) for a privileged critic or a teacher;
    a policy trained with it masks the block from its actor (``docs/training.md``)."""
    crash_height: float = 0.1
    flip_tilt_deg: float = 90.0

    def __post_init__(self) -> None:
        if self.action_type not in (*ACTION_TYPES, RESIDUAL):
            raise ValueError(
                f"unknown action_type {self.action_type!r}; allowed: {[*ACTION_TYPES, RESIDUAL]}"
            )
        if (self.action_type == RESIDUAL) != (self.residual.base is not None):
            raise ValueError(
                f"action_type={self.action_type!r} with residual.base={self.residual.base!r}: the residual "
                "action type needs a base controller and a base needs it; allowed: action_type residual "
                "with residual.base (e.g. 'pid'), or neither"
            )
        for name in ("physics_hz", "policy_hz"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value > 0):
                raise ValueError(f"{name}={value!r} must be a positive integer (Hz)")
        if self.physics_hz % self.policy_hz:
            raise ValueError(f"policy_hz={self.policy_hz} must divide physics_hz={self.physics_hz}")
        if not (math.isfinite(self.episode_seconds) and self.episode_seconds > 0):
            raise ValueError(f"episode_seconds={self.episode_seconds!r} must be a finite number > 0")
        if not (0.0 <= self.kf_spread < 0.5):
            raise ValueError(f"kf_spread={self.kf_spread!r} must be in [0, 0.5)")
        calibration = self.rotor_calibration
        number = isinstance(calibration, float | int) and not isinstance(calibration, bool)
        if calibration not in (None, "preset") and not (number and 0 <= calibration < 0.5):
            raise ValueError(
                f"rotor_calibration={calibration!r} must be None, 'preset' or a number in [0, 0.5)"
            )
        validate_segments(self.external_wrench)
        for position, spec in enumerate(self.wind):
            wind_config(spec, position)
        for position, spec in enumerate(self.loads):
            load_config(spec, position)
        for position, spec in enumerate(self.scene):
            make_scene_part(spec, position)
        if not isinstance(self.observe_wrench, bool):
            raise ValueError(f"observe_wrench={self.observe_wrench!r} must be true or false")
        if not (isinstance(self.history, int) and not isinstance(self.history, bool) and self.history >= 0):
            raise ValueError(f"history={self.history!r} must be an integer >= 0 (previous steps observed)")
        if not (
            isinstance(self.sensor_history, int)
            and not isinstance(self.sensor_history, bool)
            and self.sensor_history >= 0
        ):
            raise ValueError(
                f"sensor_history={self.sensor_history!r} must be an integer >= 0 (physics steps of sensor "
                "readings observed)"
            )
        if not isinstance(self.privileged, bool):
            raise ValueError(f"privileged={self.privileged!r} must be true or false")
        if not (0.0 < self.flip_tilt_deg <= 180.0):
            raise ValueError(f"flip_tilt_deg={self.flip_tilt_deg!r} must be in (0, 180]")

    @property
    def flown_action_type(self) -> str:
        """The action type the engine flies: a residual's base flies :data:`RESIDUAL_FLOWN`."""
        return RESIDUAL_FLOWN if self.action_type == RESIDUAL else self.action_type

    def resolved_rotor_calibration(self) -> float | None:
        """The residual σ the vehicle's rotors are calibrated to (None: the nominal mixer), the preset's
        own where ``rotor_calibration`` is ``"preset"``."""
        if self.rotor_calibration == "preset":
            return CALIBRATED_ROTORS.get(self.vehicle)
        return self.rotor_calibration

    def resolved_estimator_params(self) -> dict[str, Any] | str:
        """The settings the env's estimator is built with: ``estimator_params`` as given (a task may
        add settings it derives from its own physics, e.g. FanTracking's ``fan_walks``)."""
        return self.estimator_params

"""A fleet's physics step on the compiled kernels (:mod:`quad_wrench_env.kernels.physics`).

The numbers the kernels need are packed here once from the fleet's own components, so the kernels
read exactly the parameters the numpy reference uses; the state they update in place (autopilot
integrators, motor speeds, turbulence) is the components' own arrays, so both paths can be mixed
and compared at any step.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from quad_wrench_env.disturbances.fan import FanJet
from quad_wrench_env.kernels.physics import after_world_step, before_world_step
from quad_wrench_env.world import RigidBodyState

if TYPE_CHECKING:
    from quad_wrench_env.envs.fleet import Fleet


def supports(fleet: Fleet) -> bool:
    """Whether the kernels cover this fleet: its wind fields (a fan jet or none) and sensors (no
    motion-capture latency)."""
    winds = fleet.wind_fields
    return (
        len(winds) <= 1 and all(isinstance(w, FanJet) for w in winds) and not fleet.cfg.sensors.latency_steps
    )


class CompiledStep:
    """Packs a fleet's parameters for the kernels and runs its physics steps on them."""

    def __init__(self, fleet: Fleet) -> None:
        self.fleet = fleet
        ap = fleet.autopilot
        self.action_type, self.scales = fleet.actions.kernel_parameters()
        self.autopilot = ap.kernel_parameters()
        self.inverse = ap.mixer.inverse.copy()
        self.nominal_allocation = ap.mixer.allocation.copy()
        self.motors = np.append(fleet.rotors.kernel_parameters(), fleet.drag.coefficient)
        self.fan: FanJet | None = fleet.wind_fields[0] if fleet.wind_fields else None
        self.fan_parameters = np.zeros(7) if self.fan is None else self.fan.kernel_parameters()
        payload, profile = fleet.point_loads
        self.payload = payload.kernel_parameters()
        self.segments = profile.segments
        sensors = fleet.cfg.sensors
        self.sensing = np.array(
            (
                fleet.motor_sensor.levels, fleet.motor_sensor.step, sensors.position_noise,
                sensors.attitude_noise, sensors.velocity_noise, sensors.body_rate_noise,
            )
        )  # fmt: skip
        count = fleet.count
        self.forces, self.torques, self.loads = (
            np.zeros((count, 3)),
            np.zeros((count, 3)),
            np.zeros((count, 6)),
        )
        self.thrusts, self.body_torques = np.zeros(count), np.zeros((count, 3))
        self.measured_position, self.measured_quaternion = np.zeros((count, 3)), np.zeros((count, 4))
        self.motion = np.zeros((count, 6) if sensors.state_estimator else (0, 6))
        self.truth = np.zeros((count, 13))
        self.normals = np.zeros((count, fleet.noise.buffer.shape[2]))
        self.velocity_measured = self.motion[:, :3] if len(self.motion) else None
        self.body_rates_measured = self.motion[:, 3:] if len(self.motion) else None
        self.state = RigidBodyState.at_rest(np.zeros((count, 3)), np.tile((1.0, 0.0, 0.0, 0.0), (count, 1)))
        self._fan_noise = np.zeros((count, 3)) if self.fan is None else self.fan.noise
        self._motion_tables = np.zeros((count, 4)) if self.fan is None else self.fan.motion_tables

    def _adopt(self) -> None:
        """Take over the state the fleet read after a reset (into the kernels' own arrays) and bind
        the kernels' arguments, all of them arrays updated in place from then on."""
        fleet, mine = self.fleet, self.state
        for name in ("position", "quaternion", "velocity", "angular_velocity", "rotation", "body_rates"):
            getattr(mine, name)[:] = getattr(fleet.state, name)
        self.loads[:] = fleet.wrench_true
        fleet.state, fleet.wrench_true = mine, self.loads
        if self.fan is not None:
            self._motion_tables = self.fan.motion_tables
        s, ap, noise = mine, fleet.autopilot, fleet.noise
        self._before = (
            s.position, s.velocity, s.angular_velocity, s.rotation, fleet.time,
            ap.yaw_setpoint, ap.velocity_integral, ap.rate_integral, ap.saturated,
            fleet.rotors.speeds, fleet.rotors.allocations, self.autopilot, self.scales, self.inverse,
            self.motors, fleet.drag_points, self.fan_parameters, self._fan_noise, self._motion_tables,
            self.payload, self.segments, self.forces, self.torques, self.loads,
        )  # fmt: skip
        self._after = (
            s.position, s.quaternion, s.velocity, s.angular_velocity, s.rotation,
            s.body_rates, fleet.time, fleet.dt, noise.buffer, noise.cursor, self.normals,
            self.fan_parameters, self._fan_noise, fleet.rotors.speeds, self.sensing, self.nominal_allocation,
            self.thrusts, self.body_torques, self.measured_position, self.measured_quaternion, self.motion,
            self.truth,
        )  # fmt: skip

    def physics_steps(self, actions: np.ndarray, count: int) -> None:
        """``count`` physics steps with (N, 4) clipped normalised actions."""
        fleet = self.fleet
        if fleet.state is not self.state:
            self._adopt()
        world, noise, estimator = fleet.world, fleet.noise, fleet.estimator
        before = (self.action_type, actions, *self._before)
        position = self.state.position
        for _ in range(count):
            before_world_step(*before)
            world.step(self.forces, self.torques, position)
            noise.ready()
            after_world_step(world.read(), *self._after)
            if fleet.truth_fed:
                estimator.observe_truth(self.truth, self.loads)
            estimator.step(
                self.thrusts, self.body_torques, self.measured_position, self.measured_quaternion,
                self.velocity_measured, self.body_rates_measured,
            )  # fmt: skip

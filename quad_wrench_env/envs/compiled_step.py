"""A fleet's physics step on the compiled kernels (:mod:`quad_wrench_env.kernels.physics`).

The numbers the kernels need are packed here once from the fleet's own components
(:func:`~quad_wrench_env.kernels.physics.physics_constants`), so the kernels read exactly the
parameters the numpy reference uses. The per-vehicle arrays the kernels fill (true state, time,
applied loads, measurements) are views of one flat buffer
(:func:`~quad_wrench_env.kernels.physics.step_views`) that the fleet adopts as its own ``state``,
``time`` and ``wrench_true``. The state the components keep (autopilot setpoints and integrators,
rotor speeds and allocations, fan turbulence) becomes views of the same buffer, which the components
go on owning and updating in place, so both paths can be mixed and compared at any step; the mixer's
saturation flags, the fan's motion tables and the noise blocks stay arrays of their own.

Every kernel is called in its compiled form on arguments bound once per episode
(:func:`~quad_wrench_env.kernels.bind`). A fleet of one vehicle (the single env) meets PyBullet with
tuples instead of arrays: the before-step kernel returns the loads as ``World.step_one`` takes them
and the after-step kernel takes ``World.read_first``'s tuples, so Python builds no lists or arrays at
the boundary (about 0.9 µs less per physics step).
"""

from __future__ import annotations

from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from quad_wrench_env.disturbances.fan import FanJet
from quad_wrench_env.estimators.bank import FilterBank
from quad_wrench_env.kernels import bind, specialised
from quad_wrench_env.kernels.physics import (
    STEP_WIDTH,
    after_world_step,
    after_world_step_one,
    before_world_step,
    before_world_step_one,
    physics_constants,
    step_views,
)
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
        ap, sensors, count = fleet.autopilot, fleet.cfg.sensors, fleet.count
        self.fan: FanJet | None = fleet.wind_fields[0] if fleet.wind_fields else None
        payload, profile = fleet.point_loads
        action_type, scales = fleet.actions.kernel_parameters()
        sensing = (
            fleet.motor_sensor.levels, fleet.motor_sensor.step, sensors.position_noise,
            sensors.attitude_noise, sensors.velocity_noise, sensors.body_rate_noise,
            float(sensors.state_estimator),
        )  # fmt: skip
        self.constants = physics_constants(
            action_type, scales, ap.kernel_parameters(), ap.mixer.inverse,
            np.append(fleet.rotors.kernel_parameters(), fleet.drag.coefficient),
            np.zeros(7) if self.fan is None else self.fan.kernel_parameters(), payload.kernel_parameters(),
            np.array(sensing), ap.mixer.allocation, fleet.dt, fleet.drag_points, profile.segments,
        )  # fmt: skip
        self.single = count == 1
        """A fleet of one vehicle: it meets PyBullet with tuples (module docstring)."""
        self.buffer = np.zeros(count * STEP_WIDTH)
        self.actions = np.zeros((count, 4))
        """The policy step's (N, 4) clipped normalised actions, copied in (bound to the kernel)."""
        (
            self.time, position, quaternion, velocity, angular_velocity, rotation, body_rates,
            self.forces, self.torques, self.loads, self.thrusts, self.body_torques,
            self.measured_position, self.measured_quaternion, motion, self.truth, *components,
        ) = step_views(self.buffer, count)  # fmt: skip
        rotors = fleet.rotors
        owners = ((ap, "yaw_setpoint"), (ap, "velocity_integral"), (ap, "rate_integral"), (rotors, "speeds"),
                  (rotors, "allocations"), (self.fan, "noise"))  # fmt: skip
        for (owner, name), view in zip(owners, components, strict=True):
            if owner is not None:  # the components' state is theirs, kept here (updated in place)
                view[...] = getattr(owner, name)
                setattr(owner, name, view)
        self.state = RigidBodyState(position, quaternion, velocity, angular_velocity, rotation, body_rates)
        self.velocity_measured = motion[:, :3] if sensors.state_estimator else None
        self.body_rates_measured = motion[:, 3:] if sensors.state_estimator else None
        self.time[:] = fleet.time
        fleet.time = self.time
        self._motion_tables = np.zeros((count, 4)) if self.fan is None else self.fan.motion_tables
        self._bound: object | None = None
        """The estimator bank :attr:`estimate` is bound to."""

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
        one, world = self.single, fleet.world
        self._before = bind(
            before_world_step_one if one else before_world_step, self.actions, self.buffer,
            fleet.autopilot.saturated, self._motion_tables, self.constants,
        )  # fmt: skip
        """Returns the loads as ``World.step_one`` takes them for one vehicle (PyBullet's sequences:
        Python builds no lists from arrays), nothing for more (they are in the buffer)."""
        self._after = (self.buffer, fleet.noise.buffer, fleet.noise.cursor, self.constants)
        self.read_world = world.read_first if one else world.read_flat
        self._after_kernel = specialised(
            after_world_step_one if one else after_world_step, self.read_world(), *self._after
        )
        """Takes :attr:`read_world`'s result first: a new object of the same type every step (PyBullet's
        tuples of floats for one vehicle, a float array of rows for more)."""
        self._bind_estimator()

    def _bind_estimator(self) -> None:
        """Bind :attr:`estimate` to the fleet's estimator bank (again whenever it is swapped)."""
        measured = (
            self.thrusts, self.body_torques, self.measured_position, self.measured_quaternion,
            self.velocity_measured, self.body_rates_measured,
        )  # fmt: skip
        estimator = self._bound = self.fleet.estimator
        self.estimate = (
            estimator.bind_step(*measured)
            if isinstance(estimator, FilterBank)
            else partial(estimator.step, *measured)
        )
        """One step of the fleet's estimators on the measurements of the physics step just taken."""

    def physics_steps(self, actions: np.ndarray, count: int) -> None:
        """``count`` physics steps with (N, 4) clipped normalised actions."""
        fleet = self.fleet
        if fleet.state is not self.state:
            self._adopt()
        if fleet.estimator is not self._bound:
            self._bind_estimator()
        self.actions[:] = actions
        world, noise, estimator, truth_fed = fleet.world, fleet.noise, fleet.estimator, fleet.truth_fed
        before, read, after_kernel, after = self._before, self.read_world, self._after_kernel, self._after
        estimate = self.estimate
        forces, torques, position, one = self.forces, self.torques, self.state.position, self.single
        for _ in range(count):
            if one:
                world.step_one(*before())
            else:
                before()
                world.step(forces, torques, position)
            noise.ready()
            after_kernel(read(), *after)
            if truth_fed:
                estimator.observe_truth(self.truth, self.loads)
            estimate()

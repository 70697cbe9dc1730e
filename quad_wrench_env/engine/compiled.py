"""A fleet's physics step on compiled kernels: the engine's (:mod:`.kernels`) and its components', in the
step :mod:`.compose` writes for them.

The numbers the kernels need are packed here once from the fleet's own components
(:func:`~quad_wrench_env.engine.kernels.physics_constants`, then each component's ``kernel_parameters``),
so the kernels read exactly the parameters the components hold. The kernels work on the fleet's own step
buffer (:attr:`Fleet.buffer`, whose views are the fleet's ``state``, ``time``, ``wrench_true`` and
``wind_velocity``, the autopilot's and the rotors' state and each component's declared state, e.g. the
fan's turbulence), updated in place; the mixer's saturation flags, the components' per-vehicle tables and
the noise blocks are arrays of their own. The fleet calls :meth:`CompiledStep.rebind` after every reset
and :meth:`CompiledStep.bind_estimator` when its estimator bank is replaced.

Every kernel is called in its compiled form on arguments bound once per episode
(:func:`~quad_wrench_env.numerics.bind`). A fleet of one vehicle (the single env) meets PyBullet with
tuples instead of arrays: the before-step kernel returns the loads as ``World.step_one`` takes them and
the after-step kernel takes ``World.read_first``'s tuples, so Python builds no lists or arrays at the
boundary (about 0.9 µs less per physics step)."""

from __future__ import annotations

from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from quad_wrench_env.engine.compose import Slot, compose
from quad_wrench_env.engine.kernels import (
    STEP_WIDTH,
    component_parameters,
    physics_constants,
    record_sensor_readings,
)
from quad_wrench_env.estimators.bank import EstimatorInputs, FilterBank
from quad_wrench_env.numerics import bind, specialised

if TYPE_CHECKING:
    from quad_wrench_env.engine.fleet import Fleet


class CompiledStep:
    """Packs a fleet's parameters for the kernels and runs its physics steps on them."""

    def __init__(self, fleet: Fleet) -> None:
        self.fleet = fleet
        ap, sensors, count = fleet.autopilot, fleet.cfg.sensors, fleet.count
        latency = sensors.latency_steps
        action_type, scales = fleet.action_scaling.kernel_parameters()
        sensing = (
            fleet.motor_sensor.levels,
            fleet.motor_sensor.step,
            sensors.position_noise,
            sensors.attitude_noise,
            sensors.velocity_noise,
            sensors.body_rate_noise,
            float(sensors.state_estimator),
        )
        engine = physics_constants(
            {
                "action_type": action_type,
                "scales": scales,
                "autopilot": ap.kernel_parameters(),
                "inverse": ap.mixer.inverse,
                "motors": np.append(fleet.rotors.kernel_parameters(), fleet.drag.coefficient),
                "sensing": np.array(sensing),
                "dt": fleet.dt,
                "noise_column": fleet.sensor_noise_column,
                "delay_line": (latency, fleet.delay_line_start if latency else 0),  # unused without latency
            },
            fleet.drag_points,
        )
        components = fleet.components.ordered()
        self._components = [component for _, component in components]
        numbers = [c.kernel_parameters() for c in self._components]
        states = {id(owner): name for owner, name in fleet.component_states}
        self.constants = component_parameters(engine, numbers)
        ends = len(self.constants) - sum(len(n) for n in numbers) + np.cumsum([0] + [len(n) for n in numbers])
        self._bounds = list(zip(ends[:-1].tolist(), ends[1:].tolist(), strict=True))
        """Where each component's numbers sit in :attr:`constants`."""
        widths = [getattr(c, states[id(c)]).shape[1] if id(c) in states else 0 for _, c in components]
        slots = [
            Slot(kind, c.compiled, width, fleet.noise_columns.get(id(c), (0, 0)))
            for (kind, c), width in zip(components, widths, strict=True)
        ]
        points, noise_width = len(fleet.drag_points), fleet.noise.buffer.shape[2]
        self._step = compose(slots, STEP_WIDTH, points, noise_width)
        self.single = count == 1
        """A fleet of one vehicle: it meets PyBullet with tuples (module docstring)."""
        self.buffer = fleet.buffer
        self.actions = np.zeros((count, 4))
        """The policy step's (N, 4) clipped normalised actions, copied in (bound to the kernel)."""
        f = fleet.fields
        self.forces, self.torques, self.loads, self.truth = f["forces"], f["torques"], f["loads"], f["truth"]
        self.thrusts, self.body_torques = f["thrusts"], f["body_torques"]
        self.measured_position, self.measured_quaternion = f["measured_position"], f["measured_quaternion"]
        motion = f["motion"]
        self._table_owners = [(c, c.compiled.table) for _, c in components if c.compiled.table]
        self.state = fleet.state
        self.velocity_measured = motion[:, :3] if sensors.state_estimator else None
        self.body_rates_measured = motion[:, 3:] if sensors.state_estimator else None

    def rebind(self) -> None:
        """After a reset: read the components' numbers and tables again (a task may change them per
        episode) and bind the kernels' arguments, all of them arrays updated in place from then on."""
        fleet = self.fleet
        for component, (start, stop) in zip(self._components, self._bounds, strict=True):
            numbers = self.constants[start:stop]  # a task may change a component per episode
            fresh = component.kernel_parameters()
            if fresh.shape != numbers.shape:
                raise ValueError(
                    f"component {component.name!r} changed its number of kernel parameters from "
                    f"{numbers.size} to {fresh.size}; per-episode data of varying size belongs in its table"
                )
            numbers[:] = fresh
        tables = [getattr(owner, name) for owner, name in self._table_owners]
        one, world, step = self.single, fleet.world, self._step
        self._before = bind(
            step.before_world_step_one if one else step.before_world_step,
            self.actions,
            self.buffer,
            fleet.autopilot.saturated,
            self.constants,
            *tables,
        )
        """Returns the loads as ``World.step_one`` takes them for one vehicle (PyBullet's sequences:
        Python builds no lists from arrays), nothing for more (they are in the buffer)."""
        self._after = (self.buffer, fleet.noise.buffer, fleet.noise.cursor, self.constants, *tables)
        self.read_world = world.read_first if one else world.read_flat
        self._after_kernel = specialised(
            step.after_world_step_one if one else step.after_world_step, self.read_world(), *self._after
        )
        """Takes :attr:`read_world`'s result first: a new object of the same type every step (PyBullet's
        tuples of floats for one vehicle, a float array of rows for more)."""
        self._centre_wind = bind(step.centre_wind, fleet.count, self.buffer, self.constants, *tables)
        """The air at the centres of mass, after a policy step's last physics step."""
        frames = fleet.sensor_frames
        self._record_sensors = (
            bind(record_sensor_readings, self.buffer, self.constants, frames) if frames.shape[1] else None
        )
        """The estimators' readings of each physics step into the observation's ``sensors`` block."""
        self.bind_estimator()

    def bind_estimator(self) -> None:
        """Bind :attr:`estimate` to the fleet's estimator bank (again whenever it is swapped)."""
        measured = (
            self.thrusts,
            self.body_torques,
            self.measured_position,
            self.measured_quaternion,
            self.velocity_measured,
            self.body_rates_measured,
        )
        estimator, inputs = self.fleet.estimator, EstimatorInputs(*measured)
        self.estimate = (
            estimator.bind_step(inputs)
            if isinstance(estimator, FilterBank)
            else partial(estimator.step, inputs)
        )
        """One step of the fleet's estimators on the measurements of the physics step just taken."""

    def physics_steps(self, actions: np.ndarray, count: int) -> None:
        """``count`` physics steps with (N, 4) clipped normalised actions."""
        fleet = self.fleet
        self.actions[:] = actions
        world, noise, estimator, truth_fed = fleet.world, fleet.noise, fleet.estimator, fleet.truth_fed
        before, read, after_kernel, after = self._before, self.read_world, self._after_kernel, self._after
        estimate, record_sensors = self.estimate, self._record_sensors
        forces, torques, position, one = self.forces, self.torques, self.state.position, self.single
        contacts = world.tool is not None
        for _ in range(count):
            if one:
                world.step_one(*before())
            else:
                before()
                world.step(forces, torques, position)
            noise.ready()
            after_kernel(read(), *after)
            if contacts:
                world.add_contact_loads(self.loads, fleet.contact_force, position, self.state.rotation)
            if truth_fed:
                estimator.observe_truth(self.truth, self.loads)
            estimate()
            if record_sensors is not None:
                record_sensors()
        self._centre_wind()

"""A fleet's physics step on compiled kernels: the engine's (:mod:`.kernels`) and its components', in the
step :mod:`.compose` writes for them.

:class:`CompiledStep` is built from the fleet's step buffer (:mod:`.step_buffer`: the fleet's state,
loads and measurements, the autopilot's and the rotors' state and each component's declared state, updated
in place), the engine's constants (:func:`~quad_wrench_env.engine.kernels.physics_constants`), the
components with their slots and the world and noise it steps with; it knows nothing of the fleet. Each
component's numbers follow the engine's in :attr:`CompiledStep.constants`, read again from the component
at every :meth:`CompiledStep.rebind` (after each reset), so the kernels read exactly the parameters the
components hold; the mixer's saturation flags, the components' per-vehicle tables and the noise blocks
are arrays of their own.

Every kernel is called in its compiled form on arguments bound once per episode
(:func:`~quad_wrench_env.numerics.bind`). A fleet of one vehicle (the single env) meets PyBullet with
tuples instead of arrays: the before-step kernel returns the loads as ``World.step_one`` takes them and
the after-step kernel takes ``World.read_first``'s tuples, so Python builds no lists or arrays at the
boundary."""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial
from typing import Any

import numpy as np

from quad_wrench_env.engine.compose import Slot, compose
from quad_wrench_env.engine.draws import NoiseBlocks
from quad_wrench_env.engine.kernels import component_parameters, record_sensor_readings
from quad_wrench_env.engine.step_buffer import StepBuffer
from quad_wrench_env.engine.world import World
from quad_wrench_env.estimators.bank import EstimatorInputs, FilterBank
from quad_wrench_env.numerics import bind, specialised


class CompiledStep:
    """Runs a fleet's physics steps on the compiled kernels, over its step buffer."""

    def __init__(
        self,
        buffer: StepBuffer,
        engine_constants: np.ndarray,
        parts: Sequence[tuple[Slot, Any]],
        world: World,
        noise: NoiseBlocks,
        saturated: np.ndarray,
        contact_force: np.ndarray,
        sensor_frames: np.ndarray,
        measures_motion: bool,
    ) -> None:
        """``parts``: each component with its slot, in the composition's order; ``saturated``: the
        mixer's (N,) flags; ``contact_force``: the (N, 3) force the scene puts on each tool's tip;
        ``sensor_frames``: the observation's (N, K, width) sensor block (K = 0: none);
        ``measures_motion``: an onboard state estimator measures velocity and body rates."""
        slots = [slot for slot, _ in parts]
        self._components = [component for _, component in parts]
        numbers = [c.kernel_parameters() for c in self._components]
        self.constants = component_parameters(engine_constants, numbers)
        ends = len(self.constants) - sum(len(n) for n in numbers) + np.cumsum([0] + [len(n) for n in numbers])
        self._bounds = list(zip(ends[:-1].tolist(), ends[1:].tolist(), strict=True))
        """Where each component's numbers sit in :attr:`constants`."""
        self._step = compose(slots, buffer.layout)
        self.single = buffer.count == 1
        """A fleet of one vehicle: it meets PyBullet with tuples (module docstring)."""
        self.buffer = buffer.array
        self.count = buffer.count
        self.world, self.noise, self.saturated = world, noise, saturated
        self.contact_force, self.sensor_frames = contact_force, sensor_frames
        self.actions = np.zeros((buffer.count, 4))
        """The policy step's (N, 4) clipped normalised actions, copied in (bound to the kernel)."""
        f = buffer.fields
        self.forces, self.torques, self.loads, self.truth = f["forces"], f["torques"], f["loads"], f["truth"]
        self.thrusts, self.body_torques = f["thrusts"], f["body_torques"]
        self.measured_position, self.measured_quaternion = f["measured_position"], f["measured_quaternion"]
        self.position, self.rotation = f["position"], f["rotation"]
        motion = f["motion"]
        self._table_owners = [(c, slot.form.table) for slot, c in parts if slot.form.table]
        self.velocity_measured = motion[:, :3] if measures_motion else None
        self.body_rates_measured = motion[:, 3:] if measures_motion else None
        self.estimator: Any = None
        """The estimator bank the step feeds (:meth:`bind_estimator`)."""
        self.truth_fed = False

    def rebind(self) -> None:
        """After a reset: read the components' numbers and tables again (a task may change them per
        episode) and bind the kernels' arguments, all of them arrays updated in place from then on."""
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
        one, world, step = self.single, self.world, self._step
        self._before = bind(
            step.before_world_step_one if one else step.before_world_step,
            self.actions,
            self.buffer,
            self.saturated,
            self.constants,
            *tables,
        )
        """Returns the loads as ``World.step_one`` takes them for one vehicle (PyBullet's sequences:
        Python builds no lists from arrays), nothing for more (they are in the buffer)."""
        self._after = (self.buffer, self.noise.buffer, self.noise.cursor, self.constants, *tables)
        self.read_world = world.read_first if one else world.read_flat
        self._after_kernel = specialised(
            step.after_world_step_one if one else step.after_world_step, self.read_world(), *self._after
        )
        """Takes :attr:`read_world`'s result first: a new object of the same type every step (PyBullet's
        tuples of floats for one vehicle, a float array of rows for more)."""
        self._centre_wind = bind(step.centre_wind, self.count, self.buffer, self.constants, *tables)
        """The air at the centres of mass, after a policy step's last physics step."""
        frames = self.sensor_frames
        self._record_sensors = (
            bind(record_sensor_readings, self.buffer, self.constants, frames) if frames.shape[1] else None
        )
        """The estimators' readings of each physics step into the observation's ``sensors`` block."""
        self.bind_estimator(self.estimator, self.truth_fed)

    def bind_estimator(self, bank: Any, truth_fed: bool) -> None:
        """Feed the estimator bank ``bank`` (again whenever it is swapped, e.g. for a recorder wrapping
        it); ``truth_fed``: it reads the true state and loads (the oracle's), not the measurements."""
        self.estimator, self.truth_fed = bank, truth_fed
        measured = (
            self.thrusts,
            self.body_torques,
            self.measured_position,
            self.measured_quaternion,
            self.velocity_measured,
            self.body_rates_measured,
        )
        inputs = EstimatorInputs(*measured)
        self.estimate = bank.bind_step(inputs) if isinstance(bank, FilterBank) else partial(bank.step, inputs)
        """One step of the estimators on the measurements of the physics step just taken."""

    def physics_steps(self, actions: np.ndarray, count: int) -> None:
        """``count`` physics steps with (N, 4) clipped normalised actions."""
        self.actions[:] = actions
        world, noise, estimator, truth_fed = self.world, self.noise, self.estimator, self.truth_fed
        before, read, after_kernel, after = self._before, self.read_world, self._after_kernel, self._after
        estimate, record_sensors = self.estimate, self._record_sensors
        forces, torques, position, one = self.forces, self.torques, self.position, self.single
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
                world.add_contact_loads(self.loads, self.contact_force, position, self.rotation)
            if truth_fed:
                estimator.observe_truth(self.truth, self.loads)
            estimate()
            if record_sensors is not None:
                record_sensors()
        self._centre_wind()

"""N vehicles of one configuration flown in one PyBullet world: the core every env runs.

One physics step (``docs/architecture.md``, "One physics step, data flowing one way") for all N at
once: the autopilot turns the actions into motor commands, the true rotors lag towards them, the wind fields,
the body's drag, the rotor modifiers and the point loads give forces at body points whose resultants PyBullet
integrates; then the wind fields advance, the sensors measure and the estimators step. Every component holds
arrays with a leading vehicle axis, so a single env is a fleet of one and a vector env a fleet of N running
the same code: the same seeds give the same numbers either way. Each vehicle has its own generator (its
env's ``np_random``), time and episode.

The fleet knows components only through their seams (:mod:`quad_wrench_env.disturbances.base`,
:mod:`quad_wrench_env.scene`): the task's and the config's (``wind``, ``ground_effect``, ``scene``,
``payload``, ``external_wrench``) alike. The step runs on the engine's and the components' compiled
kernels (:class:`~quad_wrench_env.engine.compiled.CompiledStep`), the one implementation of the
physics; a component without a compiled form is refused by name. Under numba's
``NUMBA_DISABLE_JIT=1`` the same kernels run as plain Python (the debugging mode,
:mod:`quad_wrench_env.numerics`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from quad_wrench_env.autopilot import Autopilot, attitude_from_thrust
from quad_wrench_env.disturbances.base import resultant
from quad_wrench_env.disturbances.drag import QuadraticDrag
from quad_wrench_env.engine.actions import ActionScaling
from quad_wrench_env.engine.compiled import CompiledStep
from quad_wrench_env.engine.components import Components
from quad_wrench_env.engine.compose import Slot
from quad_wrench_env.engine.draws import NoiseBlocks
from quad_wrench_env.engine.env_config import EnvConfig
from quad_wrench_env.engine.fleet_view import FleetView, read_only
from quad_wrench_env.engine.kernels import (
    assemble_observations,
    delay_line_width,
    physics_constants,
    termination_codes,
)
from quad_wrench_env.engine.observation import ObservationLayout
from quad_wrench_env.engine.step_buffer import StepBuffer, StepLayout
from quad_wrench_env.engine.world import RigidBodyState, Tool, World
from quad_wrench_env.estimators import KALMAN_FILTERS, OracleBank, estimator_settings, make_estimator_bank
from quad_wrench_env.estimators.bank import FilterBank
from quad_wrench_env.rotations import cross, quat_from_matrix
from quad_wrench_env.rotors import Rotors
from quad_wrench_env.sensors import MotionCapture, MotorSpeedSensor
from quad_wrench_env.vehicle import GRAVITY, VehicleParams

ENGINE_TERMINATIONS = ("crash", "flip", "out_of_arena")
"""Reasons the engine ends an episode for (codes 1, 2, 3 of :meth:`Fleet.terminations`; 0: the
episode goes on); a task's own reasons follow."""

SENSOR_NOISE_WIDTH, STATE_ESTIMATOR_NOISE_WIDTH = 6, 6
"""Standard normal draws per vehicle and physics step of the motion capture (position, attitude) and,
with an onboard state estimator, of its velocity and body rates; they follow the wind fields' own."""


def make_tool(cfg: EnvConfig, vehicle: VehicleParams) -> Tool | None:
    """The world's tool from ``cfg.tool`` (its default offset from the vehicle's hull), or None."""
    tool = cfg.tool
    if not tool.enabled:
        return None
    offset = tool.offset
    if offset is None:
        half_length, half_height = vehicle.arm + vehicle.rotor_radius, 0.5 * vehicle.hull_height
        offset = (half_length + 0.1, 0.0, half_height + 0.1)
    return Tool(np.array(offset, dtype=float), tool.tip_radius, tool.friction)


def _state_width(component: object) -> int:
    """Floats per vehicle of ``component``'s declared state (``CompiledForm.state``; 0: none)."""
    name = component.compiled.state  # type: ignore[attr-defined]
    return getattr(component, name).shape[1] if name else 0


def refuse_uncompiled(components: Components) -> None:
    """Refuse, by name, components without a compiled form: the kernels are the only physics."""
    names = [c.name for _, c in components.ordered() if c.compiled is None]
    if names:
        raise ValueError(
            f"components {names} have no compiled form (compiled=None): give each its kernels "
            "(docs/extending.md); NUMBA_DISABLE_JIT=1 runs them as plain Python to debug"
        )


class Fleet:
    """``count`` vehicles, their autopilots, sensors and estimators, the components acting on them and
    the world they fly in."""

    def __init__(
        self,
        cfg: EnvConfig,
        vehicle: VehicleParams,
        count: int,
        components: Components,
        observation: ObservationLayout,
        gui: bool = False,
    ) -> None:
        self.cfg = cfg
        self.vehicle = vehicle
        self.count = count
        self.dt = 1.0 / cfg.physics_hz
        self.substeps = cfg.physics_hz // cfg.policy_hz
        self.components = components
        self.layout = observation
        dt = self.dt
        # The estimator's measurement noise defaults to the motion capture's; a noise-free capture
        # leaves the estimator's own default (a filter needs G > 0 to stay well conditioned). A calibrated
        # vehicle's filters report its residual as their rotor spread.
        sensors = cfg.sensors
        measured = [("position", sensors.position_noise), ("attitude", sensors.attitude_noise)]
        if sensors.state_estimator:
            measured += [("velocity", sensors.velocity_noise), ("body_rate", sensors.body_rate_noise)]
        from_env = {key: value for key, value in measured if value > 0}
        calibration = cfg.resolved_rotor_calibration()
        if calibration is not None and cfg.estimator in KALMAN_FILTERS:  # the residual they report
            from_env["rotor_spread"] = calibration
        refuse_uncompiled(components)
        self._estimator = make_estimator_bank(
            cfg.estimator,
            vehicle,
            dt,
            count,
            **{**from_env, **estimator_settings(cfg.estimator, cfg.resolved_estimator_params())},
        )
        self.truth_fed = isinstance(self._estimator, OracleBank)
        self.mocap = MotionCapture(sensors, count)
        self.motor_sensor = MotorSpeedSensor(vehicle.max_rotor_speed, sensors.motor_speed_bits)
        self.autopilot = Autopilot(vehicle, dt, count=count)
        self.action_scaling = ActionScaling.for_vehicle(cfg.flown_action_type, vehicle, cfg.action_limits)
        """The map between normalised actions and physical commands (public: agents read it)."""
        self.rotors = Rotors(vehicle, dt, count)
        self.drag_points = vehicle.drag_points()
        self.drag = QuadraticDrag(vehicle.drag_area, len(self.drag_points))
        self.noise_columns: dict[int, tuple[int, int]] = {}
        """Each wind field's own columns of the per-step normal draws (by ``id``)."""
        column = 0
        for wind in components.winds:
            self.noise_columns[id(wind)] = (column, column + wind.noise_width)
            column += wind.noise_width
        self.sensor_noise_column = column
        """The first column of the sensors' draws, after the wind fields'."""
        width = SENSOR_NOISE_WIDTH + (STATE_ESTIMATOR_NOISE_WIDTH if sensors.state_estimator else 0)
        self.noise = NoiseBlocks(count, column + width)
        self.world = World(vehicle, dt, count, gui=gui, scene=components.scene, tool=make_tool(cfg, vehicle))
        parts = [
            (Slot(kind, c.compiled, _state_width(c), self.noise_columns.get(id(c), (0, 0))), c)
            for kind, c in components.ordered()
        ]
        self.step_buffer = self._make_step_buffer([slot for slot, _ in parts])
        """The physics step's buffer: the fleet's per-vehicle arrays are its regions (:mod:`.step_buffer`)."""
        self.contact_force = np.zeros((count, 3))
        """(N, 3) force of the scene on each tool's tip in the last physics step (world frame, N)."""
        self.sensor_frames = np.zeros((count, observation.sensor_history, observation.sensor_width))
        """(N, K, width) the estimators' sensor readings of the last K physics steps, newest first (the
        observation's ``sensors`` block; K = 0 without one)."""
        self.compiled = CompiledStep(
            self.step_buffer,
            self._engine_constants(),
            parts,
            self.world,
            self.noise,
            self.autopilot.saturated,
            self.contact_force,
            self.sensor_frames,
            sensors.state_estimator,
        )
        """The physics step on the compiled kernels."""
        self.compiled.bind_estimator(self._estimator, self.truth_fed)
        arena = cfg.arena
        self._limits = np.array(
            (
                cfg.crash_height,
                math.cos(math.radians(cfg.flip_tilt_deg)),
                arena.x_min,
                arena.x_max,
                arena.y_half_width,
                arena.z_max,
                self.world.clear_height,
            )
        )
        self._observe_wrench = float(cfg.observe_wrench)
        self.estimated_state = np.zeros((count, 13))
        """(N, 13) the estimators' states as the last :meth:`view` read them."""
        self.wrench_est = np.zeros((count, 6))
        """(N, 6) the estimators' wrenches as the last :meth:`view` read them."""
        s = self.state
        self._view = FleetView(
            read_only(self.time),
            RigidBodyState(
                read_only(s.position),
                read_only(s.quaternion),
                read_only(s.velocity),
                read_only(s.angular_velocity),
                read_only(s.rotation),
                read_only(s.body_rates),
            ),
            read_only(self.contact_force),
            read_only(self.wrench_true),
            read_only(self.estimated_state),
            read_only(self.wrench_est),
        )
        """What :meth:`view` hands out: read-only views of the fleet's arrays, made once."""
        self._read_estimates = self._bind_estimates()

    def _make_step_buffer(self, slots: list[Slot]) -> StepBuffer:
        """The fleet's step buffer, laid out for ``slots``: the fleet's ``time``, ``state``,
        ``wrench_true`` and ``wind_velocity`` are its engine fields; the autopilot's and the rotors'
        state, each component's declared state (``CompiledForm.state``) and the motion capture's delay
        line are handed their regions, their numbers copied in; from then on everything updates them
        in place."""
        layout = StepLayout(
            tuple(slot.state_width for slot in slots),
            len(self.drag_points),
            self.noise.buffer.shape[2],
            delay_line_width(self.cfg.sensors.latency_steps),
        )
        buffer = StepBuffer(layout, self.count)
        ap, rotors = self.autopilot, self.rotors
        for attribute in ("yaw_setpoint", "velocity_integral", "rate_integral"):
            buffer.hand_over(ap, attribute, attribute)
        for attribute in ("speeds", "allocations", "sensed_allocations"):
            buffer.hand_over(rotors, attribute, attribute)
        for k, (_, component) in enumerate(self.components.ordered()):
            if component.compiled.state:
                buffer.hand_over(component, component.compiled.state, f"state_{k}")
        buffer.hand_over(self.mocap, "delay_line", "delay_line")
        f = buffer.fields
        self.time = f["time"]
        self.state = RigidBodyState(
            f["position"],
            f["quaternion"],
            f["velocity"],
            f["angular_velocity"],
            f["rotation"],
            f["body_rates"],
        )
        """The true states (zeros until the first reset)."""
        self.wrench_true = f["loads"]
        """(N, 6) everything the environment does to each vehicle beyond gravity and its nominal rotors."""
        self.wind_velocity = f["wind_velocity"]
        """(N, 3) air velocity at each centre of mass (world frame), after the last step or reset."""
        return buffer

    def _engine_constants(self) -> np.ndarray:
        """The engine's numbers for the kernels (:func:`~quad_wrench_env.engine.kernels.physics_constants`),
        read from the fleet's own parts."""
        ap, sensors = self.autopilot, self.cfg.sensors
        latency = sensors.latency_steps
        action_type, scales = self.action_scaling.kernel_parameters()
        sensing = (
            self.motor_sensor.levels,
            self.motor_sensor.step,
            sensors.position_noise,
            sensors.attitude_noise,
            sensors.velocity_noise,
            sensors.body_rate_noise,
            float(sensors.state_estimator),
        )
        delay_start = self.step_buffer.layout.start["delay_line"] if latency else 0  # unused without latency
        return physics_constants(
            {
                "action_type": action_type,
                "scales": scales,
                "autopilot": ap.kernel_parameters(),
                "inverse": ap.mixer.inverse,
                "motors": np.append(self.rotors.kernel_parameters(), self.drag.coefficient),
                "sensing": np.array(sensing),
                "dt": self.dt,
                "noise_column": self.sensor_noise_column,
                "delay_line": (latency, delay_start),
            },
            self.drag_points,
        )

    @property
    def estimator(self):
        """The estimator bank the physics step feeds; assigning another (e.g. a recorder wrapping it)
        makes the compiled step feed that one."""
        return self._estimator

    @estimator.setter
    def estimator(self, bank) -> None:
        self._estimator = bank
        self.compiled.bind_estimator(bank, self.truth_fed)
        self._read_estimates = self._bind_estimates()

    def _bind_estimates(self) -> Callable[[], None]:
        """Read the bank's estimates into :attr:`estimated_state` and :attr:`wrench_est`: its kernel
        bound to them, or (a bank without one, the oracle's truth) a copy."""
        bank, states, wrenches = self._estimator, self.estimated_state, self.wrench_est
        if isinstance(bank, FilterBank):
            return bank.bind_estimates(states, wrenches)

        def copy() -> None:
            states[...], wrenches[...] = bank.estimates()

        return copy

    # -- episodes ----------------------------------------------------------------------------------
    def reset_vehicle(self, index: int, rng: np.random.Generator, position: np.ndarray, yaw: float) -> None:
        """Start vehicle ``index``'s episode at ``position`` heading ``yaw``, trimmed (see
        :meth:`equilibrium`); its random draws come from ``rng`` from now on. Call :meth:`refresh`
        after the last vehicle is reset."""
        self.rotors.reset(index, rng, self.cfg.kf_spread, self.cfg.resolved_rotor_calibration())
        self.contact_force[index] = 0.0
        self.sensor_frames[index] = 0.0
        for wind in self.components.winds:
            wind.reset(index, rng)
        self.time[index] = 0.0
        rotation, rotor_speeds = self.equilibrium(index, position, yaw)
        quaternion = quat_from_matrix(rotation)
        self.world.place(np.array((index,)), position[None], quaternion[None])
        self.rotors.speeds[index] = rotor_speeds
        self.autopilot.reset(index, yaw)
        self.autopilot.trim(np.array((index,)), rotation[None], rotor_speeds[None])
        self.estimator.reset(index, position, quaternion)
        self.mocap.reset(index, position, quaternion)
        self.noise.reset(index, rng)

    def refresh(self, index: np.ndarray) -> None:
        """Read the true states of the vehicles ``index`` after they were reset (their external
        wrenches and air velocities now) and hand the truth to a truth-fed estimator. The other
        vehicles keep their states' bits: a vehicle's numbers never depend on another's restart."""
        self.state.assign(self.world.state().select(index), index)
        selected = self.state.select(index)
        self.wrench_true[index] = self.external_loads(selected, index)
        self.wind_velocity[index] = self.air_at(selected.position[:, None, :], index)[:, 0]
        self._feed_truth()
        self.compiled.rebind()

    def equilibrium(self, index: int, position: np.ndarray, yaw: float) -> tuple[np.ndarray, np.ndarray]:
        """Attitude and true rotor speeds that hold vehicle ``index`` at rest at ``position`` with
        heading ``yaw`` against gravity and the mean external loads there (the vehicle starts trimmed,
        as one that has been hovering in place; turbulence is left out of the balance)."""
        v = self.vehicle
        rows = np.array((index,))
        weight = np.array(((0.0, 0.0, v.mass * GRAVITY),))
        yaws = np.array((yaw,))
        rotation = attitude_from_thrust(weight, yaws)
        for _ in range(3):  # the loads depend weakly on the tilt and the rotor speeds: fixed point
            rest = RigidBodyState.at_rest(position[None], quat_from_matrix(rotation[0])[None])
            loads = self.external_loads(rest, rows, mean=True)
            thrust_vector = weight - loads[:, :3]
            rotation = attitude_from_thrust(thrust_vector, yaws)
            body_torque = -np.einsum("nji,nj->ni", rotation, loads[:, 3:])
            wanted = np.column_stack((np.linalg.norm(thrust_vector, axis=1), body_torque))
            self.rotors.speeds[index] = self.rotors.speeds_for(rows, wanted)[0]
        return rotation[0], self.rotors.speeds[index].copy()

    # -- one physics step --------------------------------------------------------------------------
    def step(self, actions: np.ndarray) -> None:
        """One policy step: ``substeps`` physics steps with (N, 4) clipped normalised actions."""
        self.compiled.physics_steps(actions, self.substeps)

    def air_at(self, points: np.ndarray, index: np.ndarray | slice, mean: bool = False) -> np.ndarray:
        """(n, P, 3) air velocity of all wind fields at (n, P, 3) world points of vehicles ``index``."""
        wind = np.zeros_like(points)
        time = self.time[index]
        for field in self.components.winds:
            wind += field.velocity_at(points, time, index, mean)
        return wind

    def external_loads(
        self, state: RigidBodyState, index: np.ndarray | slice, mean: bool = False
    ) -> np.ndarray:
        """(n, 6) ``[F, τ]`` of everything but gravity, the nominal rotors' thrust and reaction torque,
        about the centres of mass (world frame), for the vehicles ``index`` in the (n) states ``state``:
        drag in the wind, the rotor modifiers' thrust at the hubs, the point loads."""
        rotation = state.rotation
        offsets = self.drag_points @ rotation.transpose(0, 2, 1)  # (n, P, 3)
        point_velocity = state.velocity[:, None, :] + cross(state.angular_velocity[:, None, :], offsets)
        relative_air = self.air_at(state.position[:, None, :] + offsets, index, mean) - point_velocity
        forces = self.drag.forces(relative_air)
        forces[:, :4] += self.rotors.drag_forces(-relative_air[:, :4], rotation[:, :, 2], index)
        if self.components.rotors:
            hubs = offsets[:, :4]
            thrusts = self.rotors.thrusts(index)
            added = sum(
                modifier.added_thrust(state.position[:, None, :] + hubs, rotation, thrusts)
                for modifier in self.components.rotors
            )
            offsets = np.concatenate((offsets, hubs), axis=1)
            forces = np.concatenate((forces, added[:, :, None] * rotation[:, None, :, 2]), axis=1)
        for load in self.components.loads:
            extra = load.point_load(self.time[index], state, index)
            if extra is not None:
                offsets = np.concatenate((offsets, extra[0]), axis=1)
                forces = np.concatenate((forces, extra[1]), axis=1)
        force, torque = resultant(offsets, forces)
        return np.concatenate((force, torque), axis=1)

    def true_states(self) -> np.ndarray:
        """(N, 13) the true states as the estimators give theirs: position, velocity, quaternion (w, x,
        y, z), body rates."""
        s = self.state
        return np.concatenate((s.position, s.velocity, s.quaternion, s.body_rates), axis=1)

    def _feed_truth(self) -> None:
        if self.truth_fed:
            self.estimator.observe_truth(self.true_states(), self.wrench_true)

    # -- what the envs read ------------------------------------------------------------------------
    def view(self) -> FleetView:
        """The fleet as a task reads it now: the truth and the estimators' states and wrenches (read
        from the bank by this call), all read-only; the same views each call, showing the fleet's
        arrays as they change."""
        self._read_estimates()
        return self._view

    def observations(self, view: FleetView, last_actions: np.ndarray) -> np.ndarray:
        """(N, width) float32 observations laid out as :attr:`layout` with the engine's blocks filled
        from ``view``: the estimators' states (the attitude as two columns of the rotation matrix) and
        wrenches (zeros unless ``observe_wrench``), the last actions, and with ``layout.privileged`` the
        true state and wrench in the same form; the task's blocks are zeros (the env fills them)."""
        layout = self.layout
        out = np.zeros((self.count, layout.size), dtype=np.float32)
        starts = layout.kernel_starts
        assemble_observations(
            view.estimated_state, view.wrench_est, last_actions, self._observe_wrench, starts, out
        )
        if layout.privileged:
            truth, still = np.zeros((self.count, layout.frame), dtype=np.float32), np.zeros_like(last_actions)
            assemble_observations(self.true_states(), self.wrench_true, still, 1.0, starts, truth)
            privileged = layout.slices["privileged"]
            out[:, privileged] = truth[:, : privileged.stop - privileged.start]
        return out

    def terminations(self) -> np.ndarray:
        """(N,) codes into :data:`ENGINE_TERMINATIONS` (1-based): crash (below ``crash_height`` or
        touching the ground or a scene part that ends episodes), flip (tilt beyond ``flip_tilt_deg``),
        out_of_arena; 0 while the episode goes on."""
        s = self.state
        codes = np.empty(self.count, dtype=np.int64)
        if termination_codes(s.position, s.rotation, self._limits, codes):
            codes[self.world.crash_contacts()] = 1
        return codes

    def close(self) -> None:
        self.world.close()

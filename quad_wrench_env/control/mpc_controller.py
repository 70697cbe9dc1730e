"""Hentzen et al.'s (2019) MPC position controller (Sec. IV-D), as a linearised QP solved by DAQP.

Model (Hentzen et al. 2019 eqs. 1-2 with the attitude identified as a first-order system, Sec. IV-D a)), world
z up, state ``x = [p, v, φ, θ]`` (8) and input ``u = [T_ref, φ_ref, θ_ref]`` (3, plus the slack ``ε``
when the soft constraint is on)::

    ṗ = v,   v̇ = (T/m)·R(φ, θ, ψ)·e_z + f̂/m - g e_z,   φ̇ = (φ_ref - φ)/τ,   θ̇ = (θ_ref - θ)/τ

with ``R = Rz(ψ)·Ry(θ)·Rx(φ)``, the yaw ``ψ`` held at its current estimate (it is not optimised; the
yaw is flown by a separate proportional yaw-rate command) and the estimated external force ``f̂``
held constant over the horizon (``f̂ = 0`` without ``compensation``: the MPC then does not know the
force and, having no integrator, settles with an offset of ``f/k`` for a position stiffness ``k``).

The optimal control problem (Hentzen et al. 2019 eq. 4): quadratic cost on the state error and the input error
with a terminal cost, input bounds ``T_min <= T <= T_max``, ``|φ_ref|, |θ_ref| <= tilt_max``, 2 s
horizon at 0.1 s. The nonlinear model is linearised once per solve about the current attitude (or
the equilibrium one, ``linearization``) and the equilibrium thrust, discretised exactly (matrix
exponential of the augmented system, zero-order hold on the input). The QP is condensed (the states
eliminated through the model: the inputs ``u_0..u_{N-1}`` are the decision variables, 3N of them) and
solved by DAQP's dual active-set method (Arnström, Bemporad & Axehill 2022), warm-started from the
previous step's working set, to its exact optimum; the paper solves the nonlinear problem with
ACADO and qpOASES, an active-set method on the condensed QP, as a real-time iteration, and one
linearisation per step is the same first-order step about the current state.

The input reference (where the input cost pulls) is the equilibrium input: the thrust and tilt that
give the reference acceleration against gravity and, with ``compensation``, against ``f̂``
(:func:`quad_wrench_env.control.guidance.attitude_from_acceleration`); the attitude states are pulled towards
its tilt. Soft constraint (Sec. IV-D c)): ``|p_x - p_r,x|, |p_y - p_r,y| <= e_max + ε_k``, ``ε_k >= 0`` on
every predicted state, with the cost ``w_1·ε + w_2·ε²``. The linear term makes the penalty exact only
where ``w_1`` exceeds the hard constraint's multiplier, which grows without bound towards the edge of
feasibility; so the hard problem (no slack) is solved first and flown where it is feasible, the soft
one only where DAQP finds it infeasible (the constraint cannot be met): no slack is used while the
constraint can be met, up to its edge.

The constraint holds the height too, the vertical channel first: ``|p_z - p_r,z| <= e_z + ζ_k`` with
its own slack at ``height_priority`` times the cost. On x and y alone, at the tilt limit the hard
problem stays feasible by adding thrust (more thrust at the same tilt is more side force) and the
vehicle climbs, 0.6 m above the fast figure-8 and out of the arena in off-axis wind; with the band the
hard problem turns infeasible there and the soft one gives up the path before the height.

Where the soft problem flies (the vehicle at its limits), the current attitude can be far from the one
the solution flies: at 30° of roll the linearisation credits a roll change of -56° with +0.49 of the
thrust's vertical share (true: +0.03 at zero pitch), and with the height band first the QP "held the
height" through that error, the tilt swinging between its limits while it recovered from a saturated
phase. So there the QP is linearised again about the roll and pitch that its first solution predicts
``second_pass_seconds`` ahead (0.3 s: by then the attitude has all but reached its command) and
solved again: a second pass of the real-time iteration, only where the first cannot meet the
constraint, so that every step within the band keeps the paper's single linearisation.

The input reference beyond the tilt limit puts the vertical channel first (roll and pitch clipped, the
thrust whose vertical part balances): an input reference of the unclipped thrust ``|F|`` would pull
the vehicle up.

:class:`MPCController` runs it for a batch of vehicles (the ``mpc`` agent is a batch of one, the env's
``residual`` action type a batch of every vehicle): their QP data (references, linearisation, the
matrix exponentials, cost and bounds) computed for all vehicles at once (:meth:`PositionMPC.prepare`),
then each vehicle's own DAQP workspace updated and solved, warm-started from its previous working set,
so a vehicle's commands are those of the single controller.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import NamedTuple

import daqp
import numpy as np
import scipy.linalg

from quad_wrench_env.autopilot import AutopilotGains
from quad_wrench_env.control.guidance import ReferenceExtrapolator, attitude_from_acceleration
from quad_wrench_env.engine.actions import ActionScaling
from quad_wrench_env.rotations import wrap_angle
from quad_wrench_env.vehicle import GRAVITY, VehicleParams

NX = 8
"""State size: position (3), velocity (3), roll, pitch."""
NU = 3
"""Model input size: collective thrust (N), roll and pitch references (rad)."""
NEEDED_BLOCKS = ("position", "velocity", "attitude", "force", "reference_position", "reference_velocity")
"""The observation blocks the controller reads."""
ACTION_MAX_THRUST = 2.0
"""The attitude action's largest thrust, in hover thrusts (``(1 + a3)·m·g`` with ``a3 <= 1``)."""


@dataclass
class MPCGains:
    """Settings of :class:`PositionMPC` and :class:`MPCPolicy` (key prefix ``mpc.``)."""

    horizon_seconds: float = 2.0
    """Prediction horizon (s; Hentzen et al. 2019 Sec. IV-D d))."""
    step_seconds: float = 0.1
    """Discretisation interval (s); the horizon has ``round(horizon_seconds/step_seconds)`` steps."""
    attitude_time_constant: float | None = None
    """``τ`` (s) of the first-order attitude model; None derives it from the vehicle's autopilot,
    ``1/attitude_p`` (:meth:`quad_wrench_env.autopilot.AutopilotGains.for_vehicle`)."""
    position_weight: tuple[float, float, float] = (80.0, 80.0, 120.0)
    """Cost on the position error (1/m², per step), x, y, z (the magnitudes of ref. [4] of
    Hentzen et al. 2019)."""
    velocity_weight: tuple[float, float, float] = (4.0, 4.0, 6.0)
    """Cost on the velocity error (s²/m², per step); larger values slow the response to a step."""
    attitude_weight: float = 1.0
    """Cost on the roll and pitch error from the equilibrium tilt (1/rad², per step)."""
    input_weight: tuple[float, float, float] = (1.0, 200.0, 200.0)
    """Cost on the input error: thrust as the acceleration ``T/m`` (s⁴/m²), roll and pitch (1/rad²).
    The tilt weight sets how hard the measured attitude is fed back; lower values excite the lightly
    damped attitude loop of the autopilot (see :class:`MPCPolicy`)."""
    terminal_weight: float = 10.0
    """The terminal cost is this multiple of the stage cost on the state."""
    max_tilt_deg: float = 30.0
    """Bound on ``|φ_ref|`` and ``|θ_ref|`` (deg); the policy lowers it to the action's ``max_tilt_deg``."""
    min_thrust: float = 0.3
    """Lower thrust bound in hover thrusts ``m·g``."""
    max_thrust: float = 1.8
    """Upper thrust bound in hover thrusts; the policy lowers it to what the action can express (2)."""
    compensation: bool = False
    """Put the estimated external force into the model and the input reference (Hentzen et al. 2019,
    Sec. IV-D a))."""
    slack: bool = False
    """Add the soft cross-track constraint with its slack input (Hentzen et al. 2019 Sec. IV-D c))."""
    cross_track_limit: float = 0.05
    """``e_max`` (m) of the soft constraint on the x and y position errors."""
    slack_weight_linear: float | None = None
    """Linear cost on the slack (1/m, per step). None derives it from the exact-penalty condition: it
    must exceed the multiplier the hard constraint would have, away from the edge of feasibility at
    most the slope of the terminal position cost at ``e_max``, ``2·q_p·e_max·terminal_weight`` (1300
    with the tuned weights of ``configs/reproduce_hentzen.yaml``); near the edge the hard problem's
    own solve keeps the slack at zero (module docstring)."""
    slack_weight_quadratic: float | None = None
    """Quadratic cost on the slack (1/m², per step); None: the linear weight over ``e_max`` (both terms
    equal at a slack of ``e_max``)."""
    height_limit: float | None = 0.05
    """``e_z`` (m) of the band on the height error, ``|p_z - p_r,z| <= e_z``, that the cross-track
    constraint (``slack``) also holds, the vertical channel first: without it, at the tilt limit the
    hard constraint is met by adding thrust and the vehicle climbs (module docstring). None: the band
    on x and y alone (Hentzen et al. 2019 Sec. IV-D c))."""
    height_priority: float = 100.0
    """The height band's slack costs this multiple of the cross-track slack's (both terms), so that the
    soft problem gives up the path before the height."""
    linearization: str = "state"
    """Attitude about which the model is linearised, at the equilibrium thrust: ``"state"``, the current
    attitude, or ``"reference"``, the equilibrium tilt of the input reference (the hover point)."""
    second_pass_seconds: float | None = 0.3
    """Where the hard problem is infeasible (the vehicle at its limits: the soft problem flies), the QP
    is linearised again about the roll and pitch that the first solution predicts this far ahead (s)
    and solved again, a second pass of the real-time iteration (module docstring). None: one
    linearisation per step, as the paper's."""
    yaw: float = 0.0
    """Heading (rad) that the policy holds with a proportional yaw-rate command."""
    yaw_gain: float = 1.0
    """Gain (1/s) of that yaw-rate command."""
    primal_tolerance: float = 1.0e-6
    """DAQP's primal feasibility tolerance (its ``primal_tol``): how far a bound may be exceeded."""
    iteration_limit: int = 1000
    """DAQP's iteration limit (active-set changes); the hard problem, warm-started, takes a few."""

    def __post_init__(self) -> None:
        positive = ("horizon_seconds", "step_seconds", "max_tilt_deg", "max_thrust", "cross_track_limit")
        for name in positive:
            if not getattr(self, name) > 0.0:
                raise ValueError(f"mpc.{name}={getattr(self, name)!r} must be > 0")
        if self.attitude_time_constant is not None and not self.attitude_time_constant > 0.0:
            raise ValueError(
                f"mpc.attitude_time_constant={self.attitude_time_constant!r} must be > 0 or None"
            )
        if not 0.0 <= self.min_thrust < 1.0 < self.max_thrust:
            raise ValueError(
                f"mpc: need 0 <= min_thrust={self.min_thrust} < 1 < max_thrust={self.max_thrust}"
            )
        if not self.max_tilt_deg < 90.0:
            raise ValueError(f"mpc.max_tilt_deg={self.max_tilt_deg} must be below 90")
        for name in ("slack_weight_linear", "slack_weight_quadratic"):
            if getattr(self, name) is not None and not getattr(self, name) > 0.0:
                raise ValueError(f"mpc.{name}={getattr(self, name)!r} must be > 0 or None (derived)")
        if self.height_limit is not None and not self.height_limit > 0.0:
            raise ValueError(f"mpc.height_limit={self.height_limit!r} must be > 0 or None (no height band)")
        if not self.height_priority >= 1.0:
            raise ValueError(f"mpc.height_priority={self.height_priority!r} must be >= 1 (the height first)")
        if self.linearization not in ("reference", "state"):
            raise ValueError(f"mpc.linearization={self.linearization!r} must be 'reference' or 'state'")
        if self.horizon_seconds < self.step_seconds:
            raise ValueError("mpc.horizon_seconds must be at least one step_seconds")
        ahead = self.second_pass_seconds
        if ahead is not None and not self.step_seconds <= ahead <= self.horizon_seconds:
            raise ValueError(
                f"mpc.second_pass_seconds={ahead!r} must lie within the horizon, from step_seconds="
                f"{self.step_seconds} to horizon_seconds={self.horizon_seconds}, or be None (one pass)"
            )
        if not min(self.input_weight) > 0.0:
            raise ValueError(f"mpc.input_weight={self.input_weight!r} must be > 0 (a strictly convex QP)")
        if not self.primal_tolerance > 0.0 or self.iteration_limit < 1:
            raise ValueError(
                f"mpc: need primal_tolerance={self.primal_tolerance!r} > 0 and "
                f"iteration_limit={self.iteration_limit!r} >= 1"
            )


def cos_sin(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(cos φ, sin φ, cos θ, sin θ, cos ψ, sin ψ)`` elementwise: the factors of ``Rz(ψ)·Ry(θ)·Rx(φ)``."""
    return np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)


def thrust_direction(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """``R(φ, θ, ψ)·e_z``, the body z axis in the world frame, for ``R = Rz(ψ)·Ry(θ)·Rx(φ)``: angles of
    any one shape ``S``, the axes (S + (3,))."""
    cr, sr, cp, sp, cy, sy = cos_sin(roll, pitch, yaw)
    return np.stack((cy * sp * cr + sy * sr, sy * sp * cr - cy * sr, cp * cr), axis=-1)


def model_derivative(
    state: np.ndarray, inputs: np.ndarray, yaw: np.ndarray, force: np.ndarray, mass: float, tau: float
) -> np.ndarray:
    """``ẋ = f(x, u)`` of the nonlinear model (module docstring; Hentzen et al. 2019 eqs. 1-2): states
    (..., 8), inputs (..., 3), yaws (...), forces (..., 3)."""
    thrust, roll_ref, pitch_ref = inputs[..., 0], inputs[..., 1], inputs[..., 2]
    roll, pitch = state[..., 6], state[..., 7]
    direction = thrust_direction(roll, pitch, yaw)
    accel = (thrust / mass)[..., None] * direction + force / mass - np.array((0.0, 0.0, GRAVITY))
    attitude = np.stack(((roll_ref - roll) / tau, (pitch_ref - pitch) / tau), axis=-1)
    return np.concatenate((state[..., 3:6], accel, attitude), axis=-1)


def linearize(
    state: np.ndarray,
    thrust: np.ndarray,
    yaw: np.ndarray,
    force: np.ndarray,
    mass: float,
    tau: float,
    step: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A_d, B_d, c_d)`` of ``x_{k+1} = A_d·x_k + B_d·u_k + c_d``: the model linearised about the
    attitude of ``state`` and ``thrust`` (N), discretised exactly over ``step`` (s) with the input held
    (the matrix exponential of the augmented system). One vehicle's arguments give (8, 8), (8, 3), (8);
    a batch's (leading dimension V: states (V, 8), thrusts and yaws (V,), forces (V, 3)) the same with
    a leading V."""
    state, thrust, yaw = np.asarray(state, dtype=float), np.asarray(thrust, dtype=float), np.asarray(yaw)
    batch = state.shape[:-1]
    roll, pitch = state[..., 6], state[..., 7]
    cr, sr, cp, sp, cy, sy = cos_sin(roll, pitch, yaw)
    d_roll = np.stack((-cy * sp * sr + sy * cr, -sy * sp * sr - cy * cr, -cp * sr), axis=-1)
    d_pitch = np.stack((cy * cp * cr, sy * cp * cr, -sp * cr), axis=-1)
    a = np.zeros((*batch, NX, NX))
    a[..., 0:3, 3:6] = np.eye(3)
    a[..., 3:6, 6] = (thrust / mass)[..., None] * d_roll
    a[..., 3:6, 7] = (thrust / mass)[..., None] * d_pitch
    a[..., 6, 6] = a[..., 7, 7] = -1.0 / tau
    b = np.zeros((*batch, NX, NU))
    b[..., 3:6, 0] = thrust_direction(roll, pitch, yaw) / mass
    b[..., 6, 1] = b[..., 7, 2] = 1.0 / tau
    point = np.stack((thrust, roll, pitch), axis=-1)  # the inputs at the linearisation point (φ_ref = φ)
    c = (
        model_derivative(state, point, yaw, force, mass, tau)
        - (a @ state[..., None])[..., 0]
        - (b @ point[..., None])[..., 0]
    )
    augmented = np.zeros((*batch, NX + NU + 1, NX + NU + 1))
    augmented[..., :NX, :NX] = a
    augmented[..., :NX, NX : NX + NU] = b
    augmented[..., :NX, -1] = c
    e = scipy.linalg.expm(augmented * step)
    return e[..., :NX, :NX], e[..., :NX, NX : NX + NU], e[..., :NX, -1]


class QPData(NamedTuple):
    """A batch's condensed QP data at one solve (:meth:`PositionMPC.prepare`), leading dimension the
    vehicle: ``min ½ Uᵀ·H·U + fᵀ·U`` over the inputs ``U = (u_0, ..., u_{N-1})`` (3N), the states
    eliminated through the model."""

    states: np.ndarray
    """(V, 8) current states."""
    input_reference: np.ndarray
    """(V, N, 3) equilibrium inputs."""
    state_reference: np.ndarray
    """(V, N+1, 8)."""
    A_d: np.ndarray
    B_d: np.ndarray
    c_d: np.ndarray
    hessian: np.ndarray
    """(V, 3N, 3N) ``H``."""
    gradient: np.ndarray
    """(V, 3N) ``f``."""
    cross_track: np.ndarray
    """(V, BN, 3N) the positions of ``x_1..x_N`` on the band's B axes (:attr:`PositionMPC.band`; row
    ``B(k-1) + axis``) as functions of ``U``, less their free response (no rows without slack)."""
    lower: np.ndarray
    """(V, BN) the hard constraint on those rows: the reference less the band, less the free response."""
    upper: np.ndarray


EXIT_FLAGS = {
    2: "soft optimal",
    1: "solved",
    -1: "infeasible",
    -2: "cycling",
    -3: "unbounded",
    -4: "iteration limit",
    -5: "nonconvex",
    -6: "overdetermined initial working set",
    -7: "time limit",
}
"""DAQP's exit flags (``daqp.h``) by the name :attr:`PositionMPC.status` reports."""


class PositionMPC:
    """The QP of Hentzen et al. 2019 eq. (4) for one vehicle, condensed and solved warm by DAQP.

    ``max_tilt`` (rad), where given, lowers the roll and pitch bound to the attitude action's limit.
    After :meth:`solve`: ``predicted_inputs`` (N, 3: thrust N, roll and pitch references rad),
    ``predicted_states`` (N+1, 8, row 0 the current state: the model's rollout of those inputs),
    ``slack_values`` and ``height_slack_values`` (N each, zeros without slack or height band),
    ``input_reference`` (N, 3), ``state_reference`` (N+1, 8), the model used (``A_d``, ``B_d``,
    ``c_d``), ``status`` (:data:`EXIT_FLAGS`), ``iterations``, ``solve_time`` (s, DAQP's own),
    ``stages`` (the problems solved in the last pass: 1, or 2 where the hard problem was infeasible and
    the soft one was solved), ``passes`` (1, or 2 with the second pass: ``second_pass_seconds``) and
    ``total_time`` (s, the whole call: linearisation, condensing and solve).
    """

    def __init__(self, gains: MPCGains, mass: float, max_tilt: float | None = None) -> None:
        if gains.attitude_time_constant is None:
            raise ValueError("PositionMPC needs gains.attitude_time_constant (MPCPolicy derives it)")
        self.gains = g = gains
        self.mass = mass
        self.tau = float(g.attitude_time_constant)
        self.step = g.step_seconds
        self.horizon = n = max(1, round(g.horizon_seconds / g.step_seconds))
        hover = mass * GRAVITY
        self.tilt = tilt = (
            math.radians(g.max_tilt_deg) if max_tilt is None else min(math.radians(g.max_tilt_deg), max_tilt)
        )
        self.input_lower = np.array((g.min_thrust * hover, -tilt, -tilt))
        self.input_upper = np.array((g.max_thrust * hover, tilt, tilt))
        """Bounds of ``(T, φ_ref, θ_ref)`` (N, rad, rad)."""
        self.times = np.arange(n + 1) * self.step
        self._stage_weight = np.array(
            (*g.position_weight, *g.velocity_weight, g.attitude_weight, g.attitude_weight), float
        )
        self._state_weights = np.tile(self._stage_weight, (n, 1))  # (N, 8), rows x_1..x_N
        self._state_weights[-1] *= g.terminal_weight
        self._input_weight = np.array((g.input_weight[0] / mass**2, g.input_weight[1], g.input_weight[2]))
        linear = g.slack_weight_linear
        if linear is None:
            linear = 2.0 * max(g.position_weight[:2]) * g.cross_track_limit * g.terminal_weight
        quadratic = (
            linear / g.cross_track_limit if g.slack_weight_quadratic is None else g.slack_weight_quadratic
        )
        self.slack_weights = (linear, quadratic)
        """The cross-track slack's linear and quadratic costs in use (the height slack's are
        ``height_priority`` times these)."""
        limits = (g.cross_track_limit,) * 2 + (() if g.height_limit is None else (g.height_limit,))
        self.band = np.array(limits if g.slack else ())
        """The band's half-widths on the constrained axes of each predicted position (x, y and, with a
        ``height_limit``, z; none without slack)."""
        slacks = 1 + (len(self.band) == 3)  # ε_k on x and y; ζ_k on z with a height band
        priority = np.repeat((1.0, g.height_priority)[:slacks], n)  # ε_0..ε_{N-1}, ζ_0..ζ_{N-1}
        self._slack_costs = (np.diag(2.0 * quadratic * priority), linear * priority)
        own = (np.arange(len(self.band)) == 2).astype(int)  # axis -> its slack
        self._slack_of_row = np.eye(slacks * n)[(own[None] * n + np.arange(n)[:, None]).ravel()]
        """The soft problem's slack Hessian and gradient, and each band row's slack (row ``B·k + axis``)."""
        self._bounds = (np.tile(self.input_lower, n), np.tile(self.input_upper, n))
        self._settings = {"primal_tol": g.primal_tolerance, "iter_limit": g.iteration_limit}
        self._hard: daqp.Model | None = None
        self._soft: daqp.Model | None = None
        """DAQP's workspaces (set up at their first solve), each warm-started from its last working set."""
        self.A_d = np.eye(NX)
        self.B_d = np.zeros((NX, NU))
        self.c_d = np.zeros(NX)
        self._state = np.zeros(NX)
        self.predicted_inputs = np.zeros((n, NU))
        self.slack_values = np.zeros(n)
        self.height_slack_values = np.zeros(n)
        self.input_reference = np.zeros((n, NU))
        self.state_reference = np.zeros((n + 1, NX))
        self.status = "unsolved"
        self.iterations = 0
        self.solve_time = 0.0
        self.stages = 0
        self.passes = 0
        self.total_time = 0.0

    @property
    def predicted_states(self) -> np.ndarray:
        """(N+1, 8) the model's rollout of :attr:`predicted_inputs` from the current state."""
        states = [self._state]
        for u in self.predicted_inputs:
            states.append(self.A_d @ states[-1] + self.B_d @ u + self.c_d)
        return np.array(states)

    def equilibrium_input(self, acceleration: np.ndarray, yaw: float, force: np.ndarray) -> np.ndarray:
        """``(T, φ, θ)`` that holds ``acceleration`` (m/s², world) against gravity and ``force`` (N)."""
        return np.array(
            attitude_from_acceleration(acceleration - force / self.mass, yaw, self.mass, self.tilt)
        )

    def prepare(
        self,
        states: np.ndarray,
        yaws: np.ndarray,
        positions: np.ndarray,
        velocities: np.ndarray,
        accelerations: np.ndarray,
        forces: np.ndarray | None = None,
        attitudes: np.ndarray | None = None,
    ) -> QPData:
        """The QP data of V vehicles flying with this QP's settings, all at once: their ``states`` (V, 8)
        and ``yaws`` (V,), references ``positions``, ``velocities`` and ``accelerations`` (V, N+1, 3)
        at ``times`` and estimated external ``forces`` (V, 3; ignored without ``compensation``); the
        model linearised about the roll and pitch ``attitudes`` (V, 2) where given, else as
        ``linearization`` says."""
        g, n = self.gains, self.horizon
        states = np.asarray(states, dtype=float)
        count = len(states)
        model_forces = (
            np.zeros((count, 3)) if forces is None or not g.compensation else np.asarray(forces, dtype=float)
        )
        inputs = np.empty((count, n, NU))
        for v in range(count):
            ahead = np.asarray(accelerations[v, :n], dtype=float)
            if np.all(ahead == ahead[0]):  # the extrapolated reference: one acceleration over the horizon
                inputs[v] = self.equilibrium_input(ahead[0], yaws[v], model_forces[v])
                continue
            unique, which = np.unique(ahead, axis=0, return_inverse=True)
            inputs[v] = np.array([self.equilibrium_input(a, yaws[v], model_forces[v]) for a in unique])[
                which.ravel()
            ]
        attitude = np.concatenate((inputs, inputs[:, -1:]), axis=1)[:, :, 1:]
        state_reference = np.concatenate((positions, velocities, attitude), axis=2)
        points = states.copy()
        if attitudes is not None:
            points[:, 6:8] = attitudes
        elif g.linearization == "reference":
            points[:, 6:8] = inputs[:, 0, 1:]
        a_d, b_d, c_d = linearize(points, inputs[:, 0, 0], yaws, model_forces, self.mass, self.tau, self.step)
        hessian, gradient, cross_track, free = self._condense(states, a_d, b_d, c_d, state_reference, inputs)
        axes = len(self.band)
        reference = positions[:, 1:, :axes].reshape(count, -1) - free
        band = np.tile(self.band, n)
        lower, upper = reference - band, reference + band
        return QPData(
            states, inputs, state_reference, a_d, b_d, c_d, hessian, gradient, cross_track, lower, upper
        )

    def _condense(
        self,
        states: np.ndarray,
        a_d: np.ndarray,
        b_d: np.ndarray,
        c_d: np.ndarray,
        state_reference: np.ndarray,
        input_reference: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``H``, ``f``, the band's rows and their free response of eq. (4) with the states
        eliminated: ``x_k = x_k^0 + Σ_{j<k} A_d^{k-1-j}·B_d·u_j`` (``x^0`` the free response from
        ``x_0`` with ``u = 0``), so with ``G_m = A_d^m·B_d`` and the stage weights ``Q`` (``Q_N`` the
        terminal ones), ``H_jl = 2·Σ_{i ≥ max(j,l)} G_{i-j}ᵀ·Q_{i+1}·G_{i-l} + 2·R·δ_jl`` and
        ``f_j = 2·Σ_{i ≥ j} G_{i-j}ᵀ·Q_{i+1}·(x^0_{i+1} - x^r_{i+1}) - 2·R·u^r_j``. ``H`` is built from
        the N² products ``G_aᵀ·Q·G_b`` summed along its block diagonals (the sums share their tails)."""
        g, n, count = self.gains, self.horizon, len(states)
        steps = np.empty((count, n, NX, NU))  # G_m
        steps[:, 0] = b_d
        for m in range(1, n):
            steps[:, m] = a_d @ steps[:, m - 1]
        free = np.empty((count, n, NX))  # x^0_1..x^0_N
        x = states
        for k in range(n):
            x = (a_d @ x[..., None])[..., 0] + c_d
            free[:, k] = x
        by_input = steps.transpose(0, 1, 3, 2).reshape(count, n * NU, NX)  # row (a, i): G_a[:, i]
        products = (by_input * self._stage_weight) @ by_input.transpose(0, 2, 1)  # [(a,i), (b,j)]
        flipped = products.reshape(count, n, NU, n, NU)[:, ::-1, :, ::-1]  # [j, l] = G_{N-1-j}ᵀQG_{N-1-l}
        sums = np.zeros((count, n + 1, NU, n + 1, NU))
        for j in range(n - 1, -1, -1):  # Σ over i >= max(j, l) of the stage terms: tails shared
            sums[:, j, :, :n] = flipped[:, j] + sums[:, j + 1, :, 1:]
        hessian = (sums[:, :n, :, :n] + (g.terminal_weight - 1.0) * flipped).reshape(count, n * NU, n * NU)
        diagonal = np.arange(n * NU)
        hessian[:, diagonal, diagonal] += np.tile(self._input_weight, n)
        errors = self._state_weights * (free - state_reference[:, 1:])  # Q_k·(x^0_k - x^r_k)
        ahead = np.arange(n)[:, None] + np.arange(n)[None]  # [j, t] = j + t
        padded = np.concatenate((errors, np.zeros((count, n, NX))), axis=1)[:, ahead]  # (V, N, N, 8)
        gradient = (padded.reshape(count, n, n * NX) @ steps.reshape(count, n * NX, NU)).reshape(count, -1)
        gradient -= (self._input_weight * input_reference).reshape(count, -1)
        axes = len(self.band)
        lag = np.arange(n)[:, None] - np.arange(n)[None]  # [k, j] = k - j: G_{k-j} moves x_{k+1} by u_j
        banded = np.concatenate((steps[:, :, :axes], np.zeros((count, 1, axes, NU))), axis=1)
        rows = banded[:, np.where(lag >= 0, lag, n)].transpose(0, 1, 3, 2, 4).reshape(count, axes * n, n * NU)
        return 2.0 * hessian, 2.0 * gradient, rows, free[:, :, :axes].reshape(count, -1)

    def _solved(self, model: daqp.Model | None, *problem: np.ndarray) -> tuple[daqp.Model, np.ndarray, int]:
        """``model`` (a new one where None) given ``problem`` (``H, f, A, upper, lower``) and solved from
        its last working set: (the model, the solution, DAQP's exit flag)."""
        if model is None:
            model = daqp.Model()
            model.settings = self._settings
            model.setup(*problem)
        else:  # DAQP's update refuses a matrix of no rows (the box-constrained QP without slack)
            hessian, gradient, matrix, upper, lower = problem
            model.update(hessian, gradient, matrix if len(matrix) else None, upper, lower)
        solution, _, flag, info = model.solve()
        self.iterations += info["iterations"]
        self.solve_time += info["solve_time"]
        return model, solution, flag

    def _soft_problem(self, data: QPData, index: int) -> tuple[np.ndarray, ...]:
        """The soft problem (Hentzen et al. 2019 Sec. IV-D c)): the inputs and one slack ``ε_k >= 0``
        per step, ``p - ε <= p_r + e_max`` and ``p + ε >= p_r - e_max`` on x and y, the cost
        ``w_1·ε + w_2·ε²`` added; with a ``height_limit`` one more, ``ζ_k >= 0`` on z with the band
        ``e_z`` and ``height_priority`` times the costs."""
        slack_hessian, slack_gradient = self._slack_costs
        hessian = scipy.linalg.block_diag(data.hessian[index], slack_hessian)
        gradient = np.concatenate((data.gradient[index], slack_gradient))
        rows, per_row = data.cross_track[index], self._slack_of_row
        matrix = np.block([[rows, -per_row], [rows, per_row]])
        unbounded = np.full(len(rows), np.inf)
        slacks = per_row.shape[1]
        upper = np.concatenate((self._bounds[1], np.full(slacks, np.inf), data.upper[index], unbounded))
        lower = np.concatenate((self._bounds[0], np.zeros(slacks), -unbounded, data.lower[index]))
        return hessian, gradient, matrix, upper, lower

    def solve_prepared(self, data: QPData, index: int, again: bool = False) -> np.ndarray:
        """Solve vehicle ``index`` of ``data`` (:meth:`prepare`), warm-started from this QP's last working
        set: the hard problem, and where it is infeasible (or not solved) the soft one; the first input
        ``(T, φ_ref, θ_ref)`` (N, rad, rad). ``again``: the step's second pass (its iterations and solve
        time add to the first's)."""
        n = self.horizon
        self._state, inputs = data.states[index], data.input_reference[index]
        self.input_reference = inputs
        self.state_reference = data.state_reference[index]
        self.A_d, self.B_d, self.c_d = data.A_d[index], data.B_d[index], data.c_d[index]
        if not again:
            self.iterations, self.solve_time, self.passes = 0, 0.0, 0
        self.stages = 1
        self.passes += 1
        hard = (
            data.hessian[index],
            data.gradient[index],
            data.cross_track[index],
            np.concatenate((self._bounds[1], data.upper[index])),
            np.concatenate((self._bounds[0], data.lower[index])),
        )
        self._hard, solution, flag = self._solved(self._hard, *hard)
        if self.gains.slack and flag != 1:
            self._soft, solution, flag = self._solved(self._soft, *self._soft_problem(data, index))
            self.stages = 2
        self.status = EXIT_FLAGS.get(flag, f"exit flag {flag}")
        if flag < 1 or not np.all(np.isfinite(solution)):  # no solution: hold the equilibrium input
            self.predicted_inputs = inputs.copy()
            self.slack_values, self.height_slack_values = np.zeros(n), np.zeros(n)
        else:
            self.predicted_inputs = solution[: n * NU].reshape(n, NU)
            slacks = solution[n * NU :] if self.stages == 2 else np.zeros(0)
            slacks = np.concatenate((slacks, np.zeros(2 * n - len(slacks))))  # ζ zero without a height band
            self.slack_values, self.height_slack_values = slacks[:n], slacks[n:]
        return self.predicted_inputs[0].copy()

    def second_pass_attitude(self) -> np.ndarray | None:
        """(2,) the roll and pitch that the last solution predicts ``second_pass_seconds`` ahead, about
        which to solve again, where the last solve flew the soft problem; None where it did not, or
        without a second pass."""
        ahead = self.gains.second_pass_seconds
        if ahead is None or self.stages != 2:
            return None
        return self.predicted_states[round(ahead / self.step), 6:8]

    def solve(
        self,
        state: np.ndarray,
        yaw: float,
        positions: np.ndarray,
        velocities: np.ndarray,
        accelerations: np.ndarray,
        force: np.ndarray | None = None,
    ) -> np.ndarray:
        """The first input ``(T, φ_ref, θ_ref)`` (N, rad, rad) from the current ``state`` (8: p, v, φ,
        θ) and ``yaw`` (rad), for the reference ``positions``, ``velocities`` and ``accelerations``
        ((N+1, 3) each, at ``times``) and the estimated external ``force`` (N, world frame; ignored
        without ``compensation``): :func:`solve_batch` for a batch of one."""
        begin = time.perf_counter()
        command = solve_batch(
            [self],
            np.asarray(state, dtype=float)[None],
            np.array([yaw]),
            np.asarray(positions, dtype=float)[None],
            np.asarray(velocities, dtype=float)[None],
            np.asarray(accelerations, dtype=float)[None],
            None if force is None else np.asarray(force, dtype=float)[None],
        )[0]
        self.total_time = time.perf_counter() - begin
        return command


def solve_batch(
    qps: list[PositionMPC],
    states: np.ndarray,
    yaws: np.ndarray,
    positions: np.ndarray,
    velocities: np.ndarray,
    accelerations: np.ndarray,
    forces: np.ndarray | None,
) -> np.ndarray:
    """(V, 3) the first input ``(T, φ_ref, θ_ref)`` of each of V vehicles, vehicle ``v`` solved by
    ``qps[v]`` (:meth:`PositionMPC.prepare`'s arguments, one row per vehicle): every QP prepared at
    once and solved, then those that flew the soft problem prepared again about their
    :meth:`~PositionMPC.second_pass_attitude` and solved again."""
    data = qps[0].prepare(states, yaws, positions, velocities, accelerations, forces)
    commands = np.array([qp.solve_prepared(data, v) for v, qp in enumerate(qps)])
    points = {v: qp.second_pass_attitude() for v, qp in enumerate(qps)}
    again = np.array([v for v, point in points.items() if point is not None], dtype=int)
    if len(again):
        data = qps[0].prepare(
            states[again],
            yaws[again],
            positions[again],
            velocities[again],
            accelerations[again],
            None if forces is None else forces[again],
            attitudes=np.array([points[v] for v in again]),
        )
        for row, v in enumerate(again):
            commands[v] = qps[v].solve_prepared(data, row, again=True)
    return commands


def attitude_time_constant(vehicle: VehicleParams) -> float:
    """``τ = 1/attitude_p`` (s) of the vehicle's autopilot: the proportional attitude loop on top of a
    much faster rate loop (:mod:`quad_wrench_env.autopilot`)."""
    return 1.0 / AutopilotGains.for_vehicle(vehicle).attitude_p


class MPCController:
    """The MPC for ``count`` vehicles from their observations, through the ``attitude`` action: roll and
    pitch references and collective thrust from each vehicle's :class:`PositionMPC` (their QP data
    prepared for all at once), yaw held at ``gains.yaw`` by a proportional yaw-rate command. The
    reference acceleration is the observed reference velocity's difference between control steps
    (:class:`~quad_wrench_env.control.guidance.ReferenceExtrapolator`). :meth:`configure` before the
    first step, :meth:`restart` at each vehicle's episode start (a fresh solver: no warm start or step
    size from before)."""

    def __init__(self, gains: MPCGains, count: int = 1) -> None:
        self.gains = gains
        self.count = count
        self.reference = ReferenceExtrapolator()
        self.qps: list[PositionMPC] = []
        """Each vehicle's QP (after :meth:`configure`)."""
        self._settings = gains
        self._layout: dict[str, slice] = {}
        self._mass = 1.0
        self._dt = 0.02
        self._scaling: ActionScaling | None = None
        self._max_tilt = math.radians(30.0)

    def configure(
        self,
        layout: dict[str, slice],
        vehicle: VehicleParams,
        dt: float,
        scaling: ActionScaling,
        max_tilt: float,
    ) -> None:
        """Fly an env of observation ``layout``, ``vehicle``, control period ``dt`` (s), attitude action
        ``scaling`` and roll and pitch limit ``max_tilt`` (rad): the model's ``τ`` from the vehicle's
        autopilot where the gains leave it open, the bounds lowered to what the action can express;
        every vehicle starts afresh."""
        missing = sorted(set(NEEDED_BLOCKS) - set(layout))
        if missing:
            raise ValueError(f"the MPC needs the observation blocks {missing}, which this env lacks")
        if scaling.action_type != "attitude":
            raise ValueError(f"the MPC flies action_type='attitude', not {scaling.action_type!r}")
        g = self.gains
        self._settings = dataclasses.replace(
            g,
            attitude_time_constant=g.attitude_time_constant or attitude_time_constant(vehicle),
            max_thrust=min(g.max_thrust, ACTION_MAX_THRUST),
        )
        self._layout, self._mass, self._dt = layout, vehicle.mass, dt
        self._scaling, self._max_tilt = scaling, max_tilt
        self.qps = [self._fresh() for _ in range(self.count)]
        self.reference.reset()

    def _fresh(self) -> PositionMPC:
        return PositionMPC(self._settings, self._mass, self._max_tilt)

    def restart(self, index: np.ndarray | slice | int) -> None:
        """Vehicles ``index`` begin an episode: fresh solvers and reference histories."""
        for vehicle in np.arange(self.count)[index].ravel():
            self.qps[vehicle] = self._fresh()
        self.reference.restart(index)

    def actions(self, observations: np.ndarray) -> np.ndarray:
        """(N, 4) float32 ``attitude`` actions for (N, width) observations; advances every vehicle's
        solver and reference history."""
        if self._scaling is None:
            raise RuntimeError("call configure() before actions()")
        obs, layout, g = np.asarray(observations, dtype=float), self._layout, self.gains
        attitude = obs[:, layout["attitude"]]
        body_x, body_y = attitude[:, :3], attitude[:, 3:6]
        roll = np.arctan2(body_y[:, 2], body_x[:, 0] * body_y[:, 1] - body_x[:, 1] * body_y[:, 0])
        pitch = np.arcsin(np.clip(-body_x[:, 2], -1.0, 1.0))
        yaw = np.arctan2(body_x[:, 1], body_x[:, 0])
        states = np.column_stack((obs[:, layout["position"]], obs[:, layout["velocity"]], roll, pitch))
        self.reference.update(
            obs[:, layout["reference_position"]], obs[:, layout["reference_velocity"]], self._dt
        )
        reference = self.reference.horizon(self.qps[0].times)
        commands = solve_batch(self.qps, states, yaw, *reference, obs[:, layout["force"]])
        out = np.empty((len(obs), 4), dtype=np.float32)
        for vehicle, (thrust, roll_ref, pitch_ref) in enumerate(commands):
            yaw_rate = g.yaw_gain * wrap_angle(g.yaw - yaw[vehicle])
            out[vehicle] = self._scaling.to_action((roll_ref, pitch_ref, yaw_rate, thrust))
        return out

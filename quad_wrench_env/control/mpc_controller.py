"""Hentzen et al.'s (2019) MPC position controller (Sec. IV-D), as a linearised QP solved by OSQP.

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
exponential of the augmented system, zero-order hold on the input). The QP (states ``x_1..x_N`` and
inputs ``u_0..u_{N-1}`` as decision variables, the dynamics as equality constraints) is set up in
OSQP once; every solve only updates ``q``, ``l``, ``u`` and the dynamics blocks of ``A`` and
warm-starts. The paper solves the nonlinear problem with ACADO/qpOASES (real-time iteration); one
linearisation per step is the same first-order step about the current state.

The input reference (where the input cost pulls) is the equilibrium input: the thrust and tilt that
give the reference acceleration against gravity and, with ``compensation``, against ``f̂``
(:func:`quad_wrench_env.control.guidance.attitude_from_acceleration`); the attitude states are pulled towards
its tilt. Soft constraint (Sec. IV-D c)): ``|p_x - p_r,x|, |p_y - p_r,y| <= e_max + ε_k``, ``ε_k >= 0`` on
every predicted state, with the cost ``w_1·ε + w_2·ε²``. The linear term makes the penalty exact only
where ``w_1`` exceeds the hard constraint's multiplier, which grows without bound towards the edge of
feasibility; so the hard problem (every ``ε`` bounded to 0) is solved first and flown where OSQP
solves it, the soft one only where it does not (the constraint cannot be met): no slack is used while
the constraint can be met, up to its edge.

The input reference beyond the tilt limit puts the vertical channel first (roll and pitch clipped, the
thrust whose vertical part balances): an input reference of the unclipped thrust ``|F|`` would pull
the vehicle up.

:class:`MPCController` runs it for a batch of vehicles (the ``mpc`` agent is a batch of one, the env's
``residual`` action type a batch of every vehicle): their QP data (references, linearisation, the
matrix exponentials, cost and bounds) computed for all vehicles at once (:meth:`PositionMPC.prepare`),
then each vehicle's own OSQP problem updated and solved, warm-started from its previous solution, so a
vehicle's commands are those of the single controller.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import osqp
import scipy.linalg
from scipy import sparse

from quad_wrench_env.autopilot import AutopilotGains
from quad_wrench_env.control.guidance import ReferenceExtrapolator, attitude_from_acceleration
from quad_wrench_env.engine.actions import ActionScaling
from quad_wrench_env.rotations import wrap_angle
from quad_wrench_env.vehicle import GRAVITY, VehicleParams

NX = 8
"""State size: position (3), velocity (3), roll, pitch."""
NU = 3
"""Model input size: collective thrust (N), roll and pitch references (rad)."""
_A_PATTERN = np.zeros((NX, NX), dtype=bool)
_A_PATTERN[0:3, 0:3] = _A_PATTERN[0:3, 3:6] = _A_PATTERN[3:6, 3:6] = np.eye(3, dtype=bool)
_A_PATTERN[0:6, 6:8] = True
_A_PATTERN[6, 6] = _A_PATTERN[7, 7] = True
_B_PATTERN = np.zeros((NX, NU), dtype=bool)
_B_PATTERN[0:6, :] = True
_B_PATTERN[6, 1] = _B_PATTERN[7, 2] = True
"""Entries of ``A_d`` and ``B_d`` that can be non-zero at any linearisation point (p from p, v and the
attitude, v from v and the attitude, each attitude angle from itself and its reference; the thrust
along every axis): the QP's constraint matrix keeps this pattern, so only its values change."""
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
    linearization: str = "state"
    """Attitude about which the model is linearised, at the equilibrium thrust: ``"state"``, the current
    attitude, or ``"reference"``, the equilibrium tilt of the input reference (the hover point)."""
    yaw: float = 0.0
    """Heading (rad) that the policy holds with a proportional yaw-rate command."""
    yaw_gain: float = 1.0
    """Gain (1/s) of that yaw-rate command."""
    eps_abs: float = 1.0e-6
    """OSQP absolute tolerance."""
    eps_rel: float = 1.0e-6
    """OSQP relative tolerance."""
    max_iter: int = 4000
    """OSQP iteration limit."""
    warm_start: bool = True
    """Start each OSQP solve from the previous solution."""

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
        if self.linearization not in ("reference", "state"):
            raise ValueError(f"mpc.linearization={self.linearization!r} must be 'reference' or 'state'")
        if self.horizon_seconds < self.step_seconds:
            raise ValueError("mpc.horizon_seconds must be at least one step_seconds")


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
    """A batch's QP data at one solve (:meth:`PositionMPC.prepare`), leading dimension the vehicle."""

    states: np.ndarray
    """(V, 8) current states."""
    input_reference: np.ndarray
    """(V, N, 3) equilibrium inputs."""
    state_reference: np.ndarray
    """(V, N+1, 8)."""
    A_d: np.ndarray
    B_d: np.ndarray
    c_d: np.ndarray
    q: np.ndarray
    """(V, n·(8 + nu)) linear cost."""
    lower: np.ndarray
    """(V, rows) constraint bounds, the hard problem's (every slack bounded to 0)."""
    upper: np.ndarray
    matrix: np.ndarray
    """(V, nnz) the constraint matrix's values in OSQP's order."""


class PositionMPC:
    """The QP of Hentzen et al. 2019 eq. (4) for one vehicle, set up once in OSQP and re-solved warm.

    ``max_tilt`` (rad), where given, lowers the roll and pitch bound to the attitude action's limit.
    After :meth:`solve`: ``predicted_states`` (N+1, 8, row 0 the current state), ``predicted_inputs``
    (N, 3: thrust N, roll and pitch references rad), ``slack_values`` (N, zeros without slack),
    ``input_reference`` (N, 3), ``state_reference`` (N+1, 8), the model used (``A_d``, ``B_d``,
    ``c_d``), ``status`` (OSQP's), ``iterations``, ``solve_time`` (s, OSQP's own), ``stages`` (the
    problems solved: 1, or 2 where OSQP did not solve the hard problem and the soft one was solved)
    and ``total_time`` (s, the whole call: linearisation, update and solve).
    """

    def __init__(
        self, gains: MPCGains, mass: float, max_tilt: float | None = None, **osqp_settings: Any
    ) -> None:
        if gains.attitude_time_constant is None:
            raise ValueError("PositionMPC needs gains.attitude_time_constant (MPCPolicy derives it)")
        self.gains = g = gains
        self.mass = mass
        self.tau = float(g.attitude_time_constant)
        self.step = g.step_seconds
        self.horizon = n = max(1, round(g.horizon_seconds / g.step_seconds))
        self.nu = nu = NU + int(g.slack)
        hover = mass * GRAVITY
        self.tilt = tilt = (
            math.radians(g.max_tilt_deg) if max_tilt is None else min(math.radians(g.max_tilt_deg), max_tilt)
        )
        self.input_lower = np.array((g.min_thrust * hover, -tilt, -tilt, 0.0)[:nu])
        self.input_upper = np.array((g.max_thrust * hover, tilt, tilt, np.inf)[:nu])
        self.times = np.arange(n + 1) * self.step
        self._x = lambda k: (k - 1) * NX  # column of x_k, k = 1..N
        self._u = lambda k: n * NX + k * nu  # column of u_k, k = 0..N-1
        self.A_d = np.eye(NX)
        self.B_d = np.zeros((NX, NU))
        self.c_d = np.zeros(NX)
        self._build(osqp_settings)
        self.predicted_states = np.zeros((n + 1, NX))
        self.predicted_inputs = np.zeros((n, NU))
        self.slack_values = np.zeros(n)
        self.input_reference = np.zeros((n, NU))
        self.state_reference = np.zeros((n + 1, NX))
        self.status = "unsolved"
        self.iterations = 0
        self.solve_time = 0.0
        self.stages = 0
        self.total_time = 0.0
        self._warm: tuple[np.ndarray, np.ndarray] | None = None
        """The last solution flown (primal, dual; None before the first): the soft problem's start."""

    # -- set-up ----------------------------------------------------------------------------------
    def _build(self, osqp_settings: dict[str, Any]) -> None:
        g, n, nu = self.gains, self.horizon, self.nu
        rows: list[np.ndarray] = []
        cols: list[np.ndarray] = []
        values: list[np.ndarray] = []

        def block(row: int, col: int, pattern: np.ndarray, value: float | np.ndarray = 0.0) -> None:
            r, c = np.nonzero(pattern)
            rows.append(row + r)
            cols.append(col + c)
            values.append(np.broadcast_to(value, pattern.shape)[r, c].astype(float))

        for k in range(n):  # dynamics: x_{k+1} - A_d x_k - B_d u_k = c_d  (x_0 is data)
            rows.append(k * NX + np.arange(NX))
            cols.append(self._x(k + 1) + np.arange(NX))
            values.append(np.ones(NX))
        start = sum(v.size for v in values)
        for k in range(1, n):
            block(k * NX, self._x(k), _A_PATTERN)  # -A_d
        for k in range(n):
            block(k * NX, self._u(k), _B_PATTERN)  # -B_d
        self._model_slice = slice(start, sum(v.size for v in values))
        row = n * NX
        for k in range(n):  # input bounds
            rows.append(row + k * nu + np.arange(nu))
            cols.append(self._u(k) + np.arange(nu))
            values.append(np.ones(nu))
        row += n * nu
        if g.slack:  # p_x - ε <= p_r,x + e_max, p_x + ε >= p_r,x - e_max, same for y
            for k in range(n):
                for axis in range(2):
                    r = row + 4 * k + 2 * axis
                    block(r, self._x(k + 1) + axis, np.ones((2, 1), dtype=bool), 1.0)
                    block(r, self._u(k) + NU, np.ones((2, 1), dtype=bool), np.array(((-1.0,), (1.0,))))
            row += 4 * n
        self._rows = row
        r, c, self._values = np.concatenate(rows), np.concatenate(cols), np.concatenate(values)
        size = n * (NX + nu)
        ids = sparse.csc_matrix((np.arange(1.0, r.size + 1.0), (r, c)), shape=(row, size))
        ids.sort_indices()
        self._order = ids.data.astype(int) - 1  # CSC data slot -> entry of self._values
        self._indices, self._indptr = ids.indices, ids.indptr
        self._lower = np.full(row, -np.inf)
        self._upper = np.full(row, np.inf)
        self._lower[n * NX : n * (NX + nu)] = np.tile(self.input_lower, n)
        self._upper[n * NX : n * (NX + nu)] = np.tile(self.input_upper, n)
        self._slack_rows = n * NX + NU + nu * np.arange(n) if g.slack else np.zeros(0, dtype=int)
        """Rows of the slack's bounds ``0 <= ε_k``: ``<= 0`` in the hard problem (the bounds every solve
        starts from), ``<= ∞`` in the soft one (:meth:`_soft`)."""
        self._upper[self._slack_rows] = 0.0

        q_state = np.array(
            (*g.position_weight, *g.velocity_weight, g.attitude_weight, g.attitude_weight), float
        )
        r_input = np.array((g.input_weight[0] / self.mass**2, g.input_weight[1], g.input_weight[2]))
        linear = g.slack_weight_linear
        if linear is None:
            linear = 2.0 * max(g.position_weight[:2]) * g.cross_track_limit * g.terminal_weight
        quadratic = (
            linear / g.cross_track_limit if g.slack_weight_quadratic is None else g.slack_weight_quadratic
        )
        self.slack_weights = (linear, quadratic)
        """The slack's linear and quadratic costs in use."""
        if g.slack:
            r_input = np.append(r_input, quadratic)
        state_weights = np.tile(q_state, (n, 1))
        state_weights[-1] *= g.terminal_weight
        self._state_weights = state_weights  # (N, 8), rows x_1..x_N
        self._input_weights = r_input
        diagonal = np.concatenate((state_weights.ravel(), np.tile(r_input, n)))
        p = sparse.diags(2.0 * diagonal, format="csc")
        self.solver = osqp.OSQP()
        settings = {
            "eps_abs": g.eps_abs,
            "eps_rel": g.eps_rel,
            "max_iter": g.max_iter,
            "warm_starting": g.warm_start,
            "polishing": False,
            "verbose": False,
        }
        settings.update(osqp_settings)
        matrix = sparse.csc_matrix(
            (self._constraint_data(self.A_d[None], self.B_d[None])[0], self._indices, self._indptr),
            shape=(row, size),
        )
        self.solver.setup(p, np.zeros(size), matrix, self._lower, self._upper, **settings)

    def _soft(self, lower: np.ndarray, upper: np.ndarray) -> Any:
        """The soft problem's solution (the hard problem's bounds ``lower`` and ``upper`` with every
        slack's upper bound lifted), warm-started from the last solution flown (if any): where the hard
        problem has none (its constraint cannot be met), the least violation the slack's cost allows
        (Hentzen et al. 2019 Sec. IV-D c))."""
        soft_upper = upper.copy()
        soft_upper[self._slack_rows] = np.inf
        self.solver.update(l=lower, u=soft_upper)
        if self._warm is not None:
            self.solver.warm_start(x=self._warm[0], y=self._warm[1])
        soft = self.solver.solve(raise_error=False)
        self.iterations += soft.info.iter
        self.solve_time += soft.info.solve_time
        return soft

    def _constraint_data(self, a_d: np.ndarray, b_d: np.ndarray) -> np.ndarray:
        """(V, nnz) values of the constraint matrix in OSQP's order for models ``a_d`` (V, 8, 8) and
        ``b_d`` (V, 8, 3)."""
        n = self.horizon
        values = np.repeat(self._values[None], len(a_d), axis=0)
        blocks = [np.tile(-a_d[:, _A_PATTERN], (1, n - 1)), np.tile(-b_d[:, _B_PATTERN], (1, n))]
        values[:, self._model_slice] = np.concatenate(blocks, axis=1)
        return values[:, self._order]

    # -- solve -----------------------------------------------------------------------------------
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
    ) -> QPData:
        """The QP data of V vehicles flying with this QP's settings, all at once: their ``states`` (V, 8)
        and ``yaws`` (V,), references ``positions``, ``velocities`` and ``accelerations`` (V, N+1, 3)
        at ``times`` and estimated external ``forces`` (V, 3; ignored without ``compensation``)."""
        g, n, nu = self.gains, self.horizon, self.nu
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
        if g.linearization == "reference":
            points[:, 6:8] = inputs[:, 0, 1:]
        a_d, b_d, c_d = linearize(points, inputs[:, 0, 0], yaws, model_forces, self.mass, self.tau, self.step)
        q_state = -2.0 * self._state_weights * state_reference[:, 1:]
        input_reference = inputs if nu == NU else np.concatenate((inputs, np.zeros((count, n, 1))), axis=2)
        q_input = -2.0 * self._input_weights * input_reference
        if g.slack:
            q_input[:, :, NU] = self.slack_weights[0]
        rhs = np.tile(c_d, (1, n))
        rhs[:, :NX] += (a_d @ states[..., None])[..., 0]
        lower = np.repeat(self._lower[None], count, axis=0)
        upper = np.repeat(self._upper[None], count, axis=0)
        lower[:, : n * NX] = upper[:, : n * NX] = rhs
        if g.slack:
            bounds = positions[:, 1:, :2]
            slack_rows = slice(n * (NX + nu), None)
            slack_upper = np.full((count, n, 2, 2), np.inf)
            slack_lower = np.full((count, n, 2, 2), -np.inf)
            slack_upper[..., 0] = bounds + g.cross_track_limit
            slack_lower[..., 1] = bounds - g.cross_track_limit
            lower[:, slack_rows] = slack_lower.reshape(count, -1)
            upper[:, slack_rows] = slack_upper.reshape(count, -1)
        q = np.concatenate((q_state.reshape(count, -1), q_input.reshape(count, -1)), axis=1)
        return QPData(
            states, inputs, state_reference, a_d, b_d, c_d, q, lower, upper, self._constraint_data(a_d, b_d)
        )

    def solve_prepared(self, data: QPData, index: int) -> np.ndarray:
        """Solve vehicle ``index`` of ``data`` (:meth:`prepare`) on this QP, warm-started from its
        previous solution; the first input ``(T, φ_ref, θ_ref)`` (N, rad, rad)."""
        g, n, nu = self.gains, self.horizon, self.nu
        state, inputs = data.states[index], data.input_reference[index]
        self.input_reference = inputs
        self.state_reference = data.state_reference[index]
        self.A_d, self.B_d, self.c_d = data.A_d[index], data.B_d[index], data.c_d[index]
        lower, upper = data.lower[index], data.upper[index]  # the hard problem first
        # copies: osqp 1.1's binding reads a row of a 2-D array from the start of the array's buffer
        self.solver.update(q=data.q[index].copy(), l=lower, u=upper, Ax=data.matrix[index].copy())
        result = self.solver.solve(raise_error=False)
        self.iterations, self.solve_time, self.stages = result.info.iter, result.info.solve_time, 1
        if g.slack and result.info.status != "solved":
            result, self.stages = self._soft(lower, upper), 2
        self.status = result.info.status
        z = result.x
        if z is None or not np.all(np.isfinite(z)):  # no solution: hold the equilibrium input
            self.predicted_inputs = inputs.copy()
            self.slack_values = np.zeros(n)
            self.predicted_states = np.vstack((state, self.state_reference[1:]))
        else:
            u = z[n * NX :].reshape(n, nu)
            self.predicted_inputs = u[:, :NU].copy()
            self.slack_values = u[:, NU].copy() if g.slack else np.zeros(n)
            self.predicted_states = np.vstack((state, z[: n * NX].reshape(n, NX)))
            if g.slack:
                self._warm = (z.copy(), result.y.copy())
        return self.predicted_inputs[0].copy()

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
        without ``compensation``): :meth:`prepare` for a batch of one, then :meth:`solve_prepared`."""
        begin = time.perf_counter()
        data = self.prepare(
            np.asarray(state, dtype=float)[None],
            np.array([yaw]),
            np.asarray(positions, dtype=float)[None],
            np.asarray(velocities, dtype=float)[None],
            np.asarray(accelerations, dtype=float)[None],
            None if force is None else np.asarray(force, dtype=float)[None],
        )
        command = self.solve_prepared(data, 0)
        self.total_time = time.perf_counter() - begin
        return command


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
        data = self.qps[0].prepare(states, yaw, *reference, obs[:, layout["force"]])
        out = np.empty((len(obs), 4), dtype=np.float32)
        for vehicle, qp in enumerate(self.qps):
            thrust, roll_ref, pitch_ref = qp.solve_prepared(data, vehicle)
            yaw_rate = g.yaw_gain * wrap_angle(g.yaw - yaw[vehicle])
            out[vehicle] = self._scaling.to_action((roll_ref, pitch_ref, yaw_rate, thrust))
        return out

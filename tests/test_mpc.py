"""Hentzen et al.'s (2019) MPC position controller (Sec. IV-D, eqs. 1, 2, 4), its QP condensed and
solved with DAQP, and its guidance.

Tolerances: DAQP's solution is the active set's exact one, its bounds met to its primal tolerance
(1e-6 in the units of each bound: N, rad, m); the bound checks allow 2e-5, the margin the sparse QP in
OSQP needed before (``eps_abs + eps_rel·|T|`` with a 12.6 N thrust).
"""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import ClassVar

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from quad_wrench_env.agents.base import Policy
from quad_wrench_env.agents.mpc import MPCPolicy
from quad_wrench_env.autopilot import AutopilotGains
from quad_wrench_env.control.guidance import ReferenceExtrapolator, attitude_from_acceleration
from quad_wrench_env.control.mpc_controller import NU, NX, MPCController, MPCGains, PositionMPC, linearize
from quad_wrench_env.engine.actions import ActionLimits, ActionScaling
from quad_wrench_env.rotations import quat_from_euler_zyx, rotation_matrix
from quad_wrench_env.vehicle import GRAVITY, make_vehicle
from tests.reference_mpc import sparse_solution

MASS = 0.716  # hummingbird
TAU = 1.0 / 14.933
BOUND_TOL = 2e-5  # a bound met to DAQP's 1e-6, with the margin of the module docstring
TUNED = {"position_weight": (1298.89, 1298.89, 625.0), "velocity_weight": (103.91, 103.91, 50.0)}


def nonlinear_rhs(x: np.ndarray, u: np.ndarray, yaw: float, force: np.ndarray) -> np.ndarray:
    """Eqs. (1)-(2) and the first-order attitude, written independently of
    quad_wrench_env.control.mpc_controller: the thrust direction comes from the project's rotations
    (``R = Rz(ψ)·Ry(θ)·Rx(φ)``)."""
    body_z = rotation_matrix(quat_from_euler_zyx(x[6], x[7], yaw))[:, 2]
    accel = u[0] / MASS * body_z + force / MASS + np.array((0.0, 0.0, -GRAVITY))
    return np.concatenate((x[3:6], accel, (u[1:3] - x[6:8]) / TAU))


def hover_reference(mpc: PositionMPC, position=(0.0, 0.0, 1.0)):
    guidance = ReferenceExtrapolator()
    guidance.update(np.array(position), np.zeros(3), 0.02)
    return guidance.horizon(mpc.times)


def make_mpc(**settings) -> PositionMPC:
    return PositionMPC(MPCGains(attitude_time_constant=TAU, **settings), MASS)


def test_the_input_reference_beyond_the_tilt_limit_balances_the_weight():
    """The input reference the MPC's input cost pulls to, for an acceleration of g sideways (45 deg of
    tilt) under a 30 deg limit and a push of 1 N up: roll clipped to the limit and the thrust whose
    vertical part balances the weight less the push, ``T cos 30 = m g - 1``, not ``|F| = m g sqrt 2``,
    which would pull the vehicle up (the vertical channel first, as the PID's)."""
    mpc = make_mpc(max_tilt_deg=30.0)
    push_up = np.array((0.0, 0.0, 1.0))
    thrust, roll, pitch = mpc.equilibrium_input(np.array((0.0, -GRAVITY, 0.0)), 0.0, push_up)
    assert roll == pytest.approx(math.radians(30.0), abs=1e-12) and pitch == pytest.approx(0.0, abs=1e-12)
    assert thrust * math.cos(math.radians(30.0)) == pytest.approx(MASS * GRAVITY - 1.0, rel=1e-12)
    within = mpc.equilibrium_input(np.array((0.0, -1.0, 0.0)), 0.0, np.zeros(3))  # 5.8 deg: unclipped
    assert within[0] == pytest.approx(MASS * math.hypot(1.0, GRAVITY), rel=1e-12)


# -- guidance ------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(5))
def test_attitude_from_acceleration_reproduces_the_thrust_vector(seed):
    rng = np.random.default_rng(seed)
    acceleration, yaw = rng.uniform(-4.0, 4.0, 3), rng.uniform(-math.pi, math.pi)
    thrust, roll, pitch = attitude_from_acceleration(acceleration, yaw, MASS)
    wanted = MASS * (acceleration + np.array((0.0, 0.0, GRAVITY)))
    body_z = rotation_matrix(quat_from_euler_zyx(roll, pitch, yaw))[:, 2]
    np.testing.assert_allclose(thrust * body_z, wanted, atol=1e-12)
    assert thrust == pytest.approx(np.linalg.norm(wanted))


def test_reference_extrapolator_differences_the_reference_velocity():
    guidance = ReferenceExtrapolator()
    assert np.all(guidance.update(np.zeros(3), np.array((1.0, 0.0, 0.0)), 0.02) == 0.0)  # first step
    a = guidance.update(np.array((0.02, 0.0, 0.0)), np.array((1.1, 0.0, -0.2)), 0.02)
    np.testing.assert_allclose(a, (5.0, 0.0, -10.0))
    positions, velocities, accelerations = guidance.horizon(np.array((0.0, 0.5)))
    np.testing.assert_allclose(positions[1], (0.02 + 1.1 * 0.5 + 2.5 * 0.25, 0.0, -0.1 - 1.25))
    np.testing.assert_allclose(velocities[1], (1.1 + 2.5, 0.0, -0.2 - 5.0))
    np.testing.assert_allclose(accelerations, [a, a])
    guidance.reset()
    assert np.all(guidance.update(np.zeros(3), np.ones(3), 0.02) == 0.0)


# -- model -----------------------------------------------------------------------------------------
def test_discretised_linear_model_matches_the_nonlinear_model_for_small_deviations():
    """Over one 0.1 s step from the linearisation point plus deviations δ, the error of the affine
    model is second order in δ (solve_ivp to 1e-11): ~1e-7 for δ = 1e-3, and it falls 4x when δ halves."""
    yaw, force, thrust = 0.7, np.array((0.4, -0.3, 0.2)), 7.3
    point = np.array((0.1, -0.2, 1.0, 0.3, -0.1, 0.05, 0.12, -0.08))
    a_d, b_d, c_d = linearize(point, thrust, yaw, force, MASS, TAU, 0.1)
    direction = np.random.default_rng(0).normal(size=NX + NU)

    def error(scale: float) -> float:
        x0 = point + scale * direction[:NX]
        u = np.array((thrust, point[6], point[7])) + scale * direction[NX:]
        exact = solve_ivp(
            lambda t, x: nonlinear_rhs(x, u, yaw, force), (0.0, 0.1), x0, rtol=1e-12, atol=1e-12
        ).y[:, -1]
        return float(np.abs(a_d @ x0 + b_d @ u + c_d - exact).max())

    assert error(0.0) < 1e-10  # exact at the linearisation point
    assert error(1e-3) < 1e-6
    assert 3.0 < error(1e-2) / error(5e-3) < 5.0


@pytest.mark.parametrize(("slack", "height_limit"), [(False, None), (True, None), (True, 0.05), (True, 0.08)])
def test_the_condensed_qp_has_the_sparse_qps_solution(slack, height_limit):
    """The controller's condensed QP (the states eliminated, DAQP) against eq. (4) as the sparse QP of
    tests/reference_mpc.py (states and inputs as variables, the model as equality rows, OSQP polished
    to 1e-10) on the same model and references: from states up to 0.5 m and 1 m/s off, with
    compensation, the cross-track constraint active in some (the hard problem where it is feasible,
    the soft one where the controller found it not: ``stages``) and the thrust at its bound in some;
    the band on x and y alone (the paper's) and with the height band, its slack used in some.
    Tolerances: both are the active set's exact solution, so they differ by rounding, ~1e-16 times the
    condition of ``H`` (~1e7 with these weights): observed 1e-11 N on the thrust, 1e-12 m on a state;
    asserted 1e-7 and 1e-8. One pass (the second pass, a QP on another model, has its own test: some
    of these starts, 1 m/s off, give second-pass QPs that OSQP does not solve to 1e-10)."""
    mpc = make_mpc(
        slack=slack, compensation=True, height_limit=height_limit, second_pass_seconds=None, **TUNED
    )
    reference = hover_reference(mpc)
    rng = np.random.default_rng(1)
    stages, bounded, height_slack = set(), 0, 0.0
    for trial in range(12):
        scale = (0.04, 0.5)[trial % 2]  # within e_max and its reach, or not
        offsets = (rng.uniform(-scale, scale, 3), rng.uniform(-2 * scale, 2 * scale, 3))
        state = np.concatenate((*offsets, rng.uniform(-0.2, 0.2, 2)))
        state[2] += 1.0
        mpc.solve(state, 0.3, *reference, force=np.array((0.3, 0.1, -0.2)))
        assert mpc.status == "solved"
        stages.add(mpc.stages)
        states, inputs, slacks, height_slacks = sparse_solution(mpc, hard=mpc.stages == 1)
        np.testing.assert_allclose(mpc.predicted_inputs, inputs, atol=1e-7, rtol=0)
        np.testing.assert_allclose(mpc.predicted_states, states, atol=1e-8, rtol=0)
        np.testing.assert_allclose(mpc.slack_values, slacks, atol=1e-8, rtol=0)
        np.testing.assert_allclose(mpc.height_slack_values, height_slacks, atol=1e-8, rtol=0)
        height_slack = max(height_slack, mpc.height_slack_values.max())
        bounded += int(
            np.any(np.isclose(inputs, mpc.input_lower[:NU]) | np.isclose(inputs, mpc.input_upper[:NU]))
        )
    assert stages == ({1, 2} if slack else {1})
    assert bounded >= 3  # an input bound active in some
    assert (height_slack > 1e-3) == (height_limit is not None)


@pytest.mark.parametrize("slack", [False, True])
def test_bounds_hold_in_every_solution(slack):
    mpc = make_mpc(slack=slack)
    reference = hover_reference(mpc)
    rng = np.random.default_rng(2)
    for _ in range(20):
        state = np.concatenate((rng.uniform(-0.5, 0.5, 3), rng.uniform(-1, 1, 3), rng.uniform(-0.3, 0.3, 2)))
        state[2] += 1.0
        mpc.solve(state, rng.uniform(-math.pi, math.pi), *reference)
        assert mpc.status == "solved"
        inputs = mpc.predicted_inputs
        assert np.all(inputs >= mpc.input_lower[:NU] - BOUND_TOL)
        assert np.all(inputs <= mpc.input_upper[:NU] + BOUND_TOL)
        assert np.all(mpc.slack_values >= -BOUND_TOL)


def test_slack_is_zero_when_the_cross_track_constraint_is_inactive():
    mpc = make_mpc(slack=True)
    mpc.solve(np.array((0.0, 0.0, 1.0, 0, 0, 0, 0, 0)), 0.0, *hover_reference(mpc))
    assert mpc.status == "solved"
    assert np.abs(mpc.slack_values).max() < 1e-6
    np.testing.assert_allclose(mpc.predicted_inputs, [[MASS * GRAVITY, 0.0, 0.0]] * mpc.horizon, atol=1e-5)


def test_an_infeasible_start_still_solves_with_positive_slack():
    """0.5 m off in y: within one 0.1 s step no tilt can bring it inside e_max = 0.05 m."""
    start = np.array((0.0, 0.5, 1.0, 0, 0, 0, 0, 0))
    soft = make_mpc(slack=True)
    soft.solve(start, 0.0, *hover_reference(soft))
    assert soft.status == "solved"
    assert soft.slack_values[0] > 0.3
    assert soft.predicted_states[1, 1] - 0.05 == pytest.approx(soft.slack_values[0], abs=1e-4)
    hard_free = make_mpc(slack=False)
    hard_free.solve(start, 0.0, *hover_reference(hard_free))
    assert hard_free.status == "solved"
    assert hard_free.slack_values.max() == 0.0


def test_where_the_soft_problem_flies_the_qp_is_solved_again_about_the_attitude_its_solution_predicts():
    """0.5 m off in y and tilted: the hard problem is infeasible, so after the soft solve the QP is
    linearised again about the roll and pitch that its first solution predicts 0.3 s ahead (that of a
    QP without the second pass: the same first solve) and solved again. Its model is then
    :func:`linearize` at that attitude (itself checked against the equations above), its solution the
    sparse reference's on that model; a state within the band is solved once."""
    start = np.array((0.0, 0.5, 1.0, 0.0, 0.0, 0.0, 0.35, -0.2))
    one = make_mpc(slack=True, second_pass_seconds=None, **TUNED)
    one.solve(start, 0.3, *hover_reference(one))
    assert (one.stages, one.passes) == (2, 1)
    point = one.predicted_states[3, 6:8]
    assert np.abs(point - start[6:8]).max() > 0.1  # the second point is not the first
    two = make_mpc(slack=True, **TUNED)
    two.solve(start, 0.3, *hover_reference(two))
    assert two.passes == 2 and two.status in ("solved", "soft optimal")
    thrust = two.input_reference[0, 0]
    expected = linearize(np.concatenate((start[:6], point)), thrust, 0.3, np.zeros(3), MASS, TAU, 0.1)
    for model, linear in zip((two.A_d, two.B_d, two.c_d), expected, strict=True):
        np.testing.assert_allclose(model, linear, rtol=0, atol=1e-12)
    states, inputs, slacks, _ = sparse_solution(two, hard=two.stages == 1)
    np.testing.assert_allclose(two.predicted_inputs, inputs, atol=1e-7, rtol=0)
    np.testing.assert_allclose(two.predicted_states, states, atol=1e-8, rtol=0)
    np.testing.assert_allclose(two.slack_values, slacks, atol=1e-8, rtol=0)
    within = make_mpc(slack=True, **TUNED)
    within.solve(np.array((0.0, 0.02, 1.0, 0, 0, 0, 0, 0)), 0.0, *hover_reference(within))
    assert (within.stages, within.passes) == (1, 1)


@pytest.mark.parametrize("yaw", [0.0, 2.0])
def test_compensation_tilts_the_steady_input_against_the_estimated_force(yaw):
    """With f̂ in the model the input reference is the thrust vector ``m·g·e_z - f̂`` and the predicted
    inputs settle on it; without, both stay at hover. The model is linearised about the current (level)
    attitude, so the settled prediction misses the thrust's second-order loss with tilt,
    ``T·(1 - cos α) ≈ 0.02 N`` for the α ≈ 0.085 rad here: hence 0.03 N and 0.01 rad."""
    force = np.array((0.5, -0.3, 0.2))
    start = np.array((0.0, 0.0, 1.0, 0, 0, 0, 0, 0))
    hover = np.array((0.0, 0.0, MASS * GRAVITY))
    for compensation in (True, False):
        mpc = make_mpc(compensation=compensation)
        mpc.solve(start, yaw, *hover_reference(mpc), force=force)
        thrust, roll, pitch = mpc.input_reference[0]
        thrust_vector = thrust * rotation_matrix(quat_from_euler_zyx(roll, pitch, yaw))[:, 2]
        wanted = hover - force if compensation else hover  # without compensation f̂ = 0 in the model
        np.testing.assert_allclose(thrust_vector, wanted, atol=1e-9)
        settled = mpc.predicted_inputs[-1]  # the end of the horizon
        np.testing.assert_allclose(settled, mpc.input_reference[-1], atol=0.03 if compensation else 1e-5)
        np.testing.assert_allclose(settled[1:], mpc.input_reference[-1, 1:], atol=0.01)
        assert (abs(settled[1]) + abs(settled[2]) > 0.05) == compensation


def test_closed_loop_on_the_model_settles_on_the_reference_only_with_compensation():
    """The nonlinear model under a constant force, the MPC re-solved every 0.02 s: no offset with the
    force compensated; without, no integrator, so it settles off the reference against the force."""
    force = np.array((0.3, 0.0, 0.0))
    errors = {}
    for compensation in (True, False):
        mpc = make_mpc(compensation=compensation)
        reference = hover_reference(mpc)
        x = np.array((0.2, -0.1, 1.1, 0, 0, 0, 0, 0))
        for _ in range(250):
            u = mpc.solve(x, 0.0, *reference, force=force)
            x = solve_ivp(lambda t, s, u=u: nonlinear_rhs(s, u, 0.0, force), (0, 0.02), x, rtol=1e-8).y[:, -1]
        errors[compensation] = x[:3] - (0.0, 0.0, 1.0)
    assert np.abs(errors[True]).max() < 1e-3
    assert errors[False][0] > 0.05  # pushed along +x by the unknown force


# -- policy ----------------------------------------------------------------------------------------
class FakeEnv:
    """What :class:`MPCPolicy` reads from an env (``env.unwrapped``) and nothing else."""

    LAYOUT: ClassVar[dict[str, slice]] = {
        "position": slice(0, 3),
        "velocity": slice(3, 6),
        "attitude": slice(6, 12),
        "body_rates": slice(12, 15),
        "force": slice(15, 18),
        "torque": slice(18, 21),
        "last_action": slice(21, 25),
        "reference_position": slice(25, 28),
        "reference_velocity": slice(28, 31),
    }

    def __init__(self, action_type: str = "attitude", vehicle: str = "hummingbird") -> None:
        self.unwrapped = self
        self.cfg = SimpleNamespace(action_type=action_type, action_limits=ActionLimits(), policy_hz=50)
        self.vehicle = make_vehicle(vehicle)
        self.dt = 1.0 / 50.0  # the control period
        self.action_scaling = ActionScaling.for_vehicle(action_type, self.vehicle, ActionLimits())
        self.obs_layout = dict(self.LAYOUT)

    def observation(self, position, roll=0.0, pitch=0.0, yaw=0.0, force=(0, 0, 0), reference=(0, 0, 1)):
        rotation = rotation_matrix(quat_from_euler_zyx(roll, pitch, yaw))
        obs = np.zeros(31, dtype=np.float32)
        obs[0:3] = position
        obs[6:12] = rotation[:, :2].T.ravel()
        obs[15:18] = force
        obs[25:28] = reference
        return obs


def test_policy_conforms_and_returns_clipped_float32_actions():
    policy = MPCPolicy(compensation=True, slack=True)
    assert isinstance(policy, Policy)
    env = FakeEnv()
    policy.reset(env)
    rng = np.random.default_rng(3)
    for _ in range(10):
        obs = env.observation(
            rng.uniform(-2, 2, 3), *rng.uniform(-0.5, 0.5, 2), rng.uniform(-3, 3), force=rng.uniform(-2, 2, 3)
        )
        action = policy.act(obs)
        assert action.dtype == np.float32 and action.shape == (4,)
        assert np.all(np.abs(action) <= 1.0)


def test_policy_holds_the_equilibrium_of_the_estimated_force_at_any_heading():
    """At rest on the reference, tilted as the force needs, the action is that tilt and thrust."""
    force, yaw, vehicle = np.array((0.5, -0.3, 0.2)), 2.5, make_vehicle("hummingbird")
    thrust, roll, pitch = attitude_from_acceleration(-force / vehicle.mass, yaw, vehicle.mass)
    policy = MPCPolicy(compensation=True, yaw=yaw)
    env = FakeEnv()
    policy.reset(env)
    action = policy.act(env.observation((0, 0, 1), roll, pitch, yaw, force=force))
    tilt = math.radians(env.cfg.action_limits.max_tilt_deg)
    expected = (roll / tilt, pitch / tilt, 0.0, thrust / (vehicle.mass * GRAVITY) - 1.0)
    np.testing.assert_allclose(action, expected, atol=1e-4)


def test_policy_derives_its_model_and_bounds_from_the_vehicle_and_the_action():
    env = FakeEnv(vehicle="yuksel1kg")
    policy = MPCPolicy(max_thrust=3.0, max_tilt_deg=45.0)
    policy.reset(env)
    mpc = policy.mpc
    assert mpc.tau == pytest.approx(1.0 / AutopilotGains.for_vehicle(env.vehicle).attitude_p)
    assert mpc.input_upper[0] == pytest.approx(2.0 * env.vehicle.mass * GRAVITY)  # what the action can say
    assert mpc.input_upper[1] == pytest.approx(math.radians(env.cfg.action_limits.max_tilt_deg))
    assert MPCPolicy(attitude_time_constant=0.2).gains.attitude_time_constant == 0.2


def test_policy_refuses_another_action_type_and_unknown_gains():
    with pytest.raises(ValueError, match="attitude"):
        MPCPolicy().reset(FakeEnv(action_type="velocity"))
    with pytest.raises(ValueError, match="mpc.bogus"):
        MPCPolicy(bogus=1.0)
    env = FakeEnv()
    del env.obs_layout["reference_velocity"]
    with pytest.raises(ValueError, match="reference_velocity"):
        MPCPolicy().reset(env)


@pytest.mark.parametrize(
    ("setting", "value"),
    [("input_weight", (0.0, 200.0, 200.0)), ("primal_tolerance", 0.0), ("iteration_limit", 0)],
)
def test_gains_refuse_a_qp_daqp_cannot_solve(setting, value):
    """A zero input weight leaves the condensed QP's Hessian singular; DAQP needs a positive
    tolerance and at least one iteration: each refused by name."""
    with pytest.raises(ValueError, match=setting):
        MPCGains(**{setting: value})


@pytest.mark.parametrize(
    ("setting", "value"), [("height_limit", 0.0), ("height_limit", -0.05), ("height_priority", 0.5)]
)
def test_gains_refuse_a_height_band_that_is_none_or_comes_second(setting, value):
    """A height band of no width, or a height slack cheaper than the cross-track one (the path before
    the height, the climb the band exists to stop): refused by name and value."""
    with pytest.raises(ValueError, match=f"{setting}={value}"):
        MPCGains(**{setting: value})


@pytest.mark.parametrize("value", [0.0, 0.05, 2.5])
def test_gains_refuse_a_second_pass_outside_the_horizon(value):
    """The second pass reads the first solution's prediction: from one step (0.1 s) to the horizon (2
    s) ahead, or None; anything else refused by name and value."""
    with pytest.raises(ValueError, match=f"second_pass_seconds={value}"):
        MPCGains(second_pass_seconds=value)


def test_an_unsolved_hard_problem_falls_back_to_the_soft_one_and_then_to_the_equilibrium_input():
    """Drifting off the path at 0.44 m/s the cross-track constraint is active and the hard problem
    feasible (tests/test_mpc_exact_penalty.py): with DAQP allowed a single iteration it stops at its
    limit on the hard problem, the soft one is tried (``stages`` 2) and, stopped too, the MPC holds the
    equilibrium input (the hover thrust, level) rather than fly a partial solution; with the default
    limit the hard problem is solved in one stage."""
    state = np.array((0.0, 0.0, 1.0, 0.0, 0.44, 0.0, 0.0, 0.0))
    starved = make_mpc(slack=True, iteration_limit=1, **TUNED)
    command = starved.solve(state, 0.0, *hover_reference(starved))
    assert starved.stages == 2 and starved.status == "iteration limit"
    np.testing.assert_allclose(command, (MASS * GRAVITY, 0.0, 0.0), rtol=0, atol=1e-12)
    assert np.all(starved.slack_values == 0.0)
    solved = make_mpc(slack=True, **TUNED)
    solved.solve(state, 0.0, *hover_reference(solved))
    assert solved.stages == 1 and solved.status == "solved"


def test_a_batch_commands_what_one_controller_per_vehicle_commands():
    """Five vehicles in different states, references and forces, soft constraint and compensation on
    (vehicle 0 on the path, solved once per step, beside others that fly the soft problem and are
    solved a second time), over 30 control steps on a reference whose velocity changes, vehicle 2
    restarting at step 12: the batch's commands are those of five controllers of one vehicle each (the
    ``mpc`` agent's), fed the same observations, to 1e-6 on a normalised action (observed: bit for bit);
    the restarted vehicle's solver counts the DAQP iterations of a new controller's (a working set kept
    across the restart would warm-start it: the same exact solution in fewer iterations)."""
    env, count = FakeEnv(), 5
    gains = MPCGains(slack=True, compensation=True, position_weight=(1298.89, 1298.89, 625.0))
    tilt = math.radians(env.cfg.action_limits.max_tilt_deg)

    def configured(size: int) -> MPCController:
        controller = MPCController(gains, size)
        controller.configure(env.obs_layout, env.vehicle, env.dt, env.action_scaling, tilt)
        return controller

    batch, singles = configured(count), [configured(1) for _ in range(count)]
    rng = np.random.default_rng(4)
    start = rng.uniform(-0.3, 0.3, (count, 3)) + np.array((0.0, 0.0, 1.0))
    start[0] = (0.0, 0.0, 1.0)  # on the path: within the band, one pass, beside vehicles solved twice
    forces = rng.uniform(-1.0, 1.0, (count, 3))
    largest, passes = 0.0, set()
    for k in range(30):
        if k == 12:
            batch.restart(2)
            singles[2] = configured(1)  # a new controller: what a restart must amount to
        drift = 0.01 * k * np.array((1.0, -0.5, 0.2))
        frames = np.array(
            [
                env.observation(
                    start[v] + drift * v, 0.05 * v, -0.03 * v, 0.4 * v, forces[v], (0.02 * k, 0, 1)
                )
                for v in range(count)
            ]
        )
        frames[:, FakeEnv.LAYOUT["reference_velocity"]][:, 0] = 0.3 * np.sin(0.2 * k + np.arange(count))
        together = batch.actions(frames)
        passes.add(tuple(qp.passes for qp in batch.qps))
        alone = np.array([single.actions(frames[v : v + 1])[0] for v, single in enumerate(singles)])
        largest = max(largest, float(np.abs(together - alone).max()))
        if k >= 12:  # a restart is a new solver (no warm start from before): the same data, the same bits
            np.testing.assert_array_equal(together[2], alone[2])
            restarted, fresh = batch.qps[2], singles[2].qps[0]  # and the same DAQP iterations since
            assert (restarted.iterations, restarted.stages) == (fresh.iterations, fresh.stages)
        assert all(qp.status == "solved" for qp in batch.qps)
    assert largest <= 1e-6
    assert any(1 in step and 2 in step for step in passes)  # second passes over part of the batch

"""Yüksel et al.'s (2014) IDA-PBC controller (quad_wrench_env/agents/ida_pbc.py): the wrench action it drives,
its reading of eqs. (39)-(47), its closed loop against the target dynamics (32), and its plumbing."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from quad_wrench_env.agents.ida_pbc import (
    IDAPBCParams,
    IDAPBCPolicy,
    attitude_shift,
    equilibrium_rate,
    euler_rate_map,
    euler_zyx,
    force_equilibrium,
    load_param_set,
    steady_yaw,
)
from quad_wrench_env.engine.actions import ActionLimits, ActionScaling
from quad_wrench_env.vehicle import GRAVITY, Mixer, make_vehicle
from tests.conftest import controls_on_a_copy

E_Z = np.array((0.0, 0.0, 1.0))
P = np.diag((1.0, -1.0, -1.0))
"""The paper's NED/FRD frames to the project's z-up/FLU ones (π about x), module docstring."""


def rotation_zyx(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``R_z(ψ) R_y(θ) R_x(φ)`` as the product of the three elementary rotations (the reference the
    policy's thrust direction is held to)."""
    c, s = np.cos, np.sin
    rz = np.array(((c(yaw), -s(yaw), 0.0), (s(yaw), c(yaw), 0.0), (0.0, 0.0, 1.0)))
    ry = np.array(((c(pitch), 0.0, s(pitch)), (0.0, 1.0, 0.0), (-s(pitch), 0.0, c(pitch))))
    rx = np.array(((1.0, 0.0, 0.0), (0.0, c(roll), -s(roll)), (0.0, s(roll), c(roll))))
    return rz @ ry @ rx


def _env_kwargs(**overrides):
    """FanTracking as a free-flight test bench: yuksel1kg (Yüksel et al.'s (2014) m = 1 kg, J = diag(0.13,
    0.13, 0.22)), wrench action, no fan, drag-free as in the paper's Sec. V, nominal rotors, a roomy arena."""
    return {
        "vehicle": "yuksel1kg",
        "action_type": "wrench",
        "estimator": "oracle",
        "fan": {"enabled": False, "height": 5.0},
        "vehicle_params": {"drag_area": 0.0, "rotor_drag_decel": 0.0},
        "kf_spread": 0.0,
        "arena": {"x_min": -50.0, "x_max": 50.0, "y_half_width": 50.0, "z_max": 50.0},
        **overrides,
    }


def _forward_map(vehicle, speeds: np.ndarray) -> np.ndarray:
    """McKinnon & Schoellig 2016 eqs. (1), (8)-(10), written out for the X configuration (motors 1 front-left,
    2 back-left, 3 back-right, 4 front-right; 1 and 3 react about +z): ``[c_t, τ_x, τ_y, τ_z]``."""
    k, l, p = vehicle.kf, vehicle.arm, vehicle.km_over_kf * vehicle.kf
    w1, w2, w3, w4 = speeds**2
    return np.array(
        (
            k * (w1 + w2 + w3 + w4),  # (1)
            l * (k * w1 + k * w2 - k * w3 - k * w4),  # (8)
            l * (-k * w1 + k * w2 + k * w3 - k * w4),  # (9)
            p * w1 - p * w2 + p * w3 - p * w4,  # (10)
        )
    )


# -- the wrench action ----------------------------------------------------------------------------------
def test_wrench_action_mixer_round_trip(make_env):
    """The ``wrench`` action through the engine's ``controls`` kernel gives motor speeds whose thrust
    and body torques (the independent forward map and the mixer) are the commanded ones, and its
    scales are those the policy divides by: ``(1 + a0) m g`` and ``a_{1..3}·(l, l, k_m/k_f)·m g/2``.
    Only commands the motors can make are drawn (every ``Ω²`` of the independent map's inverse within
    ``[Ω_min², Ω_max²]``), so no saturation handling acts. Tolerance: ``Ω = sqrt(Ω²)`` then ``Ω²``
    loses a few ulps, ~1e-15 relative; 1e-9 leaves room."""
    vehicle = make_vehicle("yuksel1kg")
    env = make_env(**_env_kwargs())
    env.reset(seed=0)
    fleet = env.unwrapped.fleet
    weight = vehicle.mass * GRAVITY
    scale = np.array((weight, *(0.5 * weight * np.array((vehicle.arm, vehicle.arm, vehicle.km_over_kf)))))
    reference = np.array([_forward_map(vehicle, np.sqrt(row)) for row in np.eye(4)]).T  # Ω² -> wrench
    rng = np.random.default_rng(7)
    checked = 0
    while checked < 200:
        action = rng.uniform(-1.0, 1.0, 4)
        command = np.array((1.0 + action[0], *action[1:])) * scale
        squared = np.linalg.solve(reference, command)
        if np.any(squared < vehicle.min_rotor_speed**2) or np.any(squared > vehicle.max_rotor_speed**2):
            continue
        checked += 1
        fields = controls_on_a_copy(fleet, action[None])
        speeds = fields["speeds"][0]
        assert not fields["saturated"].any()
        np.testing.assert_allclose(_forward_map(vehicle, speeds), command, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(Mixer(vehicle).wrench(speeds), command, rtol=1e-9, atol=1e-12)


# -- Sec. IV: eqs. (37)-(47) ----------------------------------------------------------------------------
def _printed_40_41(f_star: np.ndarray, yaw: float, rho: float) -> tuple[float, float]:
    """Eqs. (40)-(41) exactly as printed, in the paper's NED frames."""
    fx, fy = f_star[0], f_star[1]
    roll = math.asin((-fx * math.cos(yaw) - fy * math.sin(yaw)) / rho)
    pitch = -math.asin((fx * math.sin(yaw) - fy * math.cos(yaw)) / (rho * math.cos(roll)))
    return roll, pitch


def test_force_equilibrium_solves_eq_37():
    """(39)-(41) substituted into (37): ``ρ* R(φ*, θ*, ψ) e₃ - m g e₃ = f*`` (project frames) and the same
    in the paper's NED frames (``R_paper = P R P``, ``f*_paper = P f*``, angles ``(φ, -θ, -ψ)``): the
    force balance to 1e-9 N (double-precision trigonometry on ~10 N: ~1e-14). With ``f* = -f_e``
    (Sec. V-C) gravity, thrust and the external force sum to zero. The printed (40)-(41), with their
    right-hand sides swapped, do not solve (37)."""
    vehicle = make_vehicle("yuksel1kg")
    m, g = vehicle.mass, GRAVITY
    rng = np.random.default_rng(3)
    for _ in range(200):
        external = rng.uniform(-4.0, 4.0, 3)
        f_star = -external
        yaw = rng.uniform(-math.pi, math.pi)
        rho, roll, pitch = force_equilibrium(f_star, yaw, m)
        assert rho == pytest.approx(math.sqrt(f_star[0] ** 2 + f_star[1] ** 2 + (f_star[2] + m * g) ** 2))
        thrust = rho * rotation_zyx(roll, pitch, yaw) @ E_Z
        np.testing.assert_allclose(thrust - m * g * E_Z, f_star, atol=1e-9)  # (37): f_ne = f*
        np.testing.assert_allclose(thrust - m * g * E_Z + external, 0.0, atol=1e-9)  # at rest
        # (37) as printed, NED: ρ R_paper e₃ = (-f*_x, -f*_y, -f*_z + m g)
        paper_force = P @ f_star
        left = rho * rotation_zyx(roll, -pitch, -yaw) @ E_Z
        np.testing.assert_allclose(
            left, (-paper_force[0], -paper_force[1], -paper_force[2] + m * g), atol=1e-9
        )
    f_star, yaw = np.array((1.0, 0.0, 0.0)), 0.0  # a push along x must pitch, not roll
    rho, roll, pitch = force_equilibrium(f_star, yaw, m)
    assert abs(roll) < 1e-12 and pitch > 0.0
    printed = _printed_40_41(P @ f_star, yaw, rho)
    assert abs(printed[0]) > 0.05 and abs(printed[1]) < 1e-12  # the printed ones roll


def test_torque_shift_puts_the_rest_attitude_of_eq_44_at_the_equilibrium():
    """(46)-(47) read as ``η̄ = η* - K_p⁻¹ τ̃_e`` (roll, pitch; ψ̄ unshifted): substituting into (44) at
    rest, ``0 = K_p(η̄ - η_ss) + τ̃_e``, gives ``η_ss = (φ*, θ*, ψ_ss)`` with (45)'s
    ``ψ_ss = ψ̄ + τ̃_ψ/k_p^ψ`` (exact up to rounding: 1e-12 rad); integrating (44) from rest reaches it
    (k_d = 2, k_p >= 1: poles ``-1 ± sqrt(1 - k_p)``, decay e⁻ᵗ at worst with a factor t at k_p = 1,
    so after 30 s less than 30·e⁻³⁰ ~ 3e-12 of the ~1 rad start is left; 1e-6 rad is the solver's)."""
    rng = np.random.default_rng(5)
    k_d = 2.0
    for _ in range(10):
        k_p = tuple(rng.uniform(1.0, 40.0, 3))
        torque = rng.uniform(-1.0, 1.0, 3)
        roll_star, pitch_star = rng.uniform(-0.3, 0.3, 2)
        yaw_bar = rng.uniform(-math.pi, math.pi)
        roll_bar, pitch_bar = attitude_shift((roll_star, pitch_star), torque, k_p)
        eta_bar = np.array((roll_bar, pitch_bar, yaw_bar))
        at_rest = eta_bar + torque / np.array(k_p)  # (45)
        expected = (roll_star, pitch_star, steady_yaw(yaw_bar, torque, k_p))
        np.testing.assert_allclose(at_rest, expected, atol=1e-12)

        gains = np.array(k_p)

        def rotation_44(_t: float, y: np.ndarray, gains=gains, eta_bar=eta_bar, torque=torque) -> np.ndarray:
            return np.concatenate((y[3:], -k_d * y[3:] + gains * (eta_bar - y[:3]) + torque))  # (44)

        solution = solve_ivp(rotation_44, (0.0, 30.0), np.zeros(6), rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(solution.y[:3, -1], expected, atol=1e-6)


def test_controller_holds_the_rest_attitude_against_the_torque(make_env):
    """The whole law (25), (31), (46)-(47): at ``η = η*`` (roll, pitch) and ``ψ = ψ_ss``, at rest, with
    the estimate equal to the truth, the commanded body torque cancels the external one, so the
    physical rotation is in equilibrium (float arithmetic on ~1 N·m: 1e-9). The yaw torque stays
    within the action's ±0.078 N·m, so neither the yaw filter (off here) nor the limit acts."""
    env = make_env(**_env_kwargs())
    policy = IDAPBCPolicy(mode="force", target_force=(0.8, -0.5, 0.3), yaw_torque_time_constant=0.0)
    policy.reset(env)
    params = policy.params
    rng = np.random.default_rng(11)
    for _ in range(20):
        torque_body = np.array((*rng.uniform(-1.0, 1.0, 2), rng.uniform(-0.05, 0.05)))
        yaw_bar = rng.uniform(-math.pi, math.pi)
        policy._yaw_bar = yaw_bar
        # ψ_ss depends on the torque in Euler coordinates, which depends on the attitude: fixed point
        roll, pitch, yaw = 0.0, 0.0, yaw_bar
        for _ in range(100):
            _, roll, pitch = force_equilibrium(np.array(params.target_force), yaw, 1.0)
            generalised = euler_rate_map(roll, pitch).T @ torque_body
            yaw = steady_yaw(yaw_bar, generalised, params.k_p)
        rotation = rotation_zyx(roll, pitch, yaw)
        torque_world = rotation @ torque_body
        generalised = euler_rate_map(roll, pitch).T @ rotation.T @ torque_world
        roll_bar, pitch_bar = attitude_shift((roll, pitch), generalised, params.k_p)
        eta_bar = np.array((roll_bar, pitch_bar, yaw_bar))
        body = policy.body_torque(rotation, np.zeros(3), eta_bar, torque_world)
        np.testing.assert_allclose(body + torque_body, 0.0, atol=1e-9)
        np.testing.assert_allclose(euler_zyx(rotation), (roll, pitch, yaw), atol=1e-12)


def test_equilibrium_rate_is_the_derivative_of_eqs_40_41():
    """:func:`equilibrium_rate` against central differences of (40)-(41) (step 1e-6: truncation ~1e-12,
    rounding ~1e-10 on angles of ~0.1 rad; 1e-7 leaves room)."""
    rng = np.random.default_rng(2)
    for _ in range(50):
        force = np.array((*rng.uniform(-3.0, 3.0, 2), rng.uniform(5.0, 15.0)))
        rate = rng.uniform(-2.0, 2.0, 3)
        yaw, yaw_rate = rng.uniform(-math.pi, math.pi), rng.uniform(-1.0, 1.0)
        h = 1e-6

        def angles(s: float, force=force, rate=rate, yaw=yaw, yaw_rate=yaw_rate) -> np.ndarray:
            return np.array(force_equilibrium(force + s * rate - GRAVITY * E_Z, yaw + s * yaw_rate, 1.0)[1:])

        numeric = (angles(h) - angles(-h)) / (2.0 * h)
        np.testing.assert_allclose(equilibrium_rate(force, rate, yaw, yaw_rate)[:2], numeric, atol=1e-7)


# -- the closed loop --------------------------------------------------------------------------------------
def _target(m_d: float, k: float, r: float, force: float, t_step: float, times: np.ndarray, lag=None):
    """Eq. (32) on one axis, ``m_d ẍ = -k x - r ẋ + f_e`` after a step of ``f_e`` at ``t_step``; with
    ``lag = (τ, attitude)`` the controller's force ``(m/m_d)(-k x - r ẋ + f_e) - f_e`` (m = 1 kg) reaches
    the vehicle through a first-order lag τ and, with ``attitude = (ω, ζ)``, through the tilt loop
    ``(2ζω s + ω²)/(s² + 2ζω s + ω²)`` (the damper on ``η̇ - η̇*``)."""

    def rhs(t: float, y: np.ndarray) -> list[float]:
        external = force if t >= t_step else 0.0
        command = (-k * y[0] - r * y[1] + external) / m_d - external
        if lag is None:
            return [y[1], command + external, 0.0, 0.0, 0.0]
        tau, attitude = lag
        applied, d_state = y[2], [0.0, 0.0]
        if attitude is not None:
            w, z = attitude
            applied = w * w * y[3] + 2.0 * z * w * y[4]
            d_state = [y[4], -w * w * y[3] - 2.0 * z * w * y[4] + y[2]]
        return [y[1], applied + external, (command - y[2]) / tau, *d_state]

    solution = solve_ivp(
        rhs, (0.0, times[-1]), np.zeros(5), t_eval=times, max_step=0.002, rtol=1e-9, atol=1e-12
    )
    return solution.y[0]


@pytest.mark.parametrize("axis", [2, 0])
def test_closed_loop_with_the_true_wrench_follows_the_target_dynamics(make_env, axis):
    """A 1 N step of the true external force (oracle estimator) at 0.5 s, 3 s on: each position axis
    against (32) integrated here with the same ``m_d``, ``K_x``, ``R_d`` (default set, ``m_d = m`` so
    that only feedback acts through the actuators; the push acts on the body itself).

    Tolerance from the lags: the commanded force reaches the vehicle through the motors (first order,
    20 ms) after the 50 Hz hold (10 ms on average): ~30 ms along the thrust (z); a horizontal force
    also needs the tilt, whose loop (ω_η = 6 rad/s, ζ = 0.8, damping ``η̇ - η̇*``) adds its transfer.
    The same loop through these lags deviates from (32) by ``d`` (~6 mm in z, ~19 mm in x, of peaks
    of 0.16 m and 0.45 m); the tolerance is ``2d + 2 mm`` (twice: the hold is a delay, not a lag, and
    the tilt loop is nonlinear and sees the yaw; 2 mm for the rest). The other axes stay within
    2 mm, and the step's static deflection ``f/k`` is reached within the tolerance."""
    force = -1.0 if axis == 2 else 1.0
    wrench = [0.5, 100.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    wrench[2 + axis] = force
    env = make_env(**_env_kwargs(external_wrench=[wrench], episode_seconds=3.5))
    params = load_param_set()
    policy = IDAPBCPolicy(dataclasses.replace(params, mode="position"))
    observation, info = env.reset(seed=0, options={"offset_y": 0.0, "fan_motion": "static"})
    policy.reset(env)
    start = info["position"].copy()
    times, positions = [0.0], [start]
    done = False
    while not done:
        observation, _, terminated, truncated, info = env.step(policy.act(observation))
        done = terminated or truncated
        times.append(info["time"])
        positions.append(info["position"].copy())
    assert not terminated
    times, moved = np.array(times), np.array(positions) - start
    m_d, k, r = params.m_d, params.k_x[axis], params.r_x[axis]
    ideal = _target(m_d, k, r, force, 0.5, times)
    attitude = None if axis == 2 else (math.sqrt(params.k_p[0] / params.n_d[0]), 0.8)
    lagged = _target(m_d, k, r, force, 0.5, times, lag=(0.03, attitude))
    tolerance = 2.0 * np.abs(lagged - ideal).max() + 0.002
    assert tolerance < 0.25 * np.abs(ideal).max()  # a test, not a formality
    np.testing.assert_allclose(moved[:, axis], ideal, atol=tolerance)
    assert moved[-1, axis] == pytest.approx(force / k, abs=tolerance)
    others = [i for i in range(3) if i != axis]
    assert np.abs(moved[:, others]).max() < 0.002


def test_balance_with_the_observer_meets_the_acceptance(make_env):
    """Sec. V-C with Yüksel et al.'s (2014) observer (c = 5 and 0.5): a constant 1 N push along x from the
    start and 1 N along -z from 1 s, ``f* = -f̂_e`` (QC4). Over 3-4.5 s (the force estimate settles as
    e^{-5t}: e^{-10} after 2 s) the mean acceleration is below 0.05 m/s² and the exerted force
    ``f_ne = ρ R e₃ - m g e₃`` (true rotor thrust and attitude) within 10 % of ``|f_e|`` of ``-f_e``
    on every axis (the issue's acceptance)."""
    wrench = [[0.0, 100.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0], [1.0, 100.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0]]
    env = make_env(**_env_kwargs(estimator="observer", external_wrench=wrench, episode_seconds=4.5))
    policy = IDAPBCPolicy(dataclasses.replace(load_param_set("QC4"), mode="balance"))
    observation, info = env.reset(seed=1, options={"offset_y": 0.0, "fan_motion": "static"})
    policy.reset(env)
    base = env.unwrapped
    weight = base.vehicle.mass * GRAVITY
    times, velocities, exerted = [], [], []
    done = False
    while not done:
        observation, _, terminated, truncated, info = env.step(policy.act(observation))
        done = terminated or truncated
        thrust = base.fleet.step_buffer.fields["rotor_wrench"][0, 0]  # true rotors: c_t, last step
        rotation = base.world.state().rotation[0]
        times.append(info["time"])
        velocities.append(info["velocity"].copy())
        exerted.append(thrust * rotation[:, 2] - weight * E_Z)
    times, velocities, exerted = np.array(times), np.array(velocities), np.array(exerted)
    window = times > 3.0 - 1e-9
    first, last = np.flatnonzero(window)[[0, -1]]
    acceleration = (velocities[last] - velocities[first - 1]) / (times[last] - times[first - 1])
    assert np.linalg.norm(acceleration) < 0.05
    target = -np.array((1.0, 0.0, -1.0))
    assert np.all(np.abs(exerted[window].mean(axis=0) - target) <= 0.1 * np.linalg.norm(target))


# -- plumbing -----------------------------------------------------------------------------------------------
def test_actions_are_float32_within_bounds(make_env):
    """A hard 1.5 s push (3.8 N, 0.9 N·m: within the action's 1.23 N·m) with the observer: every
    action is a float32 (4,) in [-1, 1] and the flight goes on."""
    env = make_env(
        **_env_kwargs(estimator="observer", external_wrench=[[0.5, 2.0, 2.0, -1.0, -3.0, 0.8, 0.4, 0.05]])
    )
    policy = IDAPBCPolicy.from_param_set("QC1")
    observation, _ = env.reset(seed=0, options={"offset_y": 0.0, "fan_motion": "static"})
    policy.reset(env)
    assert policy.mode == "position"
    for _ in range(100):
        action = policy.act(observation)
        assert action.dtype == np.float32 and action.shape == (4,)
        assert np.all(np.abs(action) <= 1.0)
        observation, _, terminated, _, _ = env.step(action)
        assert not terminated


def test_policy_scales_are_the_action_scales(make_env):
    """The thrust and body torque the policy computed come back out of the action through the env's
    own action map and the independent forward map (McKinnon & Schoellig 2016 eqs. 1, 8-10), to 1e-5 relative
    (the action is float32: 6e-8 relative, times scales of order 1)."""
    env = make_env(
        **_env_kwargs(estimator="observer", external_wrench=[[0.0, 9.0, 0.5, 0.2, -0.3, 0.2, -0.1, 0.0]])
    )
    policy = IDAPBCPolicy()
    observation, _ = env.reset(seed=0, options={"offset_y": 0.0, "fan_motion": "static"})
    policy.reset(env)
    base = env.unwrapped
    for _ in range(50):
        action = policy.act(observation)
        if np.all(np.abs(action) < 1.0):
            speeds = controls_on_a_copy(base.fleet, action[None])["speeds"][0]
            wanted = np.array((policy.last["rho"], *policy.last["body_torque"]))
            np.testing.assert_allclose(_forward_map(base.vehicle, speeds), wanted, rtol=1e-5, atol=1e-6)
        observation, *_ = env.step(action)


def test_wrong_action_type_and_missing_blocks_are_refused(make_env):
    with pytest.raises(ValueError, match="action_type='wrench'"):
        IDAPBCPolicy().reset(make_env(vehicle="yuksel1kg", action_type="velocity"))
    env = make_env(**_env_kwargs())
    layout = {k: v for k, v in env.unwrapped.obs_layout.items() if k != "torque"}
    base = env.unwrapped
    view = {"cfg": base.cfg, "vehicle": base.vehicle, "action_scaling": base.action_scaling, "dt": base.dt}
    stub = SimpleNamespace(unwrapped=SimpleNamespace(obs_layout=layout, **view))
    with pytest.raises(ValueError, match=r"observation blocks \['torque'\]"):
        IDAPBCPolicy().reset(stub)


def test_bad_parameters_are_refused_by_name():
    with pytest.raises(ValueError, match=r"ida_pbc\.k_q"):
        IDAPBCPolicy(k_q=1.0)
    with pytest.raises(ValueError, match=r"ida_pbc\.m_d"):
        IDAPBCPolicy(m_d="heavy")
    with pytest.raises(ValueError, match=r"ida_pbc\.r_eta"):
        IDAPBCPolicy(r_eta=(1.0, 1.0, 1.0), k_d=2.0)  # K_v < 0
    with pytest.raises(ValueError, match=r"ida_pbc\.mode"):
        IDAPBCPolicy(mode="hover")
    with pytest.raises(ValueError, match=r"ida_pbc\.k_x"):
        IDAPBCPolicy(k_x=(1.0, 2.0))
    with pytest.raises(ValueError, match="either params or keyword"):
        IDAPBCPolicy(IDAPBCParams(), m_d=1.0)
    with pytest.raises(ValueError, match="no IDA-PBC parameter set"):
        load_param_set("QC9")


def test_shipped_sets_load_and_the_default_is_the_dataclass_default():
    assert load_param_set() == IDAPBCParams()
    sets = {name: load_param_set(name) for name in ("QC1", "QC2", "QC3", "QC4")}
    assert sets["QC1"].m_d < sets["QC2"].m_d and sets["QC1"].r_x[2] < sets["QC2"].r_x[2]  # Sec. V-B
    qc3, qc4 = sets["QC3"], sets["QC4"]
    assert qc3.n_d[0] < qc4.n_d[0] and qc3.k_p[0] < qc4.k_p[0]  # Sec. V-C
    assert qc3.k_p[0] / qc3.n_d[0] < qc4.k_p[0] / qc4.n_d[0]  # QC4 reacts faster


def test_target_force_block_drives_the_force_mode():
    """With an observation block ``target_force`` (the ForceExertion env's), ``"auto"`` is the force
    mode and ``f*`` is the block, in the world frame; without one, ``params.target_force``."""
    vehicle = make_vehicle("yuksel1kg")
    names = [
        ("position", 3),
        ("velocity", 3),
        ("attitude", 6),
        ("body_rates", 3),
        ("force", 3),
        ("torque", 3),
        ("last_action", 4),
        ("target_force", 3),
    ]
    layout, start = {}, 0
    for name, width in names:
        layout[name] = slice(start, start + width)
        start += width
    cfg = SimpleNamespace(action_type="wrench", policy_hz=50)
    scaling = ActionScaling.for_vehicle("wrench", vehicle, ActionLimits())
    base = SimpleNamespace(cfg=cfg, vehicle=vehicle, obs_layout=layout, action_scaling=scaling, dt=0.02)
    env = SimpleNamespace(unwrapped=base)
    observation = np.zeros(start, dtype=np.float32)
    observation[layout["attitude"]] = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0)
    observation[layout["target_force"]] = (2.0, -1.0, 0.5)
    policy = IDAPBCPolicy(target_force=(9.0, 9.0, 9.0))
    policy.reset(env)
    assert policy.mode == "force"
    policy.act(observation)
    np.testing.assert_allclose(policy.last["f_star"], (2.0, -1.0, 0.5))
    del layout["target_force"]
    policy.reset(env)
    assert policy.mode == "position"
    policy = IDAPBCPolicy(mode="force", target_force=(0.3, 0.0, 0.0))
    policy.reset(env)
    policy.act(observation[: layout["last_action"].stop])
    np.testing.assert_allclose(policy.last["f_star"], (0.3, 0.0, 0.0))


def test_with_no_set_named_it_flies_the_tasks_default_set(make_env):
    """``configs/ida_pbc.yaml``'s ``task_defaults``: QC4 on ForceExertion (the default set crashes
    under the ceiling there), the ``default`` set on other tasks; a named set is kept everywhere."""
    pressing = gym.make("QuadWrench/ForceExertion-v0")
    try:
        pressing.reset(seed=0)
        policy = IDAPBCPolicy()
        policy.reset(pressing)
        assert policy.params == load_param_set("QC4")
        named = IDAPBCPolicy("QC2")
        named.reset(pressing)
        assert named.params == load_param_set("QC2")
    finally:
        pressing.close()
    elsewhere = make_env(**_env_kwargs())
    elsewhere.reset(seed=0)
    policy.reset(elsewhere)
    assert policy.params == load_param_set()

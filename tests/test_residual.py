"""The ``residual`` action type: the vehicle flies its base controller's action plus the policy's, times
``residual.scale``, clipped (quad_wrench_env/control/residual.py). At zero action it flies the classical
agent's numbers bit for bit; a correction enters as scale x action; each vehicle's base restarts with its
episode; what it cannot fly is refused by name."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import quad_wrench_env  # noqa: F401  (registers the env ids)
from quad_wrench_env.agents import make_agent
from quad_wrench_env.control.pid_controller import PIDController, PIDGains
from quad_wrench_env.control.residual import ResidualActions
from quad_wrench_env.engine.actions import ResidualSettings
from quad_wrench_env.vehicle import GRAVITY

REJECTION = "QuadWrench/DisturbanceRejection-v0"
RESIDUAL = {"action_type": "residual", "residual": {"base": "pid", "params": {"compensation": True}}}
STEPS = 120


def _fly(env, actions, seed: int = 3) -> list[np.ndarray]:
    """Positions, velocities and the observation without its last-action block at every step."""
    observation, _ = env.reset(seed=seed, options={"scenario": "jet_crossing"})
    keep = np.ones(observation.shape, dtype=bool)
    keep[env.unwrapped.obs_layout["last_action"]] = False
    trace = []
    for _ in range(STEPS):
        observation, _, terminated, _, info = env.step(actions(observation))
        trace += [info["position"], info["velocity"], observation[keep]]
        assert not terminated
    return trace


MPC_GAINS = {"position_weight": [1298.89, 1298.89, 625.0], "velocity_weight": [103.91, 103.91, 50.0]}


@pytest.mark.parametrize(
    "base, params, level",
    [
        ("pid", {"compensation": True}, "attitude"),
        ("pid", {"compensation": True}, "acceleration"),
        ("mpc", {**MPC_GAINS, "slack": True, "compensation": True}, "attitude"),
    ],
)
def test_at_zero_action_the_residual_flies_the_classical_agent_bit_for_bit(base, params, level):
    agent = make_agent(base, **params)
    settings = {"action_type": "residual", "residual": {"base": base, "params": params, "level": level}}
    classical, residual = gym.make(REJECTION, action_type="attitude"), gym.make(REJECTION, **settings)
    agent.reset(classical)
    expected = _fly(classical, agent.act)
    got = _fly(residual, lambda _: np.zeros(4, dtype=np.float32))
    for a, b in zip(expected, got, strict=True):
        np.testing.assert_array_equal(a, b)
    classical.close()
    residual.close()


def test_a_correction_is_added_as_scale_times_the_action_and_clipped():
    """A residual env flown with random corrections against an attitude env flown with
    ``clip(b + 1.2 a)``, ``b`` from a PID of the same gains beside it."""
    settings = {**RESIDUAL, "residual": {**RESIDUAL["residual"], "scale": 1.2}}
    residual, attitude = gym.make(REJECTION, **settings), gym.make(REJECTION, action_type="attitude")
    rng = np.random.default_rng(0)
    corrections = rng.uniform(-1.0, 1.0, (STEPS, 4)).astype(np.float32)
    base = PIDController(PIDGains(compensation=True))
    base.configure(
        attitude.unwrapped.obs_layout,
        attitude.unwrapped.vehicle,
        attitude.unwrapped.dt,
        attitude.unwrapped.action_scaling,
        np.radians(30.0),
    )
    steps = iter(range(STEPS))
    clipped = []

    def by_hand(observation):
        k = next(steps)
        flown = base.actions(observation[None])[0] + 1.2 * corrections[k].astype(float)
        clipped.append(np.any(np.abs(flown) > 1.0))
        return np.clip(flown, -1.0, 1.0)

    expected = _fly(attitude, by_hand)
    replay = iter(corrections)
    got = _fly(residual, lambda _: next(replay))
    for a, b in zip(expected, got, strict=True):
        np.testing.assert_array_equal(a, b)
    assert any(clipped)  # the clip was met
    residual.close()
    attitude.close()


@pytest.mark.parametrize(
    "correction",
    [(0.3, -0.5, 0.2, 0.4), (-0.8, 0.9, -0.3, 0.0), (0.0, 1.0, -0.5, -1.0), (0.9, 0.2, -0.6, 0.5)],
)
def test_at_the_acceleration_level_a_correction_is_an_acceleration_the_pid_flies(correction):
    """On the path at rest, no force (eq. (3)'s ``a_des`` = 0), the correction ``c = s·g·a`` (s = 0.5) is
    the acceleration flown: the thrust vector ``F = m·(c + g·e_z)`` as tilt and thrust, the body z axis of
    ``R = Rz(0)·Ry(θ)·Rx(φ)``, ``(sin θ cos φ, -sin φ, cos θ cos φ)``, along it, so ``φ = -asin(F_y/|F|)``,
    ``θ = atan2(F_x, F_z)``, ``T = |F|``; where φ or θ passes the 30° limit (the last two cases) both are
    clipped to it and the thrust's vertical part holds ``F_z`` (the vertical channel first). The yaw rate
    is ``s·a_4`` of its range."""
    settings = ResidualSettings(base="pid", scale=0.5, level="acceleration")
    env = gym.make(REJECTION, action_type="residual", residual=dataclasses.asdict(settings))
    u = env.unwrapped
    tilt_limit = np.radians(30.0)
    actions = ResidualActions(settings, 1, u.obs_layout, u.vehicle, u.dt, u.action_scaling, tilt_limit)
    observation = np.zeros(u.observation_space.shape, dtype=np.float32)
    layout = u.obs_layout
    observation[layout["position"]] = observation[layout["reference_position"]] = (0.0, 0.0, 1.5)
    observation[layout["attitude"]] = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0)  # level, heading 0
    a = np.array(correction, dtype=np.float32)
    roll, pitch, yaw_rate, thrust = u.action_scaling.to_command(actions.flown(observation[None], a[None])[0])
    force = u.vehicle.mass * (0.5 * GRAVITY * a[:3].astype(float) + np.array((0.0, 0.0, GRAVITY)))
    expected = np.array((-np.arcsin(force[1] / np.linalg.norm(force)), np.arctan2(force[0], force[2])))
    clipped = np.clip(expected, -tilt_limit, tilt_limit)
    assert (roll, pitch) == pytest.approx(tuple(clipped), abs=1e-5)
    if np.array_equal(clipped, expected):
        assert thrust == pytest.approx(np.linalg.norm(force), rel=1e-5)
    else:
        assert thrust * np.cos(roll) * np.cos(pitch) == pytest.approx(force[2], rel=1e-5)
    assert yaw_rate == pytest.approx(0.5 * a[3] * u.action_scaling.yaw_rate, abs=1e-5)
    env.close()


def test_a_vehicles_base_restarts_with_its_episode_and_leaves_the_others():
    """After steps, vehicle 0 restarts: its action is a fresh controller's on the same observation; vehicle
    1's that of the controller that went on (its integral and reference history kept)."""
    env = gym.make(REJECTION, action_type="attitude")
    observation, _ = env.reset(seed=1, options={"scenario": "gusts"})
    base = env.unwrapped

    def controller(count):
        c = PIDController(PIDGains(compensation=True), count)
        c.configure(base.obs_layout, base.vehicle, base.dt, base.action_scaling, np.radians(30.0))
        return c

    pair, alone = controller(2), controller(1)
    for _ in range(30):
        action = pair.actions(np.stack([observation, observation]))[1]
        alone.actions(observation[None])
        observation, *_ = env.step(action)
    pair.restart(np.array([0]))
    got = pair.actions(np.stack([observation, observation]))
    np.testing.assert_array_equal(got[0], controller(1).actions(observation[None])[0])
    np.testing.assert_array_equal(got[1], alone.actions(observation[None])[0])
    assert not np.array_equal(got[0], got[1])
    env.close()


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"action_type": "residual"}, r"action_type='residual' with residual.base=None: .* needs a base"),
        (
            {"action_type": "attitude", "residual": {"base": "pid"}},
            r"action_type='attitude' with residual.base",
        ),
        (
            {"action_type": "residual", "residual": {"base": "lqr"}},
            r"residual.base='lqr' .* allowed: \['mpc', 'pid'\]",
        ),
        ({**RESIDUAL, "residual": {"base": "pid", "scale": 0.0}}, "residual.scale=0.0"),
        ({**RESIDUAL, "residual": {"base": "pid", "scale": -0.2}}, "residual.scale=-0.2"),
        ({**RESIDUAL, "residual": {"base": "pid", "params": {"k_q": 1.0}}}, "residual.params.k_q"),
        ({**RESIDUAL, "residual": {"base": "pid", "level": "jerk"}}, r"residual.level='jerk' .* allowed"),
        (
            {**RESIDUAL, "residual": {"base": "mpc", "level": "acceleration"}},
            r"residual.level='acceleration' .* base 'mpc' has none",
        ),
        ({"action_type": "steer"}, r"unknown action_type 'steer'; allowed: .*'residual'"),
    ],
)
def test_a_residual_it_cannot_fly_is_refused_by_name(settings, message):
    with pytest.raises(ValueError, match=message):
        gym.make(REJECTION, **settings)


def test_a_task_without_a_reference_refuses_the_pid_base():
    with pytest.raises(ValueError, match=r"needs the observation blocks \['reference_position'"):
        gym.make("QuadWrench/FanTracking-v1", action_type="residual", residual={"base": "pid"})


@pytest.mark.parametrize(
    "base, params", [("pid", {"compensation": True}), ("mpc", {**MPC_GAINS, "compensation": True})]
)
def test_a_compensating_base_reads_the_estimate_the_policy_does_not_see(base, params):
    """With ``observe_wrench: false`` the policy's observation has zeros for the wrench, but the base
    (on board, beside the estimator) compensates all the same: at zero action the vehicle flies the
    same bits as with the estimate observed; a base without compensation flies otherwise."""
    residual = {"action_type": "residual", "residual": {"base": base, "params": params}}
    hidden, seen, uncompensated = (
        gym.make(REJECTION, estimator="ekf", observe_wrench=False, **residual),
        gym.make(REJECTION, estimator="ekf", **residual),
        gym.make(
            REJECTION,
            estimator="ekf",
            observe_wrench=False,
            action_type="residual",
            residual={"base": base, "params": {**params, "compensation": False}},
        ),
    )
    zero = np.zeros(4, dtype=np.float32)
    wrench = hidden.unwrapped.obs_layout["wrench"]
    positions = {}
    for name, env in (("hidden", hidden), ("seen", seen), ("uncompensated", uncompensated)):
        env.reset(seed=3, options={"scenario": "jet_crossing", "jet_speed": 12.0})
        trace = []
        for _ in range(150):
            observation, _, terminated, _, info = env.step(zero)
            trace.append(info["position"])
            assert not terminated
            if name == "hidden":
                assert not observation[wrench].any()
        positions[name] = np.array(trace)
        env.close()
    np.testing.assert_array_equal(positions["hidden"], positions["seen"])
    assert np.abs(positions["hidden"] - positions["uncompensated"]).max() > 1e-3

"""The ``residual`` action type: the vehicle flies its base controller's action plus the policy's, times
``residual.scale``, clipped (quad_wrench_env/control/residual.py). At zero action it flies the classical
agent's numbers bit for bit; a correction enters as scale x action; each vehicle's base restarts with its
episode; what it cannot fly is refused by name."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import quad_wrench_env  # noqa: F401  (registers the env ids)
from quad_wrench_env.agents import make_agent
from quad_wrench_env.control.pid_controller import PIDController, PIDGains

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
    "base, params",
    [("pid", {"compensation": True}), ("mpc", {**MPC_GAINS, "slack": True, "compensation": True})],
)
def test_at_zero_action_the_residual_flies_the_classical_agent_bit_for_bit(base, params):
    agent = make_agent(base, **params)
    settings = {"action_type": "residual", "residual": {"base": base, "params": params}}
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

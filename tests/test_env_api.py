"""FanTracking as Gymnasium and stable-baselines3 expect it; determinism; bad input; clean-up."""

from __future__ import annotations

import pickle
import sys
import warnings

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

from quad_wrench_env.envs.base import QuadWrenchEnv, clip_actions, declared_render_modes
from quad_wrench_env.tasks import TASKS
from tests.conftest import FAN_TRACKING


@pytest.mark.parametrize("action_type", ["velocity", "attitude", "wrench", "motors"])
def test_env_checkers_pass_without_warnings(make_env, action_type):
    env = make_env(action_type=action_type)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gym_check_env(env.unwrapped, skip_render_check=True)
        sb3_check_env(env.unwrapped, warn=True)


def test_reachable_by_module_prefix_without_import():
    env = gym.make("quad_wrench_env:QuadWrench/FanTracking-v1")
    env.close()


def test_spaces_and_step_types(make_env):
    env = make_env(estimator="oracle")
    obs, info = env.reset(seed=3)
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (4,), np.float32)
    assert obs.dtype == np.float32 and obs.shape == env.observation_space.shape
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert type(reward) is float and type(terminated) is bool and type(truncated) is bool
    for key in ("wrench_true", "wrench_est", "position", "fan_position"):
        assert np.asarray(info[key]).shape == ((6,) if key.startswith("wrench") else (3,))
    assert set(info["reward_terms"]) >= {"tracking", "effort"}
    assert reward == pytest.approx(sum(info["reward_terms"].values()))
    layout = env.unwrapped.obs_layout
    np.testing.assert_allclose(obs[layout["wrench"]], info["wrench_est"], rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(obs[layout["position"]], info["position"], rtol=1e-6)


def test_default_observation_is_the_ukf_estimate_not_the_truth(make_env):
    env = make_env()
    assert env.unwrapped.cfg.estimator == "ukf"
    obs, _ = env.reset(seed=0, options={"offset_y": 0.4})
    for _ in range(50):
        obs, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
    layout = env.unwrapped.obs_layout
    estimated = obs[layout["position"]].astype(float)
    assert not np.array_equal(estimated, info["position"].astype(np.float32))
    np.testing.assert_allclose(estimated, info["position"], atol=5e-3)  # mocap noise is 0.5 mm
    np.testing.assert_allclose(obs[layout["wrench"]], info["wrench_est"], rtol=1e-6, atol=1e-7)


def test_oracle_observes_the_true_wrench(make_env):
    env = make_env(estimator="oracle")
    env.reset(seed=0, options={"offset_y": 0.5})
    for _ in range(10):
        _, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
    np.testing.assert_array_equal(info["wrench_est"], info["wrench_true"])
    assert info["wrench_true"][0] > 0.1 and info["wrench_true"][5] > 0.0  # +x push, +y side


def _rollout(env, seed: int, steps: int = 200):
    obs, _ = env.reset(seed=seed)
    env.action_space.seed(seed)
    observations, rewards = [obs], []
    for _ in range(steps):
        obs, reward, terminated, truncated, _ = env.step(env.action_space.sample() * 0.3)
        observations.append(obs)
        rewards.append(reward)
        if terminated or truncated:
            break
    return np.array(observations), np.array(rewards)


def test_same_seed_same_trajectory_bit_for_bit(make_env):
    a = _rollout(make_env(), seed=7)
    env = make_env()
    _rollout(env, seed=99)  # a different episode in between must not leak into the next
    b = _rollout(env, seed=7)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    c = _rollout(env, seed=8)
    assert not np.array_equal(a[0][: len(c[0])], c[0][: len(a[0])])


def test_episode_is_30_s_at_50_hz(make_env):
    env = make_env(fan={"enabled": False})
    env.reset(seed=0)
    steps, truncated = 0, False
    while not truncated:
        _, _, terminated, truncated, info = env.step(np.zeros(4, dtype=np.float32))
        assert not terminated
        steps += 1
    assert steps == 1500 and info["time"] == pytest.approx(30.0)


def test_dt_is_the_control_period(make_env):
    """Gymnasium's convention: ``env.dt`` is one ``step`` (1/50 s here), the physics step its own name;
    one step advances ``info["time"]`` by ``dt``."""
    env = make_env(fan={"enabled": False})
    assert env.unwrapped.dt == pytest.approx(0.02) and env.unwrapped.physics_dt == pytest.approx(0.005)
    _, info = env.reset(seed=0)
    _, _, _, _, after = env.step(np.zeros(4, dtype=np.float32))
    assert after["time"] - info["time"] == pytest.approx(env.unwrapped.dt)


# The action table of quad_wrench_env/engine/actions.py's docstring, written out per type: the command
# (SI units, in to_action's order) of action a for the default limits (1 m/s, 0.5 m/s, 1 rad/s, 30 deg).
def _table_command(action_type, a, weight, arm, km_over_kf, max_speed):
    if action_type == "velocity":
        return (a[0] * 1.0, a[1] * 1.0, a[2] * 0.5, a[3] * 1.0)
    if action_type == "attitude":
        tilt = np.pi / 6.0
        return (a[0] * tilt, a[1] * tilt, a[2] * 1.0, (1.0 + a[3]) * weight)
    if action_type == "wrench":
        return ((1.0 + a[0]) * weight, *(np.array(a[1:]) * 0.5 * weight * np.array((arm, arm, km_over_kf))))
    return tuple((np.array(a) + 1.0) / 2.0 * max_speed)


@pytest.mark.parametrize("action_type", ["velocity", "attitude", "wrench", "motors"])
def test_action_scaling_is_the_documented_table_both_ways(make_env, action_type):
    """``env.unwrapped.action_scaling`` (what agents use instead of rebuilding the scales) gives the
    action table's command for an action and back, clipping commands beyond the range."""
    env = make_env(vehicle="hummingbird", action_type=action_type)
    scaling, vehicle = env.unwrapped.action_scaling, env.unwrapped.vehicle
    weight = vehicle.mass * 9.81
    rng = np.random.default_rng(3)
    for a in rng.uniform(-1.0, 1.0, (20, 4)):
        expected = _table_command(
            action_type, a, weight, vehicle.arm, vehicle.km_over_kf, vehicle.max_rotor_speed
        )
        np.testing.assert_allclose(scaling.to_command(a), expected, rtol=1e-12)
        np.testing.assert_allclose(scaling.to_action(expected), a.astype(np.float32), rtol=1e-6, atol=1e-7)
    beyond = scaling.to_command(np.full(4, 3.0))
    assert scaling.to_action(beyond).tolist() == [1.0] * 4
    with pytest.raises(ValueError, match="4 entries"):
        scaling.to_action((1.0, 2.0))


def test_leaving_the_arena_ends_the_episode_with_a_reason(make_env):
    env = make_env(fan={"enabled": False})
    env.reset(seed=0, options={"offset_y": 0.0})
    for _ in range(1500):
        _, _, terminated, _, info = env.step(np.array((0.0, 0.0, -1.0, 0.0), dtype=np.float32))
        if terminated:
            break
    assert terminated and info["termination_reason"] == "crash"
    assert info["reward_terms"]["crash"] < 0


def test_the_observation_space_holds_every_position_the_arena_allows(make_env):
    """A vehicle flown high in a tall arena (Yüksel et al.'s (2014) free-air reproduction hovers at 150 m)
    is inside the observation space: its position bound follows the arena (twice its farthest wall,
    at least 100 m)."""
    env = make_env(arena={"z_max": 400.0}, fan={"enabled": False})
    obs, _ = env.reset(seed=0, options={"offset_y": 0.0})
    layout = env.unwrapped.obs_layout
    np.testing.assert_array_equal(env.observation_space.high[layout["position"]], 800.0)
    obs[layout["position"]] = (2.3, 0.0, 150.0)
    assert env.observation_space.contains(obs)
    np.testing.assert_array_equal(make_env().observation_space.high[layout["position"]], 100.0)


def test_motor_action_can_flip_the_vehicle(make_env):
    env = make_env(action_type="motors")
    env.reset(seed=0, options={"offset_y": 0.0})
    for _ in range(200):
        _, _, terminated, _, info = env.step(np.array((1.0, 1.0, -1.0, -1.0), dtype=np.float32))
        if terminated:
            break
    assert terminated and info["termination_reason"] in ("flip", "crash")


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"vehicle": "bebop"}, "'bebop'"),
        ({"estimator": "kalman"}, "'kalman'"),
        ({"action_type": "joystick"}, "'joystick'"),
        ({"episode_secs": 10}, "'episode_secs'"),
        ({"fan": {"sped": 3.0}}, "'fan.sped'"),
        ({"policy_hz": 30}, "policy_hz=30"),
        ({"render_mode": "ascii"}, "'ascii'"),
        ({"vehicle_params": {"mass": 0.0}}, "mass=0.0"),
    ],
)
@pytest.mark.filterwarnings("ignore:.*render_mode")
def test_bad_construction_input_names_the_value(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make(FAN_TRACKING, **kwargs)


def test_bad_reset_and_step_input_names_the_value(make_env):
    env = make_env()
    with pytest.raises(ValueError, match="offset_y=12"):
        env.reset(seed=0, options={"offset_y": 12.0})
    with pytest.raises(ValueError, match="'spin'"):
        env.reset(seed=0, options={"spin": 1})
    with pytest.raises(ValueError, match="'zigzag'"):
        env.reset(seed=0, options={"fan_motion": "zigzag"})
    env.reset(seed=0)
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.array((0.0, np.nan, 0.0, 0.0), dtype=np.float32))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(3, dtype=np.float32))


def test_actions_with_infinities_are_refused_and_huge_finite_ones_clipped():
    for bad in ((np.inf, 0.0, 0.0, 0.0), (np.inf, -np.inf, 0.0, 0.0), (0.0, 0.0, np.nan, 1.0)):
        with pytest.raises(ValueError, match="NaN or infinity"):
            clip_actions(np.array(bad), (4,))
    huge = np.array((1e308, 1e308, -1e308, 0.5))  # their sum overflows; each is finite
    np.testing.assert_array_equal(clip_actions(huge, (4,)), (1.0, 1.0, -1.0, 0.5))


def test_actions_outside_the_box_are_clipped(make_env):
    env = make_env()
    env.reset(seed=1)
    obs, *_ = env.step(np.array((5.0, -5.0, 0.0, 0.0), dtype=np.float32))
    np.testing.assert_array_equal(obs[env.unwrapped.obs_layout["last_action"]], (1.0, -1.0, 0.0, 0.0))


def test_close_is_idempotent_and_no_client_leaks():
    for _ in range(200):
        env = gym.make(FAN_TRACKING)
        env.reset(seed=0)
        env.close()
        env.close()
    assert not any(p.isConnected(physicsClientId=i) for i in range(1024))


def test_env_pickles(make_env):
    env = make_env(fan={"motion": "static"})
    a, _ = env.reset(seed=5)
    clone = pickle.loads(pickle.dumps(env))
    try:
        b, _ = clone.reset(seed=5)
        np.testing.assert_array_equal(a, b)
    finally:
        clone.close()


def test_human_render_without_a_display_is_refused_clearly(monkeypatch):
    """Headless, ``human`` is not declared (Gymnasium's ``make`` would then wrap ``rgb_array`` in its
    own window); the env asked for it directly says why it cannot open one."""
    monkeypatch.delenv("DISPLAY", raising=False)
    probe = gym.make(FAN_TRACKING)
    env_class = type(probe.unwrapped)
    probe.close()
    with pytest.raises(RuntimeError, match="DISPLAY is unset"):
        env_class(render_mode="human")


def test_rgb_array_render_shows_a_scene(make_env):
    env = make_env(render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.zeros(4, dtype=np.float32))
    image = env.render()
    assert image.shape == (480, 640, 3) and image.dtype == np.uint8
    assert image.std() > 10  # not a blank frame


def test_an_estimator_bank_swapped_in_mid_episode_is_the_one_stepped():
    """What quad-wrench compare estimators does: wrap the env's bank after reset; every physics step
    then goes through the wrapper (the compiled step rebinds to it)."""

    class Counting:
        def __init__(self, inner):
            self.inner, self.calls = inner, 0

        def __getattr__(self, name):
            return getattr(self.inner, name)

        def step(self, inputs):
            self.calls += 1
            self.inner.step(inputs)

    env = gym.make(FAN_TRACKING, estimator="ukf")
    try:
        env.reset(seed=0)
        env.step(np.zeros(4, dtype=np.float32))
        fleet = env.unwrapped.fleet
        fleet.estimator = Counting(fleet.estimator)
        env.step(np.zeros(4, dtype=np.float32))
        assert fleet.estimator.calls == fleet.substeps
    finally:
        env.close()


@pytest.mark.parametrize("env_id", list(TASKS))
def test_gymnasiums_own_checker_passes_on_a_headless_machine(env_id, monkeypatch):
    """``check_env`` makes the env in every declared render mode: ``human`` is declared only where a
    window can open, so the check passes with no display."""
    monkeypatch.delenv("DISPLAY", raising=False)
    assert "human" not in declared_render_modes() or not sys.platform.startswith("linux")
    monkeypatch.setitem(QuadWrenchEnv.metadata, "render_modes", declared_render_modes())
    env = gym.make(env_id)
    try:
        gym_check_env(env.unwrapped, skip_render_check=False)
    finally:
        env.close()


def test_render_after_close_and_options_that_are_no_dict_are_refused_clearly(make_env):
    env = make_env(render_mode="rgb_array")
    with pytest.raises(ValueError, match=r"options=\['static'\] must be a dict of reset options"):
        env.reset(seed=0, options=["static"])
    env.close()
    with pytest.raises(RuntimeError, match="is closed"):
        env.render()

"""The batched env: every registered id has one, and vehicle i of it is exactly a single env seeded
with ``seed + i``, across episode ends; the SB3 adapter trains on it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecEnv, VecMonitor

import quad_wrench_env
from quad_wrench_env.envs.sb3_vec_env import SB3VecEnv
from quad_wrench_env.envs.vector import QuadWrenchVectorEnv
from tests.conftest import FAN_TRACKING

# Short episodes and a low ceiling, so that within 70 steps episodes end both ways: vehicle 2
# climbs out of the arena (terminated) and the others run out of time (truncated).
SHORT = {"episode_seconds": 0.8, "arena": {"z_max": 1.1}}


def _make_vec(num_envs: int, **kwargs) -> QuadWrenchVectorEnv:
    return gym.make_vec(FAN_TRACKING, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


def _actions(steps: int, num_envs: int) -> np.ndarray:
    actions = np.random.default_rng(0).uniform(-0.5, 0.5, (steps, num_envs, 4))
    actions[:, 2, 2] = 1.0  # vehicle 2 climbs at full speed
    return actions.astype(np.float32)


@pytest.mark.parametrize("estimator", ["ukf", "oracle", "observer", "ekf"])
def test_vehicle_i_is_the_single_env_seeded_with_seed_plus_i(estimator):
    num_envs, steps, seed = 3, 70, 11
    settings = {"estimator": estimator, **SHORT}
    actions = _actions(steps, num_envs)
    venv = _make_vec(num_envs, **settings)
    singles = [gym.make(FAN_TRACKING, **settings) for _ in range(num_envs)]
    try:
        obs, info = venv.reset(seed=seed)
        for i, env in enumerate(singles):
            single_obs, single_info = env.reset(seed=seed + i)
            np.testing.assert_allclose(obs[i], single_obs, rtol=1e-6, atol=1e-7)
            np.testing.assert_allclose(
                info["wrench_true"][i], single_info["wrench_true"], rtol=1e-9, atol=1e-12
            )
        ended = {"terminated": 0, "truncated": 0}
        for k in range(steps):
            obs, rewards, terminated, truncated, info = venv.step(actions[k])
            for i, env in enumerate(singles):
                single_obs, reward, single_terminated, single_truncated, single_info = env.step(actions[k, i])
                assert (terminated[i], truncated[i]) == (single_terminated, single_truncated)
                assert rewards[i] == pytest.approx(reward, rel=1e-9, abs=1e-12)
                if single_terminated or single_truncated:
                    ended["terminated" if single_terminated else "truncated"] += 1
                    np.testing.assert_allclose(info["final_obs"][i], single_obs, rtol=1e-6, atol=1e-7)
                    final = info["final_info"]
                    np.testing.assert_allclose(
                        final["wrench_true"][i], single_info["wrench_true"], atol=1e-12
                    )
                    if single_terminated:
                        assert final["termination_reason"][i] == single_info["termination_reason"]
                    single_obs, single_info = env.reset()
                np.testing.assert_allclose(obs[i], single_obs, rtol=1e-6, atol=1e-7)
                np.testing.assert_allclose(
                    info["wrench_true"][i], single_info["wrench_true"], rtol=1e-9, atol=1e-12
                )
                np.testing.assert_allclose(
                    info["wrench_est"][i], single_info["wrench_est"], rtol=1e-9, atol=1e-12
                )
                np.testing.assert_allclose(
                    info["position"][i], single_info["position"], rtol=1e-12, atol=1e-12
                )
        assert ended["terminated"] >= 1 and ended["truncated"] >= 2
    finally:
        venv.close()
        for env in singles:
            env.close()


def test_same_seed_same_vector_trajectory_bit_for_bit():
    """Nine vehicles (UKFs on SIMD lanes: a full block and a short one), twice from the same seed."""
    actions = np.random.default_rng(2).uniform(-0.5, 0.5, (60, 9, 4)).astype(np.float32)
    runs = []
    for _ in range(2):
        venv = _make_vec(9)
        try:
            observations = [venv.reset(seed=3)[0]]
            observations += [venv.step(action)[0] for action in actions]
        finally:
            venv.close()
        runs.append(np.array(observations))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_every_registered_id_has_a_vector_entry_point():
    for env_id in quad_wrench_env.ENV_IDS:
        venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")
        try:
            assert isinstance(venv.unwrapped, QuadWrenchVectorEnv)
            obs, _ = venv.reset(seed=0)
            assert obs.shape == (2, *venv.single_observation_space.shape) and obs.dtype == np.float32
            obs, rewards, terminated, truncated, info = venv.step(venv.action_space.sample())
            assert rewards.shape == (2,) and terminated.dtype == bool and truncated.dtype == bool
            assert info["wrench_est"].shape == (2, 6) and info["_wrench_est"].all()
        finally:
            venv.close()


def test_vehicles_started_in_one_spot_fly_through_each_other_as_alone():
    """Two vehicles started at the same spot fly as a single env does, to the bit, though their
    bodies overlap in PyBullet's world all the time (collision groups: they never touch)."""
    venv = _make_vec(2, estimator="oracle")
    env = gym.make(FAN_TRACKING, estimator="oracle")
    try:
        venv.reset(seed=[5, 5], options={"offset_y": 0.0})
        env.reset(seed=5, options={"offset_y": 0.0})
        for _ in range(50):
            action = np.array((0.3, -0.2, 0.1, 0.0), dtype=np.float32)
            _, _, _, _, info = venv.step(np.stack((action, action)))
            _, _, _, _, single = env.step(action)
        for key in ("position", "velocity", "wrench_true"):
            np.testing.assert_array_equal(info[key][0], single[key])
            np.testing.assert_array_equal(info[key][1], single[key])
        world = venv.unwrapped.fleet.world
        positions = [
            p.getBasePositionAndOrientation(b, physicsClientId=world.client)[0] for b in world.bodies
        ]
        np.testing.assert_array_equal(positions, info["position"])
    finally:
        venv.close()
        env.close()


def test_bad_input_is_refused_by_name_and_close_is_idempotent():
    with pytest.raises(ValueError, match="num_envs=0"):
        _make_vec(0)
    with pytest.raises(ValueError, match="render_mode='rgb_array'"):
        _make_vec(2, render_mode="rgb_array")
    venv = _make_vec(2)
    with pytest.raises(RuntimeError, match="reset"):
        venv.step(np.zeros((2, 4)))
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        venv.step(np.zeros(4))
    with pytest.raises(ValueError, match="NaN"):
        venv.step(np.full((2, 4), np.nan))
    with pytest.raises(ValueError, match="'spin'"):
        venv.reset(options={"spin": 1})
    venv.close()
    venv.close()
    assert not any(p.isConnected(physicsClientId=i) for i in range(1024))


def test_sb3_adapter_matches_the_vector_env_and_trains():
    venv = SB3VecEnv(_make_vec(3, estimator="oracle", **SHORT))
    reference = _make_vec(3, estimator="oracle", **SHORT)
    try:
        assert isinstance(venv, VecEnv)
        venv.seed(4)
        obs = venv.reset()
        reference_obs, _ = reference.reset(seed=4)
        np.testing.assert_array_equal(obs, reference_obs)
        dones_seen = 0
        for action in _actions(40, 3):
            venv.step_async(action)
            obs, rewards, dones, infos = venv.step_wait()
            reference_obs, reference_rewards, terminated, truncated, info = reference.step(action)
            np.testing.assert_array_equal(obs, reference_obs)
            np.testing.assert_allclose(rewards, reference_rewards, rtol=1e-6)
            for i in np.flatnonzero(dones):
                dones_seen += 1
                np.testing.assert_array_equal(infos[i]["terminal_observation"], info["final_obs"][i])
                assert infos[i]["TimeLimit.truncated"] == bool(truncated[i] and not terminated[i])
        assert dones_seen >= 3
        model = PPO(
            "MlpPolicy", VecMonitor(venv), n_steps=16, batch_size=24, n_epochs=1, seed=0, device="cpu"
        )
        model.learn(total_timesteps=96)
        assert model.num_timesteps >= 96
    finally:
        venv.close()
        reference.close()


def test_a_vehicle_of_three_crashes_on_the_ground_as_alone():
    """Vehicle 2 of three descends onto the ground plane beside the others and crashes at the step
    a single env's does."""
    settings = {"estimator": "oracle", "crash_height": -1.0, "fan": {"enabled": False}}
    venv = _make_vec(3, **settings)
    env = gym.make(FAN_TRACKING, **settings)
    down = np.array((0.0, 0.0, -1.0, 0.0), dtype=np.float32)
    try:
        venv.reset(seed=0, options={"offset_y": 0.0})
        env.reset(seed=2, options={"offset_y": 0.0})
        for _ in range(1500):
            _, _, terminated, _, info = venv.step(np.tile(down, (3, 1)))
            _, _, single_terminated, _, single_info = env.step(down)
            assert terminated[2] == single_terminated
            if single_terminated:
                assert (
                    info["final_info"]["termination_reason"][2]
                    == single_info["termination_reason"]
                    == "crash"
                )
                break
        assert single_terminated, "the descent never touched the ground"
    finally:
        venv.close()
        env.close()

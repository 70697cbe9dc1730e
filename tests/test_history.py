"""The ``history`` option: the observation frames of the K previous steps after the current one, named
in ``obs_layout``, zeros before an episode's first step, restarted with the episode on the single and
the vector env (autoresets included)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from tests.conftest import FAN_TRACKING

QUIET = {"estimator": "oracle", "fan": {"enabled": False}}


def _frame(env) -> int:
    return env.unwrapped.fleet.layout.frame


def test_each_history_block_is_the_frame_of_that_many_steps_back(make_env):
    """history_k at step t is the observation (without history) of step t - k, the action before it
    included; before the episode's first step, zeros; a new episode forgets the old one."""
    env = make_env(history=3, **QUIET)
    plain = make_env(**QUIET)
    layout, width = env.unwrapped.obs_layout, _frame(env)
    assert env.observation_space.shape == (4 * width,) == (4 * plain.observation_space.shape[0],)
    assert [layout[f"history_{k}"] for k in (1, 2, 3)] == [
        slice(k * width, (k + 1) * width) for k in (1, 2, 3)
    ]
    np.testing.assert_array_equal(
        env.observation_space.high[layout["history_2"]], plain.observation_space.high
    )
    for episode in range(2):
        obs, _ = env.reset(seed=episode)
        first, _ = plain.reset(seed=episode)
        np.testing.assert_array_equal(obs[:width], first)
        np.testing.assert_array_equal(obs[layout["history"]], 0.0)
        frames = [first]
        for t in range(6):
            action = np.array((0.1 * t, -0.2, 0.05 * t, 0.0), dtype=np.float32)
            obs, *_ = env.step(action)
            now, *_ = plain.step(action)
            np.testing.assert_array_equal(obs[:width], now)  # the history changes nothing else
            for k in (1, 2, 3):
                expected = frames[-k] if k <= len(frames) else np.zeros(width)
                np.testing.assert_array_equal(obs[layout[f"history_{k}"]], expected, err_msg=f"t={t} k={k}")
            assert obs[layout["history_1"]][layout["last_action"]] == pytest.approx(
                frames[-1][layout["last_action"]]
            )
            frames.append(now)


@pytest.mark.parametrize("value", [-1, 1.5, True, "2"])
def test_a_bad_history_is_refused_by_name(make_env, value):
    with pytest.raises(ValueError, match=r"history=.* must be an integer"):
        make_env(history=value)


def test_the_vector_envs_history_restarts_with_each_episode_and_matches_the_single_env():
    """Vehicle 1 of three descends and crashes: in that step its ``final_obs`` carries the ended
    episode's history, the returned observation the new episode's (history zeros), while vehicles 0
    and 2 keep theirs; every vehicle is the single env seeded alike, history included, to the bit."""
    settings = {**QUIET, "history": 2}
    vec = gym.make_vec(FAN_TRACKING, num_envs=3, vectorization_mode="vector_entry_point", **settings)
    singles = [gym.make(FAN_TRACKING, **settings) for _ in range(3)]
    try:
        layout = vec.unwrapped.obs_layout
        obs, _ = vec.reset(seed=10)
        for i, single in enumerate(singles):
            np.testing.assert_array_equal(obs[i], single.reset(seed=10 + i)[0])
        actions = np.zeros((3, 4), dtype=np.float32)
        actions[1, 2] = -1.0
        for _ in range(300):
            obs, _, terminated, _, info = vec.step(actions)
            alone = [single.step(actions[i]) for i, single in enumerate(singles)]
            if terminated[1]:
                break
            for i in range(3):
                np.testing.assert_array_equal(obs[i], alone[i][0])
        assert terminated[1] and not terminated[0] and not terminated[2]
        np.testing.assert_array_equal(info["final_obs"][1], alone[1][0])  # with the ended episode's history
        assert np.abs(info["final_obs"][1][layout["history"]]).max() > 0
        np.testing.assert_array_equal(obs[1][layout["history"]], 0.0)  # the new episode remembers nothing
        np.testing.assert_array_equal(obs[1], singles[1].reset()[0])
        for i in (0, 2):
            np.testing.assert_array_equal(obs[i], alone[i][0])
        obs, *_ = vec.step(actions)
        np.testing.assert_array_equal(obs[1], singles[1].step(actions[1])[0])
    finally:
        vec.close()
        for single in singles:
            single.close()

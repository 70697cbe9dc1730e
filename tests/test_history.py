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


def _wrench_regression(history: int, seed: int) -> np.ndarray:
    """R² per axis of a ridge regression from the observation (no wrench in it) to the true external
    force, fitted on 8 vehicles and scored on 8 others, flown by smooth random velocity commands in
    the fan's default episodes. Samples up to 10 steps after a restart are left out (a new episode's
    history is still filling)."""
    env = gym.make_vec(
        FAN_TRACKING,
        num_envs=16,
        vectorization_mode="vector_entry_point",
        observe_wrench=False,
        estimator="oracle",
        action_type="velocity",
        history=history,
        episode_seconds=10.0,
    )
    try:
        env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        action = np.zeros((16, 4), np.float32)
        since = np.full(16, 100)
        rows, forces, kept = [], [], []
        for step in range(400):
            noise = rng.normal(size=(16, 4)) * np.array([1.0, 1.0, 0.3, 0.3])
            action = np.clip(0.9 * action + 0.1 * noise, -1, 1).astype(np.float32)
            obs, _, terminated, truncated, info = env.step(action)
            since = np.where(terminated | truncated, 0, since + 1)
            if step > 20:
                rows.append(obs.copy())
                forces.append(info["wrench_true"][:, :3].copy())
                kept.append(since > 10)
    finally:
        env.close()
    x, y, mask = np.array(rows), np.array(forces), np.array(kept)
    x_fit, y_fit, x_test, y_test = (
        x[:, :8][mask[:, :8]],
        y[:, :8][mask[:, :8]],
        x[:, 8:][mask[:, 8:]],
        y[:, 8:][mask[:, 8:]],
    )
    mean, sd = x_fit.mean(0), x_fit.std(0) + 1e-9
    fit = np.c_[(x_fit - mean) / sd, np.ones(len(x_fit))]
    test = np.c_[(x_test - mean) / sd, np.ones(len(x_test))]
    weights = np.linalg.solve(fit.T @ fit + 10.0 * np.eye(fit.shape[1]), fit.T @ y_fit)
    residual = ((test @ weights - y_test) ** 2).sum(0)
    return 1.0 - residual / ((y_test - y_test.mean(0)) ** 2).sum(0)


@pytest.mark.parametrize("seed", [0, 3])
def test_the_history_carries_the_unobserved_wrench(seed):
    """Newton: m·dv/dt = thrust + gravity + external force. One observation holds the velocity but not
    its rate of change, so without the wrench in it the jet's push along y (the fan's lateral force,
    which the position and velocity alone do not give) cannot be read off it (R² ≈ 0); a history of 8
    frames holds the velocity's change and the commands, and a linear read-out recovers most of it.
    Measured (seeds 0-4): R² of f_y -0.12 to -0.04 without history, 0.59-0.67 with 8 frames; of f_x
    0.49-0.68 and 0.90-0.94. A history that repeated the current frame would score as none."""
    without, with_history = _wrench_regression(0, seed), _wrench_regression(8, seed)
    assert without[1] < 0.2
    assert with_history[1] > 0.45 and with_history[1] - without[1] > 0.4
    assert with_history[0] > 0.8 and with_history[0] - without[0] > 0.15

"""ProcessVectorEnv: vehicles stepped in several processes give exactly one vector env's numbers,
through autoresets; a worker's error reaches the caller; close is idempotent."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import quad_wrench_env  # noqa: F401
from quad_wrench_env.agents.sb3 import TrainConfig, evaluation_envs, train_config, training_env
from quad_wrench_env.envs.processes import ProcessVectorEnv, WorkerError
from quad_wrench_env.envs.sb3_vec_env import SB3VecEnv

SHORT = {"episode_seconds": 0.6}
"""Episodes of 0.6 s: every vehicle restarts several times in the steps below."""


def _pair(env_id: str, num_envs: int, processes: int, **kwargs) -> tuple[SB3VecEnv, SB3VecEnv]:
    one = SB3VecEnv(
        gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs),
        step_infos=False,
    )
    split = SB3VecEnv(ProcessVectorEnv(env_id, num_envs, processes, **kwargs), step_infos=False)
    return one, split


@pytest.mark.parametrize(
    ("env_id", "num_envs", "processes", "kwargs"),
    [
        ("QuadWrench/FanTracking-v1", 5, 2, {"estimator": "ukf", "action_type": "velocity"}),
        ("QuadWrench/ForceExertion-v0", 7, 3, {}),
    ],
)
def test_same_numbers_as_one_vector_env(env_id: str, num_envs: int, processes: int, kwargs: dict) -> None:
    one, split = _pair(env_id, num_envs, processes, **SHORT, **kwargs)
    try:
        assert [len(g) for g in split.venv.groups] == [
            len(g) for g in np.array_split(np.arange(num_envs), processes)
        ]
        for env in (one, split):
            env.seed(11)
        assert np.array_equal(one.reset(), split.reset())
        rng = np.random.default_rng(3)
        ended = 0
        for step in range(80):
            actions = rng.uniform(-1, 1, (num_envs, 4)).astype(np.float32)
            obs_a, rew_a, done_a, infos_a = one.step(actions)
            obs_b, rew_b, done_b, infos_b = split.step(actions)
            assert np.array_equal(obs_a, obs_b), step
            assert np.array_equal(rew_a, rew_b), step
            assert np.array_equal(done_a, done_b), step
            for a, b in zip(infos_a, infos_b, strict=True):
                assert a.keys() == b.keys()
                if "terminal_observation" in a:
                    assert np.array_equal(a["terminal_observation"], b["terminal_observation"])
                    assert a["TimeLimit.truncated"] == b["TimeLimit.truncated"]
            for name in ("reward_terms", "task_entries"):
                ours, theirs = getattr(one, name), getattr(split, name)
                assert ours.keys() == theirs.keys()
                for key in ours:
                    assert np.array_equal(ours[key], theirs[key]), (name, key, step)
            ended += int(done_a.sum())
        assert ended >= 2 * num_envs  # the autoresets were exercised, in every group
    finally:
        one.close()
        split.close()


def test_reset_options_and_seeds_reach_each_group() -> None:
    kwargs = {"estimator": "oracle", "action_type": "velocity"}
    one, split = _pair("QuadWrench/FanTracking-v1", 4, 2, **kwargs)
    try:
        for env in (one, split):
            env.seed(5)
            env.set_options({"offset_y": 0.8, "fan_motion": "static"})
        assert np.array_equal(one.reset(), split.reset())
        actions = np.zeros((4, 4), np.float32)
        assert np.array_equal(one.step(actions)[0], split.step(actions)[0])
        assert np.array_equal(one.task_entries["axis_error"], split.task_entries["axis_error"])
    finally:
        one.close()
        split.close()


def test_each_group_flies_its_own_settings() -> None:
    """``group_env``: vehicles 0-1 fly ardrone2 in the worker, 2-3 hummingbird here; each group's
    numbers are those of a vector env of its own preset (a vehicle's numbers depend only on its own
    seed, actions and settings)."""
    kwargs = {"estimator": "ukf", "action_type": "velocity", **SHORT}
    presets = ("ardrone2", "hummingbird")
    split = SB3VecEnv(
        ProcessVectorEnv("QuadWrench/FanTracking-v1", 4, 2, [{"vehicle": v} for v in presets], **kwargs),
        step_infos=False,
    )
    alone = [
        SB3VecEnv(
            gym.make_vec(
                "QuadWrench/FanTracking-v1",
                num_envs=4,
                vectorization_mode="vector_entry_point",
                vehicle=v,
                **kwargs,
            ),
            step_infos=False,
        )
        for v in presets
    ]
    try:
        for env in (split, *alone):
            env.seed(7)
        observations = [env.reset() for env in (split, *alone)]
        rng = np.random.default_rng(0)
        for _ in range(40):
            assert np.array_equal(observations[0][:2], observations[1][:2])
            assert np.array_equal(observations[0][2:], observations[2][2:])
            actions = rng.uniform(-1, 1, (4, 4)).astype(np.float32)
            observations = [env.step(actions)[0] for env in (split, *alone)]
        assert not np.array_equal(observations[1], observations[2])  # the presets do fly differently
    finally:
        for env in (split, *alone):
            env.close()
    with pytest.raises(ValueError, match="group_env has 1 entries; give one per process"):
        ProcessVectorEnv("QuadWrench/FanTracking-v1", 4, 2, [{"vehicle": "ardrone2"}])


def test_a_worker_error_names_its_cause_and_close_is_idempotent() -> None:
    venv = ProcessVectorEnv("QuadWrench/FanTracking-v1", 4, 2, estimator="oracle")
    venv.reset_vehicles(range(4), [0, 1, 2, 3], [None] * 4)
    actions = np.zeros((4, 4))
    venv.step_arrays(actions)  # the first step lays out the shared memory
    venv.step_arrays(actions)
    actions[0, 2] = np.nan  # vehicle 0 flies in the worker
    with pytest.raises(WorkerError, match="NaN"):
        venv.step_arrays(actions)
    venv.close()
    venv.close()
    with pytest.raises(RuntimeError, match="closed"):
        venv.step_arrays(np.zeros((4, 4)))


@pytest.mark.parametrize(("num_envs", "processes"), [(4, 0), (4, 5), (4, 1.5)])
def test_bad_process_counts_are_refused(num_envs: int, processes) -> None:
    with pytest.raises(ValueError, match=f"processes={processes!r}"):
        ProcessVectorEnv("QuadWrench/FanTracking-v1", num_envs, processes)


def test_training_config_takes_env_processes() -> None:
    with pytest.raises(ValueError, match="env_processes=9 must be at most num_envs=8"):
        TrainConfig(num_envs=8, env_processes=9)
    with pytest.raises(ValueError, match="env_processes=0"):
        TrainConfig(env_processes=0)
    with pytest.raises(ValueError, match="env_groups has 1 entries; give one per process"):
        TrainConfig(num_envs=8, env_processes=2, env_groups=[{"vehicle": "ardrone2"}])
    with pytest.raises(ValueError, match=r"env_groups set \['history'\]"):
        TrainConfig(num_envs=8, env_processes=2, env_groups=[{"history": 2}, {}])
    with pytest.raises(ValueError, match=r"env_groups set \['policy_hz'\]"):
        TrainConfig(num_envs=8, env_processes=2, env_groups=[{"policy_hz": 25}, {}])
    single = train_config(
        {"num_envs": 2, "env": {"estimator": "oracle"}}, {"env_groups": [{"vehicle": "hummingbird"}]}
    )
    adapter, env = training_env(single)  # one process, one group: the group's preset flies
    try:
        assert adapter.venv.cfg.vehicle == "hummingbird"
    finally:
        env.close()
    groups = [{"vehicle": "ardrone2"}, {"vehicle": "hummingbird"}]
    two = train_config(
        {"env": {"estimator": "ukf"}, "evaluation": {"env": {"episode_seconds": 5.0}}},
        {"env_processes": 2, "env_groups": groups},
    )
    assert evaluation_envs(two) == [
        {"estimator": "ukf", "vehicle": v, "episode_seconds": 5.0} for v in ("ardrone2", "hummingbird")
    ]
    config = train_config(
        {"num_envs": 4, "env": {"estimator": "oracle", "action_type": "velocity"}}, {"env_processes": 2}
    )
    adapter, env = training_env(config)
    try:
        assert isinstance(adapter.venv, ProcessVectorEnv)
        assert env.reset().shape == (4, *adapter.observation_space.shape)
    finally:
        env.close()


def test_training_in_two_processes_gives_the_same_model(tmp_path):
    """The vehicles' numbers are the same split or not, so a short PPO run learns the same weights."""
    import torch
    from stable_baselines3 import PPO

    from quad_wrench_env.agents.sb3 import train

    values = {
        "env": {"estimator": "oracle", "action_type": "velocity", **SHORT},
        "num_envs": 4,
        "total_steps": 128,
        "checkpoint_every_steps": 100000,
        "hyperparameters": {"n_steps": 16, "batch_size": 32, "n_epochs": 2},
        "evaluation": {"seeds": [900], "every_steps": 100000, "metric": "return"},
    }
    weights = []
    for processes in (1, 2):
        folder = train(
            train_config(values, {"env_processes": processes}), tmp_path / f"p{processes}", progress=False
        )
        model = PPO.load(folder / "final" / "model.zip", device="cpu")
        weights.append({k: v.clone() for k, v in model.policy.state_dict().items()})
    assert weights[0].keys() == weights[1].keys()
    for key in weights[0]:
        assert torch.equal(weights[0][key], weights[1][key]), key

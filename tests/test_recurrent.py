"""A recurrent policy (sb3-contrib's RecurrentPPO, ``algorithm: recurrent_ppo``): its hidden state
carries what it saw from step to step, each episode starts with none, and it trains on the batched env,
is saved, loaded from its run folder and flown by the one harness."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from sb3_contrib import RecurrentPPO
from stable_baselines3 import PPO

from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents.evaluate import evaluate
from quad_wrench_env.agents.sb3 import SB3Policy, TrainConfig, train
from quad_wrench_env.config import build
from tests.conftest import FAN_TRACKING


def _actions(policy: SB3Policy, env: gym.Env, observations: list[np.ndarray]) -> np.ndarray:
    """The policy's actions on ``observations`` from an episode's start."""
    policy.reset(env)
    return np.array([policy.act(obs) for obs in observations])


@pytest.mark.parametrize(("learner", "remembers"), [(RecurrentPPO, True), (PPO, False)])
def test_the_action_depends_on_earlier_observations_only_with_memory(learner, remembers):
    """Two episodes that differ in their first observation only: the recurrent policy's second action
    differs (it remembers), a feed-forward PPO's does not; the same episode again after ``reset``
    gives the same actions (the hidden state starts afresh each episode)."""
    env = gym.make(FAN_TRACKING, episode_seconds=1.0)
    try:
        policy_class = "MlpLstmPolicy" if learner is RecurrentPPO else "MlpPolicy"
        policy = SB3Policy(learner(policy_class, env, n_steps=16, batch_size=16, seed=0, device="cpu"))
        now, _ = env.reset(seed=0)
        earlier = now.copy()
        earlier[env.unwrapped.obs_layout["position"]] += 1.0
        first = _actions(policy, env, [now, now])
        second = _actions(policy, env, [earlier, now])
        np.testing.assert_array_equal(_actions(policy, env, [now, now]), first)
        assert (np.abs(first[1] - second[1]).max() > 1e-6) == remembers
    finally:
        env.close()


def test_a_recurrent_policy_trains_on_the_batched_env_and_is_flown_from_its_run_folder(tmp_path):
    config = build(
        TrainConfig,
        {
            "algorithm": "recurrent_ppo",
            "env": {"episode_seconds": 2.0},
            "num_envs": 4,
            "total_steps": 128,
            "checkpoint_every_steps": 1024,
            "hyperparameters": {"n_steps": 32, "batch_size": 64, "n_epochs": 1},
            "evaluation": {"seeds": [1], "every_steps": 1024, "metric": "return"},
        },
    )
    folder = train(config, tmp_path / "run", progress=False)
    policy = make_agent(str(folder))
    assert isinstance(policy, SB3Policy) and isinstance(policy.model, RecurrentPPO)
    result = evaluate(policy, FAN_TRACKING, [2, 2], episode_seconds=1.0)
    assert result.per_seed[0] == result.per_seed[1]  # the second episode starts with no memory

"""A learned policy's observation scaling and which model a run folder gives
(``quad_wrench_env/agents/sb3_policy.py``), without training:
``ObservationScaling`` is what ``VecNormalize.normalize_obs`` does, written here by hand; it survives its
file unchanged; a run folder loads its kept ``best/`` model behind ``best/``'s scaling (``final/`` only
without one), and the policy acts on the scaled observation."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import torch
import yaml
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecNormalize

from quad_wrench_env.agents.sb3_policy import ObservationScaling, SB3Policy, load_policy
from quad_wrench_env.envs.sb3_vec_env import SB3VecEnv
from tests.conftest import FAN_TRACKING

SIZE = 25  # FanTracking's observation


def _normalizer(rng: np.random.Generator) -> VecNormalize:
    venv = SB3VecEnv(gym.make_vec(FAN_TRACKING, num_envs=2, vectorization_mode="vector_entry_point"))
    normalize = VecNormalize(venv, clip_obs=3.0)
    normalize.obs_rms.mean = rng.normal(0.0, 2.0, SIZE)
    normalize.obs_rms.var = rng.uniform(0.01, 4.0, SIZE)
    return normalize


def test_the_scaling_is_vecnormalizes_and_survives_its_file(tmp_path):
    """``clip((obs - mean)/sqrt(var + ε), ±clip)`` with VecNormalize's own statistics: equal to its
    ``normalize_obs`` and to the formula worked out here (some entries beyond the clip), and the same
    numbers after ``save`` and ``load`` (mean, variance, clip and ε each in its place)."""
    rng = np.random.default_rng(0)
    normalize = _normalizer(rng)
    try:
        scaling = ObservationScaling.of(normalize)
        obs = rng.normal(0.0, 4.0, (50, SIZE)).astype(np.float32)
        by_hand = np.clip((obs - normalize.obs_rms.mean) / np.sqrt(normalize.obs_rms.var + 1e-8), -3.0, 3.0)
        assert np.any(np.abs(by_hand) == 3.0) and np.any(np.abs(by_hand) < 1.0)
        np.testing.assert_allclose(scaling(obs), by_hand, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(scaling(obs), normalize.normalize_obs(obs), rtol=1e-6, atol=1e-6)
        scaling.save(tmp_path / "scaling.npz")
        loaded = ObservationScaling.load(tmp_path / "scaling.npz")
        np.testing.assert_array_equal(loaded.mean, normalize.obs_rms.mean)
        np.testing.assert_array_equal(loaded.var, normalize.obs_rms.var)
        assert (loaded.clip, loaded.epsilon) == (3.0, normalize.epsilon)
        np.testing.assert_array_equal(loaded(obs), scaling(obs))
    finally:
        normalize.close()


def _model(seed: int) -> PPO:
    env = gym.make(FAN_TRACKING)
    try:
        return PPO("MlpPolicy", env, n_steps=64, device="cpu", seed=seed)
    finally:
        env.close()


def _weights(model: PPO) -> list[torch.Tensor]:
    return [p.detach().clone() for p in model.policy.parameters()]


def test_a_run_folder_gives_its_kept_model_behind_its_own_scaling(tmp_path):
    """A run folder with a ``best/`` and a ``final/`` model, each with its own scaling: the agent is
    ``best/``'s model (its weights) behind ``best/``'s scaling; without ``best/`` it is ``final/``'s.
    Its action is the model's deterministic action on the *scaled* observation."""
    rng = np.random.default_rng(1)
    folder = tmp_path / "run"
    models = {}
    for name, seed in (("best", 1), ("final", 2)):
        (folder / name).mkdir(parents=True)
        models[name] = _model(seed)
        models[name].save(folder / name / "model.zip")
        scaling = ObservationScaling(rng.normal(0.0, 1.0, SIZE), rng.uniform(0.5, 2.0, SIZE), 5.0, 1e-8)
        scaling.save(folder / name / "scaling.npz")
    (folder / "config.yaml").write_text(
        yaml.safe_dump({"env_id": FAN_TRACKING, "algorithm": "ppo", "env": {}})
    )

    for kept in ("best", "final"):
        policy = load_policy(folder)
        assert isinstance(policy, SB3Policy)
        for got, wanted in zip(_weights(policy.model), _weights(models[kept]), strict=True):
            assert torch.equal(got, wanted), kept
        with np.load(folder / kept / "scaling.npz") as data:
            np.testing.assert_array_equal(policy.scaling.mean, data["mean"])
            np.testing.assert_array_equal(policy.scaling.var, data["var"])
        obs = rng.normal(0.0, 2.0, SIZE).astype(np.float32)
        scaled = np.clip((obs - policy.scaling.mean) / np.sqrt(policy.scaling.var + 1e-8), -5.0, 5.0)
        wanted, _ = models[kept].predict(scaled.astype(np.float32), deterministic=True)
        np.testing.assert_allclose(policy.act(obs), wanted, rtol=1e-6, atol=1e-6)
        assert not np.allclose(models[kept].predict(obs, deterministic=True)[0], wanted, atol=1e-3)
        if kept == "best":  # then the same folder without its best model
            for part in ("model.zip", "scaling.npz"):
                (folder / "best" / part).unlink()


def test_a_policy_without_scaling_acts_on_the_raw_observation():
    """No scaling (a run without observation normalisation): the raw observation goes to the model;
    with a scaling of zero mean, unit variance and no ε, only its clip acts."""
    model, clip = _model(3), 0.5
    obs = np.random.default_rng(2).normal(0.0, 1.0, SIZE).astype(np.float32)
    wanted, _ = model.predict(obs, deterministic=True)
    np.testing.assert_array_equal(SB3Policy(model).act(obs), wanted)
    scaled = SB3Policy(model, ObservationScaling(np.zeros(SIZE), np.ones(SIZE), clip, 0.0)).act(obs)
    np.testing.assert_array_equal(scaled, model.predict(np.clip(obs, -clip, clip), deterministic=True)[0])

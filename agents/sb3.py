"""stable-baselines3 policies as agents of the evaluation harness.

:class:`SB3Policy` wraps a trained model and the observation statistics of the ``VecNormalize`` it
trained behind, so that ``agents.evaluate.evaluate`` runs it like any classical agent: ``reset(env)``,
``act(obs)`` on the raw observation, deterministic actions.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecNormalize


@dataclass(frozen=True)
class ObservationScaling:
    """What ``VecNormalize.normalize_obs`` does, as plain numbers: ``clip((obs - mean)/sqrt(var + ε))``."""

    mean: np.ndarray
    var: np.ndarray
    clip: float
    epsilon: float

    @classmethod
    def of(cls, normalize: VecNormalize) -> ObservationScaling:
        rms = normalize.obs_rms
        return cls(rms.mean.copy(), rms.var.copy(), float(normalize.clip_obs), float(normalize.epsilon))

    def __call__(self, observation: np.ndarray) -> np.ndarray:
        scaled = (observation - self.mean) / np.sqrt(self.var + self.epsilon)
        return np.clip(scaled, -self.clip, self.clip).astype(np.float32)

    def save(self, path: str | Path) -> None:
        np.savez(path, mean=self.mean, var=self.var, clip=self.clip, epsilon=self.epsilon)

    @classmethod
    def load(cls, path: str | Path) -> ObservationScaling:
        with np.load(path) as data:
            return cls(data["mean"], data["var"], float(data["clip"]), float(data["epsilon"]))


class SB3Policy:
    """A trained SB3 model, behind its observation scaling if it had one, as a Policy."""

    def __init__(self, model: BaseAlgorithm, scaling: ObservationScaling | None = None) -> None:
        self.model = model
        self.scaling = scaling

    def reset(self, env: gym.Env) -> None:
        expected = self.model.observation_space.shape
        got = env.observation_space.shape
        if got != expected:
            raise ValueError(f"the model was trained on observations of shape {expected}, the env has {got}")

    def act(self, observation: np.ndarray) -> np.ndarray:
        obs = observation if self.scaling is None else self.scaling(observation)
        action, _ = self.model.predict(obs, deterministic=True)
        return np.asarray(action, dtype=np.float32)

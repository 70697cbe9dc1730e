"""A trained stable-baselines3 model as an agent of the evaluation harness.

:class:`SB3Policy` wraps a trained model and the observation statistics of the ``VecNormalize`` it
trained behind, so that :func:`quad_wrench_env.agents.evaluate.evaluate` runs it like any classical
agent: ``reset(env)``, ``act(obs)`` on the raw observation, deterministic actions. :func:`load_policy`
reads a run folder (or a shipped agent, which is a run folder's ``config.yaml`` and ``best/`` kept in the
package). Training is :mod:`quad_wrench_env.agents.sb3`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecNormalize

from quad_wrench_env.config import build, load_yaml
from quad_wrench_env.registry import bare_env_id


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


MEANING_KEYS = (
    "action_type",
    "residual",
    "action_limits",
    "observe_wrench",
    "history",
    "sensor_history",
    "privileged",
    "observe_tracking_error",
    "preview_seconds",
    "observe_reference_acceleration",
    "observe_reference_jerk",
    "path_ahead_seconds",
)
"""Env settings that change what an action or an observation means (``history``, ``sensor_history``,
``privileged``, ``preview_seconds``, ``observe_reference_acceleration``, ``observe_reference_jerk`` and
``path_ahead_seconds`` its size too; ``action_limits`` the command an action stands for, ``residual`` the base
controller it corrects; the last five and ``observe_tracking_error`` are
DisturbanceRejection's own and count only where the config has them)."""


class SB3Policy:
    """A trained SB3 model, behind its observation scaling if it had one, as a Policy. A recurrent
    model (sb3-contrib's ``RecurrentPPO``) carries its hidden state from step to step; :meth:`reset`
    (each episode's start) clears it."""

    def __init__(
        self,
        model: BaseAlgorithm,
        scaling: ObservationScaling | None = None,
        trained_on: dict[str, Any] | None = None,
        trained_env_id: str | None = None,
    ) -> None:
        """``trained_on``: the training env's settings (a run's ``env`` section; a key not in it had
        the task's default); :meth:`reset` refuses an env whose :data:`MEANING_KEYS` differ from them.
        None: unknown (a bare model), nothing but the observation's shape is checked.
        ``trained_env_id``: the env id it was trained on (None: unknown)."""
        self.model = model
        self.scaling = scaling
        self.trained_on = None if trained_on is None else dict(trained_on)
        self.trained_env_id = trained_env_id
        self._memory: Any = None
        """A recurrent model's hidden state (None: a new episode; always None for the others)."""
        self._start = np.ones(1, dtype=bool)

    def env_settings(
        self, given: Mapping[str, Any] | None = None, env_id: str | None = None
    ) -> dict[str, Any]:
        """What the harness flies it with where ``given`` (the env settings asked for) leaves them: the
        :data:`MEANING_KEYS` its training env set (the others had the task's defaults), and its training
        env's estimator with that estimator's settings (``estimator_params``, e.g. the filters' fixed
        walks): it reads estimates made as in training. With another estimator ``given``, that
        estimator's defaults. With ``env_id`` the env it was trained on (a lone evaluation), every
        other setting of its training env too: its world (vehicle, scenario settings, curricula)."""
        trained, given = self.trained_on or {}, given or {}
        home = self.trained_env_id is not None and env_id is not None
        home = home and bare_env_id(env_id) == bare_env_id(self.trained_env_id)
        estimator_keys = ("estimator", "estimator_params")
        keys = [key for key in (trained if home else MEANING_KEYS) if key not in estimator_keys]
        if given.get("estimator", trained.get("estimator")) == trained.get("estimator"):
            keys += estimator_keys
        return {key: trained[key] for key in keys if key in trained}

    def reset(self, env: gym.Env) -> None:
        self._memory, self._start = None, np.ones(1, dtype=bool)
        if self.trained_on is not None:
            cfg = env.unwrapped.cfg
            names = {f.name for f in dataclasses.fields(cfg)}
            keys = [key for key in MEANING_KEYS if key in names]
            given = {key: self.trained_on[key] for key in keys if key in self.trained_on}
            trained_cfg = build(type(cfg), given)  # a key not given: the task's default
            for key in keys:
                trained, here = getattr(trained_cfg, key), getattr(cfg, key)
                if trained != here:
                    raise ValueError(
                        f"the policy was trained with {key}={trained!r}, the env has "
                        f"{key}={here!r}; make the env with {key}={given.get(key, trained)!r}"
                    )
        expected = self.model.observation_space.shape
        got = env.observation_space.shape
        if got != expected:
            raise ValueError(f"the model was trained on observations of shape {expected}, the env has {got}")

    def act(self, observation: np.ndarray) -> np.ndarray:
        obs = observation if self.scaling is None else self.scaling(observation)
        action, self._memory = self.model.predict(
            obs, state=self._memory, episode_start=self._start, deterministic=True
        )
        self._start = np.zeros(1, dtype=bool)
        return np.asarray(action, dtype=np.float32)


def algorithm_class(name: str) -> type[BaseAlgorithm]:
    """The SB3 (or sb3-contrib) class of an ``algorithm`` name of a run's config."""
    from sb3_contrib import RecurrentPPO
    from stable_baselines3 import PPO, SAC

    classes = {"ppo": PPO, "sac": SAC, "recurrent_ppo": RecurrentPPO}
    return classes["recurrent_ppo" if name == "dagger" else name]  # a distilled student flies as one


def load_policy(folder: str | Path) -> SB3Policy:
    """The agent of a run folder (or a shipped agent's folder): its best model if it kept one, else
    its last, behind its observation scaling."""
    folder = Path(folder)
    config = folder / "config.yaml"
    if not config.is_file():
        raise FileNotFoundError(f"{str(folder)!r} is not a training run folder (no config.yaml)")
    settings = load_yaml(config)
    for name in ("best", "final"):
        model = folder / name / "model.zip"
        if model.is_file():
            scaling = folder / name / "scaling.npz"
            return SB3Policy(
                algorithm_class(settings.get("algorithm", "ppo")).load(model, device="cpu"),
                ObservationScaling.load(scaling) if scaling.is_file() else None,
                trained_on=settings.get("env", {}),
                trained_env_id=settings.get("env_id"),
            )
    raise FileNotFoundError(f"{str(folder)!r} holds no best/model.zip or final/model.zip")

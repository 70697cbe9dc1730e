"""Distilling a teacher policy into a recurrent student on the student's own rollouts.

DAgger (Ross, Gordon & Bagnell 2011), as RAPTOR distils its oracle teachers into a recurrent student
(Eschmann et al. 2025): each iteration flies every vehicle ``n_steps`` steps, each step with the
teacher's action with probability ``β_i = teacher_share · teacher_decay^i`` and else the student's, and
labels every step with the teacher's action; the student (sb3-contrib's LSTM policy) is then fitted to
the labels of the last ``kept_iterations`` rollouts by the squared error of its mean action, each
rollout run through the LSTM from the state it had when flown, reset at each episode start. The student
never reads the truth: its feature extractor zeroes the ``privileged`` block
(:class:`~quad_wrench_env.agents.privileged.WithoutColumns`); the teacher's observation is rebuilt
from that block (:class:`Teacher`), so a teacher trained on the true state and wrench (the oracle arm)
labels the student's flight. The student is saved as a ``RecurrentPPO`` model and flies as one.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from sb3_contrib import RecurrentPPO
from sb3_contrib.common.recurrent.type_aliases import RNNStates
from stable_baselines3.common.utils import obs_as_tensor

from quad_wrench_env.config import check_counts
from quad_wrench_env.engine.observation import PRIVILEGED_BLOCKS


@dataclass
class DistillationSettings:
    """How the student imitates the teacher (``distillation`` in a training config)."""

    teacher_share: float = 1.0
    """The share of steps flown with the teacher's action in the first iteration."""
    teacher_decay: float = 0.5
    """That share's factor from one iteration to the next."""
    epochs: int = 4
    """Passes over the kept rollouts after each iteration."""
    kept_iterations: int = 16
    """Rollouts kept for fitting (the aggregated data, oldest dropped first)."""
    batch: int = 8
    """Rollouts of one vehicle (``n_steps`` each) per gradient step."""

    def __post_init__(self) -> None:
        for name in ("teacher_share", "teacher_decay"):
            value = getattr(self, name)
            if not (isinstance(value, float | int) and not isinstance(value, bool) and 0.0 <= value <= 1.0):
                raise ValueError(f"distillation.{name}={value!r} must be a number in [0, 1]")
        check_counts("distillation", self, ("epochs", "kept_iterations", "batch"))


TEACHER_FREE_KEYS = ("observe_wrench", "history", "sensor_history", "privileged")
"""Meaning keys a teacher's training env may set apart from the student's: the teacher reads one frame
rebuilt from the truth, whatever the student reads."""


class Teacher:
    """A trained policy (a run folder or a shipped policy's name) labelling the student env's steps: its
    observation is the student env's first frame with the engine's state and wrench blocks taken from
    the ``privileged`` block (the truth) and the wrench kept (a teacher trained with the oracle reads
    exactly what it was trained on)."""

    def __init__(self, source: str, env_id: str, student_env: dict[str, Any]) -> None:
        from quad_wrench_env.agents import make_agent
        from quad_wrench_env.agents.sb3_policy import MEANING_KEYS, SB3Policy

        policy = make_agent(source)
        if not isinstance(policy, SB3Policy) or isinstance(policy.model, RecurrentPPO):
            raise ValueError(
                f"teacher={source!r} must be a trained feed-forward policy (a run folder or name)"
            )
        trained = policy.trained_on or {}
        for key in ("history", "sensor_history", "privileged"):
            if trained.get(key):
                raise ValueError(
                    f"teacher={source!r} was trained with {key}={trained[key]!r}; a teacher reads one "
                    "frame rebuilt from the truth (allowed: a teacher without history, sensors or truth)"
                )
        own = {key: student_env[key] for key in MEANING_KEYS if key in student_env}
        own = {key: value for key, value in own.items() if key not in TEACHER_FREE_KEYS}
        settings = {**{k: v for k, v in student_env.items() if k not in MEANING_KEYS}, **own}
        env = gym.make(env_id, **{**settings, **{k: trained[k] for k in trained if k in MEANING_KEYS}})
        try:
            policy.reset(env)  # refuses a teacher whose actions or frame mean otherwise
        finally:
            env.close()
        self.policy = policy
        self.frame = policy.model.observation_space.shape[0]

    def columns(self, layout: dict[str, slice]) -> np.ndarray:
        """Which column of the student env's observation each column of the teacher's holds."""
        index = np.arange(self.frame)
        truth = layout["privileged"]
        width = truth.stop - truth.start
        if sum(w for _, w in PRIVILEGED_BLOCKS) != width:
            raise ValueError(f"the privileged block has {width} columns, not the engine's blocks")
        index[:width] = np.arange(truth.start, truth.stop)
        return index

    def act(self, observations: np.ndarray) -> np.ndarray:
        """(N, 4) deterministic actions for (N, frame) raw observations."""
        policy = self.policy
        scaled = observations if policy.scaling is None else policy.scaling(observations)
        return policy.model.predict(scaled, deterministic=True)[0]


class DaggerRecurrentPPO(RecurrentPPO):
    """sb3-contrib's ``RecurrentPPO`` whose rollouts mix in the teacher's actions and whose update
    imitates the teacher's labels (module docstring); the callbacks, saving and the flying policy are
    ``RecurrentPPO``'s. Set :attr:`teacher` and :attr:`distillation` before ``learn``."""

    teacher: Teacher | None = None
    distillation: DistillationSettings = DistillationSettings()
    teacher_columns: np.ndarray | None = None

    def _excluded_save_params(self) -> list[str]:
        return [
            *super()._excluded_save_params(),
            "teacher",
            "teacher_columns",
            "_kept",
            "_rng",
            "imitation_losses",
        ]

    def start_distillation(
        self, teacher: Teacher, settings: DistillationSettings, layout: dict[str, slice]
    ) -> None:
        self.teacher, self.distillation = teacher, settings
        self.teacher_columns = teacher.columns(layout)
        self._kept: deque[dict[str, torch.Tensor]] = deque(maxlen=settings.kept_iterations)
        self._rng = np.random.default_rng(self.seed)
        self.imitation_losses: list[float] = []
        """Each iteration's mean squared error of the student's mean action to the labels."""
        self._iterations = getattr(self, "_iterations", 0)

    def collect_rollouts(self, env, callback, rollout_buffer, n_rollout_steps: int) -> bool:
        if self.teacher is None:
            raise RuntimeError("DaggerRecurrentPPO: call start_distillation before learn")
        self.policy.set_training_mode(False)
        s = self.distillation
        share = s.teacher_share * s.teacher_decay**self._iterations
        callback.on_rollout_start()
        states = self._last_lstm_states
        first = (states.pi[0].clone(), states.pi[1].clone())
        observations, starts, labels = [], [], []
        for _ in range(n_rollout_steps):
            raw = env.get_original_obs()
            with torch.no_grad():
                obs = obs_as_tensor(self._last_obs, self.device)
                episode_starts = torch.tensor(self._last_episode_starts, dtype=torch.float32)
                distribution, pi = self.policy.get_distribution(obs, states.pi, episode_starts)
                own = distribution.distribution.mean.numpy()
            states = RNNStates(pi, states.vf)
            taught = self.teacher.act(raw[:, self.teacher_columns])
            by_teacher = self._rng.random(len(own)) < share
            actions = np.where(by_teacher[:, None], taught, np.clip(own, -1.0, 1.0)).astype(np.float32)
            observations.append(obs)
            starts.append(episode_starts)
            labels.append(torch.as_tensor(taught, dtype=torch.float32))
            new_obs, _, dones, infos = env.step(actions)
            self.num_timesteps += env.num_envs
            callback.update_locals(locals())
            if not callback.on_step():
                return False
            self._update_info_buffer(infos, dones)
            self._last_obs, self._last_episode_starts, self._last_lstm_states = new_obs, dones, states
        self._kept.append(
            {
                "observations": torch.stack(observations, 1),  # (N, T, D)
                "starts": torch.stack(starts, 1),
                "labels": torch.stack(labels, 1),
                "hidden": first[0][0],  # (N, H): each vehicle's LSTM state when its rollout began
                "cell": first[1][0],
            }
        )
        callback.on_rollout_end()
        return True

    def train(self) -> None:
        """Fit the student's mean action to the kept rollouts' labels (module docstring)."""
        self.policy.set_training_mode(True)
        self._update_learning_rate(self.policy.optimizer)
        rollouts = [(k, n) for k, part in enumerate(self._kept) for n in range(part["labels"].shape[0])]
        losses = []
        for _ in range(self.distillation.epochs):
            order = self._rng.permutation(len(rollouts))
            for first in range(0, len(order), self.distillation.batch):
                picked = [rollouts[i] for i in order[first : first + self.distillation.batch]]
                part = {key: torch.stack([self._kept[k][key][n] for k, n in picked]) for key in self._kept[0]}
                batch, steps = part["labels"].shape[:2]
                hidden = (part["hidden"][None], part["cell"][None])
                distribution, _ = self.policy.get_distribution(
                    part["observations"].reshape(batch * steps, -1), hidden, part["starts"].reshape(-1)
                )
                mean = distribution.distribution.mean.reshape(batch, steps, -1)
                loss = torch.mean((mean - part["labels"]) ** 2)
                self.policy.optimizer.zero_grad()
                loss.backward()
                torch.nn.utils.clip_grad_norm_(self.policy.parameters(), self.max_grad_norm)
                self.policy.optimizer.step()
                losses.append(loss.item())
        self._iterations += 1
        self.imitation_losses.append(float(np.mean(losses)))
        self.logger.record("distillation/imitation_loss", self.imitation_losses[-1])
        s = self.distillation
        self.logger.record(
            "distillation/teacher_share", s.teacher_share * s.teacher_decay ** (self._iterations - 1)
        )

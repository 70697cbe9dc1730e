"""stable-baselines3's ``VecEnv`` interface over a :class:`QuadWrenchVectorEnv`, so its algorithms
train on N vehicles flown in one world directly:

    venv = SB3VecEnv(gym.make_vec("QuadWrench/FanTracking-v1", num_envs=32,
                                  vectorization_mode="vector_entry_point"))
    model = PPO("MlpPolicy", VecNormalize(VecMonitor(venv)), n_steps=256, batch_size=1024, n_epochs=5)
    model.learn(1_000_000)

A :class:`~quad_wrench_env.envs.processes.ProcessVectorEnv` in place of the vector env steps the
vehicles in several processes at once, with the same numbers. (PPO's default ``n_steps=2048``
would fly 65k samples before its first update; ``quad-wrench train`` runs the project's configs.)

Both restart an episode in the step that ends it; the adapter moves the ended episode's last
observation to ``infos[i]["terminal_observation"]`` and marks time-outs with
``"TimeLimit.truncated"``, as SB3 expects. Seeds set with ``seed()`` and options set with
``set_options()`` apply at the next ``reset()``, vehicle ``i`` getting ``seed + i``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvStepReturn

from quad_wrench_env.envs.processes import ProcessVectorEnv
from quad_wrench_env.envs.vector import QuadWrenchVectorEnv


class SB3VecEnv(VecEnv):
    """A :class:`QuadWrenchVectorEnv` seen through stable-baselines3's ``VecEnv`` interface.

    ``step_infos=True`` (default) puts each step's ``reward_terms`` and the task's scalar entries
    (e.g. ``axis_error``; for a vehicle whose episode ended, the ended episode's) into every
    ``infos[i]``, for a callback of the user's. ``False`` leaves ``infos[i]`` empty but for what SB3
    reads (``terminal_observation`` and ``TimeLimit.truncated`` where an episode ended) and keeps the
    same numbers as arrays over vehicles in :attr:`reward_terms` and :attr:`task_entries`: what
    ``quad-wrench train`` logs, with no per-vehicle Python objects on the training path."""

    def __init__(self, venv: gym.vector.VectorEnv | ProcessVectorEnv, step_infos: bool = True) -> None:
        unwrapped = venv.unwrapped
        if not isinstance(unwrapped, (QuadWrenchVectorEnv, ProcessVectorEnv)):
            raise ValueError(
                f"SB3VecEnv wraps a QuadWrenchVectorEnv (gym.make_vec(..., vectorization_mode="
                f"'vector_entry_point')) or a ProcessVectorEnv, got {type(unwrapped).__name__}"
            )
        self.venv = unwrapped
        super().__init__(
            unwrapped.num_envs, unwrapped.single_observation_space, unwrapped.single_action_space
        )
        self.step_infos = step_infos
        self._actions: np.ndarray | None = None
        self.reward_terms: dict[str, np.ndarray] = {}
        """The last step's reward terms, (N,) each."""
        self.task_entries: dict[str, np.ndarray] = {}
        """The last step's task entries that are one number per vehicle, (N,) each (before restarts)."""

    def reset(self) -> np.ndarray:
        options = [opts or None for opts in self._options]
        obs, info = self.venv.reset_vehicles(range(self.num_envs), self._seeds, options)
        self.reset_infos = self._split(info, np.ones(self.num_envs, bool))
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        step = self.venv.step_arrays(self._actions)
        self.reward_terms = step.reward_terms
        self.task_entries = {k: v for k, v in step.task_entries.items() if np.ndim(v) == 1}
        dones = step.terminated | step.truncated
        infos = self._step_infos() if self.step_infos else [{} for _ in range(self.num_envs)]
        for i in np.flatnonzero(dones).tolist():
            infos[i]["terminal_observation"] = step.final_observations[i]
            infos[i]["TimeLimit.truncated"] = bool(step.truncated[i] and not step.terminated[i])
        return step.observations, step.rewards.astype(np.float32), dones, infos

    def _step_infos(self) -> list[dict[str, Any]]:
        """Per vehicle: this step's reward terms and the task's scalar entries."""
        names = list(self.reward_terms)
        keys = list(self.task_entries)
        columns = [np.asarray(self.task_entries[k], dtype=float) for k in keys]
        columns += [np.asarray(self.reward_terms[name], dtype=float) for name in names]
        out = []
        for row in np.column_stack(columns).tolist():
            entry: dict[str, Any] = dict(zip(keys, row[: len(keys)], strict=True))
            entry["reward_terms"] = dict(zip(names, row[len(keys) :], strict=True))
            out.append(entry)
        return out

    def close(self) -> None:
        self.venv.close()

    # -- what SB3 asks of every VecEnv -------------------------------------------------------------
    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [getattr(self.venv, attr_name)] * len(self._get_indices(indices))

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        raise AttributeError(f"set_attr({attr_name!r}): the vehicles share one env object; set it there")

    def env_method(
        self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs
    ) -> list[Any]:
        raise AttributeError(f"env_method({method_name!r}): the vehicles share one env object; call it there")

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        return [False] * len(self._get_indices(indices))

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None] * self.num_envs

    @staticmethod
    def _split(info: dict[str, Any], mask: np.ndarray) -> list[dict[str, Any]]:
        """Per-vehicle info dicts (entries whose ``_key`` mask is set) from a vector info."""
        out: list[dict[str, Any]] = [{} for _ in mask]
        for key, value in info.items():
            if key.startswith("_"):
                continue
            present = info.get(f"_{key}", mask) & mask
            rows = SB3VecEnv._split(value, present) if isinstance(value, dict) else value
            for i in np.flatnonzero(present).tolist():
                out[i][key] = rows[i]
        return out

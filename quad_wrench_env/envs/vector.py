"""N vehicles of one task as a Gymnasium ``VectorEnv``: one PyBullet world, one batched computation.

``gym.make_vec("QuadWrench/FanTracking-v1", num_envs=N, vectorization_mode="vector_entry_point")``
builds it (every id the package registers has a vector entry point). Vehicle ``i`` behaves exactly
as a single env of the same id and settings would, reset with seed ``seed + i``: same code (a
:class:`~quad_wrench_env.engine.fleet.Fleet` of N instead of one), same random draws, same numbers.

Episodes restart in the step that ends them (``AutoresetMode.SAME_STEP``, as stable-baselines3
expects), without reset options (Gymnasium's convention: an autoreset episode draws what its options
would have fixed; ``reset_vehicles`` restarts chosen vehicles with options): the returned
observation is the new episode's first, and the last one of the ended episode is in
``info["final_obs"]`` with its info in ``info["final_info"]``. ``info`` holds every
single-env key as an array over vehicles, each with its ``_key`` mask (Gymnasium's convention);
``reward_terms`` and ``termination_reason`` belong to the step, so for restarted vehicles they are
in ``final_info``. The vector env does not render: make a single env to watch a vehicle.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from quad_wrench_env.envs.base import QuadWrenchEnv, build_config, check_options, clip_actions, closed_error
from quad_wrench_env.envs.simulation import Simulation, StepResult


def _masked(entries: Mapping[str, Any], mask: np.ndarray) -> dict[str, Any]:
    """Vector info: each entry with its ``_key`` mask (nested dicts get masks of their own)."""
    info: dict[str, Any] = {}
    for key, value in entries.items():
        info[key] = _masked(value, mask) if isinstance(value, Mapping) else value
        info[f"_{key}"] = mask.copy()
    return info


@dataclass(frozen=True)
class Transition:
    """One step of every vehicle as arrays over vehicles (:meth:`QuadWrenchVectorEnv.step_arrays`)."""

    observations: np.ndarray
    """(N, width): where an episode ended, the next one's first observation."""
    final_observations: np.ndarray
    """(N, width): every vehicle's observation after the step, before any restart."""
    rewards: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    reward_terms: dict[str, np.ndarray]
    task_entries: dict[str, Any]
    """The task's ``info`` entries of the step, before the restarts."""


class QuadWrenchVectorEnv(VectorEnv):
    """N independent episodes of the task of ``env_class``, flown together (see the module docstring)."""

    metadata: ClassVar[dict[str, Any]] = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": []}
    env_class: ClassVar[type[QuadWrenchEnv]]
    """The single env whose task and settings every vehicle has (set by each task's subclass)."""

    def __init__(
        self,
        num_envs: int = 1,
        config: str | Path | Mapping[str, Any] | None = None,
        render_mode: str | None = None,
        **overrides: Any,
    ) -> None:
        if not (isinstance(num_envs, int) and num_envs >= 1):
            raise ValueError(f"num_envs={num_envs!r} must be an integer >= 1")
        if render_mode is not None:
            raise ValueError(
                f"render_mode={render_mode!r}: the vector env does not render; allowed: None "
                "(make a single env with gym.make to watch a vehicle)"
            )
        task_class = self.env_class.task_class
        self.cfg = build_config(task_class.config_class, config, overrides)
        cfg = self.cfg
        self.num_envs = num_envs
        self.render_mode = None
        self.simulation = Simulation(task_class, cfg, num_envs)
        """The fleet of ``num_envs`` vehicles and its task (:mod:`quad_wrench_env.envs.simulation`)."""
        self.task, self.fleet = self.simulation.task, self.simulation.fleet
        self.vehicle = self.fleet.vehicle
        self.reset_options = task_class.reset_options
        self.termination_reasons = self.simulation.termination_reasons
        self.max_steps = self.simulation.max_steps
        self.obs_layout = self.fleet.layout.slices
        self.action_scaling = self.fleet.action_scaling
        self.dt = 1.0 / cfg.policy_hz
        self.physics_dt = self.fleet.dt
        self.single_observation_space = self.fleet.layout.space(self.vehicle, self.cfg.arena)
        self.single_action_space = spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._rngs: list[np.random.Generator | None] = [None] * num_envs
        self._started = False
        self._closed = False

    # -- Gymnasium API -----------------------------------------------------------------------------
    def reset(
        self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Restart every vehicle; vehicle ``i`` gets seed ``seed + i`` (or ``seed[i]`` for a list)
        and the same task ``options``."""
        if self._closed:
            raise closed_error(self)
        if seed is None or isinstance(seed, (int, np.integer)):
            seeds = [None if seed is None else int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"seed={seed!r} must be an int, None or a list of {self.num_envs} seeds")
        return self.reset_vehicles(range(self.num_envs), seeds, [options] * self.num_envs)

    def reset_vehicles(
        self,
        indices: Sequence[int],
        seeds: Sequence[int | None],
        options: Sequence[Mapping[str, Any] | None],
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Restart the vehicles ``indices`` with their seeds and task options (None: keep the
        vehicle's generator, as a single env's ``reset()`` without a seed does)."""
        for i, seed, vehicle_options in zip(indices, seeds, options, strict=True):
            if seed is not None or self._rngs[i] is None:
                self._rngs[i], _ = seeding.np_random(seed)
            self.simulation.start(i, self._rngs[i], check_options(vehicle_options, self.reset_options))
        observations = self.simulation.restarted(np.asarray(list(indices), dtype=int))
        self._started = True
        return observations, _masked(self._infos(), np.ones(self.num_envs, bool))

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        result = self._advance(actions)
        step_observations, terminated, truncated = result.observations, result.terminated, result.truncated
        reasons = self.termination_reasons
        step_entries = {
            **self._infos(),
            "reward_terms": result.reward_terms,
            "termination_reason": np.array([reasons[c] for c in result.codes.tolist()], dtype=object),
        }
        done = terminated | truncated
        if not np.any(done):
            info = _masked(step_entries, np.ones(self.num_envs, bool))
            info["_termination_reason"] = terminated
            return step_observations, result.rewards, terminated, truncated, info
        final_info = _masked(step_entries, done)
        final_info["_termination_reason"] = terminated
        final_obs = np.full(self.num_envs, None, dtype=object)
        for i in np.flatnonzero(done).tolist():
            final_obs[i] = step_observations[i]
        next_observations = self._restart_ended(done)
        info = _masked(self._infos(), np.ones(self.num_envs, bool))
        info.update({k: v for k, v in _masked(step_entries, ~done).items() if "reward_terms" in k})
        info["termination_reason"] = step_entries["termination_reason"]
        info["_termination_reason"] = np.zeros(self.num_envs, bool)
        info.update(final_obs=final_obs, _final_obs=done, final_info=final_info, _final_info=done)
        return next_observations, result.rewards, terminated, truncated, info

    def step_arrays(self, actions: np.ndarray) -> Transition:
        """:meth:`step` without Gymnasium's ``info``: the same episodes, numbers and restarts, as
        arrays over vehicles (what training reads: ``SB3VecEnv``), with no per-vehicle objects and no
        copies of the fleet's state (the engine's ``info`` entries are not gathered)."""
        result = self._advance(actions)
        done = result.terminated | result.truncated
        next_observations = self._restart_ended(done) if np.any(done) else result.observations
        return Transition(
            next_observations,
            result.observations,
            result.rewards,
            result.terminated,
            result.truncated,
            result.reward_terms,
            result.task_info,
        )

    def close_extras(self, **kwargs: Any) -> None:
        """Release the PyBullet client; safe to call more than once."""
        self._closed = True
        self.simulation.close()

    # -- helpers -----------------------------------------------------------------------------------
    def _advance(self, actions: np.ndarray) -> StepResult:
        """One control step of every vehicle, before any restart."""
        if self._closed:
            raise closed_error(self)
        if not self._started:
            raise RuntimeError("call reset() before step()")
        return self.simulation.step(clip_actions(actions, (self.num_envs, 4)))

    def _restart_ended(self, done: np.ndarray) -> np.ndarray:
        """Start the next episode of the vehicles ``done`` (without options); every observation."""
        restarted = np.flatnonzero(done)
        for i in restarted.tolist():
            self.simulation.start(i, self._rngs[i], {})
        return self.simulation.restarted(restarted)

    def _infos(self) -> dict[str, Any]:
        return self.simulation.info()

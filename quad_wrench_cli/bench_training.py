"""Training speed: env steps per second end to end, where the time goes, and the env's own floors.

    quad-wrench bench --training [--config configs/train_fan_tracking.yaml] [--steps N] [--repeats N]

All measured in this run, wall and CPU time (machines are shared: CPU seconds count only this
process), for the training config's task, vehicles and settings:

1. the training path's wrappers, stepped in alternating blocks on the same random actions, µs per
   vehicle and policy step: the vector env's Gymnasium ``step`` (with its info), its
   ``step_arrays`` (what training steps), ``SB3VecEnv``, ``+ VecMonitor``, ``+`` SB3's
   ``VecNormalize`` and, in its place, ``+ CompiledVecNormalize`` (the training path whole, in one
   process), the same vehicles' ``step_arrays`` in ``P`` processes
   (:class:`~quad_wrench_env.envs.processes.ProcessVectorEnv`, wall time: the processes step at
   once), each with its ratio to ``step_arrays``; and the bare PyBullet floor of as many bodies
   with the loads of one physics step, times the physics steps of a policy step;
2. ``--steps`` env steps of the config's algorithm learning on that path, with the vehicles in one
   process and in ``P``, one after the other: env steps per second (wall, and per CPU-second of
   the learner's process) and the shares of wall time in env stepping (the whole wrapper stack),
   policy inference with the rest of the rollout, and the updates.

``P`` is the config's ``env_processes``, or 2 where it says 1.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any

import numpy as np

from quad_wrench_cli.common import markdown_table, show
from quad_wrench_env.bench import FLOORS, bare_pybullet_step_seconds

BLOCK = 50
"""Policy steps per timing block of the wrapper comparison."""


class _Clock:
    """Wall and CPU seconds spent inside ``with clock:`` blocks."""

    def __init__(self) -> None:
        self.wall = self.cpu = 0.0

    def __enter__(self) -> _Clock:
        self._wall, self._cpu = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc: object) -> None:
        self.wall += time.perf_counter() - self._wall
        self.cpu += time.process_time() - self._cpu


def wrapper_rows(config: Any, blocks: int) -> list[list[str]]:
    """Table 1: µs (CPU) per vehicle and policy step of each layer of the training path."""
    import gymnasium as gym
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from quad_wrench_env.agents.sb3 import training_env
    from quad_wrench_env.envs.processes import ProcessVectorEnv
    from quad_wrench_env.envs.sb3_vec_env import SB3VecEnv

    def vector() -> Any:
        return gym.make_vec(
            config.env_id, num_envs=config.num_envs, vectorization_mode="vector_entry_point", **config.env
        )

    raw, arrays = vector(), vector()
    adapter = SB3VecEnv(vector(), step_infos=False)
    monitored = VecMonitor(SB3VecEnv(vector(), step_infos=False))
    whole = training_env(dataclasses.replace(config, env_processes=1))[1]
    plain = VecNormalize(
        VecMonitor(SB3VecEnv(vector(), step_infos=False)),
        clip_obs=config.clip_observations,
        norm_obs=config.normalize_observations,
        norm_reward=config.normalize_rewards,
    )
    processes = processes_compared(config)[-1]
    split = SB3VecEnv(
        ProcessVectorEnv(config.env_id, config.num_envs, processes, **config.env), step_infos=False
    )
    layers: dict[str, Any] = {
        "vector env `step` (Gymnasium info)": raw.step,
        "vector env `step_arrays`": arrays.unwrapped.step_arrays,
        "+ SB3VecEnv": adapter.step,
        "+ VecMonitor": monitored.step,
        "+ SB3's VecNormalize": plain.step,
        "+ CompiledVecNormalize (the training path, 1 process)": whole.step,
        f"`step_arrays` in {processes} processes (wall time)": split.venv.step_arrays,
    }
    raw.reset(seed=config.seed)
    arrays.reset(seed=config.seed)
    for env in (adapter, monitored, plain, whole, split):
        env.seed(config.seed)
        env.reset()
    actions = np.random.default_rng(0).uniform(-0.3, 0.3, (BLOCK, config.num_envs, 4)).astype(np.float32)
    best = dict.fromkeys(layers, np.inf)
    for _ in range(blocks):
        for name, step in layers.items():
            clock = time.perf_counter if "wall" in name else time.process_time
            started = clock()
            for action in actions:
                step(action)
            best[name] = min(best[name], (clock() - started) / (BLOCK * config.num_envs))
    for env in (raw, arrays, adapter, monitored, plain, whole, split):
        env.close()
    substeps = raw.unwrapped.fleet.substeps
    world_step = min(
        bare_pybullet_step_seconds(BLOCK * substeps, bodies=config.num_envs, floor=FLOORS[1])
        for _ in range(blocks)
    )
    floor = world_step * substeps / config.num_envs  # per vehicle and policy step
    base = best["vector env `step_arrays`"]
    rows = [[name, f"{seconds * 1e6:.1f}", f"{seconds / base:.3f}"] for name, seconds in best.items()]
    label = f"bare PyBullet floor: {config.num_envs} bodies, {substeps} physics steps"
    return [*rows, [label, f"{floor * 1e6:.1f}", f"{floor / base:.3f}"]]


def processes_compared(config: Any) -> list[int]:
    """The vehicles' process counts compared: 1 and the config's ``env_processes`` (2 where it is 1)."""
    return [1, max(config.env_processes, 2)]


def learning_rows(config: Any, steps: int) -> list[list[str]]:
    """Table 2's column: the config's algorithm learning ``steps`` env steps on the training path."""
    import torch
    from stable_baselines3.common.vec_env import VecEnvWrapper

    from quad_wrench_env.agents.sb3 import new_model, training_env

    class TimedEnv(VecEnvWrapper):
        """The env the learner sees, timing every step (the whole wrapper stack below it)."""

        def reset(self) -> np.ndarray:
            return self.venv.reset()

        def step_async(self, actions: np.ndarray) -> None:
            with env_clock:
                self.venv.step_async(actions)

        def step_wait(self) -> Any:
            with env_clock:
                return self.venv.step_wait()

    torch.set_num_threads(config.threads)
    env_clock, update_clock, total = _Clock(), _Clock(), _Clock()
    _, env = training_env(config)
    model = new_model(config, TimedEnv(env))
    update = model.train

    def timed_update() -> None:
        with update_clock:
            update()

    model.train = timed_update
    with total:
        model.learn(steps)
    env.close()
    done = model.num_timesteps
    wall = total.wall
    inference = wall - update_clock.wall - env_clock.wall
    return [
        ["env steps", f"{done}"],
        ["env steps / s (wall)", f"{done / wall:,.0f}"],
        ["env steps / CPU-s of the learner's process", f"{done / total.cpu:,.0f}"],
        ["env stepping (the whole wrapper stack)", f"{env_clock.wall:.1f} s ({env_clock.wall / wall:.0%})"],
        ["policy inference, rollout bookkeeping", f"{inference:.1f} s ({inference / wall:.0%})"],
        ["updates", f"{update_clock.wall:.1f} s ({update_clock.wall / wall:.0%})"],
    ]


def report(config_file: str | Path, steps: int | None, repeats: int) -> None:
    """Print both tables for the training config ``config_file``."""
    from quad_wrench_env.agents.sb3 import TrainConfig
    from quad_wrench_env.config import build, load_yaml

    config = build(TrainConfig, load_yaml(config_file))
    if config.env_groups:
        raise ValueError(
            f"env_groups={config.env_groups!r}: the benchmark times one env in 1 and more processes; "
            "time a config without groups"
        )
    steps = steps or 4 * config.num_envs * config.hyperparameters.get("n_steps", 64)
    title = (
        f"training path of {config_file} ({config.env_id}, {config.num_envs} vehicles, env {config.env}), "
        f"best of {repeats} blocks of {BLOCK} policy steps, CPU time"
    )
    table = markdown_table(["layer", "µs / vehicle step", "x step_arrays"], wrapper_rows(config, repeats))
    show(f"{title}\n\n{table}\n")
    title = f"{config.algorithm.upper()} learning {steps} env steps ({config.hyperparameters}), wall time"
    counts = processes_compared(config)
    columns = [learning_rows(dataclasses.replace(config, env_processes=n), steps) for n in counts]
    rows = [[label, *(column[i][1] for column in columns)] for i, (label, _) in enumerate(columns[0])]
    header = ["what", *(f"vehicles in {n} process{'es' if n > 1 else ''}" for n in counts)]
    show(f"{title}\n\n{markdown_table(header, rows)}")

"""One harness that runs any policy on any env id over a list of seeds and scores it.

The harness is the only code that reads ``info`` (the truth), and only to score: the policy sees
observations alone. Each task scores its own episodes (``Task.metrics``: the env's own task, or the
registered task of an env id).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from quad_wrench_env.agents.base import Policy
from quad_wrench_env.config import merged
from quad_wrench_env.registry import bare_env_id, registered

TRACE_KEYS = ("time", "position", "wrench_true", "wrench_est", "wind_velocity")
"""``info`` entries recorded at every step of every task (plus ``reward`` and the task's own
``trace_keys``)."""


@dataclass
class Episode:
    """The recorded trace of one episode: arrays over steps, keyed as in ``info``."""

    seed: int
    trace: dict[str, np.ndarray]
    total_reward: float
    length: int
    termination_reason: str | None


@dataclass
class Evaluation:
    """Per-seed metrics, their mean over seeds, and the episodes they came from."""

    env_id: str
    seeds: list[int]
    per_seed: list[dict[str, float]]
    episodes: list[Episode] = field(repr=False)

    @property
    def mean(self) -> dict[str, float]:
        keys = self.per_seed[0].keys() if self.per_seed else ()
        return {k: float(np.mean([m[k] for m in self.per_seed])) for k in keys}


def episode_metrics(task: Any, episode: Episode) -> dict[str, float]:
    """The task's own scores of ``episode`` (its ``metrics``) and those of every task: the episode's
    length, return and whether it ended early. ``task``: the env's (``env.unwrapped.task``) or an env
    id, whose registered task scores (an id of no registered task: only the scores of every task)."""
    if isinstance(task, str):
        task = registered("task").get(bare_env_id(task))
    return {
        **(task.metrics(episode.trace) if task is not None else {}),
        "episode_seconds": float(episode.trace["time"][-1]),
        "return": episode.total_reward,
        "terminated_early": float(episode.termination_reason is not None),
    }


def run_episode(
    policy: Policy,
    env: gym.Env,
    seed: int,
    options: Mapping[str, Any] | None = None,
    on_step: Callable[[gym.Env, dict[str, Any]], None] | None = None,
) -> Episode:
    """Run ``policy`` on ``env`` for one episode from ``reset(seed=seed, options=options)``;
    ``on_step(env, info)``, if given, is called after the reset and after every step (e.g. to record a
    frame, :mod:`quad_wrench_env.agents.video`)."""
    observation, info = env.reset(seed=seed, options=dict(options or {}))
    policy.reset(env)
    if on_step is not None:
        on_step(env, info)
    keys = (*TRACE_KEYS, *env.unwrapped.task.trace_keys)
    records: dict[str, list] = {k: [info[k]] for k in keys if k in info}
    rewards = [0.0]
    total, length, reason = 0.0, 0, None
    while True:
        observation, reward, terminated, truncated, info = env.step(policy.act(observation))
        total += reward
        length += 1
        rewards.append(reward)
        for key, values in records.items():
            values.append(info[key])
        if on_step is not None:
            on_step(env, info)
        if terminated or truncated:
            reason = info.get("termination_reason")
            break
    trace = {k: np.asarray(v) for k, v in records.items()}
    trace["reward"] = np.asarray(rewards)
    return Episode(seed, trace, float(total), length, reason)


def flying_settings(
    policy: Policy, env_kwargs: Mapping[str, Any], env_id: str | None = None
) -> dict[str, Any]:
    """``env_kwargs`` with, for a learned policy, the settings that give its actions and
    observations their meaning (:data:`~quad_wrench_env.agents.sb3_policy.MEANING_KEYS`: action type and
    limits, observed wrench, history, DisturbanceRejection's tracking error) and, with the estimator it
    was trained with, that estimator's settings (e.g. the filters' fixed walks) as its training env had
    them, where ``env_kwargs`` does not set them (a meaning setting given that differs is refused by the
    policy's ``reset``, naming it). With ``env_id`` the env it was trained on (a lone evaluation, as
    ``quad-wrench evaluate``), every other setting of its training env too: its world. A comparison
    leaves ``env_id`` out, so that every agent meets the same episodes. A mapping given is merged into
    the trained one key by key (``jet_crossing.jet_speeds`` keeps the trained ``jet_sides``)."""
    settings = getattr(policy, "env_settings", None)
    return merged(settings(env_kwargs, env_id) if callable(settings) else {}, env_kwargs)


def evaluate(
    policy: Policy,
    env_id: str,
    seeds: Iterable[int],
    options: Mapping[str, Any] | None = None,
    **env_kwargs: Any,
) -> Evaluation:
    """Run ``policy`` on ``gym.make(env_id, **env_kwargs)`` once per seed and score every episode.
    ``policy`` is an agent, or a stable-baselines3 model (run deterministically on raw observations;
    wrap a model trained behind ``VecNormalize`` in ``quad_wrench_env.agents.sb3_policy.SB3Policy`` with its
    scaling).

    ``options`` go to every ``reset`` (e.g. ``{"offset_y": 0.8, "fan_motion": "static"}``). A
    learned policy flies with the settings its training env had (:func:`flying_settings`).
    """
    if not isinstance(policy, Policy) and hasattr(policy, "predict"):  # a bare SB3 model
        from quad_wrench_env.agents.sb3_policy import SB3Policy

        policy = SB3Policy(policy)
    seeds = [int(s) for s in seeds]
    if not seeds:
        raise ValueError("seeds must name at least one seed")
    env = gym.make(env_id, **flying_settings(policy, env_kwargs))
    task = env.unwrapped.task
    try:
        episodes = [run_episode(policy, env, seed, options) for seed in seeds]
    finally:
        env.close()
    return Evaluation(env_id, seeds, [episode_metrics(task, e) for e in episodes], episodes)


def write_report(out: Path, header: list[str], parts: Mapping[str, Callable[[], list[str]]]) -> str:
    """A markdown report: ``header``, then the lines of each part in turn (printing ``done: name`` as
    each finishes), written to ``out / "table.md"``; returns its text."""
    lines = list(header)
    for name, part in parts.items():
        lines += [*part(), ""]
        print(f"done: {name}", flush=True)
    table = "\n".join(lines)
    (out / "table.md").write_text(table)
    return table


ENDED_EARLY_COLUMN = ("terminated_early", "ended early", "{:.0%}")


def table_columns(env_id: str) -> tuple[tuple[str, str, str], ...]:
    """The columns of :func:`metrics_table` for ``env_id``: its task's ``metric_columns``, then whether
    an episode ended early."""
    task = registered("task").get(bare_env_id(env_id))
    if task is None:
        raise ValueError(f"unknown env id {env_id!r}; allowed: {sorted(registered('task'))}")
    return (*task.metric_columns, ENDED_EARLY_COLUMN)


def metrics_table(
    results: Mapping[tuple[str, str], Evaluation], columns: tuple[tuple[str, str, str], ...]
) -> list[str]:
    """Markdown rows, one per (agent, case): each metric's mean over the seeds, with its standard
    deviation where it varies, and the seeds; ``never`` where a time was never reached, ``n/a`` where
    an episode ended before the metric's window."""
    header = "| agent | case | seeds | " + " | ".join(title for _, title, _ in columns) + " |"
    lines = [header, "|" + "---|" * (3 + len(columns))]
    for (agent, case), ev in results.items():
        cells = []
        for key, _, fmt in columns:
            values = np.array([m[key] for m in ev.per_seed], dtype=float)
            if np.any(np.isnan(values)):  # e.g. an episode that ended before the metric's window
                cells.append(f"n/a ({int(np.sum(np.isnan(values)))}/{len(values)} ended early)")
                continue
            if np.any(np.isinf(values)):
                cells.append(f"never ({int(np.sum(np.isinf(values)))}/{len(values)})")
                continue
            spread = float(np.std(values))
            spread_shown = spread > 1e-9 * float(np.abs(values).max())  # not the rounding of equal values
            cells.append(fmt.format(values.mean()) + (f" ± {fmt.format(spread)}" if spread_shown else ""))
        seeds = ",".join(str(s) for s in ev.seeds)
        lines.append(f"| {agent} | {case} | {seeds} | " + " | ".join(cells) + " |")
    return lines


def compare(config: Mapping[str, Any]) -> dict[tuple[str, str], Evaluation]:
    """Every agent of a comparison config (``env_id``, ``env``, ``seeds``, ``agents``: label ->
    ``{agent, params, env}``, ``cases``: label -> ``{options, env}``) on every case, the same seeds
    for all: the config's env, then the agent's, then the case's."""
    from tqdm import tqdm

    from quad_wrench_env.agents import make_agent

    results = {}
    jobs = [(label, case) for label in config["agents"] for case in config["cases"]]
    for label, case in tqdm(jobs, desc="agents x cases", unit="evaluation"):
        spec, setup = config["agents"][label], config["cases"][case]
        env = merged(merged(config.get("env", {}), spec.get("env", {})), setup.get("env", {}))
        results[label, case] = evaluate(
            make_agent(spec["agent"], **spec.get("params", {})),
            config["env_id"],
            config["seeds"],
            options=setup.get("options", {}),
            **env,
        )
    return results

"""Reproduce Hentzen et al.'s (2019) Table I and Figs. 9 and 11, and Neural-Fly's figure-8 benchmark, in
simulation.

    quad-wrench reproduce hentzen [--config configs/reproduce_hentzen.yaml] [--only table1 fig11 fig9 figure8]

Every controller flies QuadWrench/DisturbanceRejection-v0 with the gains of the config's ``gains``
(tuned once by ``quad-wrench reproduce tune-hentzen`` on other seeds, never per scenario), on the
config's seeds, once per estimator. Writes under ``output``: ``table1.md``, ``fig11_<estimator>.png``,
``fig9.png``, ``figure8.md``, ``figure8.png`` and ``report.md`` (all tables, seeds and settings).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import matplotlib
import numpy as np
from tqdm import tqdm

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from quad_wrench_cli import reproduction
from quad_wrench_cli.common import save_figure
from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents.evaluate import Episode, episode_metrics, run_episode


class TimedPolicy:
    """Records the wall time of every ``act`` call (Hentzen et al. 2019 Fig. 9: time per controller
    iteration)."""

    def __init__(self, policy: Any) -> None:
        self.policy = policy
        self.seconds: list[float] = []

    def reset(self, env: gym.Env) -> None:
        self.policy.reset(env)

    def act(self, observation: np.ndarray) -> np.ndarray:
        start = time.perf_counter()
        action = self.policy.act(observation)
        self.seconds.append(time.perf_counter() - start)
        return action


def controller(config: dict, label: str) -> TimedPolicy:
    """The controller called ``label`` in the config: its agent's tuned gains and its switches."""
    spec = config["controllers"][label]
    return TimedPolicy(
        make_agent(spec["agent"], **config["gains"][spec["agent"]], **spec.get("switches", {}))
    )


def fly(
    config: dict, label: str, estimator: str, seed: int, options: dict, **env: Any
) -> tuple[Episode, list]:
    policy = controller(config, label)
    settings = config.get("estimator_params", {}).get(estimator)  # the papers' fixed walks
    if settings is not None:
        env = {"estimator_params": settings, **env}
    environment = gym.make(config["env_id"], estimator=estimator, **env)
    try:
        return run_episode(policy, environment, seed, options), policy.seconds
    finally:
        environment.close()


def sweep(
    config: dict, labels: list[str], speeds: list[float], desc: str, metric: str, setup: Callable
) -> dict[tuple[str, str, float], list[float]]:
    """``metric`` of every estimator, controller (``labels``) and speed over the seeds; ``setup(speed)``
    gives the reset options and the env overrides of one speed."""
    jobs = [
        (e, c, v, s) for e in config["estimators"] for c in labels for v in speeds for s in config["seeds"]
    ]
    results: dict[tuple[str, str, float], list[float]] = {}
    for estimator, label, speed, seed in tqdm(jobs, desc=desc, unit="episode"):
        options, env = setup(speed)
        episode, _ = fly(config, label, estimator, seed, options, **env)
        results.setdefault((estimator, label, speed), []).append(
            episode_metrics(config["env_id"], episode)[metric]
        )
    return results


def _cells(values: list[float], scale: float = 100.0) -> str:
    return f"{scale * np.mean(values):.1f} ± {scale * np.std(values):.1f}"


# -- Table I: the jet crossing ------------------------------------------------------------------------
def table1(config: dict, out: Path) -> list[str]:
    setup, seeds = config["table1"], config["seeds"]
    speeds, env = setup["jet_speeds"], setup.get("env", {})
    settings = f", env {env}" if env else ""
    lines = [
        f"## Table I: max horizontal deviation (cm) through the jet (mean ± sd over seeds {seeds}{settings})",
        "",
        "| controller | estimator | "
        + " | ".join(f"{v:g} m/s" for v in speeds)
        + " | improvement over PID | paper ("
        + ", ".join(f"{v:g}" for v in speeds)
        + " m/s) |",
        "|---|---|" + "---|" * len(speeds) + "---|---|",
    ]
    results = sweep(
        config,
        setup["controllers"],
        speeds,
        "Table I",
        "max_horizontal_deviation",
        lambda speed: ({"jet_speed": speed}, {"episode_seconds": setup["seconds"], **env}),
    )
    for estimator in config["estimators"]:
        base = {v: np.mean(results[estimator, setup["baseline"], v]) for v in speeds}
        for label in setup["controllers"]:
            values = [results[estimator, label, v] for v in speeds]
            gains = ", ".join(
                f"{100 * (1 - np.mean(x) / base[v]):+.0f} %" for x, v in zip(values, speeds, strict=True)
            )
            paper = ", ".join(str(p) for p in setup["paper"][label])
            lines.append(
                f"| {label} | {estimator} | "
                + " | ".join(_cells(x) for x in values)
                + f" | {gains} | {paper} |"
            )
    (out / "table1.md").write_text("\n".join(lines) + "\n")
    return lines


# -- Fig. 11: the table pass ----------------------------------------------------------------------------
def fig11(config: dict, out: Path) -> list[str]:
    setup, seeds = config["fig11"], config["seeds"]
    lines = [
        f"## Fig. 11: table pass, z error (cm) over the table (seeds {seeds})",
        "",
        "| controller | estimator | max z error | max z error over the table |",
        "|---|---|---|---|",
    ]
    table = setup["table_x"]
    for estimator in config["estimators"]:
        fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
        for label, colour in zip(setup["controllers"], ("tab:red", "tab:blue"), strict=True):
            errors, forces, maxima, over = [], [], [], []
            for seed in tqdm(seeds, desc=f"Fig. 11 {label} {estimator}", unit="episode", leave=False):
                episode, _ = fly(config, label, estimator, seed, {"scenario": "table_pass"})
                trace = episode.trace
                moving = np.flatnonzero(np.abs(np.diff(trace["reference_position"][:, 0])) > 0)
                span = slice(moving[0], moving[-1] + 2)
                x = trace["position"][span, 0]
                grid = np.linspace(setup["x_range"][0], setup["x_range"][1], 200)
                error = trace["position"][span, 2] - trace["reference_position"][span, 2]
                errors.append(np.interp(grid, x, error))
                forces.append(np.interp(grid, x, trace["wrench_est"][span, 2]))
                maxima.append(float(np.max(np.abs(error))))
                on_table = (x > table[0]) & (x < table[1])
                over.append(float(np.max(np.abs(error[on_table]))))
            for axis, values, scale in ((top, forces, 1.0), (bottom, errors, 100.0)):
                mean, sd = scale * np.mean(values, axis=0), scale * np.std(values, axis=0)
                axis.plot(grid, mean, color=colour, label=f"{label} (mean)")
                axis.fill_between(
                    grid, mean - 2 * sd, mean + 2 * sd, color=colour, alpha=0.2, label=f"{label} ± 2σ"
                )
            lines.append(f"| {label} | {estimator} | {_cells(maxima)} | {_cells(over)} |")
        for axis in (top, bottom):
            for n, edge in enumerate(table):
                label = "table edge" if n == 0 else "_table edge"  # one legend entry for both edges
                axis.axvline(edge, color="grey", linestyle=":", linewidth=1, label=label)
        top.set_ylabel("estimated f_z (N)")
        bottom.set_ylabel("z error (cm)")
        bottom.set_xlabel("x (m)")
        top.set_title(f"Table pass at 0.3 m/s, 8 cm over the table ({estimator}, seeds {seeds})")
        top.legend(fontsize=7)
        bottom.legend(fontsize=7)
        save_figure(fig, out / f"fig11_{estimator}.png")
    return lines


# -- Fig. 9: time per controller iteration ----------------------------------------------------------
def fig9(config: dict, out: Path) -> list[str]:
    setup = config["fig9"]
    seconds = {}
    for label in tqdm(setup["controllers"], desc="Fig. 9", unit="controller"):
        samples: list[float] = []
        for seed in config["seeds"]:
            _, timing = fly(
                config,
                label,
                setup["estimator"],
                seed,
                {"jet_speed": setup["jet_speed"]},
                episode_seconds=config["table1"]["seconds"],
            )
            samples += timing[1:]  # the first call of an episode sets up the solver
        seconds[label] = 1e3 * np.array(samples)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.boxplot(list(seconds.values()), whis=(0, 100))
    ax.set_xticks(range(1, len(seconds) + 1), list(seconds))
    ax.set_xlabel("controller (box: quartiles, whiskers: min and max)")
    ax.set_ylabel("time per iteration (ms)")
    ax.set_title(f"Controller iteration, jet crossing at {setup['jet_speed']:g} m/s (this machine)")
    save_figure(fig, out / "fig9.png")
    lines = [
        "## Fig. 9: time per controller iteration (ms, this machine; paper: Odroid XU4)",
        "",
        "| controller | mean | max | paper mean |",
        "|---|---|---|---|",
    ]
    for label, ms in seconds.items():
        lines.append(f"| {label} | {np.mean(ms):.2f} | {np.max(ms):.2f} | {setup['paper_ms'][label]} |")
    return lines


# -- Neural-Fly's figure-8 -------------------------------------------------------------------------------
def figure8(config: dict, out: Path) -> list[str]:
    setup, seeds = config["figure8"], config["seeds"]
    speeds = setup["wind_speeds"]
    results = sweep(
        config,
        setup["controllers"],
        speeds,
        "figure-8",
        "mean_tracking_error",
        lambda speed: ({"wind_speed": speed}, {}),
    )
    lines = [
        f"## Figure-8 (x = 1.25 sin t, z = 0.75 sin 2t): mean tracking error (cm), seeds {seeds}",
        "",
        "Simulation here; Neural-Fly's rows are real flights in a wind tunnel (O'Connell et al. 2022).",
        "",
        "| controller | estimator | " + " | ".join(f"{v:g} m/s" for v in speeds) + " |",
        "|---|---|" + "---|" * len(speeds),
    ]
    for estimator in config["estimators"]:
        for label in setup["controllers"]:
            cells = " | ".join(_cells(results[estimator, label, v]) for v in speeds)
            lines.append(f"| {label} | {estimator} | {cells} |")
    for label, values in setup["neural_fly_cm"].items():
        lines.append(f"| {label} (real flight) | - | " + " | ".join(f"{v:g}" for v in values) + " |")
    fig, axes = plt.subplots(
        1, len(config["estimators"]), figsize=(4.5 * len(config["estimators"]), 4), sharey=True
    )
    for ax, estimator in zip(np.atleast_1d(axes), config["estimators"], strict=True):
        for label in setup["controllers"]:
            means = [100 * np.mean(results[estimator, label, v]) for v in speeds]
            ax.plot(speeds, means, "o-", label=label)
        for label, values in setup["neural_fly_cm"].items():
            ax.plot(speeds, values, "x--", label=f"{label} (real flight)")
        ax.set_xlabel("wind speed (m/s)")
        ax.set_title(f"estimate: {estimator}")
        ax.legend(fontsize=7)
    np.atleast_1d(axes)[0].set_ylabel("mean tracking error (cm)")
    save_figure(fig, out / "figure8.png")
    (out / "figure8.md").write_text("\n".join(lines) + "\n")
    return lines


PARTS = {"table1": table1, "fig11": fig11, "fig9": fig9, "figure8": figure8}


TITLE = "Hentzen et al. 2019"


CONFIG = "reproduce_hentzen.yaml"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    reproduction.add_arguments(parser, PARTS, CONFIG)


def run(args: argparse.Namespace) -> int:
    return reproduction.run_parts(args, PARTS, CONFIG, TITLE)

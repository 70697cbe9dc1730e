"""Reproduce McKinnon & Schoellig's (2016) Figs. 3, 4, 6 and 7 in simulation: PNG figures and a markdown
table.

    quad-wrench reproduce mckinnon [--config configs/reproduce_mckinnon.yaml] [--only fig3 fig4] [--seeds 0 1]

Writes the figures and ``table.md`` under the config's ``output`` (``results/reproduce_mckinnon``).
"""

from __future__ import annotations

import argparse
from functools import partial
from pathlib import Path
from typing import Any

import gymnasium as gym
import matplotlib
import numpy as np
from tqdm import tqdm

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from quad_wrench_cli import reproduction
from quad_wrench_cli.common import save_figure, show
from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents.evaluate import Episode, episode_metrics, run_episode, write_report

LABELS = ("f_x", "f_y", "f_z", "tau_x", "tau_y", "tau_z")


def _episode(config: dict, policy, seed: int, options: dict | None = None, **env_overrides: Any) -> Episode:
    env = gym.make(config["env_id"], config=config, **env_overrides)
    try:
        return run_episode(policy, env, seed, options)
    finally:
        env.close()


def _hold(config: dict) -> Any:
    return make_agent("hold", **config["hold"])


def _hover(config: dict, seed: int, payload: dict, seconds: float, **env_overrides: Any) -> Episode:
    """The hold agent hovering on the fan's axis with the fan off, carrying ``payload``."""
    return _episode(
        config,
        _hold(config),
        seed,
        {"offset_y": 0.0, "fan_motion": "static"},
        fan={"enabled": False},
        payload=payload,
        episode_seconds=seconds,
        **env_overrides,
    )


def rise_time(t: np.ndarray, signal: np.ndarray, start: float, before: float, step: float) -> float:
    """10-90 % rise time of ``signal`` after ``start`` for a step of ``step`` from ``before``."""
    after = t >= start
    progress = (signal[after] - before) / step
    t_after = t[after]
    reached_10 = np.flatnonzero(progress >= 0.1)
    reached_90 = np.flatnonzero(progress >= 0.9)
    if not reached_10.size or not reached_90.size:
        return float("inf")
    return float(t_after[reached_90[0]] - t_after[reached_10[0]])


PAPER_SD = np.array((0.05, 0.02, 0.02))
"""McKinnon & Schoellig's (2016) real-flight standard deviations of (f_z, tau_x, tau_y) (Sec. III)."""


def fig3(config: dict, out: Path) -> list[str]:
    c = config["fig3"]
    rows = [
        "| kf spread | case | seed | f_z true | f_z est (mean ± sd) | tau_x true | tau_x est | tau_y true | "
        "tau_y est | within 1 sd | within paper's sd |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    fig, ax = plt.subplots(figsize=(6, 5))
    for spread in c["kf_spreads"]:
        for case, point in c["cases"].items():
            payload = {"mass": 0.0} if point is None else {"mass": c["test_mass"], "point": point}
            for seed in tqdm(config["seeds"], desc=f"Fig. 3 {case}, kf spread {spread}", leave=False):
                ep = _hover(config, seed, payload, c["seconds"], kf_spread=spread)
                keep = ep.trace["time"] >= c["settle"]
                est, true = ep.trace["wrench_est"][keep], ep.trace["wrench_true"][keep].mean(axis=0)
                mean, sd = est.mean(axis=0), est.std(axis=0)
                error = np.abs(mean - true)[2:5]
                rows.append(
                    f"| {spread} | {case} | {seed} | {true[2]:.3f} | {mean[2]:.3f} ± {sd[2]:.3f} | "
                    f"{true[3]:.4f} | {mean[3]:.4f} ± {sd[3]:.4f} | {true[4]:.4f} | "
                    f"{mean[4]:.4f} ± {sd[4]:.4f} | {'yes' if np.all(error <= sd[2:5]) else 'no'} | "
                    f"{'yes' if np.all(error <= PAPER_SD) else 'no'} |"
                )
                if spread == c["kf_spreads"][0]:
                    ax.scatter(est[::10, 2], est[::10, 4], s=2, alpha=0.3, label=f"UKF: {case}, seed {seed}")
                    ax.plot(true[2], true[4], "k+", ms=12, label="truth")
    ax.set_xlabel("f_z estimate [N]")
    ax.set_ylabel("tau_y estimate [N·m]")
    ax.set_title(
        f"Fig. 3: hover, 53 g below CoM, 53 g under a rotor (kf spread {c['kf_spreads'][0]}, + = truth)",
        fontsize=9,
    )
    handles, labels = ax.get_legend_handles_labels()
    unique = dict(zip(labels, handles, strict=True))  # one "truth" entry, the last
    unique["truth"] = unique.pop("truth")
    legend = ax.legend(unique.values(), unique.keys(), fontsize=7)
    for handle in legend.legend_handles[:-1]:
        handle.set_sizes([20.0])  # the scatters' dots, visible in the legend
    save_figure(fig, out / "fig3.png")
    return [
        "## Fig. 3: static accuracy (statistics over the last "
        f"{c['seconds'] - c['settle']:.0f} s of each hover)",
        "",
        *rows,
    ]


def fig4(config: dict, out: Path) -> list[str]:
    c = config["fig4"]
    rows = ["| seed | rise f_z [s] | rise tau_x [s] | rise tau_y [s] |", "|---|---|---|---|"]
    fig, axes = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    payload = {"mass": c["test_mass"], "point": c["point"], "attach_time": c["attach_time"]}
    for seed in tqdm(config["seeds"], desc="Fig. 4", unit="episode", leave=False):
        ep = _hover(config, seed, payload, c["seconds"])
        t, est, true = ep.trace["time"], ep.trace["wrench_est"], ep.trace["wrench_true"]
        before = est[(t > c["attach_time"] - 2.0) & (t < c["attach_time"])].mean(axis=0)
        step = true[-1] - true[0]
        rises = [rise_time(t, est[:, i], c["attach_time"], before[i], step[i]) for i in (2, 3, 4)]
        rows.append(f"| {seed} | " + " | ".join(f"{r:.2f}" for r in rises) + " |")
        axes[0].plot(t, est[:, 2], lw=0.8, label=f"UKF estimate (seed {seed})")
        axes[1].plot(t, est[:, 4], lw=0.8, label=f"UKF estimate (seed {seed})")
    axes[0].plot(t, true[:, 2], "k", lw=1.2, label="truth")
    axes[1].plot(t, true[:, 4], "k", lw=1.2, label="truth")
    axes[0].set_ylabel("f_z [N]")
    axes[1].set_ylabel("tau_y [N·m]")
    axes[1].set_xlabel("time [s]")
    axes[0].set_title(
        f"Fig. 4: 53 g attached under a rotor at {c['attach_time']} s (seeds {config['seeds']})"
    )
    axes[0].legend(fontsize=7)
    axes[1].legend(fontsize=7)
    save_figure(fig, out / "fig4.png")
    return ["## Fig. 4: step response (10-90 % rise time of the estimate)", "", *rows]


def fig6(config: dict, out: Path) -> list[str]:
    c = config["fig6"]
    xs, ys = np.array(c["x"]), np.array(c["y"])
    est = np.zeros((len(xs), len(ys), 6))
    true = np.zeros_like(est)
    for i, x in enumerate(tqdm(xs, desc="Fig. 6", unit="row", leave=False)):
        for j, y in enumerate(ys):
            ep = _episode(
                config,
                _hold(config),
                c["seed"],
                {"offset_y": float(y), "fan_motion": "static"},
                standoff_distance=float(x),
                episode_seconds=c["seconds"],
            )
            keep = ep.trace["time"] >= c["seconds"] - c["average_last"]
            est[i, j] = ep.trace["wrench_est"][keep].mean(axis=0)
            true[i, j] = ep.trace["wrench_true"][keep].mean(axis=0)
    fig, axes = plt.subplots(2, 2, figsize=(9, 7), sharex=True, sharey=True)
    for row, (k, unit) in enumerate(((0, "N"), (5, "N·m"))):
        limit = np.abs(true[:, :, k]).max()
        for col, (data, name) in enumerate(((est, "UKF estimate"), (true, "truth"))):
            ax = axes[row, col]
            image = ax.pcolormesh(
                ys, xs, data[:, :, k], cmap="RdBu_r", vmin=-limit, vmax=limit, shading="nearest"
            )
            fig.colorbar(image, ax=ax, label=f"{LABELS[k]} [{unit}]")
            ax.set_title(f"{LABELS[k]}, {name}")
            ax.set_xlabel("y [m]")
            ax.set_ylabel("x (distance from fan) [m]")
    fig.suptitle(f"Fig. 6: loads in front of the fan, {c['seconds']} s hover per point (seed {c['seed']})")
    save_figure(fig, out / "fig6.png")
    rows = ["| x [m] | y [m] | f_x est | f_x true | tau_z est | tau_z true |", "|---|---|---|---|---|---|"]
    middle = len(xs) // 2
    for j, y in enumerate(ys):
        rows.append(
            f"| {xs[middle]:.1f} | {y:+.1f} | {est[middle, j, 0]:.3f} | {true[middle, j, 0]:.3f} | "
            f"{est[middle, j, 5]:+.4f} | {true[middle, j, 5]:+.4f} |"
        )
    error = np.abs(est - true)
    return [
        "## Fig. 6: force and torque map (the row at the middle distance; all points in fig6.png)",
        "",
        *rows,
        "",
        f"Largest |estimate - truth| over the grid: f_x {error[:, :, 0].max():.3f} N, "
        f"tau_z {error[:, :, 5].max():.4f} N·m.",
    ]


def fig7(config: dict, out: Path) -> list[str]:
    c = config["fig7"]
    rows = [
        "| seed | mean abs(y - y_axis) after 5 s [m] | time within 0.15 m | first within 0.15 m [s] |",
        "|---|---|---|---|",
    ]
    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for n, seed in enumerate(tqdm(config["seeds"], desc="Fig. 7", unit="episode", leave=False)):
        ep = _episode(
            config, make_agent("admittance", **c["agent"]), seed, c["options"], episode_seconds=c["seconds"]
        )
        m = episode_metrics(config["env_id"], ep)
        rows.append(
            f"| {seed} | {m['mean_abs_error_after_5s']:.3f} | {m['fraction_within_0.15m']:.0%} | "
            f"{m['time_to_0.15m']:.2f} |"
        )
        t = ep.trace["time"]
        if n == 0:
            axes[0].plot(t, ep.trace["fan_position"][:, 1], "k--", label="y_fan")
            axes[1].plot(
                t, ep.trace["wrench_true"][:, 5], color="0.6", lw=0.8, label=f"tau_z true (seed {seed})"
            )
        axes[0].plot(t, ep.trace["position"][:, 1], lw=1.0, label=f"y (seed {seed})")
        axes[1].plot(t, ep.trace["wrench_est"][:, 5], lw=0.8, label=f"tau_z UKF (seed {seed})")
    axes[0].set_ylabel("y [m]")
    axes[1].set_ylabel("tau_z [N·m]")
    axes[1].set_xlabel("time [s]")
    axes[0].legend(fontsize=7)
    axes[1].legend(fontsize=7)
    axes[0].set_title("Fig. 7: admittance control on the UKF's tau_z, fan 2.3 m away moving along y")
    save_figure(fig, out / "fig7.png")
    return ["## Fig. 7: fan tracking with the UKF estimate", "", *rows]


FIGURES = {"fig3": fig3, "fig4": fig4, "fig6": fig6, "fig7": fig7}


CONFIG = "reproduce_mckinnon.yaml"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    reproduction.add_arguments(parser, FIGURES, CONFIG)


def run(args: argparse.Namespace) -> int:
    config, label = reproduction.load(args, CONFIG)
    out = Path(config.get("output", "results/reproduce_mckinnon"))
    out.mkdir(parents=True, exist_ok=True)
    env = config.get("env", {})
    lines = [
        f"# McKinnon & Schoellig 2016 in simulation: config {label}, vehicle {env.get('vehicle')}, "
        f"estimator {env.get('estimator')}, seeds {config['seeds']}",
        "",
    ]
    chosen = {name: partial(FIGURES[name], config, out) for name in args.only or FIGURES}
    show(write_report(out, lines, chosen))
    return 0

"""Compare the UKF, the EKF and the nonlinear observer on the same recorded flights.

    quad-wrench compare estimators [--config configs/compare_estimators.yaml] [--only fig5 fig4 cost nees]

Writes figures and ``table.md`` to the config's ``output`` folder. ``nees`` is the filters' consistency on
flights of the env (:mod:`quad_wrench_cli.consistency`).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import gymnasium as gym
import matplotlib
import numpy as np
from tqdm import tqdm

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from quad_wrench_cli.common import add_config_argument, load_config, save_figure, show, usage_errors
from quad_wrench_cli.consistency import nees_table
from quad_wrench_cli.estimator_benchmark import benchmark_table
from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents.evaluate import run_episode, write_report
from quad_wrench_env.bench import bare_pybullet_step_seconds, estimator_step_seconds
from quad_wrench_env.estimators import OracleBank, make_estimator
from quad_wrench_env.estimators.bank import EstimatorInputs, TruthRecorder
from quad_wrench_env.vehicle import make_vehicle

LABELS = ("f_x", "f_y", "f_z", "tau_x", "tau_y", "tau_z")
UNITS = ("N", "N", "N", "N·m", "N·m", "N·m")


@dataclass
class Stream:
    """Everything an estimator sees in one flight, at the physics rate, and the truth to score it."""

    dt: float
    inputs: list[tuple] = field(default_factory=list)
    truth: list[np.ndarray] = field(default_factory=list)


class _Recorder(TruthRecorder):
    """Wraps the env's oracle bank (one vehicle) and records each step's sensor data, the inputs of
    the estimator interface, with the true wrench."""

    def __init__(self, inner: OracleBank, stream: Stream) -> None:
        super().__init__(inner)
        self.stream = stream

    def step(self, inputs: EstimatorInputs) -> None:
        thrusts, body_torques, positions, quaternions = inputs[:4]
        self.stream.inputs.append(
            (float(thrusts[0]), body_torques[0].copy(), positions[0].copy(), quaternions[0].copy())
        )
        self.stream.truth.append(self.truth[1][0])


def record(config: dict, seed: int, **env_kwargs: Any) -> Stream:
    """Fly once with position hold on the true state and record the sensor stream."""
    env = gym.make(config["env_id"], estimator="oracle", fan={"enabled": False}, **env_kwargs)
    try:
        base = env.unwrapped
        stream = Stream(base.physics_dt)
        base.fleet.estimator = _Recorder(base.fleet.estimator, stream)
        run_episode(
            make_agent("hold", **config["hold"]), env, seed, {"offset_y": 0.0, "fan_motion": "static"}
        )
        return stream
    finally:
        env.close()


def replay(name: str, vehicle: str, stream: Stream, settings: dict) -> np.ndarray:
    """(steps, 6) wrench estimates of estimator ``name`` on the recorded stream."""
    estimator = make_estimator(name, make_vehicle(vehicle), stream.dt, **settings)
    _, _, position, quaternion = stream.inputs[0]
    estimator.reset(position, quaternion)
    out = np.empty((len(stream.inputs), 6))
    for k, (thrust, torque, position, quaternion) in enumerate(stream.inputs):
        est = estimator.step(thrust, torque, position, quaternion)
        out[k, :3], out[k, 3:] = est.force, est.torque
    return out


def step_metrics(t: np.ndarray, est: np.ndarray, true: np.ndarray, segments: list) -> dict[str, float]:
    """RMSE of force and torque, mean 10-90 % rise time over the steps, steady-state sd."""
    error = est - true
    rises, spreads = [], []
    for start, end, *_ in segments:
        window = (t >= start) & (t < end)
        before = (t >= start - 1.0) & (t < start)
        settled = (t >= end - 2.0) & (t < end)
        for i in range(6):
            step = true[window, i].mean() - true[before, i].mean()
            if abs(step) < 1e-9:
                continue
            progress = (est[window, i] - est[before, i].mean()) / step
            t_window = t[window]
            r10, r90 = np.flatnonzero(progress >= 0.1), np.flatnonzero(progress >= 0.9)
            rises.append(t_window[r90[0]] - t_window[r10[0]] if r10.size and r90.size else np.inf)
            spreads.append((i, est[settled, i].std()))
    return {
        "rmse_force": float(np.sqrt(np.mean(error[:, :3] ** 2))),
        "rmse_torque": float(np.sqrt(np.mean(error[:, 3:] ** 2))),
        "rise_time": float(np.mean(rises)),
        "sd_force": float(np.mean([s for i, s in spreads if i < 3])),
        "sd_torque": float(np.mean([s for i, s in spreads if i >= 3])),
    }


def fig5(config: dict, out: Path) -> list[str]:
    c = config["fig5"]
    lines = [
        "## McKinnon & Schoellig 2016 Fig. 5: changing wrench, low and high noise (mean over seeds)",
        "",
        "| case | estimator | RMSE force [N] | RMSE torque [N·m] | rise time [s] | sd force [N] | "
        "sd torque [N·m] |",
        "|---|---|---|---|---|---|---|",
    ]
    ratios = []
    for case, settings in c["cases"].items():
        metrics: dict[str, list[dict]] = {name: [] for name in config["estimators"]}
        traces = {}
        for seed in tqdm(config["seeds"], desc=f"Fig. 5 {case}", unit="flight", leave=False):
            stream = record(
                config,
                seed,
                vehicle=c["vehicle"],
                sensors=settings["sensors"],
                external_wrench=c["wrench"],
                episode_seconds=c["seconds"],
            )
            t = stream.dt * np.arange(1, len(stream.inputs) + 1)
            true = np.array(stream.truth)
            for name in config["estimators"]:
                params = {
                    **_measurement_noise(settings["sensors"]),
                    **settings["estimator_params"].get(name, {}),
                }
                est = replay(name, c["vehicle"], stream, params)
                metrics[name].append(step_metrics(t, est, true, c["wrench"]))
                if seed == config["seeds"][0]:
                    traces[name] = est
        means = {
            name: {k: float(np.mean([r[k] for r in runs])) for k in runs[0]} for name, runs in metrics.items()
        }
        for name, mean in means.items():
            lines.append(
                f"| {case} | {name} | {mean['rmse_force']:.4f} | {mean['rmse_torque']:.5f} | "
                f"{mean['rise_time']:.2f} | {mean['sd_force']:.4f} | {mean['sd_torque']:.5f} |"
            )
        observer, ukf = means["observer"], means["ukf"]
        ratios.append(
            f"- {case}: observer/UKF RMSE ratio, force {observer['rmse_force'] / ukf['rmse_force']:.2f}, "
            f"torque {observer['rmse_torque'] / ukf['rmse_torque']:.2f}"
        )
        _plot(
            t,
            true,
            traces,
            out / f"fig5_{case}.png",
            f"McKinnon & Schoellig 2016 Fig. 5, {case} ({c['vehicle']}, seed {config['seeds'][0]})",
        )
    return [*lines, "", *ratios]


def fig4_yuksel(config: dict, out: Path) -> list[str]:
    c = config["fig4_yuksel"]
    lines = [
        "## Yüksel et al. 2014 Fig. 4 profile on yuksel1kg (worst settled error over segments and "
        "components, relative to the applied value; pass = within 10 %)",
        "",
        "| kf spread | estimator | seed | worst settled error / applied | pass |",
        "|---|---|---|---|---|",
    ]
    for spread in c["kf_spreads"]:
        for seed in tqdm(config["seeds"], desc=f"Fig. 4 kf spread {spread}", unit="flight", leave=False):
            stream = record(
                config,
                seed,
                vehicle=c["vehicle"],
                sensors=c["sensors"],
                kf_spread=spread,
                external_wrench=c["wrench"],
                episode_seconds=c["seconds"],
            )
            t = stream.dt * np.arange(1, len(stream.inputs) + 1)
            true = np.array(stream.truth)
            traces = {}
            for name in config["estimators"]:
                params = {**_measurement_noise(c["sensors"]), **c["estimator_params"].get(name, {})}
                est = replay(name, c["vehicle"], stream, params)
                traces[name] = est
                worst = 0.0
                for _, end, *wrench in c["wrench"]:
                    window = (t >= end - c["settle_window"]) & (t < end)
                    for i, value in enumerate(wrench):
                        if value != 0:
                            error = abs(est[window, i].mean() - true[window, i].mean())
                            worst = max(worst, error / abs(value))
                lines.append(
                    f"| {spread} | {name} | {seed} | {worst:.3f} | {'yes' if worst <= 0.1 else 'no'} |"
                )
            if seed == config["seeds"][0] and spread == c["kf_spreads"][0]:
                _plot(
                    t,
                    true,
                    traces,
                    out / "fig4_yuksel.png",
                    f"Yüksel et al. 2014 Fig. 4 profile (yuksel1kg, kf spread {spread}, seed {seed})",
                )
    return lines


def cost(config: dict, out: Path) -> list[str]:
    c = config["cost"]
    bare = min(bare_pybullet_step_seconds(c["steps"]) for _ in range(c["repeats"]))
    times = {}
    for n in config["estimators"]:
        estimator_step_seconds(n, 2)  # compiled code loads on first use
        times[n] = min(estimator_step_seconds(n, c["steps"]) for _ in range(c["repeats"]))
    lines = [
        "## Hentzen et al. 2019 Sec. V-C: cost per step on this machine (best of repeats)",
        "",
        "| what | µs per step |",
        "|---|---|",
        f"| bare PyBullet step (four rotor forces) | {bare * 1e6:.1f} |",
    ]
    lines += [f"| {n} | {times[n] * 1e6:.1f} |" for n in config["estimators"]]
    if not {"ukf", "ekf"} <= set(config["estimators"]):
        return lines
    paper = "Hentzen et al. 2019 measured 2.5 on its flight computer"
    return [*lines, "", f"UKF/EKF cost ratio: {times['ukf'] / times['ekf']:.2f} ({paper})"]


def _measurement_noise(sensors: dict) -> dict:
    return {"position": sensors["position_noise"], "attitude": sensors["attitude_noise"]}


def _plot(t: np.ndarray, true: np.ndarray, traces: dict, path: Path, title: str) -> None:
    fig, axes = plt.subplots(6, 1, figsize=(9, 11), sharex=True)
    for i, ax in enumerate(axes):
        for name, est in reversed(traces.items()):  # the noisiest (observer) underneath
            ax.plot(t, est[:, i], lw=0.7, label=name)
        ax.plot(t, true[:, i], "k", lw=1.2, label="truth")
        ax.set_ylabel(f"{LABELS[i]} [{UNITS[i]}]")
        ax.legend(fontsize=6, ncol=4, loc="upper left")
    axes[0].set_title(title)
    axes[-1].set_xlabel("time [s]")
    save_figure(fig, path, dpi=110)


PARTS = {"fig5": fig5, "fig4": fig4_yuksel, "cost": cost, "nees": nees_table, "benchmark": benchmark_table}
CONFIG = "compare_estimators.yaml"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_argument(parser, CONFIG)
    parser.add_argument("--only", nargs="+", choices=list(PARTS), help="run only these parts (default: all)")


def run(args: argparse.Namespace) -> int:
    config, label = load_config(args.config, CONFIG)
    with usage_errors():
        lines = [f"# Estimator comparison: config {label}, seeds {config['seeds']}", ""]
    out = Path(config.get("output", "results/compare_estimators"))
    out.mkdir(parents=True, exist_ok=True)
    chosen = {name: partial(PARTS[name], config, out) for name in args.only or PARTS}
    show(write_report(out, lines, chosen))
    return 0

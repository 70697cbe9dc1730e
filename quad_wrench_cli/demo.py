"""The main job (make run): agents compared on FanTracking, a metrics table and plots of y, y_fan, tau_z.

    quad-wrench demo [--config configs/fan_tracking.yaml] [--seeds 100 101 102]

Every agent of the config flies with every estimator on every case, all on the same seeds; prints the
table and writes ``metrics.md`` and ``tracking.png`` under the config's ``output``
(``results/fan_tracking`` by default).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from tqdm import tqdm

from quad_wrench_cli.common import add_config_argument, load_config, save_figure, seed, show, usage_errors
from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents.evaluate import Evaluation, evaluate, metrics_table, table_columns

CONFIG = "fan_tracking.yaml"


def run_all(config: dict, seeds: list[int]) -> dict[tuple[str, str], Evaluation]:
    """Every agent with every estimator on every case, all on the same seeds."""
    results = {}
    jobs = [
        (a, e, c) for a in config["agents"] for e in config.get("estimators", [None]) for c in config["cases"]
    ]
    for agent_name, estimator, case in tqdm(jobs, desc="FanTracking", unit="evaluation"):
        label = agent_name if estimator is None else f"{agent_name} + {estimator}"
        overrides = {} if estimator is None else {"estimator": estimator}
        results[label, case] = evaluate(
            make_agent(agent_name, **(config["agents"][agent_name] or {})),
            config["env_id"],
            seeds,
            options=config["cases"][case],
            config=config,
            **overrides,
        )
    return results


def plot(results: dict[tuple[str, str], Evaluation], path: Path) -> None:
    cases = sorted({case for _, case in results}, key=list(dict.fromkeys(c for _, c in results)).index)
    fig, axes = plt.subplots(2, len(cases), figsize=(5 * len(cases), 6), sharex=True, squeeze=False)
    for col, case in enumerate(cases):
        top, bottom = axes[0, col], axes[1, col]
        first = True
        for (agent, c), ev in results.items():
            if c != case:
                continue
            episode = ev.episodes[0]
            t = episode.trace["time"]
            if first:
                top.plot(t, episode.trace["fan_position"][:, 1], "k--", label="y_fan")
                top.plot(t, episode.trace["jet_axis_y"], "k:", label=f"jet axis at vehicle ({agent})")
                bottom.plot(
                    t, episode.trace["wrench_true"][:, 5], color="0.6", lw=0.8, label=f"tau_z true ({agent})"
                )
                first = False
            top.plot(t, episode.trace["position"][:, 1], label=f"y ({agent})")
            bottom.plot(t, episode.trace["wrench_est"][:, 5], lw=1.0, label=f"tau_z est ({agent})")
        top.set_title(f"{case} (seed {ev.seeds[0]})")
        top.set_ylabel("y [m]")
        bottom.set_ylabel("tau_z [N·m]")
        bottom.set_xlabel("time [s]")
        top.legend(fontsize=7)
        bottom.legend(fontsize=7)
    save_figure(fig, path)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_argument(parser, CONFIG)
    parser.add_argument("--seeds", type=seed, nargs="+", metavar="SEED", help="override the config's seeds")


def run(args: argparse.Namespace) -> int:
    config, label = load_config(args.config, CONFIG)
    with usage_errors():
        seeds = args.seeds or config["seeds"]
        for name, params in config["agents"].items():  # unknown agents and gains, before any flight
            make_agent(name, **(params or {}))
    out = Path(config.get("output", "results/fan_tracking"))
    out.mkdir(parents=True, exist_ok=True)
    results = run_all(config, seeds)
    table = "\n".join(metrics_table(results, table_columns(config["env_id"])))
    env = config.get("env", {})
    title = f"FanTracking, config {label}: vehicle {env.get('vehicle', 'ardrone2')}, seeds {seeds}"
    (out / "metrics.md").write_text(f"{title}\n\n{table}\n")
    plot(results, out / "tracking.png")
    show(f"{title}\n\n{table}\n\nwrote {out / 'metrics.md'} and {out / 'tracking.png'}")
    return 0

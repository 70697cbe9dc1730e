"""Compare agents, classical and learned, on one env id: the same held-out seeds, every case.

    quad-wrench compare agents [--config configs/compare_agents.yaml]

Each agent flies each case (reset options and env overrides on top of the config's ``env`` and the
agent's own ``env``) through ``quad_wrench_env.agents.evaluate``; writes ``table.md`` (mean ± sd over the
seeds), ``errors.png`` (the task's first metric per case and agent) and ``training.png`` (the learned agents'
evaluation curves during training) under the config's ``output``.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from quad_wrench_cli.common import add_config_argument, load_config, save_figure, show, usage_errors
from quad_wrench_env.agents import SHIPPED, make_agent, shipped_agents
from quad_wrench_env.agents.evaluate import Evaluation, compare, metrics_table, table_columns
from quad_wrench_env.config import load_yaml

CONFIG = "compare_agents.yaml"


def plot(results: dict[tuple[str, str], Evaluation], metric: str, title: str, path: Path) -> None:
    agents = list(dict.fromkeys(a for a, _ in results))
    cases = list(dict.fromkeys(c for _, c in results))
    fig, ax = plt.subplots(figsize=(1.6 * len(cases) + 3, 4.5))
    width = 0.8 / len(agents)
    for k, agent in enumerate(agents):
        means = [np.mean([m[metric] for m in results[agent, c].per_seed]) for c in cases]
        spreads = [np.std([m[metric] for m in results[agent, c].per_seed]) for c in cases]
        ax.bar(np.arange(len(cases)) + k * width, means, width, yerr=spreads, label=agent, capsize=2)
    ax.set_xticks(np.arange(len(cases)) + 0.4 - width / 2, cases, rotation=20, ha="right")
    ax.set_yscale("log")
    ax.set_xlabel("case")
    ax.set_ylabel(title)
    ax.set_title(f"seeds {results[agents[0], cases[0]].seeds}")
    ax.legend(fontsize=7)
    save_figure(fig, path)


def plot_training(config: dict, path: Path) -> bool:
    """The evaluation curves (``curve.csv``) of the learned agents, against wall time; False if none."""
    fig, ax = plt.subplots(figsize=(7, 4))
    plotted = False
    titles = {key: title for key, title, _ in table_columns(config["env_id"])}  # with their units
    for label, spec in config["agents"].items():
        folder = SHIPPED / spec["agent"] if spec["agent"] in shipped_agents() else Path(spec["agent"])
        if not (folder / "curve.csv").is_file():
            continue
        with (folder / "curve.csv").open() as handle:
            rows = list(csv.DictReader(handle))
        metric = load_yaml(folder / "config.yaml")["evaluation"]["metric"]
        minutes = [float(r["wall_seconds"]) / 60.0 for r in rows]
        ax.plot(minutes, [float(r["metric"]) for r in rows], "o-", label=label)
        ax.set_ylabel(f"{titles.get(metric, metric)} on the evaluation seeds", fontsize=8)
        plotted = True
    if plotted:
        ax.set_yscale("log")
        ax.set_xlabel("wall time [min]")
        ax.set_title("learned agents during training (NaN: an episode ended before the metric's window)")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(path, dpi=120)
    plt.close(fig)
    return plotted


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_argument(parser, CONFIG)


def run(args: argparse.Namespace) -> int:
    config, label = load_config(args.config, CONFIG)
    with usage_errors():
        columns = table_columns(config["env_id"])
        out = Path(config["output"])
        for spec in config["agents"].values():  # unknown agents and gains, before any flight
            make_agent(spec["agent"], **spec.get("params", {}))
    out.mkdir(parents=True, exist_ok=True)
    results = compare(config)
    title = f"{config['env_id']}, config {label}, env {config.get('env', {})}, seeds {config['seeds']}"
    table = "\n".join([title, "", *metrics_table(results, columns), ""])
    (out / "table.md").write_text(table)
    plot(results, columns[0][0], columns[0][1], out / "errors.png")
    curves = " and training.png" if plot_training(config, out / "training.png") else ""
    show(f"{table}\nwrote {out / 'table.md'}, {out / 'errors.png'}{curves}")
    return 0

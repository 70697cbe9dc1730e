"""Compare agents on FanTracking: a metrics table (stdout and markdown) and plots of y, y_fan, tau_z.

python scripts/compare_fan_tracking.py --config configs/fan_tracking.yaml
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from agents import make_agent
from agents.evaluate import FAN_TRACKING_COLUMNS, Evaluation, evaluate, metrics_table
from quad_wrench_env.config import load_yaml


def run_all(config: dict, seeds: list[int]) -> dict[tuple[str, str], Evaluation]:
    """Every agent with every estimator on every case, all on the same seeds."""
    results = {}
    for agent_name, params in config["agents"].items():
        for estimator in config.get("estimators", [None]):
            label = agent_name if estimator is None else f"{agent_name} + {estimator}"
            overrides = {} if estimator is None else {"estimator": estimator}
            for case, options in config["cases"].items():
                results[label, case] = evaluate(
                    make_agent(agent_name, **(params or {})),
                    config["env_id"],
                    seeds,
                    options=options,
                    config=config,
                    **overrides,
                )
                print(f"done: {label} / {case}", flush=True)
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
                top.plot(t, episode.trace["jet_axis_y"], "k:", label="jet axis at vehicle")
                bottom.plot(t, episode.trace["wrench_true"][:, 5], color="0.6", lw=0.8, label="tau_z true")
                first = False
            top.plot(t, episode.trace["position"][:, 1], label=f"y ({agent})")
            bottom.plot(t, episode.trace["wrench_est"][:, 5], lw=1.0, label=f"tau_z est ({agent})")
        top.set_title(f"{case} (seed {ev.seeds[0]})")
        top.set_ylabel("y [m]")
        bottom.set_ylabel("tau_z [N·m]")
        bottom.set_xlabel("time [s]")
        top.legend(fontsize=7)
        bottom.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="configs/fan_tracking.yaml")
    parser.add_argument("--seeds", type=int, nargs="*", help="override the config's seeds")
    args = parser.parse_args()
    config = load_yaml(args.config)
    seeds = args.seeds or config["seeds"]
    out = Path(config.get("output", "results/fan_tracking"))
    out.mkdir(parents=True, exist_ok=True)
    results = run_all(config, seeds)
    table = "\n".join(metrics_table(results, FAN_TRACKING_COLUMNS))
    env = config.get("env", {})
    title = f"FanTracking, config {args.config}: vehicle {env.get('vehicle', 'ardrone2')}, seeds {seeds}"
    print(f"\n{title}\n\n{table}\n")
    (out / "metrics.md").write_text(f"{title}\n\n{table}\n")
    plot(results, out / "tracking.png")
    print(f"wrote {out / 'metrics.md'} and {out / 'tracking.png'}")


if __name__ == "__main__":
    main()

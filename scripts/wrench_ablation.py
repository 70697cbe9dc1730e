"""PPO with and without the estimated wrench in its observation: is the wrench what solves the task?

Both variants train at once (one process and one core each) for the same wall-clock budget, then
both and the classical baseline fly the same held-out seeds through ``agents.evaluate``. Writes
``table.md``, ``curves.png`` and each variant's model, observation scaling and curve under the
config's ``output``.

python scripts/wrench_ablation.py --config configs/wrench_ablation.yaml [--minutes 10]
"""

from __future__ import annotations

import argparse
import csv
import math
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from agents import make_agent
from agents.evaluate import Evaluation, evaluate
from agents.sb3 import ObservationScaling, SB3Policy
from quad_wrench_env.config import load_yaml, merged

METRICS = (
    ("mean_abs_error_after_5s", "mean abs(y - y_axis) after 5 s [m]", "{:.3f}"),
    ("fraction_within_0.15m", "time within 0.15 m", "{:.0%}"),
    ("mean_abs_standoff_error_after_5s", "mean abs(x - x_ref) after 5 s [m]", "{:.3f}"),
    ("terminated_early", "ended early", "{:.0%}"),
)


def train(name: str, config: dict[str, Any], out: Path) -> dict[str, Any]:
    """Train one variant for the budget; save ``model.zip``, ``scaling.npz`` and ``curve.csv``."""
    import gymnasium as gym
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    import quad_wrench_env  # noqa: F401  (registers the env ids)
    from quad_wrench_env.envs.sb3_vec_env import SB3VecEnv

    torch.set_num_threads(1)
    t = config["train"]
    env_kwargs = merged(config.get("env", {}), config["variants"][name])
    venv = gym.make_vec(
        config["env_id"], num_envs=t["num_envs"], vectorization_mode="vector_entry_point", **env_kwargs
    )
    env = VecNormalize(VecMonitor(SB3VecEnv(venv)), gamma=t["ppo"]["gamma"], **t["normalize"])
    env.seed(t["seed"])
    activation = {"tanh": torch.nn.Tanh, "relu": torch.nn.ReLU}[t["activation"]]
    model = PPO(
        "MlpPolicy", env, seed=t["seed"], device="cpu", verbose=0,
        policy_kwargs={"net_arch": list(t["net_arch"]), "activation_fn": activation}, **t["ppo"],
    )  # fmt: skip
    budget = 60.0 * float(t["minutes"])
    start = time.perf_counter()
    rows: list[tuple[int, float, float]] = []

    class Budget(BaseCallback):
        """Stops at the wall-clock budget; records the mean return of recent episodes per update."""

        def _on_step(self) -> bool:
            return time.perf_counter() - start < budget

        def _on_rollout_end(self) -> None:
            returns = [info["r"] for info in self.model.ep_info_buffer]
            if returns:
                rows.append((self.num_timesteps, time.perf_counter() - start, sum(returns) / len(returns)))

    model.learn(int(t["max_steps"]), callback=Budget())
    wall = time.perf_counter() - start
    folder = out / name
    folder.mkdir(parents=True, exist_ok=True)
    model.save(folder / "model.zip")
    ObservationScaling.of(env).save(folder / "scaling.npz")
    with (folder / "curve.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(("steps", "wall_seconds", "mean_episode_return"))
        writer.writerows(rows)
    env.close()
    return {"name": name, "steps": int(model.num_timesteps), "wall_seconds": wall}


def load_policy(folder: Path) -> SB3Policy:
    from stable_baselines3 import PPO

    return SB3Policy(
        PPO.load(folder / "model.zip", device="cpu"), ObservationScaling.load(folder / "scaling.npz")
    )


def markdown(results: dict[tuple[str, str], Evaluation]) -> list[str]:
    lines = [
        "| agent | case | " + " | ".join(title for _, title, _ in METRICS) + " |",
        "|" + "---|" * (2 + len(METRICS)),
    ]
    for (agent, case), ev in results.items():
        mean = ev.mean
        cells = [fmt.format(mean[key]) if math.isfinite(mean[key]) else "never" for key, _, fmt in METRICS]
        lines.append(f"| {agent} | {case} | " + " | ".join(cells) + " |")
    return lines


def plot_curves(out: Path, names: list[str]) -> None:
    fig, ax = plt.subplots(figsize=(7, 4))
    for name in names:
        with (out / name / "curve.csv").open() as handle:
            rows = list(csv.DictReader(handle))
        ax.plot(
            [float(r["steps"]) for r in rows], [float(r["mean_episode_return"]) for r in rows], label=name
        )
    ax.set_xlabel("environment steps")
    ax.set_ylabel("mean episode return (last 100 episodes)")
    ax.set_title("PPO on FanTracking-v1, with and without the estimated wrench")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "curves.png", dpi=120)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="configs/wrench_ablation.yaml")
    parser.add_argument("--minutes", type=float, help="override the training budget per variant")
    parser.add_argument("--evaluate-only", action="store_true", help="score the saved models again")
    args = parser.parse_args()
    config = load_yaml(args.config)
    if args.minutes is not None:
        if not (math.isfinite(args.minutes) and args.minutes > 0):
            parser.error(f"--minutes={args.minutes} must be a positive number")
        config["train"]["minutes"] = args.minutes
    out = Path(config["output"])
    out.mkdir(parents=True, exist_ok=True)
    names = list(config["variants"])
    runs: list[dict[str, Any]] = []
    if not args.evaluate_only:
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=len(names), mp_context=context) as pool:
            runs = list(pool.map(train, names, [config] * len(names), [out] * len(names)))
        plot_curves(out, names)
    e = config["evaluate"]
    seeds = e["seeds"]
    results: dict[tuple[str, str], Evaluation] = {}
    agents = {f"PPO {name}": (load_policy(out / name), config["variants"][name]) for name in names}
    for agent, params in e["baseline"].items():
        agents[agent] = (make_agent(agent, **(params or {})), {})
    for label, (policy, overrides) in agents.items():
        for case, options in e["cases"].items():
            results[label, case] = evaluate(
                policy, config["env_id"], seeds, options=options, **merged(config.get("env", {}), overrides)
            )
            print(f"done: {label} / {case}", flush=True)
    t = config["train"]
    header = [
        f"# Wrench ablation, config {args.config}",
        "",
        f"PPO, {t['num_envs']} batched vehicles, seed {t['seed']}, {t['minutes']} min wall-clock per "
        f"variant (both at once, one core each), evaluated deterministically on held-out seeds "
        f"{seeds[0]}-{seeds[-1]}.",
        "",
        *[f"- {r['name']}: {r['steps']} steps in {r['wall_seconds']:.0f} s" for r in runs],
        "",
    ]
    table = "\n".join([*header, *markdown(results), ""])
    (out / "table.md").write_text(table)
    print(table)


if __name__ == "__main__":
    main()

"""Tune Hentzen et al.'s (2019) position controllers once, the same way for both (their Sec. V-F: "an
overdamped position step response with minimum rise time").

    quad-wrench reproduce tune-hentzen [--config configs/tune_hentzen.yaml] [--only pid mpc]

Each controller family maps one number, its bandwidth ``λ`` (1/s), to its gains (:data:`FAMILIES`).
For every candidate ``λ`` the controller, without compensation, answers a reference step of ``step``
m along x and, separately, along z from a hover in still air (DisturbanceRejection's ``gusts``
scenario with its turbulence and bump switched off), on the config's tuning seeds and estimator. The
chosen ``λ`` is the one with the shortest 10-90 % rise time whose overshoot (the peak above the value
held over the last ``settle`` s, as a fraction of the step) stays at or below ``max_overshoot`` on
every seed and both axes. Writes ``tuning.md`` and ``gains.yaml`` (the chosen
gains, to copy into ``configs/reproduce_hentzen.yaml``) under the config's ``output``.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import yaml

from quad_wrench_cli.common import add_config_argument, load_config, show, usage_errors
from quad_wrench_cli.reproduce_mckinnon import rise_time
from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents.evaluate import run_episode
from quad_wrench_env.control.mpc_controller import MPCGains
from quad_wrench_env.vehicle import GRAVITY

ENV_ID = "QuadWrench/DisturbanceRejection-v0"


def pid_gains(bandwidth: float) -> dict[str, float]:
    """The PID's own bandwidth parametrisation (:mod:`quad_wrench_env.agents.pid`)."""
    return {"bandwidth": bandwidth}


def mpc_gains(bandwidth: float) -> dict[str, Any]:
    """The MPC's state weights as the LQR of a double integrator ``p̈ = a`` with input weight ``r``
    per (m/s²)² would have them for bandwidth ``λ`` and damping ratio 1: ``q_p = r·λ⁴``,
    ``q_v = 2·r·λ²`` (gain ``k_p = λ²``, ``k_d = 2λ``, as the PID's). ``r`` is the MPC's own input
    weight in those units: the tilt weight over g² horizontally (a tilt θ gives ``a ≈ g·θ``), the
    thrust weight (already per (m/s²)²) vertically."""
    default = MPCGains()
    r = (
        np.array((default.input_weight[1], default.input_weight[2], default.input_weight[0] * GRAVITY**2))
        / GRAVITY**2
    )
    return {
        "position_weight": [float(v) for v in r * bandwidth**4],
        "velocity_weight": [float(v) for v in 2.0 * r * bandwidth**2],
    }


FAMILIES: dict[str, Callable[[float], dict[str, float]]] = {"pid": pid_gains, "mpc": mpc_gains}
"""Agent name -> its gains at bandwidth ``λ``."""


class ReferenceStep(gym.ObservationWrapper):
    """Moves the observed reference by ``offset`` (m): a step of the reference at ``t = 0``."""

    def __init__(self, env: gym.Env, offset: np.ndarray) -> None:
        super().__init__(env)
        self._slice = env.unwrapped.obs_layout["reference_position"]
        self._offset = offset.astype(np.float32)

    def observation(self, observation: np.ndarray) -> np.ndarray:
        observation = observation.copy()
        observation[self._slice] += self._offset
        return observation


def step_response(
    agent: str, gains: dict[str, float], axis: int, seed: int, config: dict
) -> tuple[float, float]:
    """``(rise time s, overshoot fraction)`` of ``agent`` for a reference step along ``axis``."""
    offset = np.zeros(3)
    offset[axis] = config["step"]
    env = ReferenceStep(
        gym.make(
            ENV_ID,
            estimator=config["estimator"],
            estimator_params=config.get("estimator_params", {}),
            episode_seconds=config["seconds"],
            gusts={"w20": 0.0, "peak": [0.0, 0.0]},
        ),
        offset,
    )
    try:
        episode = run_episode(make_agent(agent, **gains), env, seed, {"scenario": "gusts"})
    finally:
        env.close()
    t, moved = episode.trace["time"], episode.trace["position"][:, axis] - episode.trace["position"][0, axis]
    held = float(np.mean(moved[t >= t[-1] - config["settle"]]))
    return rise_time(t, moved, 0.0, 0.0, config["step"]), (float(np.max(moved)) - held) / config["step"]


def tune(agent: str, bandwidths: list[float], config: dict) -> tuple[float, list[dict[str, Any]]]:
    rows = []
    for lam in bandwidths:
        gains = FAMILIES[agent](lam)
        results = [
            step_response(agent, gains, axis, seed, config) for axis in (0, 2) for seed in config["seeds"]
        ]
        rows.append(
            {
                "bandwidth": lam,
                "rise_x": np.mean([r for r, _ in results[: len(config["seeds"])]]),
                "rise_z": np.mean([r for r, _ in results[len(config["seeds"]) :]]),
                "overshoot": max(o for _, o in results),
                "rise": max(r for r, _ in results),
            }
        )
        print(f"{agent} λ={lam}: {rows[-1]}", flush=True)
    admissible = [r for r in rows if r["overshoot"] <= config["max_overshoot"]]
    if not admissible:
        raise SystemExit(
            f"{agent}: no bandwidth in {bandwidths} keeps the overshoot <= {config['max_overshoot']}"
        )
    return min(admissible, key=lambda r: r["rise"])["bandwidth"], rows


CONFIG = "tune_hentzen.yaml"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_argument(parser, CONFIG)
    parser.add_argument(
        "--only", nargs="+", choices=list(FAMILIES), help="tune only these agents (default: all)"
    )


def run(args: argparse.Namespace) -> int:
    config, _ = load_config(args.config, CONFIG)
    with usage_errors():
        out = Path(config["output"])
        lines = [
            f"# Tuning of Hentzen et al.'s (2019) controllers ({config['estimator']}, "
            f"seeds {config['seeds']}, step {config['step']} m, "
            f"overshoot <= {config['max_overshoot']:.0%})",
            "",
            "| agent | λ (1/s) | rise x (s) | rise z (s) | max overshoot |",
            "|---|---|---|---|---|",
        ]
    out.mkdir(parents=True, exist_ok=True)
    chosen = {}
    for agent, bandwidths in config["bandwidths"].items():
        if args.only and agent not in args.only:
            continue
        best, rows = tune(agent, bandwidths, config)
        chosen[agent] = FAMILIES[agent](best)
        for r in rows:
            mark = " **chosen**" if r["bandwidth"] == best else ""
            rises = f"{r['rise_x']:.2f} | {r['rise_z']:.2f}"
            lines.append(f"| {agent} | {r['bandwidth']}{mark} | {rises} | {r['overshoot']:.1%} |")
    (out / "tuning.md").write_text("\n".join(lines) + "\n")
    (out / "gains.yaml").write_text(yaml.safe_dump(chosen, sort_keys=False))
    show("\n".join(lines))
    return 0

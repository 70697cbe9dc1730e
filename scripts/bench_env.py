"""Env steps per second against PyBullet's own cost, measured in the same run.

    python scripts/bench_env.py [--steps 3000] [--repeats 3]

Rows: one bare PyBullet step of one body with an applied force and torque and a state read (the
floor under any env built on PyBullet), and a FanTracking policy step (4 physics steps) per
estimator and action type. Ratios compare per physics step. Best of ``--repeats`` runs each.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import quad_wrench_env  # noqa: F401  (registers the env ids)
from quad_wrench_env.bench import bare_pybullet_step_seconds
from quad_wrench_env.estimators import ESTIMATORS


def env_step_seconds(steps: int, resets: int = 20, **kwargs) -> tuple[float, float]:
    """Seconds per policy step (resets excluded) and per reset (mean of ``resets`` after the first)."""
    env = gym.make("QuadWrench/FanTracking-v0", **kwargs)
    try:
        env.reset(seed=0)
        start = time.perf_counter()
        for seed in range(1, resets + 1):
            env.reset(seed=seed)
        reset = (time.perf_counter() - start) / resets
        action = np.zeros(4, dtype=np.float32)
        elapsed = 0.0
        start = time.perf_counter()
        for _ in range(steps):
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                elapsed += time.perf_counter() - start
                env.reset()
                start = time.perf_counter()
        elapsed += time.perf_counter() - start
        return elapsed / steps, reset
    finally:
        env.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=3000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    bare = min(bare_pybullet_step_seconds(4 * args.steps) for _ in range(args.repeats))
    rows = [("bare PyBullet physics step", bare, bare, None)]
    for estimator in ESTIMATORS:
        for action_type in ("velocity", "motors"):
            runs = [
                env_step_seconds(args.steps, estimator=estimator, action_type=action_type)
                for _ in range(args.repeats)
            ]
            step = min(r[0] for r in runs)
            reset = min(r[1] for r in runs)
            rows.append((f"FanTracking {estimator}/{action_type}", step, step / 4, reset))
    print(
        f"{'what':34s} {'µs/call':>9s} {'µs/physics step':>16s} {'bare/ours':>10s} "
        f"{'policy steps/s':>15s} {'sim s per wall s':>17s} {'reset ms':>9s}"
    )
    for name, per_call, per_physics, reset in rows:
        is_env = reset is not None
        print(
            f"{name:34s} {per_call * 1e6:9.1f} {per_physics * 1e6:16.1f} {bare / per_physics:10.1%} "
            f"{(1 / per_call if is_env else float('nan')):15.0f} "
            f"{(1 / (per_call * 50) if is_env else 1 / (per_call * 200)):17.1f} "
            f"{(reset * 1e3 if is_env else float('nan')):9.2f}"
        )


if __name__ == "__main__":
    main()

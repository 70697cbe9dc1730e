"""The single env's speed against another commit: µs per policy step of the same episode, the two
checkouts timed alternately, each in a fresh process, on this machine, in one run.

    python scripts/single_env_speed.py BASE [--rounds 5] [--env QuadWrench/FanTracking-v1]
    python scripts/single_env_speed.py --time ENV_ID   # one checkout's time (run by the above)

One process flies ``ENV_ID`` with its defaults (FanTracking: the UKF) for 500 control steps of seeded
actions (uniform in [-0.3, 0.3], seed 0; reset with seed 0 first, with seed 1 where an episode ends),
five times after one untimed pass that compiles, and prints its best µs per policy step (the machine's
noise only ever adds time). The work tree and ``BASE`` (checked out as ``scripts/same_numbers.py``
does) alternate for ``--rounds`` rounds; the table has every round and each side's best. Not part of
CI: the machine's noise is in every figure, and only the two sides of one run compare.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from same_numbers import ROOT, checkout  # run as a script: its folder is first on the path

STEPS, REPEATS = 500, 5


def policy_step_seconds(env_id: str) -> float:
    """Best seconds per policy step of :data:`REPEATS` timed passes (module docstring)."""
    import gymnasium as gym

    import quad_wrench_env  # noqa: F401  (registers the ids)

    env = gym.make(env_id)
    actions = np.random.default_rng(0).uniform(-0.3, 0.3, size=(STEPS, 4)).astype(np.float32)
    best = float("inf")
    try:
        for repeat in range(REPEATS + 1):
            env.reset(seed=0)
            start = time.perf_counter()
            for action in actions:
                _, _, terminated, truncated, _ = env.step(action)
                if terminated or truncated:
                    env.reset(seed=1)
            if repeat:  # the first pass compiles
                best = min(best, (time.perf_counter() - start) / STEPS)
    finally:
        env.close()
    return best


def compare(base: str, env_id: str, rounds: int) -> None:
    script = Path(__file__).resolve()
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"work tree": ROOT, base: checkout(base, Path(tmp) / "base")}
        times: dict[str, list[float]] = {label: [] for label in trees}
        try:
            for _ in range(rounds):
                for label, tree in trees.items():
                    env = {**os.environ, "PYTHONPATH": str(tree)}
                    out = subprocess.run(
                        [sys.executable, str(script), "--time", env_id],
                        cwd=tree,
                        env=env,
                        check=True,
                        capture_output=True,
                        text=True,
                    )
                    times[label].append(float(out.stdout.split()[-1]))
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(trees[base])])
    print(f"{env_id}, µs per policy step, {rounds} alternating rounds (best of {REPEATS} each):")
    for label, values in times.items():
        print(f"  {label:12s} best {min(values):7.1f}   rounds {' '.join(f'{v:.1f}' for v in values)}")
    ratio = min(times["work tree"]) / min(times[base])
    print(f"  work tree / {base}: {ratio:.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("base", nargs="?", help="the commit to compare against")
    parser.add_argument("--rounds", type=int, default=5, help="alternating rounds (default 5)")
    parser.add_argument("--env", default="QuadWrench/FanTracking-v1", help="the env id to fly")
    parser.add_argument("--time", metavar="ENV_ID", help="time this checkout alone and print µs")
    args = parser.parse_args()
    if args.time:
        print(f"{policy_step_seconds(args.time) * 1e6:.2f}")
        return
    if not args.base:
        parser.error("give BASE (a commit) or --time ENV_ID")
    if args.rounds < 1:
        parser.error(f"--rounds={args.rounds} must be at least 1")
    compare(args.base, args.env, args.rounds)


if __name__ == "__main__":
    main()

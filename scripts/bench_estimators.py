"""Microseconds per estimator step, against one bare PyBullet physics step, in the same run.

    python scripts/bench_estimators.py [--steps 4000] [--repeats 5]

Each estimator is fed a hovering vehicle's noisy motion-capture pose (0.5 mm, 2 mrad) and the hover
thrust; the best of ``--repeats`` timings is reported (the machine's noise only ever adds time).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from quad_wrench_env.bench import bare_pybullet_step_seconds
from quad_wrench_env.estimators import ESTIMATORS, TruthFed, make_estimator
from quad_wrench_env.rotations import quat_exp, quat_multiply
from quad_wrench_env.vehicle import GRAVITY, make_vehicle

DT = 0.005


def estimator_step_seconds(name: str, steps: int, seed: int = 0) -> float:
    vehicle = make_vehicle("ardrone2")
    est = make_estimator(name, vehicle, DT)
    rng = np.random.default_rng(seed)
    position, q = np.array((0.0, 0.0, 1.0)), np.array((1.0, 0.0, 0.0, 0.0))
    positions = position + 5e-4 * rng.standard_normal((steps, 3))
    quaternions = [quat_multiply(q, quat_exp(2e-3 * rng.standard_normal(3))) for _ in range(steps)]
    est.reset(position, q)
    if isinstance(est, TruthFed):
        est.observe_truth(est.state, np.zeros(3), np.zeros(3))
    thrust, torque = vehicle.mass * GRAVITY, np.zeros(3)
    start = time.perf_counter()
    for k in range(steps):
        est.step(thrust, torque, positions[k], quaternions[k])
    return (time.perf_counter() - start) / steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=4000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    bare = min(bare_pybullet_step_seconds(args.steps) for _ in range(args.repeats))
    print(f"{'what':32s} {'µs/step':>9s} {'x bare PyBullet step':>21s}")
    print(f"{'bare PyBullet physics step':32s} {bare * 1e6:9.1f} {1.0:21.1f}")
    for name in ESTIMATORS:
        seconds = min(estimator_step_seconds(name, args.steps) for _ in range(args.repeats))
        print(f"{'estimator ' + name + ' step':32s} {seconds * 1e6:9.1f} {seconds / bare:21.1f}")


if __name__ == "__main__":
    main()

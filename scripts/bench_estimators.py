"""Microseconds per estimator step, against one bare PyBullet physics step, in the same run.

    python scripts/bench_estimators.py [--steps 4000] [--repeats 5]

Each estimator is fed a hovering vehicle's noisy motion-capture pose (0.5 mm, 2 mrad) and the hover
thrust; the best of ``--repeats`` timings is reported (the machine's noise only ever adds time). The
last rows step banks of 8 and 64 UKFs as one batched computation (what a batched env runs).
"""

from __future__ import annotations

import argparse

from quad_wrench_env.bench import bare_pybullet_step_seconds, estimator_step_seconds, filter_bank_step_seconds
from quad_wrench_env.estimators import ESTIMATORS


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
    for count in (8, 64):
        bank = min(filter_bank_step_seconds(count, args.steps // 8) for _ in range(args.repeats)) / count
        print(f"{f'UKF bank of {count}, per filter':32s} {bank * 1e6:9.1f} {bank / bare:21.1f}")


if __name__ == "__main__":
    main()

"""Microseconds per estimator step, against one bare PyBullet physics step, in the same run.

    quad-wrench bench --estimators [--steps 4000] [--repeats 5]

Each estimator is fed a hovering vehicle's noisy motion-capture pose (0.5 mm, 2 mrad) and the hover
thrust; the best of ``--repeats`` timings is reported (the machine's noise only ever adds time).
Each single estimator is timed on its kernel (the estimators' one implementation, compiled); the
rows step banks of 1, 8 and 64 UKFs as one batched computation (what the envs run): banks of 8
and 64 run on SIMD lanes, and again filter by filter, the lanes' baseline in the same run. The last two
rows step banks of 32 UKFs and 32 learned estimators, side by side (a 32-vehicle vector env's bank).
"""

from __future__ import annotations

from quad_wrench_env.bench import bare_pybullet_step_seconds, estimator_step_seconds, filter_bank_step_seconds
from quad_wrench_env.estimators import ESTIMATORS
from quad_wrench_env.numerics import COMPILED

STEPS, REPEATS = 4000, 5
"""Defaults of ``quad-wrench bench --estimators``' ``--steps`` and ``--repeats``."""


def report(steps: int, repeats: int) -> None:
    """Print the table: each timing the best of ``repeats`` runs of ``steps`` estimator steps."""
    bare = min(bare_pybullet_step_seconds(steps) for _ in range(repeats))
    print(f"{'what':52s} {'µs/step':>9s} {'x bare PyBullet step':>21s}")
    print(f"{'bare PyBullet physics step':52s} {bare * 1e6:9.1f} {1.0:21.1f}")
    for name in ESTIMATORS:
        estimator_step_seconds(name, 2)  # compiled code loads on first use
        seconds = min(estimator_step_seconds(name, steps) for _ in range(repeats))
        label = f"estimator {name} step"
        print(f"{label:52s} {seconds * 1e6:9.1f} {seconds / bare:21.1f}")
    for count in (1, 8):  # compiled code loads on first use (filter by filter, lanes)
        filter_bank_step_seconds(count, 2)
    for count in (1, 8, 64):
        bank_steps = max(steps // count, 20)
        kernels = [(False, "")]
        if COMPILED and count > 1:  # on lanes, then the lanes' baseline
            kernels.append((True, " (filter by filter)"))
        for by_filter, kind in kernels:
            bank = min(
                filter_bank_step_seconds(count, bank_steps, filter_by_filter=by_filter)
                for _ in range(repeats)
            )
            label = f"UKF bank of {count}{kind}, per filter"
            print(f"{label:52s} {bank / count * 1e6:9.1f} {bank / count / bare:21.1f}")
    count = 32
    for name in ("ukf", "learned"):
        filter_bank_step_seconds(count, 2, name=name)
        bank = min(
            filter_bank_step_seconds(count, max(steps // count, 20), name=name) for _ in range(repeats)
        )
        label = f"{name} bank of {count}, per vehicle"
        print(f"{label:52s} {bank / count * 1e6:9.1f} {bank / count / bare:21.1f}")

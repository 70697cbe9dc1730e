"""Microseconds per vehicle-step of the classical controllers, one vehicle at a time against a batch.

    quad-wrench bench --controllers [--steps 100] [--repeats 3]

A DisturbanceRejection vector env of 32 vehicles (``attitude`` action, seed 0) is flown for ``--steps``
control steps by each controller as one batch, its observations recorded; then the same observations
are fed to 32 controllers of one vehicle each (what the ``pid`` and ``mpc`` agents are) and to one batch
of 32 (what the ``residual`` action type and a vector env's evaluation run), alternately, the best of
``--repeats`` timings kept (the machine's noise only ever adds time). The controllers are those of
``configs/compare_disturbance_rejection.yaml``.
"""

from __future__ import annotations

from quad_wrench_env.bench import controller_step_seconds, recorded_observations

STEPS, REPEATS, VEHICLES = 100, 3, 32
"""Defaults of ``--steps`` and ``--repeats``; the batch's size."""
TUNED = {"position_weight": [1298.89, 1298.89, 625.0], "velocity_weight": [103.91, 103.91, 50.0]}
CONTROLLERS = {
    "PID + compensation": ("pid", {"bandwidth": 3.5, "compensation": True}),
    "MPC + compensation": ("mpc", {**TUNED, "compensation": True}),
    "MPC + slack + compensation": ("mpc", {**TUNED, "slack": True, "compensation": True}),
}
"""Row label -> (base controller, its gains)."""


def report(steps: int, repeats: int) -> None:
    """Print the table: µs per vehicle-step, one at a time and as a batch of :data:`VEHICLES`."""
    batch_label = f"batch of {VEHICLES}"
    print(
        f"{'controller':28s} {'one at a time':>14s} {batch_label:>12s} {'ratio':>6s}  [µs per vehicle-step]"
    )
    for label, (base, params) in CONTROLLERS.items():
        env, observations = recorded_observations(base, params, VEHICLES, steps)
        single = batch = float("inf")
        for _ in range(repeats):  # alternately, so that a drifting machine moves both alike
            single = min(single, controller_step_seconds(base, params, env, observations, batched=False))
            batch = min(batch, controller_step_seconds(base, params, env, observations, batched=True))
        print(f"{label:28s} {single * 1e6:14.1f} {batch * 1e6:12.1f} {batch / single:6.2f}")

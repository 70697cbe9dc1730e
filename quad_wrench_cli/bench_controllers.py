"""Microseconds per vehicle-step of the classical controllers, one vehicle at a time against a batch.

    quad-wrench bench --controllers [--steps 750] [--repeats 2]

A DisturbanceRejection vector env of 32 vehicles (``attitude`` action, seed 0, a scenario drawn for
each) is flown for ``--steps`` control steps (by default one 15-s episode: the disturbances, where the
MPC works hardest, come seconds into it) by each controller as one batch, its observations recorded;
then the same observations are fed to 32 controllers of one vehicle each (what the ``pid`` and ``mpc``
agents are) and to one batch of 32 (what the ``residual`` action type and a vector env's evaluation
run), alternately, the best of ``--repeats`` timings kept (the machine's noise only ever adds time).
The controllers are those of ``configs/compare_disturbance_rejection.yaml``. A second table splits the
MPC's batch time: DAQP's own solve time, the rest (the condensed QP's data for the batch, DAQP's
update, which factors the Hessian, and Python) and the iterations, with the share of vehicle-steps
that took two solves (the hard problem was infeasible, the soft one was solved) and of the iterations
spent there.
"""

from __future__ import annotations

from quad_wrench_env.bench import controller_step_seconds, recorded_observations, solver_profile

STEPS, REPEATS, VEHICLES = 750, 2, 32
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
    batches, profiles = {}, {}
    for label, (base, params) in CONTROLLERS.items():
        env, observations = recorded_observations(base, params, VEHICLES, steps)
        single = batch = float("inf")
        for _ in range(repeats):  # alternately, so that a drifting machine moves both alike
            single = min(single, controller_step_seconds(base, params, env, observations, batched=False))
            batch = min(batch, controller_step_seconds(base, params, env, observations, batched=True))
        print(f"{label:28s} {single * 1e6:14.1f} {batch * 1e6:12.1f} {batch / single:6.2f}")
        if base == "mpc":
            batches[label], profiles[label] = batch, solver_profile(base, params, env, observations)
    print(
        f"\n{'batch of ' + str(VEHICLES):28s} {'DAQP solve':>10s} {'the rest':>9s} {'iterations':>18s} "
        f"{'two-stage':>9s} {'its iterations':>14s}  [µs per vehicle-step; iterations mean/median/max]"
    )
    for label, p in profiles.items():
        solve, rest = p["solve_seconds"] * 1e6, (batches[label] - p["solve_seconds"]) * 1e6
        counts = f"{p['iterations_mean']:.0f}/{p['iterations_median']:.0f}/{p['iterations_max']:.0f}"
        print(
            f"{label:28s} {solve:10.1f} {rest:9.1f} {counts:>18s} {p['two_stage_share']:9.1%} "
            f"{p['two_stage_iteration_share']:14.1%}"
        )

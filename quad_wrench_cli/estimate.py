"""Run a wrench estimator on a recorded flight: its wrench series, its band and a plot.

    quad-wrench estimate flight.csv --estimator ukf
    quad-wrench estimate flight.csv --estimator ekf --vehicle hummingbird --param force_walk=0.003
    quad-wrench evaluate hold QuadWrench/FanTracking-v1 --seeds 0 --log flight.csv   # a simulated flight

LOG is a flight log, one row per sample (its columns: docs/estimators.md, "Flight logs"); a bad one is
refused with the column and the row. The estimator gets what the env hands it: the thrust and body torque
of the vehicle preset's nominal mixer from the logged motor speeds, the logged pose, and velocity and body
rates where the log has them; the oracle returns the log's true wrench. Writes LOG-STEM_ESTIMATOR.csv
(t, f_x ... tau_z [N, N·m, world frame] and the half-width of the ±2 sd band of each, empty where the
estimator carries no covariance) and LOG-STEM_ESTIMATOR.png to --output.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from quad_wrench_cli.common import add_key_value_argument, save_figure, usage_errors, write_csv
from quad_wrench_cli.compare_estimators import LABELS, UNITS
from quad_wrench_env.config import apply_overrides
from quad_wrench_env.engine.env_config import EnvConfig
from quad_wrench_env.estimators import ESTIMATORS, Estimator, StateEstimate, TruthFed, make_estimator
from quad_wrench_env.flight_log import FlightLog, read_flight_log
from quad_wrench_env.rotations import rows_times
from quad_wrench_env.vehicle import PRESETS, Mixer, VehicleParams, make_vehicle


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", metavar="LOG", help="a flight log (CSV, see docs/estimators.md)")
    parser.add_argument(
        "--estimator",
        default="ukf",
        help=f"the estimator to run: {', '.join(ESTIMATORS)}, or a user's registered one as "
        "package.module:name (default: ukf)",
    )
    parser.add_argument(
        "--vehicle",
        choices=sorted(PRESETS),
        default=EnvConfig.vehicle,
        help=f"the vehicle preset whose nominal mixer turns motor speeds into thrust and torque (default: "
        f"{EnvConfig.vehicle}, as in FanTracking-v1; DisturbanceRejection-v0 flies hummingbird, "
        "ForceExertion-v0 yuksel1kg)",
    )
    add_key_value_argument(
        parser,
        "--param",
        "an estimator setting as in gym.make's estimator_params (repeatable), e.g. force_walk=0.003; an env "
        "also passes its sensors' noise (position, attitude, and velocity, body_rate with a state "
        "estimator): give them for a flight whose sensors differ from the defaults",
    )
    parser.add_argument(
        "--output",
        metavar="DIR",
        default="results/estimate",
        help="the folder of the CSV and the plot (default: results/estimate)",
    )


def replay(
    log: FlightLog, estimator: Estimator, vehicle: VehicleParams
) -> tuple[np.ndarray, np.ndarray | None]:
    """``estimator`` (built for ``vehicle`` with ``log.period``; the oracle needs the log's true wrench) on
    ``log`` as an env runs it: the (n, 6) estimated ``[f, τ]`` (world frame) after each row, the first
    after the reset; and the (n, 6) standard deviations of its covariance, None where there is no band
    to draw (the observer's NaN: it carries none; the oracle's zeros: the truth)."""
    truth_fed = isinstance(estimator, TruthFed)
    squared = log.motor_speeds * log.motor_speeds
    nominal = rows_times(squared, Mixer(vehicle).allocation.T)  # [c_t, τ], as the env's sensors give them
    estimator.reset(log.position[0], log.quaternion[0])
    wrenches, variances = np.empty((len(log.time), 6)), np.empty((len(log.time), 6))
    for k in range(len(log.time)):
        velocity, body_rates = (None if v is None else v[k] for v in (log.velocity, log.body_rates))
        if truth_fed:  # the truth's state is not reported here: the measured pose will do
            state = StateEstimate(log.position[k], np.zeros(3), log.quaternion[k], np.zeros(3))
            estimator.observe_truth(state, log.wrench[k, :3], log.wrench[k, 3:])
        if k:
            position, quaternion = log.position[k], log.quaternion[k]
            estimator.step(nominal[k, 0], nominal[k, 1:], position, quaternion, velocity, body_rates)
        estimate = estimator.estimate
        wrenches[k, :3], wrenches[k, 3:] = estimate.force, estimate.torque
        variances[k] = np.diag(estimate.covariance)
    return wrenches, np.sqrt(variances) if np.isfinite(variances).all() and variances.any() else None


def _rows(time: np.ndarray, wrenches: np.ndarray, sd: np.ndarray | None) -> list[dict[str, str]]:
    """The CSV's rows: t, the estimate and the half-width of its ±2 sd band (empty cells without one),
    every number as ``repr`` writes it."""
    rows = []
    for k, t in enumerate(time.tolist()):
        row = {"t": repr(t)} | {label: repr(v) for label, v in zip(LABELS, wrenches[k].tolist(), strict=True)}
        bands = [""] * 6 if sd is None else [repr(2.0 * v) for v in sd[k].tolist()]
        rows.append(row | {f"{label}_band": b for label, b in zip(LABELS, bands, strict=True)})
    return rows


def _plot(log: FlightLog, wrenches: np.ndarray, sd: np.ndarray | None, path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(6, 1, figsize=(9, 11), sharex=True)
    for i, ax in enumerate(axes):
        if sd is not None:
            low, high = wrenches[:, i] - 2.0 * sd[:, i], wrenches[:, i] + 2.0 * sd[:, i]
            ax.fill_between(log.time, low, high, color="C0", alpha=0.25, lw=0, label="±2 sd")
        ax.plot(log.time, wrenches[:, i], "C0", lw=0.8, label="estimate")
        if log.wrench is not None:
            ax.plot(log.time, log.wrench[:, i], "k", lw=1.0, label="truth (log)")
        ax.set_ylabel(f"{LABELS[i]} [{UNITS[i]}]")
        ax.legend(fontsize=6, ncol=3, loc="upper left")
    axes[0].set_title(title)
    axes[-1].set_xlabel("time [s]")
    save_figure(fig, path, dpi=110)


def run(args: argparse.Namespace) -> int:
    with usage_errors():
        vehicle = make_vehicle(args.vehicle)
        log = read_flight_log(args.log, vehicle)
        settings = apply_overrides({}, args.param)
        estimator = make_estimator(args.estimator, vehicle, log.period, **settings)
        if isinstance(estimator, TruthFed) and log.wrench is None:
            raise ValueError(
                f"the {args.estimator} returns the true wrench: it needs the log's columns fx, fy, fz, tx, "
                "ty, tz"
            )
    wrenches, sd = replay(log, estimator, vehicle)
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    stem = out / f"{Path(args.log).stem}_{args.estimator.replace(':', '_')}"
    write_csv(stem.with_suffix(".csv"), _rows(log.time, wrenches, sd))
    title = f"{args.estimator} on {Path(args.log).name} ({args.vehicle}, {1.0 / log.period:.6g} Hz)"
    _plot(log, wrenches, sd, stem.with_suffix(".png"), title)
    summary = f"{title}: {len(log.time)} samples"
    if log.wrench is not None:
        error = wrenches - log.wrench
        summary += (
            f"; RMSE against the log's true wrench: force {np.sqrt(np.mean(error[:, :3] ** 2)):.4g} N, "
            f"torque {np.sqrt(np.mean(error[:, 3:] ** 2)):.4g} N·m"
        )
    print(summary)
    print(f"wrote {stem.with_suffix('.csv')}, {stem.with_suffix('.png')}")
    return 0

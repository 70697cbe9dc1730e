"""The estimator benchmark: every estimator on every vehicle over the same named flights, one table.

    quad-wrench compare estimators --only benchmark [--config configs/compare_estimators.yaml]

Each flight of the config's ``benchmark.flights`` (hover, manoeuvring flight, the fan, a step of the
external wrench, a jet crossing, gusts, pressing on a wall: any env id, reset options and agent) is
flown by ``runs`` vehicles of one vector env with the estimator in the loop (as
:mod:`quad_wrench_cli.consistency` flies them), for every estimator and vehicle preset of the config. A
user's estimator enters with one line, its ``"package.module:name"`` in ``benchmark.estimators``.

Per estimator, vehicle and flight, over the runs that went to the end and every policy step after
``settle`` seconds: the RMS error of the force and of the torque (estimate minus ``info["wrench_true"]``),
the bias (the norm of the mean error), and for an estimator with a covariance the NEES of each block
averaged over the runs and steps and the share of steps whose average over the runs lies in the 95 %
band of a consistent filter (as the ``nees`` part). The
``step`` flight adds a step of ``step.force`` times the weight along x and ``step.torque`` times the
weight times the arm about z at ``step.at`` seconds: the latency (from the step to 10 % of it) and the
10-90 % rise time of the mean estimate's x force and z torque. The cost is µs per estimator step on
that vehicle (best of ``cost.repeats``, as the ``cost`` part).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from quad_wrench_cli.consistency import FILTERS, Flown, filter_settings, flown, with_settings
from quad_wrench_env.bench import estimator_step_seconds
from quad_wrench_env.disturbances.wrench_profile import in_weights
from quad_wrench_env.estimators.consistency import average_nees_band, nees
from quad_wrench_env.vehicle import make_vehicle

STEP_FLIGHT = "step"
"""The flight whose external wrench steps at ``step.at``: its latency and rise time."""


def step_wrench(vehicle: str, step: Mapping[str, float], seconds: float) -> list[list[float]]:
    """The ``external_wrench`` segment of the step flight for ``vehicle``: from ``step.at`` to the end."""
    segment = [step["at"], seconds + 1.0, step["force"], 0.0, 0.0, 0.0, 0.0, step["torque"]]
    return in_weights([segment], make_vehicle(vehicle))


def response(time: np.ndarray, estimate: np.ndarray, start: float, size: float) -> tuple[float, float]:
    """Latency (from ``start`` to 10 % of ``size``) and 10-90 % rise time of a step response; NaN where
    the estimate never gets there."""
    after = time >= start

    def first(fraction: float) -> float:
        reached = np.flatnonzero(after & (estimate * np.sign(size) >= fraction * abs(size)))
        return float(time[reached[0]]) if reached.size else math.nan

    ten, ninety = first(0.1), first(0.9)
    return ten - start, ninety - ten


def _metrics(f: Flown) -> dict[str, float]:
    """RMS error, bias and (with a covariance) mean NEES of the force and the torque blocks."""
    kept = ~f.ended
    error = (f.estimate - f.truth)[:, kept]
    out: dict[str, float] = {"runs": int(kept.sum()), "ended": int(f.ended.sum())}
    for name, block in (("force", slice(0, 3)), ("torque", slice(3, 6))):
        e = error[..., block]
        out[f"rmse_{name}"] = float(np.sqrt(np.mean(np.sum(e * e, axis=-1)))) if e.size else math.nan
        out[f"bias_{name}"] = float(np.linalg.norm(e.reshape(-1, 3).mean(axis=0))) if e.size else math.nan
        if f.covariance is not None and e.size and np.any(f.covariance[:, kept][..., block, block] != 0):
            average = nees(e, f.covariance[:, kept][..., block, block]).mean(axis=1)  # over the runs
            low, high = average_nees_band(out["runs"], 3)
            out[f"nees_{name}"] = float(average.mean())
            out[f"in_band_{name}"] = float(np.mean((average >= low) & (average <= high)))
    return out


def _nees_cell(metrics: Mapping[str, float], name: str) -> str:
    if f"nees_{name}" not in metrics:
        return "-"
    return f"{metrics[f'nees_{name}']:.3g} ({100.0 * metrics[f'in_band_{name}']:.0f} %)"


def benchmark_table(config: Mapping[str, Any], out: Path) -> list[str]:
    """The ``benchmark`` part of ``quad-wrench compare estimators``: the table of every estimator,
    vehicle and flight, then the step responses and costs (``out`` gets nothing more)."""
    c = config["benchmark"]
    seeds = list(range(c["first_seed"], c["first_seed"] + c["runs"]))
    step = c["step"]
    rows, responses = [], []
    settings = filter_settings(c)
    jobs = [
        (e, v, label)
        for e in c["estimators"]
        for v in c["vehicles"]
        for label in (settings if e in FILTERS else "-")
    ]
    for estimator, vehicle, label in tqdm(jobs, desc="benchmark", unit="estimator", leave=False):
        for name, flight in c["flights"].items():
            if estimator in FILTERS:
                flight = with_settings(flight, settings[label])
            if name == STEP_FLIGHT:
                seconds = flight.get("env", {}).get("episode_seconds", 30.0)
                env = {**flight.get("env", {}), "external_wrench": step_wrench(vehicle, step, seconds)}
                flight = {**flight, "env": env}
            f = flown(config["env_id"], flight, name, vehicle, estimator, seeds, c["settle"])
            metrics = _metrics(f)
            rows.append(
                f"| {estimator} | {label} | {vehicle} | {name} | {metrics['runs']} ({metrics['ended']}) | "
                f"{metrics['rmse_force']:.3g} | {metrics['rmse_torque']:.3g} | {metrics['bias_force']:.3g} | "
                f"{metrics['bias_torque']:.3g} | {_nees_cell(metrics, 'force')} | "
                f"{_nees_cell(metrics, 'torque')} |"
            )
            if name == STEP_FLIGHT and metrics["runs"]:
                mean = f.estimate[:, ~f.ended].mean(axis=1)
                size = flight["env"]["external_wrench"][0]
                force = response(f.time, mean[:, 0], step["at"], size[2])
                torque = response(f.time, mean[:, 5], step["at"], size[7])
                cost = min(
                    estimator_step_seconds(
                        estimator, config["cost"]["steps"], vehicle=vehicle, **settings.get(label, {})
                    )
                    for _ in range(config["cost"]["repeats"])
                )
                responses.append(
                    f"| {estimator} | {label} | {vehicle} | {force[0]:.2f} | {force[1]:.2f} | "
                    f"{torque[0]:.2f} | {torque[1]:.2f} | {cost * 1e6:.1f} |"
                )
    first, last = seeds[0], seeds[-1]
    return [
        f"## Estimator benchmark: every estimator and vehicle over the same flights (seeds {first}-{last}, "
        f"after {c['settle']:g} s)",
        "",
        "| estimator | settings | vehicle | flight | runs (ended early) | RMSE force [N] | RMSE torque [N·m] "
        "| bias force [N] | bias torque [N·m] | NEES force (in band) | NEES torque (in band) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
        *rows,
        "",
        f"NEES: the mean over the runs and steps (d = 3 per block; a consistent filter's is 3) and the share "
        f"of steps whose average over the runs lies in the 95 % band of that average; '-' for an estimator "
        f"without a covariance (the observer) or with a zero one (the oracle). Latency and rise are read at "
        f"the policy steps (0.02 s apart). Step flight: a step of {step['force']:g} x the weight along x and "
        f"{step['torque']:g} x weight x arm about z at {step['at']:g} s.",
        "",
        "| estimator | settings | vehicle | latency f_x [s] | rise f_x [s] | latency tau_z [s] "
        "| rise tau_z [s] | µs per step |",
        "|---|---|---|---|---|---|---|---|",
        *responses,
    ]

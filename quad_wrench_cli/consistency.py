"""Are the filters' covariances honest? Their NEES on flights of the env, against the chi-square band.

    quad-wrench compare estimators --only nees [--config configs/compare_estimators.yaml]

Each flight of the config's ``nees.flights`` (hover, manoeuvring flight, the fan) is flown by ``runs``
vehicles of one vector env, vehicle ``i`` with seed ``first_seed + i`` (the episode of
``gym.make(...).reset(seed=first_seed + i)``), with the estimator in the loop as the env runs it, for
every vehicle preset and filter of the config. After every policy step past ``settle`` seconds, the
error ``info["wrench_est"] - info["wrench_true"]`` and its covariance ``info["wrench_cov"]`` give each
run's NEES of the force block and of the torque block (d = 3 each), which is averaged over the runs and
set against the 95 % band of a consistent filter (:mod:`quad_wrench_env.estimators.consistency`;
Bar-Shalom, Li & Kirubarajan 2001, Sec. 5.4.2). The last step of an episode is left out (its info
belongs to the next episode, which the vector env starts in the same step), and so is any run that
ended early (a crash), whose count the table gives.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from tqdm import tqdm

from quad_wrench_env.agents import make_agent
from quad_wrench_env.estimators.consistency import average_nees_band, nees

Policy = Callable[[int, np.ndarray], np.ndarray]
"""``(policy step, observations (M, width)) -> actions (M, 4)``."""
FILTERS = ("ukf", "ekf")
"""The estimators with a covariance to test (the observer carries none, the oracle's is zero)."""


def weave(amplitude: list[float], frequency: list[float], seeds: list[int], policy_hz: int) -> Policy:
    """Manoeuvring flight through the velocity action: ``a_j = A_j sin(2π f_j t + φ_ij)`` for the four
    components (x, y, z velocity and yaw rate, normalised), each run ``i`` with its phases ``φ_i``
    drawn from its seed. Open loop: a sine's integral is bounded, so the vehicle weaves about its
    start (``A_j / (π f_j)`` peak to peak, in units of the action's full scale times a second)."""
    amplitudes, frequencies = np.asarray(amplitude, dtype=float), np.asarray(frequency, dtype=float)
    if amplitudes.shape != (4,) or frequencies.shape != (4,):
        raise ValueError(
            f"nees weave: amplitude={amplitude!r} and frequency={frequency!r} must be 4 numbers each "
            "(x, y, z velocity and yaw rate)"
        )
    if not (np.all(np.abs(amplitudes) <= 1.0) and np.all(frequencies > 0.0)):
        raise ValueError(
            f"nees weave: amplitude={amplitude!r} must be within [-1, 1] (the action's range) and "
            f"frequency={frequency!r} above 0 Hz"
        )
    phases = np.array([np.random.default_rng(seed).uniform(0.0, 2.0 * math.pi, 4) for seed in seeds])

    def act(step: int, observations: np.ndarray) -> np.ndarray:
        return amplitudes * np.sin(2.0 * math.pi * frequencies * (step / policy_hz) + phases)

    return act


def agents(name: str, params: Mapping[str, Any], env: Any) -> Policy:
    """One agent ``name`` per vehicle of the vector ``env``, each acting on its own observation."""
    policies = [make_agent(name, **params) for _ in range(env.num_envs)]
    for policy in policies:
        policy.reset(env)

    def act(step: int, observations: np.ndarray) -> np.ndarray:
        return np.array([policy.act(o) for policy, o in zip(policies, observations, strict=True)])

    return act


def flight_policy(name: str, flight: Mapping[str, Any], env: Any, seeds: list[int]) -> Policy:
    """What flies flight ``name`` on the vector ``env``: its agent per vehicle, or its weave."""
    if ("agent" in flight) == ("weave" in flight):
        raise ValueError(f"flights.{name}: give either 'agent' or 'weave', got keys {sorted(flight)}")
    if "agent" in flight:
        return agents(flight["agent"], flight.get("agent_params", {}), env)
    spec = flight["weave"]
    if set(spec) != {"amplitude", "frequency"}:
        raise ValueError(
            f"flights.{name}.weave has keys {sorted(spec)}; allowed and needed: amplitude, frequency"
        )
    return weave(spec["amplitude"], spec["frequency"], seeds, env.cfg.policy_hz)


@dataclass
class Flown:
    """One flight of M runs, recorded at every policy step after the settling time (steps, M, ...):
    the time, the true and the estimated wrench and the covariance (None for an estimator that
    carries none), and which runs ended early."""

    time: np.ndarray
    truth: np.ndarray
    estimate: np.ndarray
    covariance: np.ndarray | None
    ended: np.ndarray


def flown(
    env_id: str,
    flight: Mapping[str, Any],
    name: str,
    vehicle: str,
    estimator: str,
    seeds: list[int],
    settle: float,
) -> Flown:
    """Fly ``flight`` (``agent`` or ``weave``; optional ``env_id``, ``env`` settings and reset ``options``)
    with M = len(``seeds``) vehicles of one vector env, the estimator in the loop, and record it."""
    env = gym.make_vec(
        flight.get("env_id", env_id),
        num_envs=len(seeds),
        vectorization_mode="vector_entry_point",
        vehicle=vehicle,
        estimator=estimator,
        **flight.get("env", {}),
    )
    try:
        base = env.unwrapped
        observations, _ = env.reset(seed=seeds, options=flight.get("options"))
        act = flight_policy(name, flight, base, seeds)
        settled = round(settle * base.cfg.policy_hz)
        ended = np.zeros(len(seeds), dtype=bool)
        times, truth, estimate, covariance = [], [], [], []
        for step in range(base.max_steps - 1):
            observations, _, terminated, _, info = env.step(act(step, observations))
            ended |= terminated
            if step + 1 >= settled:
                times.append(info["time"][0])
                truth.append(info["wrench_true"])
                estimate.append(info["wrench_est"])
                if "wrench_cov" in info:
                    covariance.append(info["wrench_cov"])
    finally:
        env.close()
    return Flown(
        np.array(times),
        np.array(truth),
        np.array(estimate),
        np.array(covariance) if covariance else None,
        ended,
    )


def with_settings(flight: Mapping[str, Any], settings: Mapping[str, Any]) -> dict[str, Any]:
    """``flight`` with the filter ``settings`` (``estimator_params`` keys) over those its env gives."""
    env = dict(flight.get("env", {}))
    env["estimator_params"] = {**env.get("estimator_params", {}), **settings}
    return {**flight, "env": env}


def filter_settings(c: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """A part's ``settings`` (label: the filters' ``estimator_params``, each flight flown with each),
    ``{"default": {}}`` where it gives none."""
    settings = c.get("settings", {"default": {}})
    if not (
        isinstance(settings, Mapping) and settings and all(isinstance(v, Mapping) for v in settings.values())
    ):
        raise ValueError(
            f"settings={settings!r} must map a label to the filters' estimator_params, e.g. "
            "{adaptive: {}, fixed: {adaptive_walks: false}}"
        )
    return dict(settings)


def fly(
    config: Mapping[str, Any],
    vehicle: str,
    estimator: str,
    name: str,
    settings: Mapping[str, Any] | None = None,
) -> tuple[np.ndarray, np.ndarray, int]:
    """The (steps, M) NEES of the force and of the torque of flight ``name`` (the filter with ``settings``)
    after the settling time, one column per run that went to the end, and the number of runs that ended
    early."""
    c = config["nees"]
    seeds = list(range(c["first_seed"], c["first_seed"] + c["runs"]))
    flight = with_settings(c["flights"][name], settings or {})
    f = flown(config["env_id"], flight, name, vehicle, estimator, seeds, c["settle"])
    error = f.estimate - f.truth
    force = nees(error[..., :3], f.covariance[..., :3, :3])
    torque = nees(error[..., 3:], f.covariance[..., 3:, 3:])
    return force[:, ~f.ended], torque[:, ~f.ended], int(f.ended.sum())


def _cells(values: np.ndarray, low: float, high: float) -> str:
    """Mean NEES over the steps (and the RMS error in sds it means), and the percentages of steps
    whose average over the runs is within and above the band."""
    average = values.mean(axis=1)
    mean = float(average.mean())
    inside = 100.0 * np.mean((average >= low) & (average <= high))
    above = 100.0 * np.mean(average > high)
    return f"{mean:.3g} ({math.sqrt(mean / 3.0):.2g} sd) | {inside:.0f} % | {above:.0f} %"


def nees_table(config: Mapping[str, Any], out: Path) -> list[str]:
    """The ``nees`` part of ``quad-wrench compare estimators``: one row per vehicle, flight and filter
    (``out``, where the other parts draw their figures, gets nothing more: the table is the result)."""
    c = config["nees"]
    refused = [name for name in c["estimators"] if name not in FILTERS]
    if refused:
        raise ValueError(f"nees.estimators: {refused} carry no covariance to test; allowed: {list(FILTERS)}")
    first, last = c["first_seed"], c["first_seed"] + c["runs"] - 1
    lines = [
        f"## Consistency: NEES of the force and of the torque (d = 3 each), averaged over the runs "
        f"(seeds {first}-{last}) at every policy step after {c['settle']:g} s",
        "",
        "| vehicle | flight | filter | settings | runs (ended early) | 95 % band of the average | force "
        "NEES (RMS error) | force in band | force above | torque NEES (RMS error) | torque in band | "
        "torque above |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    settings = filter_settings(c)
    jobs = [
        (v, f, e, s) for v in c["vehicles"] for f in c["flights"] for e in c["estimators"] for s in settings
    ]
    for vehicle, name, estimator, label in tqdm(jobs, desc="NEES", unit="flight", leave=False):
        force, torque, ended = fly(config, vehicle, estimator, name, settings[label])
        runs = force.shape[1]
        row = f"| {vehicle} | {name} | {estimator} | {label} | {runs} ({ended}) |"
        if runs == 0:
            lines.append(row + " - |" * 7)
            continue
        low, high = average_nees_band(runs, 3)
        cells = f"{_cells(force, low, high)} | {_cells(torque, low, high)}"
        lines.append(f"{row} {low:.2f}-{high:.2f} | {cells} |")
    lines += [
        "",
        "A consistent filter's NEES averages d = 3, and its average over the runs stays within the band "
        "at 95 % of the steps; above the band the filter is overconfident (its covariance too small for "
        'its errors). The RMS error in sds is sqrt(NEES / 3). The truth is `info["wrench_true"]`, which '
        "leaves out the rotors' thrust-coefficient errors (`kf_spread`) that the filters see as an "
        "external wrench.",
    ]
    return lines

"""Fit the learned wrench estimator: fly, record what the filters read, fit a network to the true wrench.

    quad-wrench fit-estimator configs/fit_estimator.yaml [--set training.epochs=5] [--run-dir runs/NAME]

For each vehicle preset of the config, every flight of its ``flights`` (an agent or an open-loop weave
on any env id, with reset options and env settings, as ``compare estimators``' benchmark flies them,
and optional steady ``pushes`` sized by the preset's weight, :data:`FLIGHT_KEYS`) is flown by ``runs``
vehicles of one vector env and again by ``held_out_runs`` on seeds after those; each vehicle's actions
get an Ornstein-Uhlenbeck perturbation of its own size (uniform up to ``action_noise`` of the action's
range) so that the controllers vary. At every physics step the env's estimator interface is recorded
(thrust, motor torque, measured pose, measured velocity and body rates with an onboard state estimator)
with the truth: the external wrench and the true velocity and body rates
(:mod:`quad_wrench_env.estimators.fitting` fits on them). A run that ends early is left out.

The run folder holds ``config.yaml``, and per vehicle ``<vehicle>.npz`` (the model, loadable with
``estimator_params={"model": PATH}``; its provenance: the config, the commit, the losses) and
``<vehicle>_curve.csv`` (the losses per epoch). A config with an unknown key or a bad value exits with
code 2 before anything is flown and leaves no folder.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import yaml
from tqdm import tqdm

from quad_wrench_cli.common import UsageError, add_key_value_argument, usage_errors, write_csv
from quad_wrench_cli.consistency import flight_policy
from quad_wrench_env.config import apply_overrides, build, check_counts, load_yaml
from quad_wrench_env.disturbances.wrench_profile import in_weights, validate_segments
from quad_wrench_env.estimators import OracleBank
from quad_wrench_env.estimators.bank import EstimatorInputs, TruthRecorder
from quad_wrench_env.estimators.learned import FittedFor, LearnedModel
from quad_wrench_env.estimators.learned_kernel import FRAME_STEPS, stream_frames, tracker_gains
from quad_wrench_env.rotations import rotation_matrices
from quad_wrench_env.vehicle import PRESETS

FLIGHT_KEYS = frozenset({"agent", "agent_params", "weave", "env_id", "env", "options", "pushes"})
"""What a flight may give: ``compare estimators``' flights, and ``pushes``, external wrench segments
``[start, end, f_x, f_y, f_z, τ_x, τ_y, τ_z]`` with the forces in weights and the torques in weight
times arm (the same push on every preset; world frame)."""


@dataclass
class FitConfig:
    """A ``fit-estimator`` config (``configs/fit_estimator.yaml``)."""

    vehicles: list[str]
    flights: dict[str, dict[str, Any]]
    env_id: str = "QuadWrench/FanTracking-v1"
    env: dict[str, Any] = field(default_factory=dict)
    """Env settings of every flight (under each flight's own), e.g. ``sensors``."""
    first_seed: int = 100_000
    runs: int = 16
    held_out_runs: int = 4
    action_noise: float = 0.1
    training: Any = None

    def __post_init__(self) -> None:
        from quad_wrench_env.estimators.fitting import TrainingSettings

        unknown = sorted(set(self.vehicles) - set(PRESETS))
        if not self.vehicles or unknown:
            raise ValueError(f"vehicles={self.vehicles!r}: unknown {unknown}; allowed: {sorted(PRESETS)}")
        if not self.flights:
            raise ValueError("flights: give at least one flight")
        for name, flight in self.flights.items():
            extra = sorted(set(flight) - FLIGHT_KEYS) if isinstance(flight, Mapping) else None
            if extra is None or extra or (("agent" in flight) == ("weave" in flight)):
                raise ValueError(
                    f"flights.{name}={flight!r}: unknown keys {extra}; allowed: {sorted(FLIGHT_KEYS)}, with "
                    "one of agent and weave"
                )
            if "pushes" in flight:
                try:
                    validate_segments(flight["pushes"])
                except ValueError as error:
                    raise ValueError(f"flights.{name}.pushes: {error}") from None
        check_counts(None, self, ("runs", "held_out_runs"))
        if not (math.isfinite(self.action_noise) and 0.0 <= self.action_noise <= 1.0):
            raise ValueError(f"action_noise={self.action_noise!r} must be in [0, 1] (the action's range)")
        self.training = build(TrainingSettings, self.training or {}, prefix="training.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("config", help="a fitting config (configs/fit_estimator.yaml)")
    add_key_value_argument(parser, "--set", "override a config key, dotted (repeatable): training.epochs=5")
    parser.add_argument(
        "--run-dir", metavar="DIR", help="the run folder (default: runs/<config name>-<time>)"
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


class StreamRecorder(TruthRecorder):
    """Records, at every physics step, the estimator interface's inputs and the truth for all N
    vehicles; :attr:`starts` holds each vehicle's pose at its last reset."""

    def __init__(self, inner: OracleBank) -> None:
        super().__init__(inner)
        self.starts = np.zeros((inner.count, 7))
        self.inputs: list[tuple[np.ndarray, ...]] = []
        self.truths: list[tuple[np.ndarray, np.ndarray]] = []

    def reset(self, index, position, quaternion_wxyz):
        super().reset(index, position, quaternion_wxyz)
        self.starts[index, :3], self.starts[index, 3:] = position, quaternion_wxyz

    def step(self, inputs: EstimatorInputs) -> None:
        present = inputs if inputs.velocities is not None else inputs[:4]
        self.inputs.append(tuple(a.copy() for a in present))
        self.truths.append(self.truth)


def targets_of(states: np.ndarray, wrenches: np.ndarray) -> np.ndarray:
    """(T, 12) targets of one run: the force, the external torque in the true body frame, the velocity
    and the body rates."""
    rotations = rotation_matrices(states[:, 6:10])
    body_torque = np.einsum("tji,tj->ti", rotations, wrenches[:, 3:])
    return np.concatenate((wrenches[:, :3], body_torque, states[:, 3:6], states[:, 10:13]), axis=1)


def record(
    config: FitConfig, name: str, flight: Mapping[str, Any], vehicle: str, seeds: list[int]
) -> tuple[list[tuple[np.ndarray, np.ndarray]], FittedFor]:
    """Fly ``flight`` with one vector env of len(``seeds``) vehicles: each run that went to the end as
    (its (T, frame width) frames, (T, 12) targets at each frame's last step), and what its features
    are for."""
    env_settings = {**config.env, **flight.get("env", {})}
    if "pushes" in flight:
        env_settings["external_wrench"] = in_weights(flight["pushes"], PRESETS[vehicle])
    env = gym.make_vec(
        flight.get("env_id", config.env_id),
        num_envs=len(seeds),
        vectorization_mode="vector_entry_point",
        vehicle=vehicle,
        estimator="oracle",
        **env_settings,
    )
    try:
        base = env.unwrapped
        recorder = StreamRecorder(base.fleet.estimator)
        base.fleet.estimator = recorder
        observations, _ = env.reset(seed=seeds, options=flight.get("options"))
        act = flight_policy(name, flight, base, seeds)
        rng = np.random.default_rng([seeds[0], len(seeds)])
        sizes = rng.uniform(0.0, config.action_noise, (len(seeds), 1))
        noise, decay = np.zeros((len(seeds), 4)), 0.9
        ended = np.zeros(len(seeds), dtype=bool)
        starts = recorder.starts.copy()
        for step in range(base.max_steps - 1):
            noise = decay * noise + math.sqrt(1.0 - decay**2) * sizes * rng.standard_normal(noise.shape)
            actions = np.clip(act(step, observations) + noise, -1.0, 1.0)
            observations, _, terminated, truncated, _ = env.step(actions)
            ended |= terminated | truncated
    finally:
        env.close()
    columns = [np.array(c) for c in zip(*recorder.inputs, strict=True)]
    states = np.array([s for s, _ in recorder.truths])
    wrenches = np.array([w for _, w in recorder.truths])
    dt, mass = base.fleet.dt, base.fleet.vehicle.mass
    gains = tracker_gains(dt)
    runs = []
    for i in np.flatnonzero(~ended):
        measured = [c[:, i] for c in columns[4:]] or [np.empty((0, 3))] * 2
        frames = stream_frames(*(c[:, i] for c in columns[:4]), *measured, starts[i], dt, mass, gains)
        targets = targets_of(states[:, i], wrenches[:, i])[FRAME_STEPS - 1 :: FRAME_STEPS]
        runs.append((frames, targets[: len(frames)]))
    return runs, FittedFor(vehicle, dt, len(columns) > 4)


def fit_vehicle(config: FitConfig, vehicle: str, folder: Path, progress: bool, source: dict[str, Any]) -> str:
    """Fly, fit and save ``<vehicle>.npz``; one line of what came out."""
    from quad_wrench_env.agents.sb3 import _commit
    from quad_wrench_env.estimators.fitting import Flights, fit

    started = time.perf_counter()
    training, held_out = Flights(), Flights()
    first_held = config.first_seed + config.runs
    parts = [(training, config.first_seed, config.runs), (held_out, first_held, config.held_out_runs)]
    fitted_for = set()
    jobs = tqdm(
        config.flights.items(), desc=f"{vehicle}: flying", unit="flight", disable=not progress, leave=False
    )
    for name, flight in jobs:
        for flights, first, count in parts:
            runs, made_for = record(config, name, flight, vehicle, list(range(first, first + count)))
            fitted_for.add(made_for)
            for features, targets in runs:
                flights.add(features, targets, name)
    if len(fitted_for) != 1:
        raise UsageError(
            f"the flights differ in time step or sensors ({sorted(map(str, fitted_for))}); "
            "one model needs one"
        )
    (made_for,) = fitted_for
    flown = time.perf_counter() - started
    bar = tqdm(
        total=config.training.epochs,
        desc=f"{vehicle}: fitting",
        unit="epoch",
        disable=not progress,
        leave=False,
    )

    def report(epoch: int, train_loss: float, held_loss: float) -> None:
        bar.set_postfix(train=f"{train_loss:.3f}", held_out=f"{held_loss:.3f}")
        bar.update()

    arrays, fitted = fit(training, held_out, config.training, FRAME_STEPS * made_for.dt, report)
    bar.close()
    provenance = {
        "config": source,
        "commit": _commit(),
        "kept_epoch": fitted["kept_epoch"],
        "held_out_loss": fitted["held_out_loss"],
        "held_out_nees_before_scaling": fitted["held_out_nees"],
        "training_steps": training.steps,
        "held_out_steps": held_out.steps,
        "seconds_flying": round(flown, 1),
        "seconds_fitting": round(time.perf_counter() - started - flown, 1),
    }
    LearnedModel(made_for, arrays, provenance).save(folder / f"{vehicle}.npz")
    write_csv(folder / f"{vehicle}_curve.csv", fitted["history"])
    return (
        f"{vehicle}: {training.steps} frames fitted, {held_out.steps} held out; "
        f"kept epoch {fitted['kept_epoch']} "
        f"(held-out loss {fitted['held_out_loss']:.4f}); {flown:.0f} s flying, "
        f"{provenance['seconds_fitting']:.0f} s fitting -> {folder / (vehicle + '.npz')}"
    )


def run(args: argparse.Namespace) -> int:
    source_path = Path(args.config)
    with usage_errors():
        source = apply_overrides(load_yaml(source_path), args.set)
        config = build(FitConfig, source)
    folder = Path(args.run_dir or f"runs/{source_path.stem}-{time.strftime('%Y%m%d-%H%M%S')}")
    if folder.exists() and any(folder.iterdir()):
        raise UsageError(f"--run-dir {folder} is not empty; allowed: a new or empty folder")
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "config.yaml").write_text(
        yaml.safe_dump({**source, "training": asdict(config.training)}, sort_keys=False)
    )
    for vehicle in config.vehicles:
        print(fit_vehicle(config, vehicle, folder, not args.no_progress, source), flush=True)
    return 0

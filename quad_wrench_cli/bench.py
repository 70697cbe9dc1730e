"""Speed benchmark: this project's env against PyBullet's own floor and against the peers, one run.

    quad-wrench bench [--steps 2000] [--repeats 3] [--soak-minutes 60]
                      [--peers [--gym-pybullet-drones PATH] [--peers-dir DIR]]
    quad-wrench bench --estimators [--steps 4000] [--repeats 5]
    quad-wrench bench --controllers [--steps 750] [--repeats 2]
    quad-wrench bench --training [--config configs/train_fan_tracking.yaml] [--steps N] [--repeats 5]


Tables printed (all measured in this run, best of ``--repeats`` for timings):
1. floors: one bare PyBullet step of one body with its state read and either four rotor forces
   applied (the issue's definition of the limit) or one resultant force and torque (what the envs
   apply), and the same per body in a 64-body world;
2. the single FanTracking env per estimator: µs per policy step and per physics step (4 per policy
   step), each floor as a share of ours, policy steps/s, simulated seconds per wall second with
   resets counted at the default episode length, and the mean reset time;
   then the UKF env timed with the floors in alternating blocks in one process (a share a drifting
   machine cannot move), and the same env with the fan, Dryden turbulence, a second jet and ground
   effect over a table all on, against the plain one measured alternately in the same run;
3. the vector env of 64 vehicles on one core: µs per vehicle and physics step, its ratio to the
   64-body floors per body, vehicle-seconds per wall second;
4. the cost of each part of a step (UKF env; the 64-vehicle vector env, per vehicle), timed in
   isolation;
5. peak memory of this process; with ``--soak-minutes`` the rates and resident memory of the first
   and last ten simulated minutes of one long run;
6. with ``--peers`` only, the peers, each in a virtual environment of its own under ``--peers-dir``
   (installed on first use, never in this project's dependencies; how much pip will download is said
   before anything else runs): PyFlyt's QuadX-Hover-v4, RotorPy's simulator and its batched torch env
   with 64 vehicles, and gym-pybullet-drones' HoverAviary when ``--gym-pybullet-drones`` names a
   checkout of its source (it is not on the package index). A peer that cannot be installed or run is
   reported as skipped, with the reason.

``--estimators`` times the wrench estimators instead (:mod:`quad_wrench_cli.bench_estimators`),
``--training`` the training path and a short learning run (:mod:`quad_wrench_cli.bench_training`),
``--controllers`` the classical controllers one vehicle at a time and batched
(:mod:`quad_wrench_cli.bench_controllers`).
"""

from __future__ import annotations

import argparse
import resource
import time
from pathlib import Path

import gymnasium as gym
from rich.console import Console

from quad_wrench_cli import bench_controllers, bench_estimators, bench_training
from quad_wrench_cli.common import UsageError, add_config_argument, load_config, markdown_table, show
from quad_wrench_cli.peers import download_summary, jobs, missing, peers
from quad_wrench_env.agents import make_agent
from quad_wrench_env.bench import (
    FLOORS,
    bare_pybullet_step_seconds,
    env_step_seconds,
    paired_floor_shares,
    paired_step_seconds,
    step_parts_seconds,
    vector_step_seconds,
)
from quad_wrench_env.config import config_path
from quad_wrench_env.estimators import ESTIMATORS

POLICY_HZ, SUBSTEPS, EPISODE_SECONDS, VECTOR_ENVS = 50, 4, 30.0, 64
STEPS, REPEATS = 2000, 3
"""Defaults of ``--steps`` and ``--repeats``."""


def resident_mib() -> float:
    """This process's resident memory now (MiB; Linux ``/proc``, else the peak so far)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
        return pages * resource.getpagesize() / 2**20
    except (OSError, IndexError, ValueError):
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def soak(minutes: float) -> str:
    """One long UKF run, position hold in the moving jet: rates and memory of the first and last ten
    simulated minutes."""
    env = gym.make("QuadWrench/FanTracking-v1", episode_seconds=minutes * 60.0, fan={"motion": "sine"})
    try:
        observation, _ = env.reset(seed=0, options={"offset_y": 0.0})
        policy = make_agent("hold")
        policy.reset(env)
        window = 10 * 60 * POLICY_HZ
        total = int(minutes * 60 * POLICY_HZ)
        marks = {}
        start = time.perf_counter()
        for k in range(1, total + 1):
            observation, _, terminated, _, info = env.step(policy.act(observation))
            if k == window or k == total - window:
                marks[k] = (time.perf_counter(), resident_mib())
            if terminated:
                return f"soak run ended early at {k / POLICY_HZ:.0f} s: {info.get('termination_reason')}"
        end = (time.perf_counter(), resident_mib())
        first = window / POLICY_HZ / (marks[window][0] - start)
        last = window / POLICY_HZ / (end[0] - marks[total - window][0])
        return (
            f"soak, {minutes:.0f} simulated minutes (UKF, seed 0): first 10 min {first:.1f} sim s/wall s, "
            f"last 10 min {last:.1f}; resident memory after 10 min {marks[window][1]:.1f} MiB, at the end "
            f"{end[1]:.1f} MiB; estimator status {info['estimator_status']}"
        )
    finally:
        env.close()


def env_rows(args: argparse.Namespace, floors: dict[str, float]) -> list[list[str]]:
    rows = []
    for estimator in ESTIMATORS:
        runs = [env_step_seconds(args.steps, estimator=estimator) for _ in range(args.repeats)]
        step, reset = min(r[0] for r in runs), min(r[1] for r in runs)
        physics = step / SUBSTEPS
        per_episode = EPISODE_SECONDS * POLICY_HZ * step + reset
        rows.append(
            [
                f"FanTracking-v1, {estimator}",
                f"{step * 1e6:.0f}",
                f"{physics * 1e6:.1f}",
                *(f"{floor / physics:.1%}" for floor in floors.values()),
                f"{1 / step:.0f}",
                f"{EPISODE_SECONDS / per_episode:.1f}",
                f"{reset * 1e3:.2f}",
            ]
        )
    return rows


ALL_DISTURBANCES = {
    "wind": [
        {"model": "dryden", "w20": 1.0, "altitude": 1.0, "mean": [0.5, 0.0, 0.0]},
        {"model": "jet", "position": [2.3, -2.5, 1.0], "direction": [0.0, 1.0, 0.0], "speed": 10.0},
    ],
    "ground_effect": True,
    "scene": [{"kind": "table", "center": [2.3, 0.0], "size": [1.0, 1.0], "height": 0.7}],
}
"""The fan (FanTracking's own), Dryden turbulence, Hentzen et al.'s (2019) second jet and ground effect over a
table, all on: the open engine's cost on the compiled path (limit: 1.3x the plain env)."""


def disturbance_rows(args: argparse.Namespace) -> list[list[str]]:
    """Plain FanTracking against it with every disturbance on, UKF, compiled, timed in alternating
    blocks in one process (``paired_step_seconds``)."""
    plain = {"estimator": "ukf"}
    base, heavy = (
        seconds / SUBSTEPS
        for seconds in paired_step_seconds(
            args.steps // 4, 8 * args.repeats, [plain, {**plain, **ALL_DISTURBANCES}]
        )
    )
    return [
        ["FanTracking-v1, ukf", f"{base * 1e6:.1f}", "1.00x"],
        ["+ Dryden, second jet, ground effect over a table", f"{heavy * 1e6:.1f}", f"{heavy / base:.2f}x"],
    ]


def vector_rows(args: argparse.Namespace, floors: dict[str, float]) -> list[list[str]]:
    rows = []
    for estimator in ("ukf", "oracle"):
        step = min(
            vector_step_seconds(args.steps // 8, VECTOR_ENVS, estimator=estimator)
            for _ in range(args.repeats)
        )
        per_vehicle = step / SUBSTEPS / VECTOR_ENVS
        rows.append(
            [
                f"FanTracking-v1 x {VECTOR_ENVS}, {estimator}",
                f"{per_vehicle * 1e6:.2f}",
                *(f"{per_vehicle / floor:.1f}x" for floor in floors.values()),
                f"{VECTOR_ENVS / POLICY_HZ / step:.0f}",
            ]
        )
    return rows


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--steps",
        type=_count,
        metavar="N",
        help=f"policy steps per timing (default: {STEPS}; with --estimators "
        f"{bench_estimators.STEPS} estimator steps, with --controllers {bench_controllers.STEPS})",
    )
    parser.add_argument(
        "--repeats",
        type=_count,
        metavar="N",
        help=f"timings per row, the best kept (default: {REPEATS}; with "
        f"--estimators {bench_estimators.REPEATS})",
    )
    parser.add_argument(
        "--soak-minutes",
        type=float,
        metavar="MINUTES",
        default=0.0,
        help="simulated minutes of one long run: 0 (none, the default) or at least 20 (two 10-min windows)",
    )
    parser.add_argument(
        "--estimators", action="store_true", help="time the wrench estimators instead (µs per estimator step)"
    )
    parser.add_argument(
        "--controllers",
        action="store_true",
        help="time the classical controllers instead (µs per vehicle-step, one at a time and batched)",
    )
    parser.add_argument(
        "--training",
        action="store_true",
        help="time the training path instead: its wrappers against the vector env and a short learning run",
    )
    add_config_argument(parser, "train_fan_tracking.yaml")
    parser.add_argument(
        "--peers",
        action="store_true",
        help="also time the peer simulators, installing them on first use (the download size is said first)",
    )
    parser.add_argument(
        "--gym-pybullet-drones",
        metavar="PATH",
        help="with --peers: time gym-pybullet-drones from this checkout",
    )
    parser.add_argument(
        "--peers-dir",
        default="~/.cache/quad-wrench-env/peers",
        metavar="DIR",
        help="the peers' virtual environments (default: %(default)s)",
    )


def _count(text: str) -> int:
    """argparse type: an integer >= 1."""
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"{text!r} must be an integer >= 1")
    return int(text)


def run(args: argparse.Namespace) -> int:
    if args.soak_minutes and not args.soak_minutes >= 20:
        raise UsageError(
            f"--soak-minutes {args.soak_minutes:g}: allowed 0 (no soak) or at least 20 (two 10-min windows)"
        )
    if args.gym_pybullet_drones and not args.peers:
        raise UsageError("--gym-pybullet-drones times a peer: add --peers")
    if args.gym_pybullet_drones and not Path(args.gym_pybullet_drones).is_dir():
        raise UsageError(f"--gym-pybullet-drones {args.gym_pybullet_drones!r} is not a folder")
    if args.config and not args.training:
        raise UsageError("--config names a training config: add --training")
    if args.training:
        load_config(args.config, "train_fan_tracking.yaml")  # a missing or invalid file: exit 2
        bench_training.report(
            args.config or config_path("train_fan_tracking.yaml"), args.steps, args.repeats or REPEATS
        )
        return 0
    if args.controllers:
        bench_controllers.report(
            args.steps or bench_controllers.STEPS, args.repeats or bench_controllers.REPEATS
        )
        return 0
    if args.estimators:
        bench_estimators.report(
            args.steps or bench_estimators.STEPS, args.repeats or bench_estimators.REPEATS
        )
        return 0
    args.steps, args.repeats = args.steps or STEPS, args.repeats or REPEATS
    if args.peers:
        with Console(stderr=True).status("working out the peers' download size with pip ..."):
            summary = download_summary(missing(jobs(args), Path(args.peers_dir).expanduser()))
        print(summary, flush=True)

    floors = {
        floor: min(bare_pybullet_step_seconds(4 * args.steps, floor=floor) for _ in range(args.repeats))
        for floor in FLOORS
    }
    floors64 = {
        floor: min(
            bare_pybullet_step_seconds(args.steps // 4, bodies=VECTOR_ENVS, floor=floor)
            for _ in range(args.repeats)
        )
        / VECTOR_ENVS
        for floor in FLOORS
    }
    show(
        markdown_table(
            [
                "floor: bare PyBullet step with state read and ...",
                "1 body, µs",
                f"{VECTOR_ENVS} bodies, µs per body",
            ],
            [[floor, f"{floors[floor] * 1e6:.2f}", f"{floors64[floor] * 1e6:.2f}"] for floor in FLOORS],
        )
        + "\n"
    )
    show(
        markdown_table(
            [
                "single env",
                "µs/policy step",
                "µs/physics step",
                *(f"floor ({floor}) / ours" for floor in FLOORS),
                "policy steps/s",
                "sim s per wall s, resets counted",
                "reset ms",
            ],
            env_rows(args, floors),
        )
        + "\n"
    )
    shares = paired_floor_shares(args.steps // 4, 4 * args.repeats, estimator="ukf")
    show(
        markdown_table(
            [
                "single env, timed with the floors in alternating blocks",
                "µs/physics step",
                *(f"floor ({floor}) / ours" for floor in FLOORS),
            ],
            [
                [
                    "FanTracking-v1, ukf",
                    f"{shares['physics step'] * 1e6:.1f}",
                    *(f"{shares[floor]:.1%}" for floor in FLOORS),
                ]
            ],
        )
        + "\n"
    )
    show(
        markdown_table(["every disturbance on", "µs/physics step", "vs plain"], disturbance_rows(args)) + "\n"
    )
    show(
        markdown_table(
            [
                "vector env (one core)",
                "µs per vehicle and physics step",
                *(f"ours / floor ({floor}), {VECTOR_ENVS}-body world" for floor in FLOORS),
                "vehicle-s per wall s",
            ],
            vector_rows(args, floors64),
        )
        + "\n"
    )
    part_tables = [  # a step steps all 64 vehicles: fewer steps than the single env's
        ("ukf env", "µs per policy step", min(args.steps, 500), 1),
        (
            f"ukf vector env x {VECTOR_ENVS}",
            "µs per vehicle and policy step",
            max(args.steps // 16, 20),
            VECTOR_ENVS,
        ),
    ]
    for title, unit, steps, num_envs in part_tables:
        parts = step_parts_seconds(steps, num_envs=num_envs, estimator="ukf")
        rows = [[name, f"{seconds * 1e6:.2f}"] for name, seconds in parts.items()]
        show(markdown_table([f"part of a step ({title})", unit], rows) + "\n")
    print(
        f"peak memory of this process: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB\n"
    )
    if args.soak_minutes > 0:
        print(soak(args.soak_minutes) + "\n")
    if args.peers:
        show(peers(args))
    return 0

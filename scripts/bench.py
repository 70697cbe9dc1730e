"""Speed benchmark: this project's env against PyBullet's own floor and against the peers, one run.

    python scripts/bench.py [--steps 2000] [--repeats 3] [--soak-minutes 60]
                            [--gym-pybullet-drones PATH] [--skip-peers] [--peers-dir DIR]

Tables printed (all measured in this run, best of ``--repeats`` for timings):
1. floors: one bare PyBullet step of one body with its state read and either four rotor forces
   applied (the issue's definition of the limit) or one resultant force and torque (what the envs
   apply), and the same per body in a 64-body world;
2. the single FanTracking env per estimator and backend (numba kernels, numpy reference): µs per
   policy step and per physics step (4 per policy step), each floor as a share of ours, policy
   steps/s, simulated seconds per wall second with resets counted at the default episode length,
   and the mean reset time;
   then the UKF env timed with the floors in alternating blocks in one process (a share a drifting
   machine cannot move), and the same env with the fan, Dryden turbulence, a second jet and ground
   effect over a table all on (compiled), against the plain one measured alternately in the same run;
3. the vector env of 64 vehicles on one core: µs per vehicle and physics step, its ratio to the
   64-body floors per body, vehicle-seconds per wall second;
4. the cost of each part of a step (UKF env, each backend; the 64-vehicle vector env on numba, per
   vehicle), timed in isolation;
5. peak memory of this process; with ``--soak-minutes`` the rates and resident memory of the first
   and last ten simulated minutes of one long run;
6. the peers, each in a virtual environment of its own under ``--peers-dir`` (created on first use,
   never in this project's dependencies): PyFlyt's QuadX-Hover-v4, RotorPy's simulator and its batched
   torch env with 64 vehicles, and gym-pybullet-drones' HoverAviary when ``--gym-pybullet-drones``
   names a checkout of its source (it is not on the package index). A peer that cannot be installed
   or run is reported as skipped, with the reason.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import gymnasium as gym

from agents import make_agent
from quad_wrench_env.bench import (
    FLOORS,
    bare_pybullet_step_seconds,
    component_seconds,
    env_step_seconds,
    paired_floor_shares,
    paired_step_seconds,
    vector_step_seconds,
)
from quad_wrench_env.estimators import ESTIMATORS
from quad_wrench_env.kernels import NUMBA_AVAILABLE

ROOT = Path(__file__).resolve().parents[1]
POLICY_HZ, SUBSTEPS, EPISODE_SECONDS, VECTOR_ENVS = 50, 4, 30.0, 64
BACKENDS = ("numba", "numpy") if NUMBA_AVAILABLE else ("numpy",)

PYFLYT = """
import json, time, gymnasium as gym, numpy as np, PyFlyt.gym_envs
env = gym.make("PyFlyt/QuadX-Hover-v4", agent_hz=40)
env.reset(seed=0); env.action_space.seed(0)
steps, resets, start = 4000, 0, time.perf_counter()
reset_time = 0.0
for _ in range(steps):
    *_, term, trunc, _ = env.step(env.action_space.sample() * 0.0)
    if term or trunc:
        t = time.perf_counter(); env.reset(); reset_time += time.perf_counter() - t; resets += 1
total = time.perf_counter() - start
print(json.dumps({"sim_rate": steps / 40 / total, "sim_rate_no_resets": steps / 40 / (total - reset_time),
                  "resets": resets, "reset_ms": 1e3 * reset_time / max(resets, 1)}))
"""

GYM_PYBULLET_DRONES = """
import json, time, numpy as np
from gym_pybullet_drones.envs.HoverAviary import HoverAviary
env = HoverAviary()
env.reset(seed=0)
hz = env.CTRL_FREQ
steps, resets, start = 2000, 0, time.perf_counter()
reset_time = 0.0
action = np.zeros(env.action_space.shape, dtype=np.float32)
for _ in range(steps):
    *_, term, trunc, _ = env.step(action)
    if term or trunc:
        t = time.perf_counter(); env.reset(); reset_time += time.perf_counter() - t; resets += 1
total = time.perf_counter() - start
print(json.dumps({"sim_rate": steps / hz / total, "sim_rate_no_resets": steps / hz / (total - reset_time),
                  "resets": resets, "reset_ms": 1e3 * reset_time / max(resets, 1)}))
"""

ROTORPY_CORE = """
import json, time, numpy as np
from rotorpy.vehicles.multirotor import Multirotor
from rotorpy.vehicles.crazyflie_params import quad_params
vehicle = Multirotor(quad_params)
state = dict(vehicle.initial_state)
hover = np.sqrt(quad_params["mass"] * 9.81 / (4 * quad_params["k_eta"]))
control = {"cmd_motor_speeds": np.full(4, hover)}
dt, steps, start = 0.01, 1000, time.perf_counter()
for _ in range(steps):
    state = vehicle.step(state, control, dt)
total = time.perf_counter() - start
print(json.dumps({"sim_rate": steps * dt / total, "sim_rate_no_resets": steps * dt / total}))
"""

ROTORPY_BATCHED = """
import json, time, numpy as np, torch
from rotorpy.learning.quadrotor_environments import QuadrotorEnv
from rotorpy.vehicles.crazyflie_params import quad_params
torch.set_num_threads(1)
n = 64
hover = np.sqrt(quad_params["mass"] * 9.81 / (4 * quad_params["k_eta"]))
init = {"x": torch.zeros(n, 3).double(), "v": torch.zeros(n, 3).double(),
        "q": torch.tensor([0, 0, 0, 1]).repeat(n, 1).double(), "w": torch.zeros(n, 3).double(),
        "wind": torch.zeros(n, 3).double(), "rotor_speeds": torch.full((n, 4), hover).double()}
env = QuadrotorEnv(num_envs=n, initial_states=init, control_mode="cmd_motor_speeds")
env.reset()
steps, start = 500, time.perf_counter()
action = np.zeros((n, 4), dtype=np.float32)
for _ in range(steps):
    env.step(action)
total = time.perf_counter() - start
rate = n * steps * env.t_step / total
print(json.dumps({"sim_rate": rate, "sim_rate_no_resets": rate, "vehicles": n}))
"""

PEERS = {
    "PyFlyt QuadX-Hover-v4 (240 Hz physics, 40 Hz agent)": (["PyFlyt"], PYFLYT, "pyflyt"),
    "RotorPy Multirotor.step (100 Hz)": (["rotorpy"], ROTORPY_CORE, "rotorpy"),
    "RotorPy batched QuadrotorEnv, 64 vehicles (vehicle-s/wall s)": (
        ["rotorpy[batched]", "stable-baselines3"],
        ROTORPY_BATCHED,
        "rotorpy",
    ),
}


def table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return "\n".join(lines + ["| " + " | ".join(row) + " |" for row in rows])


def peer_python(peers_dir: Path, name: str, requirements: list[str]) -> Path:
    """The python of the peer's own virtual environment, created and filled on first use."""
    venv = peers_dir / name
    python = venv / "bin" / "python"
    stamp = venv / ("installed-" + "-".join(sorted(r.replace("/", "_") for r in requirements)))
    if not stamp.exists():
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
        subprocess.run(
            [
                str(python),
                "-m",
                "pip",
                "install",
                "--quiet",
                "-c",
                str(ROOT / "constraints.txt"),
                *requirements,
            ],
            check=True,
            capture_output=True,
            text=True,
        )
        stamp.touch()
    return python


def run_peer(python: Path, snippet: str, extra_path: str | None = None) -> dict:
    env = None
    if extra_path:
        import os

        env = {**os.environ, "PYTHONPATH": extra_path}
    done = subprocess.run([str(python), "-c", snippet], capture_output=True, text=True, timeout=900, env=env)
    if done.returncode != 0:
        raise RuntimeError(done.stderr.strip().splitlines()[-1] if done.stderr.strip() else "failed")
    return json.loads(done.stdout.strip().splitlines()[-1])


def peers(args: argparse.Namespace) -> str:
    peers_dir = Path(args.peers_dir).expanduser()
    peers_dir.mkdir(parents=True, exist_ok=True)
    rows = []
    jobs = dict(PEERS)
    if args.gym_pybullet_drones:
        requirements = [
            "numpy",
            "scipy",
            "transforms3d",
            "matplotlib",
            "pybullet",
            "gymnasium",
            "setuptools<81",
        ]
        jobs["gym-pybullet-drones HoverAviary (240 Hz physics, 30 Hz agent)"] = (
            requirements,
            GYM_PYBULLET_DRONES,
            "gym-pybullet-drones",
        )
    else:
        rows.append(
            [
                "gym-pybullet-drones HoverAviary",
                "skipped: pass --gym-pybullet-drones PATH (not on PyPI)",
                "",
                "",
            ]
        )
    for label, (requirements, snippet, venv_name) in jobs.items():
        try:
            python = peer_python(peers_dir, venv_name, requirements)
            extra = (
                str(Path(args.gym_pybullet_drones).resolve()) if venv_name == "gym-pybullet-drones" else None
            )
            result = run_peer(python, snippet, extra)
            reset = f"{result['reset_ms']:.1f}" if "reset_ms" in result else "n/a"
            rows.append([label, f"{result['sim_rate']:.1f}", f"{result['sim_rate_no_resets']:.1f}", reset])
        except (subprocess.SubprocessError, RuntimeError, OSError, ValueError) as error:
            message = getattr(error, "stderr", None) or str(error)
            rows.append([label, f"skipped: {str(message).strip().splitlines()[-1][:120]}", "", ""])
    return table(["peer", "sim s per wall s, resets counted", "without resets", "reset ms"], rows)


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
    for backend in BACKENDS:
        for estimator in ESTIMATORS:
            runs = [
                env_step_seconds(args.steps, estimator=estimator, backend=backend)
                for _ in range(args.repeats)
            ]
            step, reset = min(r[0] for r in runs), min(r[1] for r in runs)
            physics = step / SUBSTEPS
            per_episode = EPISODE_SECONDS * POLICY_HZ * step + reset
            rows.append(
                [
                    f"FanTracking-v1, {estimator}, {backend}",
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
"""The fan (FanTracking's own), Dryden turbulence, paper 003's second jet and ground effect over a
table, all on: the open engine's cost on the compiled path (limit: 1.3x the plain env)."""


def disturbance_rows(args: argparse.Namespace) -> list[list[str]]:
    """Plain FanTracking against it with every disturbance on, UKF, compiled, timed in alternating
    blocks in one process (``paired_step_seconds``)."""
    plain = {"estimator": "ukf", "backend": "numba"}
    base, heavy = (
        seconds / SUBSTEPS
        for seconds in paired_step_seconds(
            args.steps // 4, 8 * args.repeats, [plain, {**plain, **ALL_DISTURBANCES}]
        )
    )
    return [
        ["FanTracking-v1, ukf, numba", f"{base * 1e6:.1f}", "1.00x"],
        ["+ Dryden, second jet, ground effect over a table", f"{heavy * 1e6:.1f}", f"{heavy / base:.2f}x"],
    ]


def vector_rows(args: argparse.Namespace, floors: dict[str, float]) -> list[list[str]]:
    rows = []
    for estimator, backend in (("ukf", "numba"), ("oracle", "numba"), ("ukf", "numpy")):
        step = min(
            vector_step_seconds(args.steps // 8, VECTOR_ENVS, estimator=estimator, backend=backend)
            for _ in range(args.repeats)
        )
        per_vehicle = step / SUBSTEPS / VECTOR_ENVS
        rows.append(
            [
                f"FanTracking-v1 x {VECTOR_ENVS}, {estimator}, {backend}",
                f"{per_vehicle * 1e6:.2f}",
                *(f"{per_vehicle / floor:.1f}x" for floor in floors.values()),
                f"{VECTOR_ENVS / POLICY_HZ / step:.0f}",
            ]
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--soak-minutes", type=float, default=0.0, help="0 (no soak) or at least 20: two 10-minute windows"
    )
    parser.add_argument("--gym-pybullet-drones", metavar="PATH")
    parser.add_argument("--skip-peers", action="store_true")
    parser.add_argument("--peers-dir", default="~/.cache/quad-wrench-env/peers")
    args = parser.parse_args()
    if args.soak_minutes and not args.soak_minutes >= 20:
        parser.error(
            f"--soak-minutes {args.soak_minutes:g}: allowed 0 (no soak) or at least 20 (two 10-min windows)"
        )

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
    print(
        table(
            [
                "floor: bare PyBullet step with state read and ...",
                "1 body, µs",
                f"{VECTOR_ENVS} bodies, µs per body",
            ],
            [[floor, f"{floors[floor] * 1e6:.2f}", f"{floors64[floor] * 1e6:.2f}"] for floor in FLOORS],
        )
        + "\n"
    )
    print(
        table(
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
    if NUMBA_AVAILABLE:
        shares = paired_floor_shares(args.steps // 4, 4 * args.repeats, estimator="ukf", backend="numba")
        print(
            table(
                ["single env, timed with the floors in alternating blocks", "µs/physics step",
                 *(f"floor ({floor}) / ours" for floor in FLOORS)],
                [["FanTracking-v1, ukf, numba", f"{shares['physics step'] * 1e6:.1f}",
                  *(f"{shares[floor]:.1%}" for floor in FLOORS)]],
            )
            + "\n"
        )  # fmt: skip
        print(
            table(
                ["disturbances on the compiled path", "µs/physics step", "vs plain"], disturbance_rows(args)
            )
            + "\n"
        )
    print(
        table(
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
    part_tables = [(f"ukf env, {backend}", "µs", args.steps, 1, backend) for backend in BACKENDS]
    if NUMBA_AVAILABLE:  # a call steps all 64 vehicles: fewer calls than the single env's
        part_tables.append(
            (
                f"ukf vector env x {VECTOR_ENVS}, numba",
                "µs per vehicle",
                max(args.steps // 8, 20),
                VECTOR_ENVS,
                "numba",
            )
        )
    for title, unit, calls, num_envs, backend in part_tables:
        parts = component_seconds(calls, num_envs=num_envs, backend=backend)
        rows = [[name, f"{seconds * 1e6:.2f}"] for name, seconds in parts.items()]
        print(table([f"part of a step ({title})", unit], rows) + "\n")
    print(
        f"peak memory of this process: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB\n"
    )
    if args.soak_minutes > 0:
        print(soak(args.soak_minutes) + "\n")
    if not args.skip_peers:
        print(peers(args))


if __name__ == "__main__":
    main()

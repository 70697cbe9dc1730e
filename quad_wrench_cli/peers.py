"""The peer simulators of ``quad-wrench bench --peers``: each runs in a virtual environment of its own
under ``--peers-dir``, never in this project's dependencies, installed on first use; before anything is
installed :func:`download_summary` says how much pip will fetch.

PyFlyt's QuadX-Hover-v4, RotorPy's simulator and its batched torch env with 64 vehicles, and
gym-pybullet-drones' HoverAviary when ``--gym-pybullet-drones`` names a checkout of its source (it is
not on the package index). A peer that cannot be installed or run is reported as skipped, with the
reason.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import urllib.request
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from urllib.parse import unquote, urlparse

from rich.console import Console

from quad_wrench_cli.common import markdown_table

CONSTRAINTS = Path(__file__).resolve().parents[1] / "constraints.txt"
"""The project's pins (a source checkout's; an install without it pins nothing)."""

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
GYM_PYBULLET_DRONES_REQUIREMENTS = [
    "numpy",
    "scipy",
    "transforms3d",
    "matplotlib",
    "pybullet",
    "gymnasium",
    "setuptools<81",
]
Job = tuple[list[str], str, str]
"""A peer's requirements, its timing snippet and the name of its virtual environment."""


def jobs(args: argparse.Namespace) -> dict[str, Job]:
    """The peers to time, by label: :data:`PEERS` and gym-pybullet-drones when given its checkout."""
    chosen = dict(PEERS)
    if args.gym_pybullet_drones:
        chosen["gym-pybullet-drones HoverAviary (240 Hz physics, 30 Hz agent)"] = (
            GYM_PYBULLET_DRONES_REQUIREMENTS,
            GYM_PYBULLET_DRONES,
            "gym-pybullet-drones",
        )
    return chosen


def _constraints() -> list[str]:
    return ["-c", str(CONSTRAINTS)] if CONSTRAINTS.is_file() else []


def _stamp(peers_dir: Path, name: str, requirements: list[str]) -> Path:
    """The file that marks ``requirements`` installed in the peer's environment ``name``."""
    return peers_dir / name / ("installed-" + "-".join(sorted(r.replace("/", "_") for r in requirements)))


def peer_python(peers_dir: Path, name: str, requirements: list[str]) -> Path:
    """The python of the peer's own virtual environment, created and filled on first use."""
    venv = peers_dir / name
    python = venv / "bin" / "python"
    stamp = _stamp(peers_dir, name, requirements)
    if not stamp.exists():
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
        subprocess.run(
            [str(python), "-m", "pip", "install", "--quiet", *_constraints(), *requirements],
            check=True,
            capture_output=True,
            text=True,
        )
        stamp.touch()
    return python


def missing(chosen: dict[str, Job], peers_dir: Path) -> dict[str, list[str]]:
    """Per peer environment, the requirements of ``chosen`` not installed there yet."""
    needed: dict[str, list[str]] = {}
    for requirements, _, name in chosen.values():
        if not _stamp(peers_dir, name, requirements).exists():
            needed.setdefault(name, [])
            needed[name] += [r for r in requirements if r not in needed[name]]
    return needed


def _size(url: str) -> int | None:
    """Bytes of the file at ``url`` (a ``file:`` URL's from the disk, else from a HEAD request)."""
    try:
        if urlparse(url).scheme == "file":
            return os.path.getsize(unquote(urlparse(url).path))
        with urllib.request.urlopen(urllib.request.Request(url, method="HEAD"), timeout=30) as response:
            length = response.headers.get("Content-Length")
            return int(length) if length is not None else None
    except (OSError, ValueError):
        return None


def download_summary(needed: dict[str, list[str]]) -> str:
    """What installing ``needed`` (:func:`missing`) fetches: pip's resolution of each environment's
    requirements as a fresh install (``pip install --dry-run --report``), each file's size from the
    index (a HEAD request) or the disk; what pip's cache already holds is not fetched again."""
    if not needed:
        return "The peers are installed already: nothing to download."
    urls: list[str] = []
    for requirements in needed.values():
        with tempfile.TemporaryDirectory() as folder:
            report = Path(folder) / "report.json"
            command = [sys.executable, "-m", "pip", "install", "--dry-run", "--ignore-installed", "--quiet"]
            command += ["--report", str(report), *_constraints(), *requirements]
            done = subprocess.run(command, capture_output=True, text=True, timeout=900)
            if done.returncode != 0:
                reason = (done.stderr.strip().splitlines() or ["pip failed"])[-1]
                return f"Could not work out the peers' download size ({reason}); installing them anyway."
            urls += [item["download_info"]["url"] for item in json.loads(report.read_text())["install"]]
    with ThreadPoolExecutor(8) as pool:
        sizes = dict(zip(urls, pool.map(_size, urls), strict=True))
    remote = [size for url, size in sizes.items() if urlparse(url).scheme != "file"]
    local = [size for url, size in sizes.items() if urlparse(url).scheme == "file"]
    mib = sum(s for s in remote if s is not None) / 2**20
    text = (
        f"Installing the peers ({', '.join(needed)}) into their own environments downloads about "
        f"{mib:.0f} MiB ({len(remote)} files"
    )
    unknown = sum(s is None for s in remote)
    text += f", {unknown} of unknown size)" if unknown else ")"
    if local:
        text += (
            f" and copies {sum(s or 0 for s in local) / 2**20:.0f} MiB of local wheels ({len(local)} files)"
        )
    return text + "; files already in pip's cache are not downloaded again."


def run_peer(python: Path, snippet: str, extra_path: str | None = None) -> dict:
    env = None
    if extra_path:
        env = {**os.environ, "PYTHONPATH": extra_path}
    done = subprocess.run([str(python), "-c", snippet], capture_output=True, text=True, timeout=900, env=env)
    if done.returncode != 0:
        raise RuntimeError(done.stderr.strip().splitlines()[-1] if done.stderr.strip() else "failed")
    return json.loads(done.stdout.strip().splitlines()[-1])


def peers(args: argparse.Namespace) -> str:
    peers_dir = Path(args.peers_dir).expanduser()
    peers_dir.mkdir(parents=True, exist_ok=True)
    rows = []
    if not args.gym_pybullet_drones:
        rows.append(
            [
                "gym-pybullet-drones HoverAviary",
                "skipped: pass --gym-pybullet-drones PATH (not on PyPI)",
                "",
                "",
            ]
        )
    console = Console(stderr=True)
    for label, (requirements, snippet, venv_name) in jobs(args).items():
        try:
            with console.status(f"{label}: installing on first use, then timing ..."):
                python = peer_python(peers_dir, venv_name, requirements)
                gym_pybullet_drones = venv_name == "gym-pybullet-drones"
                extra = str(Path(args.gym_pybullet_drones).resolve()) if gym_pybullet_drones else None
                result = run_peer(python, snippet, extra)
            reset = f"{result['reset_ms']:.1f}" if "reset_ms" in result else "n/a"
            rows.append([label, f"{result['sim_rate']:.1f}", f"{result['sim_rate_no_resets']:.1f}", reset])
        except (subprocess.SubprocessError, RuntimeError, OSError, ValueError) as error:
            message = getattr(error, "stderr", None) or str(error)
            rows.append([label, f"skipped: {str(message).strip().splitlines()[-1][:120]}", "", ""])
    return markdown_table(["peer", "sim s per wall s, resets counted", "without resets", "reset ms"], rows)

"""Same numbers: does a change keep every trajectory, observation, reward and metric bit for bit?

    python scripts/same_numbers.py BASE [REVISION]     # compare two commits (REVISION: the work tree)
    python scripts/same_numbers.py --dump FILE.json     # what one checkout gives (run by the above)

For a refactoring that must not move a number: each revision is checked out into a temporary folder
(the work tree as it is when REVISION is omitted) and, with that folder first on the path, flies the
same cases one after the other on this machine, in one run; each case's bytes (float64 and float32
arrays, rewards, flags, the harness's metrics) are hashed, and the two revisions' hashes are compared
case by case. Exit code 1 and the differing cases when any differ.

The cases, through public names only (so that both revisions run them): every registered task x
vehicle preset x estimator, a single env and a 3-vehicle vector env (seeded random actions, autoreset,
60 control steps each); every action type on each task; each task with every configurable
disturbance at once, and with motion-capture latency; the classical agents and the shipped learned
policies through the harness (one held-out seed). Not part of CI: it takes minutes.

The UKF and the EKF fly with fixed walks (``estimator_params: {adaptive_walks: false}``) and every
vehicle with the nominal mixer (``rotor_calibration: null``) where the checkout has those defaults
(covariance-matched walks, a calibrated ``crazyflie2``), so that such a revision is held to the numbers
of one without; the shipped policies fly with the estimator they were trained with and carry its
settings.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STEPS = 60
SEED = 7
EVERYTHING = {  # every configurable disturbance at once, acting within the 60 steps
    "wind": [
        {"model": "dryden", "w20": 2.0, "altitude": 1.0, "mean": [0.5, 0.0, 0.0]},
        {"model": "one_cosine", "peak": [0.0, 2.0, 0.0], "start": 0.2, "duration": 0.5},
        {"model": "jet", "position": [3.0, -2.0, 1.0], "direction": [0.0, 1.0, 0.0], "speed": 6.0},
    ],
    "ground_effect": True,
    "scene": [{"kind": "table", "center": [2.3, 0.0], "size": [1.0, 1.0], "height": 0.6}],
    "payload": {"mass": 0.05, "point": [0.1, 0.1, 0.0], "attach_time": 0.1, "release_time": 0.8},
    "external_wrench": [[0.3, 0.9, 0.2, 0.0, -0.1, 0.0, 0.01, 0.0]],
}
AGENTS = {  # the classical agents, each on its task and action type
    "QuadWrench/FanTracking-v1": [("hold", {}, "velocity"), ("admittance", {}, "velocity")],
    "QuadWrench/DisturbanceRejection-v0": [
        ("pid", {"compensation": True}, "attitude"),
        ("mpc", {"compensation": True}, "attitude"),
    ],
    "QuadWrench/ForceExertion-v0": [("ida_pbc", {}, "wrench")],
}


def _digest(*parts: object) -> str:
    import numpy as np

    h = hashlib.sha256()
    for part in parts:
        if isinstance(part, dict):
            for key in sorted(part):
                h.update(key.encode())
                h.update(_digest(part[key]).encode())
        elif isinstance(part, (list, tuple)):
            for item in part:
                h.update(_digest(item).encode())
        elif isinstance(part, np.ndarray) and part.dtype != object:
            h.update(str(part.dtype).encode() + np.ascontiguousarray(part).tobytes())
        else:
            h.update(repr(part).encode())
    return h.hexdigest()[:16]


def _fixed_walks(env_id: str, kwargs: dict) -> dict:
    """``kwargs`` with the UKF's or the EKF's walks fixed and the nominal mixer where the checkout has
    those settings (module docstring)."""
    import dataclasses

    import gymnasium as gym

    from quad_wrench_env.envs.base import EnvConfig  # there in every revision
    from quad_wrench_env.estimators import FilterNoise

    if EnvConfig.rotor_calibration == "preset":
        kwargs = {**kwargs, "rotor_calibration": None}
    if "adaptive_walks" not in {f.name for f in dataclasses.fields(FilterNoise)}:
        return kwargs
    estimator = kwargs.get("estimator")
    if estimator is None:
        env = gym.make(env_id, disable_env_checker=True)
        estimator = env.unwrapped.cfg.estimator
        env.close()
    return (
        {**kwargs, "estimator_params": {"adaptive_walks": False}} if estimator in ("ukf", "ekf") else kwargs
    )


def _fly_single(env_id: str, **kwargs: object) -> str:
    import gymnasium as gym
    import numpy as np

    env = gym.make(env_id, disable_env_checker=True, **_fixed_walks(env_id, kwargs))
    rng = np.random.default_rng(SEED)
    seed = SEED
    obs, info = env.reset(seed=seed)
    parts = [obs, info["wrench_true"], info["wrench_est"], info["position"]]
    for _ in range(STEPS):
        obs, reward, terminated, truncated, info = env.step(rng.uniform(-1.0, 1.0, 4).astype(np.float32))
        parts += [obs, reward, terminated, truncated, info["wrench_true"], info["wrench_est"]]
        parts += [info["position"], info["velocity"], info["reward_terms"]]
        if terminated or truncated:
            seed += 1
            obs, info = env.reset(seed=seed)
            parts.append(obs)
    env.close()
    return _digest(parts)


def _fly_vector(env_id: str, **kwargs: object) -> str:
    import gymnasium as gym
    import numpy as np

    env = gym.make_vec(
        env_id, num_envs=3, vectorization_mode="vector_entry_point", **_fixed_walks(env_id, kwargs)
    )
    rng = np.random.default_rng(SEED)
    obs, info = env.reset(seed=SEED)
    parts = [obs, info["wrench_true"]]
    for _ in range(STEPS):
        obs, reward, terminated, truncated, info = env.step(rng.uniform(-1, 1, (3, 4)).astype(np.float32))
        parts += [obs, reward, terminated, truncated, info["wrench_true"], info["wrench_est"]]
    env.close()
    return _digest(parts)


def dump(path: Path) -> None:
    """Fly every case with the package on the path and write ``{case: hash}`` to ``path``."""

    import yaml

    import quad_wrench_env  # noqa: F401 (registers the envs)
    from quad_wrench_env.agents import SHIPPED, make_agent, shipped_agents
    from quad_wrench_env.agents.evaluate import evaluate
    from quad_wrench_env.estimators import ESTIMATORS
    from quad_wrench_env.vehicle import PRESETS

    def scored(evaluation: object) -> str:
        return _digest(evaluation.per_seed, [e.trace for e in evaluation.episodes])

    hashes: dict[str, str] = {}
    for env_id, agents in AGENTS.items():
        for vehicle in sorted(PRESETS):
            for estimator in ESTIMATORS:
                case = f"{env_id} {vehicle} {estimator}"
                hashes[f"single {case}"] = _fly_single(env_id, vehicle=vehicle, estimator=estimator)
                hashes[f"vector {case}"] = _fly_vector(env_id, vehicle=vehicle, estimator=estimator)
        for action_type in ("velocity", "attitude", "wrench", "motors"):
            hashes[f"single {env_id} action {action_type}"] = _fly_single(env_id, action_type=action_type)
        hashes[f"single {env_id} every disturbance"] = _fly_single(env_id, **EVERYTHING)
        hashes[f"vector {env_id} every disturbance"] = _fly_vector(env_id, **EVERYTHING)
        hashes[f"single {env_id} latency 2"] = _fly_single(env_id, sensors={"latency_steps": 2})
        for name, params, action_type in agents:
            fixed = _fixed_walks(env_id, {})
            result = evaluate(make_agent(name, **params), env_id, [2000], action_type=action_type, **fixed)
            hashes[f"agent {env_id} {name}"] = scored(result)
        print(env_id, "done", flush=True)
    for name in shipped_agents():
        env_id = yaml.safe_load((SHIPPED / name / "config.yaml").read_text())["env_id"]
        estimator = yaml.safe_load((SHIPPED / name / "config.yaml").read_text())["env"]["estimator"]
        hashes[f"policy {name}"] = scored(evaluate(make_agent(name), env_id, [2000], estimator=estimator))
    path.write_text(json.dumps(hashes, indent=1))


def checkout(revision: str | None, folder: Path) -> Path:
    """The package of ``revision`` (the work tree when None) in ``folder``."""
    if revision is None:
        return ROOT
    subprocess.run(
        ["git", "-C", str(ROOT), "worktree", "add", "--detach", "-f", str(folder), revision],
        check=True,
        capture_output=True,
    )
    return folder


def compare(base: str, revision: str | None) -> int:
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for label, rev in (("base", base), ("revision", revision)):
            tree = checkout(rev, Path(tmp) / label)
            out = Path(tmp) / f"{label}.json"
            env = {**os.environ, "PYTHONPATH": str(tree)}
            script = ROOT / "scripts" / "same_numbers.py"
            subprocess.run([sys.executable, str(script), "--dump", str(out)], cwd=tree, env=env, check=True)
            results[label] = json.loads(out.read_text())
            if rev is not None:
                subprocess.run(
                    ["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)], check=True
                )
    base_hashes, new_hashes = results["base"], results["revision"]
    cases = sorted(set(base_hashes) | set(new_hashes))
    differing = [c for c in cases if base_hashes.get(c) != new_hashes.get(c)]
    for case in differing:
        print(f"DIFFERS {case}: {base_hashes.get(case)} -> {new_hashes.get(case)}")
    same = len(cases) - len(differing)
    print(f"{same} of {len(cases)} cases the same bit for bit ({base} against {revision or 'the work tree'})")
    return 1 if differing else 0


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("base", nargs="?", help="the commit to compare against")
    parser.add_argument("revision", nargs="?", help="the commit to compare (default: the work tree)")
    parser.add_argument("--dump", type=Path, help="fly the cases with this checkout and write their hashes")
    args = parser.parse_args()
    if args.dump:
        dump(args.dump)
        return 0
    if not args.base:
        parser.error("give BASE (a commit) or --dump FILE")
    return compare(args.base, args.revision)


if __name__ == "__main__":
    sys.exit(main())

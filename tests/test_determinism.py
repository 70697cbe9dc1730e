"""Vehicle i of a vector env gives the same bits as the single env seeded alike, on every host.

The README promises that vehicle ``i`` of ``gym.make_vec(id, num_envs=N, ...)`` reset with ``seed``
behaves exactly as ``gym.make(id).reset(seed=seed + i)``. These tests fly one vehicle (one seed, one
sequence of actions) alone and at the last index of vector envs of 1, 2, 3, 8, 9 and 64 vehicles,
whose other vehicles fly other seeds and random actions (and crash and restart), and compare every
float64 number the env reports (the true position, velocity and wrench, the estimate) and the
observation for equality. What makes this hold on any CPU: all vehicles fly at PyBullet's origin
(no frame shift rounds their positions), the compiled kernels loop vehicle by vehicle or run the
same IEEE operations on SIMD lanes, never sums regrouped by the vector width (the UKF's covariance
sum runs in order on one filter and on the lanes alike), and the numpy code at resets multiplies rows
by :func:`~quad_wrench_env.rotations.rows_times` instead of BLAS, whose kernels group sums by the
number of rows. Bits across machines are not promised (libm, the compile target).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import quad_wrench_env  # noqa: F401  (registers the ids)

REPORTED = ("position", "velocity", "wrench_true", "wrench_est")
"""The info keys compared (float64), beside the observation (float32)."""

SIZES = ((1, 0), (2, 1), (3, 2), (8, 7), (9, 8), (64, 63))
"""(vehicles, index of the one compared): a bank of one, filter by filter, SIMD lanes, a full block
of eight, a block and one more, and many blocks."""

SEED, STEPS = 100, 50
"""The compared vehicle's seed and its policy steps (1 s)."""

TASKS = {
    "QuadWrench/FanTracking-v1": {"action_scale": 1.0},
    "QuadWrench/DisturbanceRejection-v0": {"action_scale": 0.5},
    "QuadWrench/ForceExertion-v0": {"action_scale": 0.3},
}
"""Each task with the size of its compared vehicle's random actions (small enough that it flies a
second before its task ends it: pressing the wall, not crashing into it)."""


def _record(obs: np.ndarray, info: dict, index: int | None = None) -> np.ndarray:
    rows = [np.ravel(info[key] if index is None else info[key][index]) for key in REPORTED]
    return np.concatenate([np.asarray(obs, dtype=np.float64).ravel(), *rows])


def fly_alone(env_id: str, actions: np.ndarray, **settings) -> np.ndarray:
    """The compared vehicle's records, (steps + 1, k), up to the step that ends its episode."""
    env = gym.make(env_id, **settings)
    try:
        obs, info = env.reset(seed=SEED)
        records = [_record(obs, info)]
        for action in actions:
            obs, _, terminated, truncated, info = env.step(action)
            records.append(_record(obs, info))
            if terminated or truncated:
                break
        return np.array(records)
    finally:
        env.close()


def fly_among(
    env_id: str, actions: np.ndarray, count: int, index: int, restart_every: int = 0, **settings
) -> np.ndarray:
    """The same vehicle's records at ``index`` of a vector env of ``count``: reset with ``SEED -
    index`` so that it gets ``SEED``; the others fly random actions in [-1, 1] and, with
    ``restart_every``, are restarted every that many steps (as autoresets restart crashed ones)."""
    venv = gym.make_vec(env_id, num_envs=count, vectorization_mode="vector_entry_point", **settings)
    others = np.random.default_rng(count)
    rest = [i for i in range(count) if i != index]
    try:
        obs, info = venv.reset(seed=SEED - index)
        records = [_record(obs[index], info, index)]
        for step, action in enumerate(actions, start=1):
            if restart_every and step % restart_every == 0:
                venv.unwrapped.reset_vehicles(rest, [None] * len(rest), [None] * len(rest))
            batch = others.uniform(-1.0, 1.0, (count, actions.shape[1]))
            batch[index] = action
            obs, _, terminated, truncated, info = venv.step(batch)
            if terminated[index] or truncated[index]:  # the returned obs is already the next episode's
                records.append(_record(info["final_obs"][index], info["final_info"], index))
                break
            records.append(_record(obs[index], info, index))
        return np.array(records)
    finally:
        venv.close()


def compare_at_every_size(
    env_id: str, sizes=SIZES, steps: int = STEPS, restart_every: int = 0, **settings
) -> list[int]:
    """Asserts the same bits at every (size, index); returns how many steps each flight compared."""
    scale = TASKS[env_id]["action_scale"]
    actions = np.random.default_rng(SEED).uniform(-scale, scale, (steps, 4))
    alone = fly_alone(env_id, actions, **settings)
    compared = []
    for count, index in sizes:
        among = fly_among(env_id, actions, count, index, restart_every, **settings)
        assert among.shape == alone.shape, f"{count} vehicles: {len(among) - 1} steps, alone {len(alone) - 1}"
        mismatch = np.flatnonzero((among != alone).any(axis=1))
        assert mismatch.size == 0, (
            f"{env_id}, vehicle {index} of {count}: first differs at step {mismatch[0]}, by up to "
            f"{np.abs(among - alone).max():.3g}"
        )
        compared.append(len(among) - 1)
    return compared


@pytest.mark.parametrize("env_id", list(TASKS))
def test_a_vehicle_gives_the_same_bits_at_any_index_of_a_vector_env_of_any_size(env_id):
    """Each task with its default estimator on the compiled path (the UKF of FanTracking runs filter
    by filter in banks of 1-2 and on SIMD lanes from 3). Catches frames that shift positions (they
    differed by 1e-14 m from the first step) and sums regrouped by the vector width (1e-13 N)."""
    compared = compare_at_every_size(env_id)
    assert min(compared) >= 25, f"too short a flight to compare: {compared} steps"


@pytest.mark.parametrize("env_id", list(TASKS))
def test_other_vehicles_restarting_leave_a_vehicle_its_bits(env_id):
    """Autoresets restart crashed vehicles while the others fly on: a restart reads the restarted
    vehicles' states from PyBullet and must leave the others' (the compiled step's) bits alone.
    Re-reading every vehicle changed the others in the last bit, so a training run on vehicles in
    two processes differed from the same run in one (0.40 vs 0.11 m after 500 k steps)."""
    compare_at_every_size(env_id, sizes=((2, 1), (9, 8)), restart_every=7)


@pytest.mark.parametrize("estimator", ["ekf", "observer", "oracle"])
def test_every_estimator_gives_the_same_bits_in_a_fleet(estimator):
    compare_at_every_size("QuadWrench/FanTracking-v1", sizes=((3, 2), (9, 8)), estimator=estimator)


def test_the_same_bits_hold_when_the_kernels_are_compiled_for_another_cpu(tmp_path):
    """The compiled path for numba's ``generic`` x86-64 target (SSE2, no AVX) in a fresh cache: the
    SIMD lanes become scalar code, and vehicle 8 of 9 must still give the single env's bits."""
    here = Path(__file__).parent
    script = (
        f"import sys, json; sys.path.insert(0, {str(here)!r}); import test_determinism as t; "
        "print(json.dumps(t.compare_at_every_size('QuadWrench/FanTracking-v1', sizes=((1, 0), (9, 8)), "
        "steps=30)))"
    )
    environment = {
        **os.environ,
        "NUMBA_CPU_NAME": "generic",
        "NUMBA_CACHE_DIR": str(tmp_path / "numba"),
        "QUAD_WRENCH_CACHE_DIR": str(tmp_path / "steps"),
    }
    result = subprocess.run(
        [sys.executable, "-c", script], env=environment, capture_output=True, text=True, timeout=600
    )
    assert result.returncode == 0, result.stderr[-3000:]
    assert json.loads(result.stdout.strip().splitlines()[-1]) == [30, 30]

"""``info["wrench_cov"]``: the estimator's covariance of ``info["wrench_est"]``, in the same (world) frame,
on the single and the vector env; absent for the observer (it carries none), zeros for the oracle."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from quad_wrench_env.kernels import NUMBA_AVAILABLE
from tests.conftest import FAN_TRACKING

BLOCKS = {"force": np.s_[:3, :3], "torque": np.s_[3:, 3:], "force-torque": np.s_[:3, 3:]}


def _yaw_matrix(angle: float) -> np.ndarray:
    """The rotation about world z by ``angle``, written out (not the package's rotations)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array(((c, -s, 0.0), (s, c, 0.0), (0.0, 0.0, 1.0)))


def _fly_yawed(estimator: str, backend: str, yaw: float) -> dict:
    """A short flight with no air and noise-free motion capture, started ``yaw`` beyond FanTracking's
    start heading and commanded a world velocity and yaw rate turned by ``yaw`` too: without a fan the
    world is the same in every horizontal direction, so the flight is the yaw-0 flight turned about
    the start point. Returns the last step's info."""
    env = gym.make(
        FAN_TRACKING, estimator=estimator, backend=backend, fan={"enabled": False},
        sensors={"position_noise": 0.0, "attitude_noise": 0.0},
    )  # fmt: skip
    task = env.unwrapped.task
    start = task.reset_vehicle

    def turned_start(index, rng, options):
        position, heading = start(index, rng, options)
        return position, heading + yaw

    task.reset_vehicle = turned_start
    try:
        env.reset(seed=0, options={"offset_y": 0.0})
        velocity = _yaw_matrix(yaw) @ np.array((0.6, 0.3, 0.0))
        action = np.array((*velocity, 0.2), dtype=np.float32)
        for _ in range(60):
            _, _, terminated, _, info = env.step(action)
            assert not terminated
        return info
    finally:
        env.close()


@pytest.mark.parametrize("backend", ["numpy", pytest.param("numba", marks=pytest.mark.skipif(
    not NUMBA_AVAILABLE, reason="numba is not installed"))])  # fmt: skip
@pytest.mark.parametrize("estimator", ["ukf", "ekf"])
def test_the_wrench_covariance_is_symmetric_positive_and_turns_with_the_vehicle(estimator, backend):
    """The filters' ``info["wrench_cov"]`` is a symmetric (to rounding) positive semi-definite 6x6
    matrix in the world frame: a flight turned by a known yaw α gives ``Rz(α) C Rz(α)ᵀ`` block by block
    (force, torque and the cross blocks), to rounding, where C is the unturned flight's; each block of
    C differs from its turned form by far more than that (the check could fail)."""
    alpha = 0.7
    straight, turned = (_fly_yawed(estimator, backend, yaw) for yaw in (0.0, alpha))
    rotate = np.kron(np.eye(2), _yaw_matrix(alpha))  # diag(Rz, Rz) on [f, τ]
    np.testing.assert_allclose(turned["wrench_est"], rotate @ straight["wrench_est"], atol=1e-7)
    expected = rotate @ straight["wrench_cov"] @ rotate.T
    for info in (straight, turned):
        covariance = info["wrench_cov"]
        assert covariance.shape == (6, 6)
        np.testing.assert_allclose(covariance, covariance.T, rtol=0, atol=1e-13 * np.abs(covariance).max())
        assert np.linalg.eigvalsh(covariance).min() > 0.0
    for name, block in BLOCKS.items():
        scale = np.abs(straight["wrench_cov"][block]).max()
        error = np.abs(turned["wrench_cov"][block] - expected[block]).max()
        unturned = np.abs(turned["wrench_cov"][block] - straight["wrench_cov"][block]).max()
        assert error < 1e-7 * scale < 1e-2 * unturned, name


def test_the_observer_reports_none_and_the_oracle_zeros_on_both_envs():
    """No covariance is invented: the observer's bank reports NaN and its env's ``info`` has no
    ``wrench_cov`` (a NaN would fail Gymnasium's determinism check), the oracle's (the truth) is
    zero; the vector env gives every vehicle's with a leading vehicle axis and its mask, and a
    filter's equals the single env's of the same seed."""
    env = gym.make(FAN_TRACKING, estimator="observer")
    try:
        _, info = env.reset(seed=0)
        assert "wrench_cov" not in info and np.isnan(env.unwrapped.fleet.estimator.wrench_covariances()).all()
        _, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
        assert "wrench_cov" not in info
    finally:
        env.close()
    env = gym.make(FAN_TRACKING, estimator="oracle")
    try:
        _, info = env.reset(seed=0)
        assert (info["wrench_cov"] == 0.0).all()
        _, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
        assert info["wrench_cov"].shape == (6, 6) and (info["wrench_cov"] == 0.0).all()
    finally:
        env.close()
    vector = gym.make_vec(FAN_TRACKING, num_envs=2, vectorization_mode="vector_entry_point", estimator="ekf")
    singles = [gym.make(FAN_TRACKING, estimator="ekf") for _ in range(2)]
    try:
        vector.reset(seed=5)
        for i, single in enumerate(singles):
            single.reset(seed=5 + i)
        for _ in range(3):
            _, _, _, _, info = vector.step(np.zeros((2, 4), dtype=np.float32))
            assert info["wrench_cov"].shape == (2, 6, 6) and info["_wrench_cov"].all()
            for i, single in enumerate(singles):
                _, _, _, _, single_info = single.step(np.zeros(4, dtype=np.float32))
                np.testing.assert_allclose(
                    info["wrench_cov"][i], single_info["wrench_cov"], rtol=1e-9, atol=1e-15
                )
    finally:
        vector.close()
        for single in singles:
            single.close()

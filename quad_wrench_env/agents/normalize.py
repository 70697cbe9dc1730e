"""stable-baselines3's ``VecNormalize`` with its per-step work in one compiled call.

``VecNormalize.step_wait`` spends a noticeable share of the vector env's own step in some twenty small
numpy calls (the running statistics of the observations and of the discounted returns, the scaling, a
deep copy of the observations; docs/architecture.md, "Measurements behind the hot paths").
:class:`CompiledVecNormalize` does the same arithmetic in the same order in one numba call per
step, so it gives the same bits (``tests/test_normalize.py`` checks it against ``VecNormalize``
itself), and it saves as ``VecNormalize`` does (same attributes); its ``load`` takes a
``vecnormalize.pkl`` saved by either.

The orders reproduced are numpy's (2.x): a float32 mean or variance along axis 0 of an (N, D) array
adds the rows one after another in float32; a float64 sum of a 1-D array is numpy's pairwise sum
(eight running sums over blocks of up to 128 values, halves above). ``RunningMeanStd`` merges the
batch moments by Chan et al.'s parallel formula in float64, as SB3 writes it.
"""

from __future__ import annotations

import numpy as np
from stable_baselines3.common.vec_env import VecNormalize
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvStepReturn

from quad_wrench_env.numerics import njit


@njit
def _pairwise_sum(a: np.ndarray) -> float:
    """numpy's float64 ``add.reduce`` of a 1-D array, in its order."""
    n = a.shape[0]
    if n < 8:
        total = 0.0
        for i in range(n):
            total += a[i]
        return total
    if n <= 128:
        r = a[:8].copy()
        i = 8
        while i < n - n % 8:
            for j in range(8):
                r[j] += a[i + j]
            i += 8
        total = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
        while i < n:
            total += a[i]
            i += 1
        return total
    half = n // 2
    half -= half % 8
    return _pairwise_sum(a[:half]) + _pairwise_sum(a[half:])


@njit
def _merge(mean: np.ndarray, var: np.ndarray, count: float, batch_mean, batch_sum_sq, n: int) -> float:
    """``RunningMeanStd.update_from_moments`` in place (float64, SB3's order) with the batch's mean
    and ``batch_var * n`` (in the batch's precision: float32 for observations, as numpy multiplies
    a float32 array by an int); returns the new count."""
    total = count + n
    for j in range(mean.shape[0]):
        delta = np.float64(batch_mean[j]) - mean[j]
        m_2 = var[j] * count + np.float64(batch_sum_sq[j]) + delta * delta * count * n / total
        mean[j] = mean[j] + delta * n / total
        var[j] = m_2 / (count + n)
    return n + count


@njit
def _observations_step(
    obs: np.ndarray,
    mean: np.ndarray,
    var: np.ndarray,
    count: float,
    update: bool,
    epsilon: float,
    clip: float,
    out: np.ndarray,
) -> float:
    """The observation statistics updated with the (N, D) float32 batch ``obs`` (if ``update``) and
    the batch scaled into ``out``; returns the new count."""
    n, d = obs.shape
    if update:
        total = obs[0].copy()
        for i in range(1, n):
            total += obs[i]
        batch_mean = total / np.float32(n)
        squares = np.zeros(d, np.float32)  # 0 + x is x: the same bits as numpy's first row
        for i in range(n):
            for j in range(d):
                deviation = obs[i, j] - batch_mean[j]
                squares[j] += deviation * deviation
        batch_var = squares / np.float32(n)
        count = _merge(mean, var, count, batch_mean, batch_var * np.float32(n), n)
    scale = np.sqrt(var + epsilon)
    for i in range(n):
        for j in range(d):
            out[i, j] = min(max((np.float64(obs[i, j]) - mean[j]) / scale[j], -clip), clip)
    return count


@njit
def _rewards_step(
    rewards: np.ndarray,
    returns: np.ndarray,
    gamma: float,
    mean: np.ndarray,
    var: np.ndarray,
    count: float,
    update: bool,
    scale_rewards: bool,
    epsilon: float,
    clip: float,
    out: np.ndarray,
) -> float:
    """The discounted returns and their statistics updated (if ``update``) and the rewards scaled
    into ``out`` (float32; unscaled without ``scale_rewards``); returns the new count."""
    n = rewards.shape[0]
    if update:
        for i in range(n):
            returns[i] = returns[i] * gamma + np.float64(rewards[i])
        batch_mean = _pairwise_sum(returns) / n
        squares = np.empty(n)
        for i in range(n):
            squares[i] = (returns[i] - batch_mean) * (returns[i] - batch_mean)
        batch_var = _pairwise_sum(squares) / n
        count = _merge(mean, var, count, np.array([batch_mean]), np.array([batch_var * n]), n)
    if scale_rewards:
        scale = np.sqrt(var[0] + epsilon)
        for i in range(n):
            out[i] = min(max(np.float64(rewards[i]) / scale, -clip), clip)
    else:
        for i in range(n):
            out[i] = rewards[i]
    return count


class CompiledVecNormalize(VecNormalize):
    """``VecNormalize`` (same arguments, attributes, saving and numbers) whose step is one compiled
    call; it takes (N, D) float32 array observations (every env of this package gives them)."""

    @classmethod
    def load(cls, load_path: str, venv: VecEnv) -> CompiledVecNormalize:
        """The statistics saved by a ``VecNormalize`` or a ``CompiledVecNormalize`` at ``load_path``,
        on ``venv``."""
        saved = VecNormalize.load(load_path, venv)
        env = cls.__new__(cls)
        env.__setstate__(saved.__getstate__())
        env.set_venv(venv)
        return env

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, dones, infos = self.venv.step_wait()
        if not (isinstance(obs, np.ndarray) and obs.dtype == np.float32 and obs.ndim == 2):
            raise TypeError(
                f"CompiledVecNormalize takes (N, D) float32 array observations, got {type(obs).__name__} "
                f"{getattr(obs, 'dtype', '')} {getattr(obs, 'shape', '')}; use VecNormalize for others"
            )
        self.old_obs, self.old_reward = obs, rewards
        scaled_obs = obs.copy()
        if self.norm_obs:
            rms = self.obs_rms
            rms.count = _observations_step(
                obs, rms.mean, rms.var, rms.count, self.training, self.epsilon, self.clip_obs, scaled_obs
            )
        scaled_rewards = np.empty(rewards.shape, np.float32)
        rms = self.ret_rms
        mean, var = rms.mean.reshape(1), rms.var.reshape(1)
        rms.count = _rewards_step(
            np.asarray(rewards),
            self.returns,
            self.gamma,
            mean,
            var,
            rms.count,
            self.training,
            self.norm_reward,
            self.epsilon,
            self.clip_reward,
            scaled_rewards,
        )
        for i in np.flatnonzero(dones).tolist():
            if "terminal_observation" in infos[i]:
                infos[i]["terminal_observation"] = self.normalize_obs(infos[i]["terminal_observation"])
        self.returns[dones] = 0
        return scaled_obs, scaled_rewards, dones, infos

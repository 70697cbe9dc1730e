"""CompiledVecNormalize gives stable-baselines3's VecNormalize's bits: observations, rewards, running
statistics and returns, through episode ends, in training and in evaluation mode, and loads its
saved statistics."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from quad_wrench_env.agents.normalize import CompiledVecNormalize


class _Recorded(VecEnv):
    """A VecEnv that replays random float32 observations, rewards and episode ends."""

    def __init__(self, num_envs: int, width: int, seed: int) -> None:
        space = spaces.Box(-np.inf, np.inf, (width,), np.float32)
        super().__init__(num_envs, space, spaces.Box(-1, 1, (4,), np.float32))
        self.rng = np.random.default_rng(seed)
        self.scales = 10.0 ** self.rng.uniform(-3, 3, width)

    def _obs(self) -> np.ndarray:
        offset = self.rng.normal(size=self.observation_space.shape) * self.scales
        return (
            self.rng.normal(size=(self.num_envs, *self.observation_space.shape)) * self.scales + offset
        ).astype(np.float32)

    def reset(self) -> np.ndarray:
        return self._obs()

    def step_async(self, actions: np.ndarray) -> None:
        pass

    def step_wait(self):
        dones = self.rng.uniform(size=self.num_envs) < 0.05
        infos = [{"terminal_observation": self._obs()[0]} if d else {} for d in dones]
        rewards = (self.rng.normal(size=self.num_envs) * 30.0).astype(np.float32)
        return self._obs(), rewards, dones, infos

    def close(self) -> None: ...
    def get_attr(self, attr_name, indices=None):
        return [None] * self.num_envs

    def set_attr(self, attr_name, value, indices=None): ...
    def env_method(self, method_name, *args, indices=None, **kwargs): ...
    def env_is_wrapped(self, wrapper_class, indices=None):
        return [False] * self.num_envs


@pytest.mark.parametrize("num_envs", [1, 5, 8, 32, 200])
@pytest.mark.parametrize(("norm_obs", "norm_reward"), [(True, True), (True, False), (False, True)])
def test_the_same_bits_as_vec_normalize(num_envs: int, norm_obs: bool, norm_reward: bool) -> None:
    kwargs = {
        "norm_obs": norm_obs,
        "norm_reward": norm_reward,
        "clip_obs": 5.0,
        "clip_reward": 8.0,
        "gamma": 0.97,
    }
    theirs = VecNormalize(_Recorded(num_envs, 23, seed=num_envs), **kwargs)
    ours = CompiledVecNormalize(_Recorded(num_envs, 23, seed=num_envs), **kwargs)
    np.testing.assert_array_equal(theirs.reset(), ours.reset())
    for step in range(120):
        if step == 80:  # evaluation mode: the statistics stay
            theirs.training = ours.training = False
        a, b = theirs.step(np.zeros((num_envs, 4))), ours.step(np.zeros((num_envs, 4)))
        for x, y in zip(a[:3], b[:3], strict=True):
            assert x.dtype == y.dtype
            np.testing.assert_array_equal(x, y, err_msg=f"step {step}")
        for x, y in zip(a[3], b[3], strict=True):
            if "terminal_observation" in x:
                np.testing.assert_array_equal(x["terminal_observation"], y["terminal_observation"])
        for name in ("obs_rms", "ret_rms") if norm_obs else ("ret_rms",):
            p, q = getattr(theirs, name), getattr(ours, name)
            np.testing.assert_array_equal(p.mean, q.mean)
            np.testing.assert_array_equal(p.var, q.var)
            assert p.count == q.count
        np.testing.assert_array_equal(theirs.returns, ours.returns)


def test_saved_statistics_load_from_either(tmp_path) -> None:
    ours = CompiledVecNormalize(_Recorded(4, 6, seed=1))
    ours.reset()
    for _ in range(10):
        ours.step(np.zeros((4, 4)))
    ours.save(str(tmp_path / "ours.pkl"))
    plain = VecNormalize.load(str(tmp_path / "ours.pkl"), _Recorded(4, 6, seed=1))
    plain.save(str(tmp_path / "plain.pkl"))
    for saved in ("ours.pkl", "plain.pkl"):
        loaded = CompiledVecNormalize.load(str(tmp_path / saved), _Recorded(4, 6, seed=1))
        assert type(loaded) is CompiledVecNormalize and loaded.venv is not None
        for name in ("obs_rms", "ret_rms"):
            np.testing.assert_array_equal(getattr(loaded, name).mean, getattr(ours, name).mean)
            np.testing.assert_array_equal(getattr(loaded, name).var, getattr(ours, name).var)
            assert getattr(loaded, name).count == getattr(ours, name).count


def test_other_observations_are_refused_by_name() -> None:
    class Float64(_Recorded):
        def _obs(self) -> np.ndarray:
            return super()._obs().astype(np.float64)

    env = CompiledVecNormalize(Float64(2, 3, seed=0))
    env.reset()
    with pytest.raises(TypeError, match="float32 array observations, got ndarray float64"):
        env.step(np.zeros((2, 4)))

"""The observation's ``privileged`` block (the truth) and the asymmetric actor-critic that reads it in its
critic only (issue 48, item 1c)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch

from quad_wrench_env.agents.privileged import PrivilegedCriticPolicy
from quad_wrench_env.agents.sb3 import TrainConfig, train
from quad_wrench_env.agents.sb3_policy import load_policy
from quad_wrench_env.config import build
from tests.conftest import FAN_TRACKING
from tests.test_sb3 import HYPERPARAMETERS, SMALL


def _rotation(q: np.ndarray) -> np.ndarray:
    """The rotation matrix of a unit quaternion (w, x, y, z), written out."""
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


@pytest.mark.parametrize("count", [1, 3])
def test_the_privileged_block_is_the_truth(count):
    """After every step the block holds the true position, velocity, attitude (body x and y axes in the
    world), body rates, force and torque (``info``'s and the fleet's true state), while the engine's
    blocks stay the estimator's (the UKF's, not the truth) and the observation is unchanged before it."""
    settings = {"estimator": "ukf", "sensor_history": 2}
    if count == 1:
        env, plain = gym.make(FAN_TRACKING, privileged=True, **settings), gym.make(FAN_TRACKING, **settings)
    else:
        vector = {"num_envs": count, "vectorization_mode": "vector_entry_point", **settings}
        env, plain = (
            gym.make_vec(FAN_TRACKING, privileged=True, **vector),
            gym.make_vec(FAN_TRACKING, **vector),
        )
    layout = env.unwrapped.obs_layout
    block = layout["privileged"]
    assert (block.start, block.stop) == (plain.observation_space.shape[-1], env.observation_space.shape[-1])
    assert block.stop - block.start == 21
    observation, _ = env.reset(seed=3)
    other, _ = plain.reset(seed=3)
    rng = np.random.default_rng(1)
    for _ in range(6):
        action = rng.uniform(-0.5, 0.5, (count, 4)).astype(np.float32)
        act = action[0] if count == 1 else action
        observation, *_, info = env.step(act)
        other, *_ = plain.step(act)
        observation, other = np.atleast_2d(observation), np.atleast_2d(other)
        np.testing.assert_array_equal(observation[:, : block.start], other)
        state = env.unwrapped.fleet.state
        truth = observation[:, block]
        for n in range(count):
            r = _rotation(state.quaternion[n])
            expected = np.concatenate(
                (
                    state.position[n],
                    state.velocity[n],
                    r[:, 0],
                    r[:, 1],
                    state.body_rates[n],
                    np.atleast_2d(info["wrench_true"])[n],
                )
            )
            np.testing.assert_allclose(truth[n], expected.astype(np.float32), rtol=1e-6, atol=1e-6)
        assert not np.allclose(observation[:, layout["velocity"]], truth[:, 3:6], atol=1e-6)
    env.close()
    plain.close()


def test_the_actor_never_reads_the_privileged_block_and_the_critic_does(tmp_path):
    """A tiny asymmetric run: changing the privileged columns leaves the actor's action unchanged and
    moves the critic's value; the run saves, reloads as its class and flies by folder."""
    values = {
        **SMALL,
        "privileged_critic": True,
        "total_steps": 1024,
        "hyperparameters": HYPERPARAMETERS["ppo"],
    }
    config = build(TrainConfig, values)
    assert config.env["privileged"] is True
    folder = train(config, tmp_path / "run", progress=False)
    policy = load_policy(folder)
    model = policy.model
    assert isinstance(model.policy, PrivilegedCriticPolicy)
    env = gym.make(FAN_TRACKING, **config.env)
    observation, _ = env.reset(seed=0)
    block = env.unwrapped.obs_layout["privileged"]
    changed = observation.copy()
    changed[block] += np.float32(5.0)
    with torch.no_grad():
        pair = [torch.as_tensor(o[None]) for o in (observation, changed)]
        actions = [model.policy.get_distribution(o).distribution.mean for o in pair]
        values = [model.policy.predict_values(o) for o in pair]
    torch.testing.assert_close(actions[0], actions[1], rtol=0, atol=0)
    assert not torch.allclose(values[0], values[1])
    policy.reset(env)
    assert np.all(np.isfinite(policy.act(observation)))
    env.close()


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ({"privileged_critic": True, "algorithm": "sac"}, "privileged_critic=true with algorithm='sac'"),
        ({"privileged_critic": True, "algorithm": "recurrent_ppo"}, "algorithm='recurrent_ppo'"),
        ({"privileged_critic": True, "env": {"privileged": False}}, "needs env.privileged true"),
        ({"env": {"privileged": True}}, "the actor would read the truth"),
        ({"privileged_critic": "yes"}, "privileged_critic='yes'"),
    ],
)
def test_a_privileged_critic_its_learner_cannot_build_is_refused_by_name(values, message):
    with pytest.raises(ValueError, match=message):
        build(TrainConfig, values)


def test_the_env_refuses_a_privileged_setting_that_is_not_a_bool():
    with pytest.raises(ValueError, match="privileged=1"):
        gym.make(FAN_TRACKING, privileged=1)

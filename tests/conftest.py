"""Shared fixtures: environments built and always closed."""

from __future__ import annotations

import gymnasium as gym
import pytest

import quad_wrench_env  # noqa: F401  (registers the env ids)

FAN_TRACKING = "QuadWrench/FanTracking-v1"


@pytest.fixture
def make_env():
    """``make_env(**kwargs)`` -> a FanTracking env, closed after the test."""
    envs = []

    def factory(env_id: str = FAN_TRACKING, **kwargs):
        env = gym.make(env_id, **kwargs)
        envs.append(env)
        return env

    yield factory
    for env in envs:
        env.close()

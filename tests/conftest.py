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


def assert_usage_error(argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    """``quad-wrench argv`` exits with code 2 and one line with ``message``, no traceback."""
    from quad_wrench_cli.main import main

    with pytest.raises(SystemExit) as exit_:
        main(argv)
    err = capsys.readouterr().err
    assert exit_.value.code == 2
    assert "error: " in err and message in err, err
    assert "Traceback" not in err

"""Shared fixtures: environments built and always closed."""

from __future__ import annotations

import copy

import gymnasium as gym
import numpy as np
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


def controls_on_a_copy(fleet, actions, instant_motors: bool = True, buffer=None):
    """The engine's ``controls`` kernel (autopilot and motors) for ``fleet``'s vehicles from (N, 4)
    ``actions``, on ``buffer`` (a copy of the fleet's step buffer when None: the flight is left alone)
    and a copy of its saturation flags; returns that buffer's fields by name
    (:func:`~quad_wrench_env.engine.kernels.step_views`) and the mixer's flags (``"saturated"``). With
    ``instant_motors`` the motors' lag gains are 1, so ``speeds`` is the command (clipped to the
    motors' range)."""
    import numpy as np

    from quad_wrench_env.engine.kernels import CONSTANT_FIELDS, STEP_FIELDS, controls, offsets, step_views

    buffer = fleet.step_buffer.array.copy() if buffer is None else buffer
    constants = fleet.compiled.constants.copy()
    if instant_motors:
        start = offsets(CONSTANT_FIELDS)["motors"]
        constants[start : start + 2] = 1.0  # alpha up and down: the speed reaches the command in one step
    saturated = fleet.autopilot.saturated.copy()
    controls(np.asarray(actions, dtype=float), buffer, saturated, constants)
    fields = dict(zip((name for name, _ in STEP_FIELDS), step_views(buffer, fleet.count), strict=True))
    return {**fields, "saturated": saturated}


class EstimatorSpy:
    """An estimator bank that records what the physics step hands its inner bank (assigned as the
    fleet's estimator, the compiled step calls its ``step``), with the rotors' speeds and the truth."""

    def __init__(self, inner, fleet) -> None:
        self._inner, self._fleet, self.calls = inner, fleet, []

    def __getattr__(self, name: str):
        return getattr(self._inner, name)

    def step(self, inputs):
        truth = copy.deepcopy(self._fleet.state)  # the fleet's state is updated in place
        measured = [None if a is None else np.array(a, copy=True) for a in inputs]
        self.calls.append((measured, self._fleet.rotors.speeds.copy(), truth))
        return self._inner.step(inputs)

"""The benchmark's measuring functions run on the current code (their numbers are for scripts/)."""

from __future__ import annotations

import math

import pytest

from quad_wrench_env.bench import FLOORS, bare_pybullet_step_seconds, component_seconds
from quad_wrench_env.kernels import NUMBA_AVAILABLE


def test_the_floor_refuses_an_unknown_load_by_name():
    assert bare_pybullet_step_seconds(5, bodies=2) > 0.0
    with pytest.raises(ValueError, match="floor='three rotors'"):
        bare_pybullet_step_seconds(5, floor="three rotors")
    assert len(FLOORS) == 2


@pytest.mark.parametrize(
    "num_envs", [1, pytest.param(3, marks=pytest.mark.skipif(not NUMBA_AVAILABLE, reason="numba"))]
)
def test_the_parts_of_a_step_are_timed_per_vehicle(num_envs):
    parts = component_seconds(3, num_envs=num_envs)
    assert "policy step: observation, reward, termination, info" in parts
    assert any(name.startswith("physics step: estimator (ukf") for name in parts)
    assert all(math.isfinite(seconds) for seconds in parts.values())

"""The benchmark's measuring functions do what quad-wrench bench relies on (no wall-clock times asserted)."""

from __future__ import annotations

import math

import gymnasium as gym
import pytest

import quad_wrench_env.bench as bench
from quad_wrench_env.bench import (
    FLOORS,
    STEP_PARTS,
    bare_pybullet_step_seconds,
    paired_step_seconds,
    step_parts_seconds,
)


def test_the_floor_refuses_an_unknown_load_by_name():
    """Catches a floor silently timing some default load for a misspelt one."""
    with pytest.raises(ValueError, match="floor='three rotors'"):
        bare_pybullet_step_seconds(2, floor="three rotors")
    assert FLOORS == ("four rotor forces", "resultant force and torque")
    for floor in FLOORS:
        assert math.isfinite(bare_pybullet_step_seconds(2, bodies=2, floor=floor))


def test_paired_timing_gives_one_figure_per_setting_and_steps_every_env(monkeypatch):
    """Catches a paired benchmark that times the wrong env, skips one or returns figures out of
    order: one figure per setting, each env stepped blocks x steps times (plus one warm-up step)."""
    made = []
    real_make = gym.make

    def make(env_id, **kwargs):
        env = real_make(env_id, **kwargs)
        counter = {"steps": 0, "kwargs": kwargs}
        step = env.step

        def counted(action):
            counter["steps"] += 1
            return step(action)

        env.step = counted
        made.append(counter)
        return env

    monkeypatch.setattr(bench.gym, "make", make)
    settings = [{"estimator": "oracle"}, {"estimator": "observer"}]
    figures = paired_step_seconds(steps=3, blocks=2, settings=settings)
    assert len(figures) == 2 and all(math.isfinite(f) and f > 0 for f in figures)
    assert [m["kwargs"] for m in made] == settings
    assert [m["steps"] for m in made] == [1 + 2 * 3] * 2


def test_the_parts_of_a_step_add_up_to_the_timed_step():
    """Every part of :data:`STEP_PARTS` is reported and timed inside real steps, single and vector env: they
    add up to the timed step, each a time (none negative), those the env runs non-zero (no sensor
    block here)."""
    for num_envs in (1, 2):
        parts = step_parts_seconds(20, num_envs=num_envs, blocks=2, estimator="ekf")
        assert list(parts) == [*STEP_PARTS, "whole step (timed)", "whole step", "the timers' own cost"]
        spent = [parts[name] for name in STEP_PARTS]
        assert math.isclose(sum(spent), parts["whole step (timed)"], rel_tol=1e-9)
        assert min(spent) >= 0.0
        assert [name for name in STEP_PARTS if parts[name] == 0.0] == ["physics: sensor block (kernel)"]
        assert parts["whole step"] > 0.0  # (no order between the timed and plain steps: a noisy machine)
        assert parts["the timers' own cost"] == parts["whole step (timed)"] - parts["whole step"]

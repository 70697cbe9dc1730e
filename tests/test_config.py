"""Config files and overrides: typed, merged, and strict about unknown keys."""

from __future__ import annotations

from pathlib import Path

import pytest

from quad_wrench_env.config import section
from quad_wrench_env.envs.fan_tracking import FanTrackingConfig

ROOT = Path(__file__).resolve().parents[1]


def test_shipped_config_builds_the_env(make_env):
    env = make_env(config=ROOT / "configs" / "fan_tracking.yaml", episode_seconds=5.0)
    cfg = env.unwrapped.cfg
    assert isinstance(cfg, FanTrackingConfig)
    assert cfg.vehicle == "ardrone2" and cfg.episode_seconds == 5.0


def test_overrides_merge_into_nested_sections(make_env, tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("env:\n  fan:\n    outlet_speed: 4.0\n    motion: static\n")
    env = make_env(config=path, fan={"height": 1.2})
    fan = env.unwrapped.cfg.fan
    assert (fan.outlet_speed, fan.motion, fan.height) == (4.0, "static", 1.2)


def test_missing_file_and_bad_values_are_named(make_env, tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.yaml"):
        section(tmp_path / "nope.yaml", "env")
    with pytest.raises(ValueError, match="turbulence_intensity=1.5"):
        make_env(fan={"turbulence_intensity": 1.5})
    with pytest.raises(ValueError, match="'fan.motions.wobble'|wobble"):
        make_env(fan={"motions": {"wobble": {}}})

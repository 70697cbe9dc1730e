"""Config files and overrides: typed, merged, and strict about unknown keys."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from quad_wrench_env.config import build, config_path, section, shipped_configs
from quad_wrench_env.tasks.fan_tracking import FanTrackingConfig

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
    with pytest.raises(ValueError, match=r"unknown fan motion\(s\) \['wobble'\] in fan\.motions"):
        make_env(fan={"motions": {"wobble": {}}})


def test_a_value_of_the_wrong_type_is_refused_by_its_key(make_env):
    with pytest.raises(ValueError, match=r"^episode_seconds='30' must be a number \(float\); got str$"):
        make_env(episode_seconds="30")
    with pytest.raises(ValueError, match=r"^fan\.outlet_speed='10' must be a number \(float\); got str$"):
        make_env(fan={"outlet_speed": "10"})
    with pytest.raises(ValueError, match=r"^physics_hz=True must be an integer \(int\); got bool$"):
        make_env(physics_hz=True)
    with pytest.raises(ValueError, match=r"^observe_wrench=1 must be true or false \(bool\); got int$"):
        make_env(observe_wrench=1)
    with pytest.raises(
        ValueError, match=r"^payload\.point='abc' must be a list \(tuple\[float, float, float\]\)"
    ):
        make_env(payload={"point": "abc"})


def test_yaml_types_fill_the_fields(make_env):
    """YAML gives ints for floats and lists for tuples; both are taken as they are."""
    env = make_env(
        episode_seconds=5,
        fan={"outlet_speed": 8, "motions": {"piecewise": {"segments": [[5, 0.1], [5, -0.1]]}}},
        payload={"mass": 0.053, "point": [0, 0, -0.06]},
        episodes={"motions": ["static", "sine"]},
        vehicle_params={"mass": 0.45},
    )
    cfg = env.unwrapped.cfg
    assert (cfg.episode_seconds, cfg.fan.outlet_speed, cfg.episodes.motions) == (5, 8, ("static", "sine"))


@dataclass
class _Inner:
    gain: float = 1.0


@dataclass
class _Outer:
    count: int = 1
    scale: float | None = None
    names: tuple[str, ...] = ()
    options: dict[str, float] = field(default_factory=dict)
    inner: _Inner = field(default_factory=_Inner)


def test_build_checks_each_annotation():
    built = build(_Outer, {"count": 2, "scale": 3, "names": ["a"], "options": {"k": 1}, "inner": {"gain": 2}})
    assert built == _Outer(2, 3, ["a"], {"k": 1}, _Inner(2))
    assert build(_Outer, {"scale": None}).scale is None
    bad = [
        ({"count": True}, r"^x\.count=True must be an integer \(int\); got bool$"),
        ({"count": 2.0}, r"^x\.count=2\.0 must be an integer \(int\); got float$"),
        ({"scale": True}, r"^x\.scale=True must be a number \(float\) or None; got bool$"),
        ({"scale": "1"}, r"^x\.scale='1' must be a number \(float\) or None; got str$"),
        ({"names": "a"}, r"^x\.names='a' must be a list \(tuple\[str, \.\.\.\]\); got str$"),
        ({"options": [1]}, r"^x\.options=\[1\] must be a mapping \(dict\[str, float\]\); got list$"),
        ({"inner": 2}, r"^x\.inner=2 must be a mapping of _Inner keys; got int$"),
        ({"inner": {"gain": "2"}}, r"^x\.inner\.gain='2' must be a number \(float\); got str$"),
        (
            {"inner": {"gian": 2}},
            r"^unknown config key\(s\) 'x\.inner\.gian'; allowed: \['x\.inner\.gain'\]$",
        ),
    ]
    for values, match in bad:
        with pytest.raises(ValueError, match=match):
            build(_Outer, values, prefix="x.")


def test_every_config_file_ships_with_the_package():
    folder = ROOT / "configs"
    names = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*.y*ml"))
    assert "fan_tracking.yaml" in names and "rl_zoo3/ppo.yml" in names
    assert shipped_configs() == names
    for name in names:
        assert config_path(name).read_text() == (folder / name).read_text()
    with pytest.raises(
        ValueError, match=r"no shipped config 'nope\.yaml'; available: \[.*'fan_tracking\.yaml'"
    ):
        config_path("nope.yaml")


def test_pyproject_lists_every_package():
    """``[tool.setuptools] packages`` is written by hand (for the configs mapping): it must name
    every folder of Python files, or a non-editable install silently lacks it."""
    tomllib = pytest.importorskip("tomllib")
    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    tops = ("quad_wrench_env", "agents", "quad_wrench_cli")
    folders = [d for top in tops for d in (ROOT / top, *(ROOT / top).rglob("*"))]
    packages = {".".join(d.relative_to(ROOT).parts) for d in folders if d.is_dir() and any(d.glob("*.py"))}
    assert set(setuptools["packages"]) == {*packages, "quad_wrench_env.configs"}
    assert setuptools["package-dir"] == {"quad_wrench_env.configs": "configs"}


@pytest.mark.parametrize(
    "name", sorted(p.name for p in (Path(__file__).parents[1] / "configs").glob("train_*.yaml"))
)
def test_every_training_config_builds_its_env_and_steps_it(name):
    """A shipped training config is a valid TrainConfig whose env resets and takes a step."""
    import gymnasium as gym

    from quad_wrench_env.agents.sb3 import train_config
    from quad_wrench_env.config import load_yaml

    config = train_config(load_yaml(Path(__file__).parents[1] / "configs" / name), {})
    env = gym.make(config.env_id, **config.env)
    try:
        env.reset(seed=0)
        observation, *_ = env.step(np.zeros(4))
        assert np.all(np.isfinite(observation))
    finally:
        env.close()

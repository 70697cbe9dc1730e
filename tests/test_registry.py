"""The one registry (``quad_wrench_env.registry``): every kind holds the package's own entries, an
entry registered from outside is used by name wherever the package's are (a config's ``wind``, the
harness, ``gym.make``), and names are refused clearly when unknown or taken."""

from __future__ import annotations

import pickle
import sys
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from quad_wrench_env import registry
from quad_wrench_env.agents import AGENTS, make_agent
from quad_wrench_env.agents.evaluate import evaluate
from quad_wrench_env.disturbances.base import make_wind, wind_config
from quad_wrench_env.estimators import ESTIMATORS
from quad_wrench_env.tasks import TASKS
from tests.test_open_engine import Crosswind, Hold

EXAMPLES = Path(__file__).resolve().parents[1] / "docs" / "examples"


@pytest.fixture
def scratch(monkeypatch):
    """The registry as it is, restored after the test (registrations are process-wide)."""
    for kind in registry.HOMES:
        registry.registered(kind)  # the package's own first
        monkeypatch.setitem(registry._ENTRIES, kind, dict(registry._ENTRIES[kind]))
    return registry


def test_every_kind_holds_the_packages_entries():
    expected = {
        "wind": {"dryden", "jet", "one_cosine"},
        "load": set(),  # the payload and the scheduled wrench have keys of their own
        "scene": {"table", "wall", "ceiling"},
        "estimator": {"ukf", "ekf", "observer", "oracle", "learned"},
        "task": {
            "QuadWrench/FanTracking-v1",
            "QuadWrench/DisturbanceRejection-v0",
            "QuadWrench/ForceExertion-v0",
        },
        "agent": {"hold", "admittance", "pid", "mpc", "ida_pbc"},
    }
    for kind, names in expected.items():
        assert set(registry.registered(kind)) == names
    assert set(AGENTS) == expected["agent"] and set(ESTIMATORS) == expected["estimator"]
    assert set(TASKS) == expected["task"] and all(env_id in gym.registry for env_id in TASKS)


@dataclass
class GustyConfig:
    speed: float = 2.0


def test_a_wind_model_registered_outside_is_built_by_name_and_flies(scratch):
    @scratch.register("wind", "gusty")
    class Gusty(Crosswind):
        config_class = GustyConfig

        def __init__(self, config: GustyConfig, count: int) -> None:
            super().__init__()
            self.speed = config.speed

    name, config = wind_config({"model": "gusty", "speed": 3.0})
    assert (name, config) == ("gusty", GustyConfig(3.0))
    assert make_wind({"model": "gusty"}, count=2).speed == 2.0
    env = gym.make("QuadWrench/FanTracking-v1", fan={"enabled": False}, wind=[{"model": "gusty"}])
    try:
        _, info = env.reset(seed=0)
        np.testing.assert_allclose(info["wind_velocity"], (0.0, 2.0, 0.0))
    finally:
        env.close()


def test_a_task_registered_outside_gets_its_id_entry_points_and_harness(scratch):
    class RegistryHold(Hold):
        env_id = "Test/RegistryHold-v0"

    scratch.register("task")(RegistryHold)
    try:
        spec = gym.spec(RegistryHold.env_id)
        assert spec.entry_point == "quad_wrench_env.envs.env_classes:RegistryHoldEnv"
        assert spec.vector_entry_point == "quad_wrench_env.envs.env_classes:RegistryHoldVectorEnv"
        env = gym.make(RegistryHold.env_id, estimator="oracle")
        assert pickle.loads(pickle.dumps(env.unwrapped)).task_class is RegistryHold
        env.close()
        result = evaluate(make_agent("hold"), RegistryHold.env_id, [0], episode_seconds=0.2)
        assert "max_distance" in result.per_seed[0]  # the task's own metric, through env.unwrapped.task
    finally:
        del gym.registry[RegistryHold.env_id]


def test_unknown_names_kinds_and_taken_names_are_refused_clearly(scratch):
    with pytest.raises(ValueError, match=r"unknown agent 'nope'; allowed: \['admittance', 'hold'"):
        registry.lookup("agent", "nope")
    with pytest.raises(ValueError, match=r"unknown registry kind 'planet'; allowed: \['wind', 'load'"):
        registry.register("planet", "earth", object())
    taken = r"agent 'pid' is already registered as quad_wrench_env\.agents\.pid"
    with pytest.raises(ValueError, match=taken):
        scratch.register("agent", "pid", type("OtherPID", (), {}))
    with pytest.raises(ValueError, match="a task registers under its env_id"):
        scratch.register("task", "Other/Name-v0", Hold)
    with pytest.raises(ValueError, match=r"wind\[0\]: unknown model 'thermal'; allowed: \['dryden'"):
        wind_config({"model": "thermal"})


def test_a_users_estimator_enters_the_comparison_with_one_line_of_config(
    scratch, tmp_path, monkeypatch, capsys
):
    """``"module:name"`` imports the module (which registers its entries): the quasi-static estimator of
    docs/examples/ joins ``quad-wrench compare estimators``'s table by adding it to ``estimators``."""
    from quad_wrench_cli.main import main

    monkeypatch.syspath_prepend(str(EXAMPLES))
    monkeypatch.delitem(sys.modules, "quasi_static", raising=False)  # registers again, in this registry
    config = tmp_path / "estimators.yaml"
    config.write_text(
        "env_id: QuadWrench/FanTracking-v1\n"
        "estimators: [ukf, ekf, 'quasi_static:quasi_static']\n"
        f"seeds: [0]\noutput: {tmp_path / 'out'}\ncost: {{steps: 50, repeats: 1}}\n"
    )
    assert main(["compare", "estimators", "--config", str(config), "--only", "cost"]) == 0
    rows = [
        line.split("|")[1].strip() for line in capsys.readouterr().out.splitlines() if line.startswith("| ")
    ]
    assert {"ukf", "ekf", "quasi_static:quasi_static"} <= set(rows)
    assert "quasi_static" in registry.registered("estimator")


def test_a_module_that_does_not_import_is_named(scratch):
    with pytest.raises(ValueError, match=r"'no_such_module:x': module 'no_such_module' does not import"):
        registry.lookup("estimator", "no_such_module:x")


def test_every_scene_part_conforms_and_refuses_an_unknown_touch():
    """The ``ScenePart`` seam's conformance, for every registered kind built with its defaults: boxes
    with positive half extents, a top that is None or a rectangle, a touch of ``TOUCHES``."""
    from quad_wrench_env.scene import TOUCHES, ScenePart, make_scene_part

    for kind in registry.registered("scene"):
        part = make_scene_part({"kind": kind})
        assert isinstance(part, ScenePart) and part.touch in TOUCHES and part.friction > 0
        assert part.boxes() and all(min(half) > 0 for _, half in part.boxes())
        top = part.top()
        assert top is None or (len(top) == 5 and top[0] < top[1] and top[2] < top[3])
    with pytest.raises(ValueError, match=r"touch='perch' is unknown; allowed: \['crash', 'report'\]"):
        make_scene_part({"kind": "wall", "touch": "perch"})

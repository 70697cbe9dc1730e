"""The engine's seams from outside: a new wind field and a new task, each written here in one place
and nothing in the engine; what has no compiled form is refused by name; and the envs' lifecycle
(closed envs, steps past an episode's end)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
import pytest

from quad_wrench_env.disturbances.base import CompiledForm
from quad_wrench_env.engine.components import Components
from quad_wrench_env.engine.env_config import EnvConfig
from quad_wrench_env.envs.env_classes import env_classes
from quad_wrench_env.numerics import njit
from quad_wrench_env.tasks.base import TaskDefaults, TaskRecord
from tests.conftest import FAN_TRACKING

CROSSWIND = 2.0
"""m/s along +y: the test's own wind field."""


class Crosswind:
    """A uniform wind along +y: its kernels (unless ``compiled=None``) and the air at a given state,
    both here."""

    name = "crosswind"
    noise_width = 0
    compiled: CompiledForm | None = CompiledForm(
        __name__, (("velocity", "crosswind_velocity"), ("advance", "calm"))
    )

    def __init__(self) -> None:
        self.speed = CROSSWIND
        """m/s; a task may change it between episodes."""

    def kernel_parameters(self) -> np.ndarray:
        return np.array((self.speed,))

    def reset(self, index: int, rng: np.random.Generator) -> None:
        """Nothing random."""

    def velocity_at(self, points, t, index, mean=False) -> np.ndarray:
        wind = np.zeros(points.shape)
        wind[..., 1] = self.speed
        return wind


class UncompiledCrosswind(Crosswind):
    name = "uncompiled_crosswind"
    compiled = None


@njit
def crosswind_velocity(params, table, state, points, time, out):
    for n in range(points.shape[0]):
        for p in range(points.shape[1]):
            out[n, p, 1] += params[0]


@njit
def calm(params, table, state, position, velocity, dt, normals):
    """Nothing to advance."""


@dataclass
class HoldConfig(EnvConfig):
    wind_field: str = "compiled"
    """``"compiled"`` or ``"uncompiled"``: which of the test's crosswinds the task brings."""
    radius: float = 0.3
    """m from the reference that ends the episode as ``"left_the_ball"``."""


class Hold(TaskDefaults):
    """Hold a reference point in a crosswind: a task with its own observation block, termination,
    reward term, info and metric, in one class."""

    env_id: ClassVar[str] = "QuadWrench/TestHold-v0"
    config_class: ClassVar[type[EnvConfig]] = HoldConfig
    reset_options: ClassVar[tuple[str, ...]] = ()
    observation_blocks: ClassVar[tuple[tuple[str, int, float], ...]] = (("reference_position", 3, 10.0),)
    termination_reasons: ClassVar[tuple[str, ...]] = ("left_the_ball",)
    trace_keys: ClassVar[tuple[str, ...]] = ("distance",)

    def __init__(self, cfg: HoldConfig, vehicle: Any, count: int) -> None:
        self.cfg = cfg
        self.reference = np.tile((2.0, 0.0, 1.0), (count, 1))

    def components(self) -> Components:
        self.wind = Crosswind() if self.cfg.wind_field == "compiled" else UncompiledCrosswind()
        return Components(winds=[self.wind])

    def reset_vehicle(self, index: int, rng: np.random.Generator, options: Mapping[str, Any]):
        return self.reference[index].copy(), 0.0

    def start(self, view, index) -> TaskRecord:
        return self._record(view, {}, None)

    def step(self, view, actions, ended) -> TaskRecord:
        distance = np.linalg.norm(view.state.position - self.reference, axis=1)
        return self._record(view, {"distance": -distance}, (distance > self.cfg.radius).astype(int))

    def _record(self, view, reward_terms, codes) -> TaskRecord:
        distance = np.linalg.norm(view.state.position - self.reference, axis=1)
        return TaskRecord(reward_terms, codes, self.reference.copy(), {"distance": distance})

    @staticmethod
    def metrics(trace: Mapping[str, np.ndarray]) -> dict[str, float]:
        return {"max_distance": float(np.max(trace["distance"]))}


HoldEnv, HoldVectorEnv = env_classes(Hold)


@pytest.mark.parametrize("num_envs", [1, 2])
def test_a_task_and_a_wind_field_written_outside_the_engine_fly(num_envs):
    """The test's task brings its own observation block (after the engine's, named in obs_layout),
    termination (named in info), reward term and info; its crosswind pushes the vehicle along +y
    and shows in wrench_true (drag of a 2 m/s wind on the hovering vehicle: body drag ρ/2·C_dA·v²
    plus rotor drag, which decelerates a hovering vehicle at ``rotor_drag_decel`` per m/s,
    ``docs/physics.md``, "Rotors") and in wind_velocity; the single env and the vector env alike (the
    vector env's second vehicle climbs and stays in the ball)."""
    env = HoldEnv(estimator="oracle") if num_envs == 1 else HoldVectorEnv(num_envs=2, estimator="oracle")
    try:
        layout = env.unwrapped.obs_layout
        assert layout["reference_position"] == slice(25, 28)
        assert env.observation_space.shape[-1] == 28
        observation, info = env.reset(seed=0)
        first = (lambda values: values) if num_envs == 1 else (lambda values: values[0])
        np.testing.assert_array_equal(first(observation)[layout["reference_position"]], (2.0, 0.0, 1.0))
        np.testing.assert_allclose(first(info["wind_velocity"]), (0.0, CROSSWIND, 0.0))
        v = env.unwrapped.vehicle
        drag = 0.5 * 1.2 * v.drag_area * CROSSWIND**2 + v.rotor_drag_decel * v.mass * CROSSWIND
        assert first(info["wrench_true"])[1] == pytest.approx(drag, rel=0.02)  # the trim tilts the rotors ~2°
        actions = np.array(((0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 0.2, 0.0)), dtype=np.float32)  # off along +y
        actions = actions[0] if num_envs == 1 else actions
        for _ in range(500):
            observation, reward, terminated, _, info = env.step(actions)
            if first(terminated):  # (the vector env's info then holds the next episode's start)
                break
            assert first(reward) == pytest.approx(-first(info["distance"]))
        else:
            raise AssertionError("flying away never left the ball")
        if num_envs == 1:
            assert info["termination_reason"] == "left_the_ball" and info["position"][1] > 0.0
        else:
            assert not terminated[1] and info["final_info"]["termination_reason"][0] == "left_the_ball"
    finally:
        env.close()


def test_a_component_without_a_compiled_form_is_refused_by_name():
    with pytest.raises(ValueError, match=r"uncompiled_crosswind.*no compiled form.*NUMBA_DISABLE_JIT=1"):
        HoldEnv(wind_field="uncompiled")


def test_the_removed_backend_key_is_refused_by_name():
    for backend in ("numpy", "numba", "auto"):
        with pytest.raises(ValueError, match="'backend'"):
            gym.make(FAN_TRACKING, backend=backend)


def test_a_closed_env_says_so_on_step_and_reset():
    env = gym.make(FAN_TRACKING)
    env.reset(seed=0)
    env.close()
    env.close()  # idempotent
    for call in (lambda: env.step(np.zeros(4)), lambda: env.reset(seed=0)):
        with pytest.raises(RuntimeError, match="is closed"):
            call()
    venv = gym.make_vec(FAN_TRACKING, num_envs=2, vectorization_mode="vector_entry_point")
    venv.close()
    with pytest.raises(RuntimeError, match="is closed"):
        venv.reset(seed=0)


def test_stepping_past_the_end_of_an_episode_warns_once(caplog):
    """Today's silent -10 per step after a crash becomes a warning, once per ended episode."""
    env = gym.make(FAN_TRACKING, estimator="oracle", episode_seconds=0.1)
    try:
        env.reset(seed=0)
        for _ in range(5):
            *_, truncated, _ = env.step(np.zeros(4))
        assert truncated
        with pytest.warns(UserWarning, match="after the episode ended") as record:
            env.step(np.zeros(4))
            env.step(np.zeros(4))
        assert len([w for w in record if "after the episode ended" in str(w.message)]) == 1
        env.reset(seed=1)
        with pytest.warns(UserWarning, match="after the episode ended"):
            for _ in range(6):
                env.step(np.zeros(4))
    finally:
        env.close()


def test_a_metric_of_the_task_reaches_the_harness():
    from quad_wrench_env.agents.evaluate import Episode, episode_metrics

    trace = {"time": np.arange(3) * 0.02, "distance": np.array((0.0, 0.2, 0.1))}
    scores = Hold.metrics(trace)
    assert scores == {"max_distance": 0.2}
    generic = episode_metrics("QuadWrench/Unknown-v0", Episode(0, trace, 1.0, 2, None))
    assert set(generic) == {"episode_seconds", "return", "terminated_early"}
    assert math.isclose(generic["episode_seconds"], 0.04)


def test_a_component_changed_between_episodes_is_read_again_by_the_compiled_step():
    """A task may change a component's numbers per episode (e.g. a jet's speed per reset): the compiled
    step packs them again at every episode start, so the step after the reset feels the new wind,
    as the reset's own loads (computed at the state) do."""
    env = HoldEnv(estimator="oracle")
    try:
        drag = []
        for speed in (CROSSWIND, 2.0 * CROSSWIND):
            env.unwrapped.task.wind.speed = speed
            at_reset = env.reset(seed=2)[1]
            info = env.step(np.zeros(4, dtype=np.float32))[4]
            np.testing.assert_allclose(info["wind_velocity"], (0.0, speed, 0.0), atol=1e-12)
            np.testing.assert_allclose(info["wrench_true"][1], at_reset["wrench_true"][1], rtol=0.02)
            drag.append(info["wrench_true"][1])
        assert drag[1] > 2.5 * drag[0]  # quadratic body drag plus linear rotor drag of twice the wind
    finally:
        env.close()


def test_kernels_in_a_script_are_refused_with_a_reason():
    from quad_wrench_env.engine.compose import Slot

    with pytest.raises(ValueError, match="importable module, not in __main__"):
        Slot("wind", CompiledForm("__main__", (("velocity", "v"), ("advance", "a"))), 0)


def test_the_vehicles_of_a_vector_env_share_one_copy_of_the_scene():
    """The scene is built once, where every vehicle flies: a vehicle descending onto a table crashes
    on it at the step a single env's does, whatever its index (a copy per vehicle would be several
    boxes in one place, each pushing back)."""
    table = {"kind": "table", "center": [2.3, 0.0], "size": [1.0, 1.0], "height": 0.6}
    settings = {"estimator": "oracle", "scene": [table], "fan": {"enabled": False}, "crash_height": -1.0}
    venv = gym.make_vec(FAN_TRACKING, num_envs=3, vectorization_mode="vector_entry_point", **settings)
    env = gym.make(FAN_TRACKING, **settings)
    down = np.array((0.0, 0.0, -1.0, 0.0))
    try:
        world = venv.unwrapped.fleet.world
        venv.reset(seed=3, options={"offset_y": 0.0})
        env.reset(seed=5, options={"offset_y": 0.0})
        assert len(world._crash_bodies) == 2  # the ground and one table
        for step in range(300):
            _, _, terminated, _, info = venv.step(np.tile(down, (3, 1)))
            _, _, single_terminated, _, single = env.step(down)
            assert terminated[2] == single_terminated, f"step {step}"
            if single_terminated:
                assert info["final_info"]["termination_reason"][2] == single["termination_reason"] == "crash"
                assert single["position"][2] > 0.6  # on the table, not the ground
                break
        assert single_terminated, "the descent never touched the table"
    finally:
        venv.close()
        env.close()

"""The compiled kernels against the numpy reference: the same flights to rounding, feature by feature
and component by component (every component with a compiled form has a case here). The estimators
have their kernels only, on both backends (their checks: ``tests/test_ukf.py``,
``tests/test_reference_estimators.py``); their banks' bound step and restart are checked here."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import warnings

import gymnasium as gym
import numpy as np
import pytest

import quad_wrench_env.disturbances
import quad_wrench_env.kernels as kernels
from quad_wrench_env.engine import fleet as fleet_module
from quad_wrench_env.engine.kernels import (
    CONSTANT_FIELDS,
    CONSTANT_WIDTH,
    STEP_FIELDS,
    STEP_WIDTH,
    component_parameters,
    component_slice,
    drag_points,
    offsets,
    physics_constants,
    step_views,
)
from quad_wrench_env.estimators import make_estimator_bank
from quad_wrench_env.kernels import NUMBA_AVAILABLE, bind, resolve_backend, specialised
from quad_wrench_env.kernels.linalg import weighted_gram
from quad_wrench_env.rotations import quat_exp
from quad_wrench_env.vehicle import GRAVITY, make_vehicle
from tests.conftest import FAN_TRACKING

needs_numba = pytest.mark.skipif(not NUMBA_AVAILABLE, reason="numba is not installed")

_TABLE = {"kind": "table", "center": [2.3, 0.1], "size": [1.0, 1.0], "height": 0.9}
CASES = {
    "velocity, ukf": {},
    "attitude, oracle": {"action_type": "attitude", "estimator": "oracle"},
    "wrench, piecewise fan": {"action_type": "wrench", "fan": {"motion": "piecewise"}},
    "motors, no fan": {"action_type": "motors", "fan": {"enabled": False}, "estimator": "oracle"},
    "payload and scheduled wrench": {
        "fan": {"motion": "constant_speed"},
        "payload": {"mass": 0.05, "point": [0.1, 0.1, 0.0], "attach_time": 0.2, "release_time": 0.6},
        "external_wrench": [[0.1, 0.5, 0.2, 0.0, -0.3, 0.0, 0.01, 0.02]],
    },
    "state estimator, ekf": {"estimator": "ekf", "sensors": {"state_estimator": True}},
    "crazyflie, observer": {"vehicle": "crazyflie2", "estimator": "observer"},
    "dryden in a mean wind": {
        "wind": [{"model": "dryden", "w20": 2.0, "altitude": 1.0, "mean": [0.5, 0.2, 0.0]}]
    },
    "one-cosine gust, no fan": {
        "fan": {"enabled": False},
        "wind": [
            {"model": "one_cosine", "peak": [0.0, 1.5, 0.2], "start": 0.3, "duration": 0.5, "hold": False}
        ],
    },
    "second jet": {
        "wind": [{"model": "jet", "position": [2.3, -1.5, 1.0], "direction": [0, 1, 0], "speed": 10.0}]
    },
    "turbulent jets, vector": {
        "num_envs": 2,
        "wind": [
            {
                "model": "jet",
                "position": [2.3, -1.5, 1.0],
                "direction": [0, 1, 0],
                "turbulence_intensity": 0.2,
            },
            {
                "model": "jet",
                "position": [2.3, 1.5, 0.9],
                "direction": [0, -1, 0.1],
                "speed": 6.0,
                "turbulence_intensity": 0.1,
                "turbulence_length": 0.3,
            },
        ],
    },
    "ground effect over a table": {
        "fan": {"height": 1.0},
        "ground_effect": True,
        "scene": [_TABLE],
        "estimator": "oracle",
    },
    "everything at once, vector": {
        "num_envs": 3,
        "ground_effect": True,
        "scene": [_TABLE, {"kind": "wall", "x": 5.5}],
        "wind": [
            {"model": "dryden", "w20": 1.0, "altitude": 1.0},
            {"model": "one_cosine", "peak": [0.5, 0.0, 0.0], "start": 0.2, "duration": 0.4},
            {"model": "jet", "position": [2.3, -1.0, 1.0], "direction": [0, 1, 0], "speed": 3.0},
        ],
        "payload": {"mass": 0.05, "point": [0.1, 0.0, 0.0]},
        "external_wrench": [[0.0, 1.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.01]],
    },
}


def _make(backend: str, settings: dict):
    settings = dict(settings)
    count = settings.pop("num_envs", 0)
    if count:
        return gym.make_vec(
            FAN_TRACKING, num_envs=count, vectorization_mode="vector_entry_point", backend=backend, **settings
        )
    return gym.make(FAN_TRACKING, backend=backend, **settings)


@needs_numba
@pytest.mark.parametrize("case", sorted(CASES))
def test_compiled_flight_equals_the_numpy_reference(case):
    """100 policy steps of random actions (2 s): observations agree to float32 rounding, the true
    wrench and the air at the centre of mass to 1e-9 (the two sum in different orders; nothing else
    differs)."""
    envs = {b: _make(b, CASES[case]) for b in ("numpy", "numba")}
    try:
        assert envs["numba"].unwrapped.fleet.compiled is not None
        assert envs["numpy"].unwrapped.fleet.compiled is None
        first = {b: env.reset(seed=3) for b, env in envs.items()}
        # two implementations: the same numbers to float64 rounding, so their float32 within 2 ulps
        np.testing.assert_allclose(first["numpy"][0], first["numba"][0], rtol=2.5e-7, atol=1e-12)
        shape = envs["numpy"].action_space.shape
        actions = np.random.default_rng(3).uniform(-0.6, 0.6, (100, *shape))
        for action in actions:
            (a, ra, ta, ua, ia), (b, rb, tb, ub, ib) = (env.step(action) for env in envs.values())
            np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6)
            for key in (
                "wrench_true",
                "wind_velocity",
                "axis_error",
                "jet_axis_y",
                "fan_position",
                "wrench_est",
                "position",
            ):
                np.testing.assert_allclose(ia[key], ib[key], rtol=1e-7, atol=1e-9, err_msg=key)
            np.testing.assert_allclose(ra, rb, rtol=1e-7, atol=1e-9)
            np.testing.assert_array_equal(ta, tb)
            np.testing.assert_array_equal(ua, ub)
            if np.any(ta) or np.any(ub):
                break
    finally:
        for env in envs.values():
            env.close()


def _components_with_a_compiled_form() -> set[str]:
    """The ``name`` of every class under ``quad_wrench_env.disturbances`` that has a compiled form."""
    package = quad_wrench_env.disturbances
    names = set()
    for info in pkgutil.iter_modules(package.__path__):
        module = importlib.import_module(f"{package.__name__}.{info.name}")
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if cls.__module__ == module.__name__ and getattr(cls, "compiled", None) is not None:
                names.add(cls.name)
    return names


@needs_numba
def test_every_component_with_a_compiled_form_has_a_backend_case():
    """A registered component (wind model, point load, rotor modifier) without a case above fails
    here: the flight cases must cover each one's kernels against its numpy form."""
    covered = set()
    for settings in CASES.values():
        env = _make("numpy", settings)
        try:
            covered |= {component.name for _, component in env.unwrapped.fleet.components.ordered()}
        finally:
            env.close()
    missing = _components_with_a_compiled_form() - covered
    assert not missing, f"components without a backend case in CASES: {sorted(missing)}"


def test_backend_names_are_checked():
    with pytest.raises(ValueError, match="backend='fortran'"):
        resolve_backend("fortran")
    with pytest.raises(ValueError, match="backend='fortran'"):
        gym.make(FAN_TRACKING, backend="fortran")
    assert resolve_backend("auto") == ("numba" if NUMBA_AVAILABLE else "numpy")


def test_auto_says_so_when_numba_does_not_import(monkeypatch):
    """A plain install without a working numba is told, once, that it runs the slow reference."""
    monkeypatch.setattr(kernels, "_numba", None)
    monkeypatch.setattr(kernels, "NUMBA_AVAILABLE", False)
    monkeypatch.setattr(kernels, "_warned_missing", False)
    with pytest.warns(UserWarning, match="numba does not import"):
        assert kernels.resolve_backend("auto") == "numpy"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert kernels.resolve_backend("auto") == "numpy"  # once
    with pytest.raises(ValueError, match="backend='numba' needs numba"):
        kernels.resolve_backend("numba")


@needs_numba
def test_a_setting_without_a_compiled_form_is_refused_by_numba_and_warned_about_by_auto(monkeypatch):
    """No silent fallback: ``backend="numba"`` refuses motion-capture latency by name; ``"auto"`` warns
    once, naming it, and runs the numpy reference."""
    with pytest.raises(ValueError, match=r"sensors.latency_steps=2.*no compiled form"):
        gym.make(FAN_TRACKING, backend="numba", sensors={"latency_steps": 2})
    monkeypatch.setattr(fleet_module, "_WARNED", set())
    with pytest.warns(UserWarning, match=r"numpy reference.*sensors.latency_steps=2"):
        env = gym.make(FAN_TRACKING, backend="auto", sensors={"latency_steps": 2})
    try:
        assert env.unwrapped.fleet.compiled is None
        env.reset(seed=0)
        _, _, terminated, _, _ = env.step(np.zeros(4, dtype=np.float32))
        assert not terminated
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            gym.make(FAN_TRACKING, backend="auto", sensors={"latency_steps": 2}).close()  # once only
    finally:
        env.close()


@needs_numba
def test_the_components_state_stays_in_the_compiled_steps_buffer():
    """The autopilot's, rotors' and fan's state are views of the compiled step's one buffer (one
    kernel argument), through steps, resets and the numpy code that also updates them."""
    env = gym.make(FAN_TRACKING, backend="numba")
    try:
        fleet = env.unwrapped.fleet
        parts = (
            fleet.autopilot.yaw_setpoint, fleet.autopilot.velocity_integral, fleet.autopilot.rate_integral,
            fleet.rotors.speeds, fleet.rotors.allocations, env.unwrapped.task.fan.noise,
        )  # fmt: skip
        for seed in (0, 1):
            env.reset(seed=seed)
            env.step(np.full(4, 0.3, dtype=np.float32))
        fleet.rotors.step(fleet.actions.motor_command(np.zeros((1, 4)), fleet.state))  # numpy reference
        now = (
            fleet.autopilot.yaw_setpoint, fleet.autopilot.velocity_integral, fleet.autopilot.rate_integral,
            fleet.rotors.speeds, fleet.rotors.allocations, env.unwrapped.task.fan.noise,
        )  # fmt: skip
        for before, after in zip(parts, now, strict=True):
            assert after is before and np.shares_memory(after, fleet.compiled.buffer)
    finally:
        env.close()


@needs_numba
def test_one_vehicle_after_step_from_pybullets_tuples_equals_the_one_from_rows():
    """A single env's compiled step reads PyBullet's tuples (``World.read_first``) into
    ``after_world_step_one``; it fills the buffer exactly as ``after_world_step`` does from the row."""
    env = gym.make(FAN_TRACKING, backend="numba")
    try:
        env.reset(seed=0)
        env.step(np.zeros(4, dtype=np.float32))
        fleet = env.unwrapped.fleet
        compiled, world = fleet.compiled, fleet.world
        assert compiled.read_world == world.read_first
        readings, row = world.read_first(), world.read_flat()
        np.testing.assert_array_equal(row, np.concatenate([np.concatenate(part) for part in readings]))
        buffers, cursors = [], []
        step = compiled._step
        for kernel, read in ((step.after_world_step_one, readings), (step.after_world_step, row)):
            buffer, cursor = compiled.buffer.copy(), fleet.noise.cursor.copy()
            kernel(
                read,
                buffer,
                fleet.noise.buffer,
                cursor,
                compiled.constants,
                env.unwrapped.task.fan.motion_tables,
            )
            buffers.append(buffer)
            cursors.append(cursor)
        np.testing.assert_array_equal(buffers[0], buffers[1])
        np.testing.assert_array_equal(cursors[0], cursors[1])
        assert not np.array_equal(buffers[0], compiled.buffer)  # the step wrote something
    finally:
        env.close()


def _descend_until_terminated(backend: str) -> tuple[int, float]:
    """Fly straight down with no crash height until the episode ends; return the step and height.
    Checks on the way that no contact is reported above ``World.clear_height``."""
    env = gym.make(FAN_TRACKING, backend=backend, crash_height=-1.0, fan={"enabled": False})
    try:
        env.reset(seed=0, options={"offset_y": 0.0})
        world = env.unwrapped.world
        for step in range(1500):
            _, _, terminated, _, info = env.step(np.array((0.0, 0.0, -1.0, 0.0), dtype=np.float32))
            if world.crash_contacts().any():
                assert info["position"][2] < world.clear_height
            if terminated:
                assert info["termination_reason"] == "crash"
                return step, float(info["position"][2])
        raise AssertionError("the descent never touched the ground")
    finally:
        env.close()


def test_touching_the_ground_is_a_crash_on_both_backends():
    """With no crash height only the contact PyBullet reports ends a descent: the vehicle rests on
    its hull (box half height above the ground), and the compiled path, which asks for contacts only
    below ``World.clear_height``, ends it at the same step."""
    step, height = _descend_until_terminated("numpy")
    half_height = make_vehicle("ardrone2").hull_height / 2
    assert height < half_height + 0.02
    if NUMBA_AVAILABLE:
        assert _descend_until_terminated("numba") == pytest.approx((step, height), rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("count", [1, 3])
def test_step_views_cut_the_buffer_as_step_fields_say(count):
    """The engine's per-vehicle arrays are C-ordered views of one flat buffer in STEP_FIELDS order."""
    buffer = np.arange(count * STEP_WIDTH, dtype=float)
    start = 0
    for (name, width), view in zip(STEP_FIELDS, step_views(buffer, count), strict=True):
        np.testing.assert_array_equal(view.ravel(), buffer[start : start + count * width], err_msg=name)
        assert view.shape[0] == count and view.flags.c_contiguous and np.shares_memory(view, buffer), name
        start += count * width
    assert start == buffer.size
    with pytest.raises(ValueError, match="STEP_WIDTH"):
        step_views(buffer[:-1], count)


@pytest.mark.parametrize("shape", [(18, 25), (5, 3), (1, 1)])
def test_weighted_gram_is_the_symmetric_product_summed_in_order(shape):
    """``weighted_gram`` equals ``W Cᵀ`` to rounding and, to the bit, each entry summed over the
    columns in order as plain floats (what the UKF's SIMD lanes do: sums regrouped by the compiler
    would depend on the CPU's vector width), exactly symmetric, the same bits on every call."""
    rng = np.random.default_rng(1)
    columns = rng.standard_normal(shape)
    weighted = columns * rng.uniform(-0.5, 2.0, shape[1])
    out, again = np.full((shape[0],) * 2, np.nan), np.empty((shape[0],) * 2)
    weighted_gram(weighted, columns, out)
    weighted_gram(weighted, columns, again)
    np.testing.assert_allclose(out, weighted @ columns.T, rtol=1e-13, atol=1e-13 * shape[1])
    in_order = np.zeros_like(out)  # the lower triangle, mirrored
    for a, c in np.ndindex(out.shape):
        for j in range(shape[1]):
            in_order[a, c] += float(weighted[max(a, c), j]) * float(columns[min(a, c), j])
    np.testing.assert_array_equal(out, in_order)
    np.testing.assert_array_equal(out, out.T)
    np.testing.assert_array_equal(out, again)


def test_a_bound_kernel_reads_its_arrays_afresh_and_equals_the_plain_call():
    """``bind``: the compiled form for the bound arrays' types, on the arrays as they are at each call."""
    rng = np.random.default_rng(2)
    columns, out, expected = rng.standard_normal((4, 7)), np.empty((4, 4)), np.empty((4, 4))
    weighted = columns.copy()
    bound = bind(weighted_gram, weighted, columns, out)
    for _ in range(2):
        weighted *= rng.uniform(0.5, 1.5, 7)  # changed in place: the bound call sees it
        bound()
        weighted_gram(weighted, columns, expected)
        np.testing.assert_array_equal(out, expected)
    assert specialised(np.dot, columns, columns.T) is np.dot  # not a compiled kernel: itself


def test_physics_constants_are_packed_where_their_declaration_says():
    """Each named part of CONSTANT_FIELDS at its declared offset, the drag points after them, then
    each component's numbers where ``component_slice`` finds them."""
    rng = np.random.default_rng(0)
    widths = dict(CONSTANT_FIELDS)
    parts = {name: rng.random(width) for name, width in CONSTANT_FIELDS if name != "drag_point_count"}
    points = rng.random((9, 3))
    packed = physics_constants(parts, points)
    for name, start in offsets(CONSTANT_FIELDS).items():
        expected = 9 if name == "drag_point_count" else parts[name]
        np.testing.assert_array_equal(packed[start : start + widths[name]], np.ravel(expected), err_msg=name)
    np.testing.assert_array_equal(drag_points(packed), points)
    components = [rng.random(7), np.zeros(0), rng.random(16)]
    full = component_parameters(packed, components)
    np.testing.assert_array_equal(full[: packed.size], packed)
    for k, numbers in enumerate(components):
        np.testing.assert_array_equal(component_slice(full, k), numbers)
    assert sum(widths.values()) == CONSTANT_WIDTH
    with pytest.raises(ValueError, match="scales has 9 numbers; the kernels read 10"):
        physics_constants({**parts, "scales": rng.random(9)}, points)


@pytest.mark.parametrize("name", ["ukf", "ekf", "observer"])
def test_a_bound_step_reads_its_arrays_afresh_and_equals_step(name):
    """``bind_step`` (what the compiled env step calls) gives exactly what ``step`` gives with the
    same inputs, refilled in place between calls, and refuses a non-finite one by name."""
    vehicle, count = make_vehicle("ardrone2"), 3
    stepped, bound = (make_estimator_bank(name, vehicle, 0.005, count) for _ in range(2))
    rng = np.random.default_rng(2)
    thrusts, torques = np.full(count, vehicle.mass * GRAVITY), np.zeros((count, 3))
    positions, quaternions = np.zeros((count, 3)), np.tile((1.0, 0.0, 0.0, 0.0), (count, 1))
    for bank in (stepped, bound):
        for i in range(count):
            bank.reset(i, positions[i], quaternions[i])
    step = bound.bind_step(thrusts, torques, positions, quaternions)
    for _ in range(50):
        thrusts[:] = vehicle.mass * GRAVITY + 0.1 * rng.normal(size=count)
        positions[:] = 1e-3 * rng.normal(size=(count, 3))
        quaternions[:] = quat_exp(2e-3 * rng.normal(size=(count, 3)))
        stepped.step(thrusts, torques, positions, quaternions)
        step()
    np.testing.assert_array_equal(bound.wrenches(), stepped.wrenches())
    np.testing.assert_array_equal(bound.states(), stepped.states())
    positions[1, 2] = np.nan
    with pytest.raises(ValueError, match=r"non-finite input\(s\) \['positions'\]"):
        step()
    assert np.isfinite(bound.states()).all()


def test_a_ukf_whose_state_overflows_restarts_from_the_measured_pose():
    """A filter whose state leaves the finite numbers (here a force of 1e308 N) restarts at rest at
    the measured pose and reports it; its neighbour in the bank is untouched."""
    vehicle = make_vehicle("ardrone2")
    bank = make_estimator_bank("ukf", vehicle, 0.005, 2)
    level = np.array((1.0, 0.0, 0.0, 0.0))
    for i in range(2):
        bank.reset(i, np.zeros(3), level)
    bank.rests[1, 12] = 1e308
    measured = np.array(((0.0, 0.0, 0.0), (0.5, -0.2, 1.0)))
    with np.errstate(over="ignore", invalid="ignore"):
        bank.step(np.full(2, vehicle.mass * GRAVITY), np.zeros((2, 3)), measured, np.tile(level, (2, 1)))
    assert bank.statuses() == ["ok", "reinitialised"]
    np.testing.assert_array_equal(bank.states()[1, :3], measured[1])
    assert np.isfinite(bank.covariances).all() and np.isfinite(bank.rests).all()

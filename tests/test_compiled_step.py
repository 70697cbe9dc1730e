"""The compiled physics step's plumbing: the step buffer and its views, the constants' packing, the
bound kernels, the single env's PyBullet tuples, the motion capture's delay line, contacts; the
estimator banks' bound step and restart. The physics the kernels compute is checked against
references written apart from them (``tests/test_reference_*.py``, ``tests/test_physics.py``,
``tests/test_disturbances.py``, ...)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

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
from quad_wrench_env.estimators.bank import EstimatorInputs
from quad_wrench_env.numerics import bind, specialised
from quad_wrench_env.numerics.linalg import weighted_gram
from quad_wrench_env.rotations import quat_exp
from quad_wrench_env.vehicle import GRAVITY, make_vehicle
from tests.conftest import FAN_TRACKING


def test_the_components_state_stays_in_the_compiled_steps_buffer():
    """The autopilot's, rotors', fan's and motion capture's state are views of the compiled step's one
    buffer (one kernel argument), through steps and resets."""
    env = gym.make(FAN_TRACKING, sensors={"latency_steps": 2})
    try:
        fleet = env.unwrapped.fleet
        parts = (
            fleet.autopilot.yaw_setpoint,
            fleet.autopilot.velocity_integral,
            fleet.autopilot.rate_integral,
            fleet.rotors.speeds,
            fleet.rotors.allocations,
            env.unwrapped.task.fan.noise,
            fleet.mocap.delay_line,
        )
        for seed in (0, 1):
            env.reset(seed=seed)
            env.step(np.full(4, 0.3, dtype=np.float32))
        now = (
            fleet.autopilot.yaw_setpoint,
            fleet.autopilot.velocity_integral,
            fleet.autopilot.rate_integral,
            fleet.rotors.speeds,
            fleet.rotors.allocations,
            env.unwrapped.task.fan.noise,
            fleet.mocap.delay_line,
        )
        for before, after in zip(parts, now, strict=True):
            assert after is before and np.shares_memory(after, fleet.compiled.buffer)
    finally:
        env.close()


def test_one_vehicle_after_step_from_pybullets_tuples_equals_the_one_from_rows():
    """A single env's compiled step reads PyBullet's tuples (``World.read_first``) into
    ``after_world_step_one``; it fills the buffer exactly as ``after_world_step`` does from the row."""
    env = gym.make(FAN_TRACKING)
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


def test_touching_the_ground_is_a_crash():
    """With no crash height only the contact PyBullet reports ends a descent: the vehicle rests on
    its hull (box half height above the ground); the compiled step asks for contacts only below
    ``World.clear_height``, and none is reported above it on the way down."""
    env = gym.make(FAN_TRACKING, crash_height=-1.0, fan={"enabled": False})
    try:
        env.reset(seed=0, options={"offset_y": 0.0})
        world = env.unwrapped.world
        for _ in range(1500):
            _, _, terminated, _, info = env.step(np.array((0.0, 0.0, -1.0, 0.0), dtype=np.float32))
            if world.crash_contacts().any():
                assert info["position"][2] < world.clear_height
            if terminated:
                assert info["termination_reason"] == "crash"
                break
        else:
            raise AssertionError("the descent never touched the ground")
    finally:
        env.close()
    assert info["position"][2] < make_vehicle("ardrone2").hull_height / 2 + 0.02


@pytest.mark.parametrize("latency", [0, 1, 3])
def test_the_motion_capture_sees_the_pose_latency_physics_steps_old(latency):
    """Noise-free motion capture with ``latency_steps`` L, one physics step per policy step: the pose
    the estimators are handed after step k is the true pose after step k - L (the start pose until L
    steps have passed), through a reset of the episode. Catches a delay line that hands out the
    current pose, the newest instead of the oldest, or keeps the last episode's poses."""
    quiet = {"position_noise": 0.0, "attitude_noise": 0.0, "latency_steps": latency}
    env = gym.make(FAN_TRACKING, policy_hz=200, estimator="oracle", sensors=quiet)
    try:
        fleet = env.unwrapped.fleet
        actions = np.random.default_rng(0).uniform(-1.0, 1.0, (12, 4)).astype(np.float32)
        for seed in (0, 1):
            env.reset(seed=seed)
            truth = [(fleet.state.position[0].copy(), fleet.state.quaternion[0].copy())]
            for k, action in enumerate(actions, start=1):
                env.step(action)
                truth.append((fleet.state.position[0].copy(), fleet.state.quaternion[0].copy()))
                position, quaternion = truth[max(k - latency, 0)]
                fields = fleet.step_buffer.fields
                np.testing.assert_array_equal(fields["measured_position"][0], position)
                np.testing.assert_allclose(fields["measured_quaternion"][0], quaternion, atol=1e-15)
            assert not np.array_equal(truth[-1][0], truth[-1 - latency][0]) or latency == 0  # it moved
    finally:
        env.close()


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
    step = bound.bind_step(EstimatorInputs(thrusts, torques, positions, quaternions))
    for _ in range(50):
        thrusts[:] = vehicle.mass * GRAVITY + 0.1 * rng.normal(size=count)
        positions[:] = 1e-3 * rng.normal(size=(count, 3))
        quaternions[:] = quat_exp(2e-3 * rng.normal(size=(count, 3)))
        stepped.step(EstimatorInputs(thrusts, torques, positions, quaternions))
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
        bank.step(
            EstimatorInputs(
                np.full(2, vehicle.mass * GRAVITY), np.zeros((2, 3)), measured, np.tile(level, (2, 1))
            )
        )
    assert bank.statuses() == ["ok", "reinitialised"]
    np.testing.assert_array_equal(bank.states()[1, :3], measured[1])
    assert np.isfinite(bank.covariances).all() and np.isfinite(bank.rests).all()


def test_the_debugging_mode_runs_the_same_kernels_as_plain_python():
    """Under numba's ``NUMBA_DISABLE_JIT=1`` (the documented debugging mode, where the removed
    ``backend`` key points) each task's env, with motion-capture latency and a vector env of two,
    flies on its kernels as plain Python and gives the compiled numbers to rounding (libm against
    numba's math: 1e-9 relative on the wrench estimate and the observation, float32)."""
    script = (
        "import json, sys, numpy as np, gymnasium as gym, quad_wrench_env\n"
        "from quad_wrench_env.numerics import COMPILED\n"
        "out = {'compiled': COMPILED}\n"
        "for env_id in quad_wrench_env.ENV_IDS:\n"
        "    env = gym.make_vec(env_id, num_envs=2, vectorization_mode='vector_entry_point',\n"
        "                       sensors={'latency_steps': 2})\n"
        "    obs, info = env.reset(seed=3)\n"
        "    for _ in range(10):\n"
        "        obs, *_, info = env.step(np.full((2, 4), 0.2, dtype=np.float32))\n"
        "    out[env_id] = [obs.tolist(), info['wrench_est'].tolist()]\n"
        "    env.close()\n"
        "print(json.dumps(out))\n"
    )
    runs = {}
    for mode in ("0", "1"):
        environment = {**os.environ, "NUMBA_DISABLE_JIT": mode}
        done = subprocess.run(
            [sys.executable, "-c", script], env=environment, capture_output=True, text=True, timeout=600
        )
        assert done.returncode == 0, done.stderr[-3000:]
        runs[mode] = json.loads(done.stdout.strip().splitlines()[-1])
    assert runs["0"].pop("compiled") and not runs["1"].pop("compiled")
    assert runs["0"].keys() == runs["1"].keys() and len(runs["0"]) == 3
    for env_id, (observation, estimate) in runs["0"].items():
        plain_observation, plain_estimate = runs["1"][env_id]
        np.testing.assert_allclose(plain_observation, observation, rtol=1e-6, atol=1e-6, err_msg=env_id)
        np.testing.assert_allclose(plain_estimate, estimate, rtol=1e-9, atol=1e-12, err_msg=env_id)

"""The world against analytic answers, without the autopilot.

PyBullet integrates with semi-implicit Euler: after n steps from rest under a constant acceleration a
the displacement is a·dt²·n(n+1)/2 instead of a·(n·dt)²/2, a relative error of 1/n (0.5 % after 1 s
at 200 Hz). The 1 % tolerance is that bound with room, not a tuned number.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from quad_wrench_env.engine.world import World
from quad_wrench_env.rotations import quat_from_euler_zyx
from quad_wrench_env.rotors import Rotors
from quad_wrench_env.vehicle import GRAVITY, make_vehicle
from tests.conftest import controls_on_a_copy

DT = 1.0 / 200.0
STEPS = 200


@pytest.fixture
def world():
    w = World(make_vehicle("ardrone2"), DT)
    w.place(np.array((0,)), np.array(((0.0, 0.0, 50.0),)), np.array(((1.0, 0.0, 0.0, 0.0),)))
    yield w
    w.close()


def _fly(world: World, force: np.ndarray, torque: np.ndarray, steps: int = STEPS):
    """Fly the world's one body under a constant world-frame force and torque; its final state."""
    for _ in range(steps):
        world.step(force[None], torque[None], world.state().position)
    return world.state().select(0)


def test_bodies_in_one_spot_never_touch():
    """Two bodies put in the same place under the same loads move exactly as one alone: collision
    groups keep vehicles from touching each other."""
    vehicle = make_vehicle("ardrone2")
    pair, alone = World(vehicle, DT, count=2), World(vehicle, DT)
    try:
        start, level = np.array(((0.0, 0.0, 2.0),)), np.array(((1.0, 0.0, 0.0, 0.0),))
        pair.place(np.array((0, 1)), np.repeat(start, 2, axis=0), np.repeat(level, 2, axis=0))
        alone.place(np.array((0,)), start, level)
        force, torque = np.array((0.4, -0.3, vehicle.mass * GRAVITY)), np.array((1e-3, -2e-3, 5e-4))
        for _ in range(100):
            pair.step(np.tile(force, (2, 1)), np.tile(torque, (2, 1)), pair.state().position)
            alone.step(force[None], torque[None], alone.state().position)
        both, one = pair.read(), alone.read()
        np.testing.assert_array_equal(both[0], both[1])
        np.testing.assert_array_equal(both[0], one[0])
    finally:
        pair.close()
        alone.close()


def test_one_vehicle_step_and_read_equal_the_array_forms():
    """``step_one`` and ``read_first`` (the single env's compiled path) move and read the body exactly
    as ``step`` and ``read_flat``; ``step_one`` refuses a world of more vehicles by its count."""
    vehicle = make_vehicle("ardrone2")
    worlds = arrays, one = World(vehicle, DT), World(vehicle, DT)
    try:
        start, tilted = np.array(((0.0, 0.0, 2.0),)), quat_from_euler_zyx(0.3, -0.2, 0.1)[None]
        for w in worlds:
            w.place(np.array((0,)), start, tilted)
        force, torque = np.array((0.4, -0.3, vehicle.mass * GRAVITY)), np.array((1e-3, -2e-3, 5e-4))
        for _ in range(50):
            arrays.step(force[None], torque[None], arrays.state().position)
            one.step_one(tuple(force), tuple(torque), one.read_first()[0][0])
        (position, orientation), (linear, angular) = one.read_first()
        np.testing.assert_array_equal(arrays.read_flat(), position + orientation + linear + angular)
    finally:
        for w in worlds:
            w.close()
    pair = World(vehicle, DT, count=2)
    try:
        with pytest.raises(ValueError, match="this world has 2"):
            pair.step_one((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    finally:
        pair.close()


def test_free_fall(world):
    state = _fly(world, np.zeros(3), np.zeros(3))
    t = STEPS * DT
    assert 50.0 - state.position[2] == pytest.approx(0.5 * GRAVITY * t * t, rel=0.01)
    assert state.velocity[2] == pytest.approx(-GRAVITY * t, rel=0.01)


def test_pure_thrust_climbs_at_the_net_acceleration(world):
    mass = world.vehicle.mass
    state = _fly(world, np.array((0.0, 0.0, 2.0 * mass * GRAVITY)), np.zeros(3))
    t = STEPS * DT
    assert state.position[2] - 50.0 == pytest.approx(0.5 * GRAVITY * t * t, rel=0.01)
    np.testing.assert_allclose(state.position[:2], 0.0, atol=1e-9)


def test_torque_is_applied_in_the_world_frame():
    """Yawed by 90°, a torque about world x turns the body about its own y axis (inertia J_y)."""
    vehicle = make_vehicle("ardrone2")
    w = World(vehicle, DT)
    try:
        w.place(
            np.array((0,)), np.array(((0.0, 0.0, 50.0),)), quat_from_euler_zyx(0.0, 0.0, math.pi / 2.0)[None]
        )
        tau = 1e-3
        state = _fly(w, np.zeros(3), np.array((tau, 0.0, 0.0)), steps=20)
        expected = tau / vehicle.inertia[1] * 20 * DT
        np.testing.assert_allclose(state.angular_velocity, (expected, 0.0, 0.0), rtol=0.01, atol=1e-6)
    finally:
        w.close()


def test_motor_lag_is_first_order(make_env):
    """The engine's motors (``controls`` kernel, the ``motors`` action): one time constant towards a
    command closes 1 - 1/e of the gap, up and down with their own constants, exactly for the discrete
    lag; a command beyond the range stops at the motors' limit."""
    vehicle = make_vehicle("hummingbird", motor_time_constant_up=0.05, motor_time_constant_down=0.1)
    lags = {"motor_time_constant_up": 0.05, "motor_time_constant_down": 0.1}
    env = make_env(
        vehicle="hummingbird",
        action_type="motors",
        estimator="oracle",
        fan={"enabled": False},
        vehicle_params=lags,
    )
    env.reset(seed=0)
    fleet = env.unwrapped.fleet
    buffer = fleet.step_buffer.array.copy()
    speeds = controls_on_a_copy(fleet, np.zeros((1, 4)), False, buffer)["speeds"]  # a view of ``buffer``
    speeds[:] = 300.0
    command = np.full((1, 4), 2.0 * 700.0 / vehicle.max_rotor_speed - 1.0)  # 700 rad/s
    for _ in range(10):  # one time constant up
        controls_on_a_copy(fleet, command, False, buffer)
    np.testing.assert_allclose(speeds, 300.0 + 400.0 * (1 - math.exp(-1)), rtol=1e-9)
    start, low = speeds.copy(), vehicle.min_rotor_speed
    for _ in range(20):  # one time constant down, towards the lowest speed
        controls_on_a_copy(fleet, np.full((1, 4), -1.0), False, buffer)
    np.testing.assert_allclose(speeds, low + (start - low) * math.exp(-1), rtol=1e-9)
    for _ in range(400):
        controls_on_a_copy(fleet, np.ones((1, 4)), False, buffer)
    np.testing.assert_allclose(speeds, vehicle.max_rotor_speed, rtol=1e-12)


def test_rotor_drag_decelerates_as_specified():
    vehicle = make_vehicle("ardrone2")
    rotors = Rotors(vehicle, DT)
    rotors.reset(0, np.random.default_rng(0), 0.0)
    drag = rotors.drag_forces(np.tile((1.0, 0.0, 0.5), (1, 4, 1)), np.array(((0.0, 0.0, 1.0),)))
    total = drag[0].sum(axis=0)
    np.testing.assert_allclose(total / vehicle.mass, (-vehicle.rotor_drag_decel, 0.0, 0.0))


def test_per_rotor_coefficients_spread_as_configured():
    vehicle = make_vehicle("ardrone2")
    rotors = Rotors(vehicle, DT)
    draws = []
    for seed in range(300):
        rotors.reset(0, np.random.default_rng(seed), 0.02)
        draws.append(rotors.allocations[0, 0] / vehicle.kf - 1.0)  # row 0 of the allocation: k_i
    # 1200 draws of N(0, 0.02²): the sample sd is within ~4 % of 0.02 with overwhelming probability
    assert np.std(draws) == pytest.approx(0.02, rel=0.1)

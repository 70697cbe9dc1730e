"""Hentzen et al.'s (2019) PID (``quad_wrench_env/agents/pid.py``) against hand computations (issue 33): its
integral term held within the documented bound g·tan 30° through a long saturation and unwinding at once
afterwards, eq. (3) term by term, and the gains of one bandwidth with their cap. The observations are written
by hand into a real env's layout; the integral term is read from the public ``desired_acceleration``
(eq. (3) minus its proportional, derivative and feed-forward parts, computed here)."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from quad_wrench_env.agents.pid import PIDPolicy
from quad_wrench_env.autopilot import AutopilotGains
from quad_wrench_env.vehicle import GRAVITY

ENV_ID = "QuadWrench/DisturbanceRejection-v0"
DT = 1.0 / 50.0  # the policy step (policy_hz 50)
G_TAN_30 = GRAVITY * math.tan(math.radians(30.0))
"""The documented bound on each axis' integral term (m/s²): the force the 30° tilt limit can hold."""


@pytest.fixture
def env():
    env = gym.make(ENV_ID, estimator="oracle")
    env.reset(seed=0, options={"scenario": "gusts"})
    yield env
    env.close()


def _observation(
    env,
    position,
    velocity=(0.0, 0.0, 0.0),
    reference=None,
    reference_velocity=(0.0, 0.0, 0.0),
    force=(0.0, 0.0, 0.0),
) -> np.ndarray:
    """A level observation with these blocks (every number exact in float32)."""
    layout = env.unwrapped.obs_layout
    obs = np.zeros(env.observation_space.shape, dtype=np.float32)
    obs[layout["attitude"]] = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0)
    obs[layout["position"]] = position
    obs[layout["velocity"]] = velocity
    obs[layout["reference_position"]] = position if reference is None else reference
    obs[layout["reference_velocity"]] = reference_velocity
    obs[layout["force"]] = force
    return obs


def test_the_integral_term_stays_within_g_tan_30_and_unwinds_at_once(env):
    """A 2 m, -1 m and 0.5 m position error held for 12 s (the vehicle stuck, as under a saturated
    tilt): the integral term ``k_i·∫e`` accumulates ``k_i·e·dt`` per step until it reaches the bound
    and stays there, on every axis (the accumulated integral is clamped, not its increment, which
    would let it grow to k_i·e·12 s = 36 m/s²); then the error reverses and the term leaves the bound
    on the very next step and falls at ``k_i·|e|`` per second (no wind-up stored beyond the bound to
    unwind first): x crosses zero after L/(k_i·2 m) = 1.9 s, not 12 s."""
    k_p, k_d, k_i = 4.0, 3.5, 1.5
    policy = PIDPolicy(k_p_xy=k_p, k_d_xy=k_d, k_i_xy=k_i, k_p_z=k_p, k_d_z=k_d, k_i_z=k_i)
    limit = policy.gains.max_integral_acceleration
    assert limit == pytest.approx(G_TAN_30, abs=5e-3)  # the default is the documented g·tan 30°
    policy.reset(env)
    position, reference = np.array((2.5, 0.0, 1.5)), np.array((4.5, -1.0, 2.0))
    expected = np.zeros(3)
    # 12 s 2 m short of the reference, then 6 s as far beyond it (the same error the other way)
    for phase, (where, target, steps) in enumerate(((position, reference, 600), (reference, position, 300))):
        obs = _observation(env, where, reference=target)
        error = target - where
        for step in range(steps):
            integral = policy.desired_acceleration(obs) - k_p * error  # no velocity error, no a_ref
            expected = np.clip(expected + k_i * error * DT, -limit, limit)
            assert np.all(np.abs(integral) <= limit + 1e-12), (phase, step, integral)
            np.testing.assert_allclose(integral, expected, rtol=0, atol=1e-12, err_msg=f"{phase}, {step}")
            if phase == 1 and step == 0:  # off the bound at once, by one step's increment
                np.testing.assert_allclose(integral, [limit - 0.06, -limit + 0.03, limit - 0.015], atol=1e-12)
            if phase == 1 and step == math.ceil(limit / 0.06) - 1:
                assert integral[0] < 0.0  # through zero after ~1.9 s
        if phase == 0:
            np.testing.assert_allclose(integral, [limit, -limit, limit], atol=1e-12)  # held at the bound


@pytest.mark.parametrize("feedforward", [True, False])
def test_equation_3_term_by_term(env, feedforward):
    """Two steps of eq. (3) with every term non-zero, per axis gains: ``a_des = k_p·e_p + k_d·e_v +
    k_i·∫e_p - f̂/m (+ a_ref)``, ``e = reference - estimate``, the integral a rectangle sum of dt
    per step, ``a_ref`` the observed reference velocity's difference over dt (0 on the first step).
    Catches a sign of any term, the integral without dt or one step late, the force not divided by
    the mass, the feed-forward on when it is off."""
    gains = {"k_p_xy": 2.0, "k_d_xy": 1.5, "k_i_xy": 0.5, "k_p_z": 3.0, "k_d_z": 2.5, "k_i_z": 0.25}
    policy = PIDPolicy(compensation=True, feedforward=feedforward, **gains)
    policy.reset(env)
    mass = env.unwrapped.vehicle.mass
    k_p, k_d, k_i = (np.array((gains[f"k_{n}_xy"], gains[f"k_{n}_xy"], gains[f"k_{n}_z"])) for n in "pdi")
    integral = np.zeros(3)
    previous_reference_velocity = None
    steps = [
        ((2.5, 0.25, 1.5), (0.5, -0.25, 0.125), (2.75, 0.0, 1.25), (0.25, 0.5, -0.5), (0.5, -0.75, 0.25)),
        ((2.5, 0.375, 1.5), (0.25, 0.0, -0.125), (2.5, 0.125, 1.75), (0.5, 0.25, -0.25), (-0.25, 0.5, 1.0)),
    ]
    for position, velocity, reference, reference_velocity, force in steps:
        obs = _observation(env, position, velocity, reference, reference_velocity, force)
        e_p = np.array(reference) - np.array(position)
        e_v = np.array(reference_velocity) - np.array(velocity)
        integral = integral + k_i * e_p * DT
        a_ref = (
            np.zeros(3)
            if previous_reference_velocity is None
            else (np.array(reference_velocity) - previous_reference_velocity) / DT
        )
        previous_reference_velocity = np.array(reference_velocity)
        expected = k_p * e_p + k_d * e_v + integral - np.array(force) / mass + (a_ref if feedforward else 0.0)
        np.testing.assert_allclose(policy.desired_acceleration(obs), expected, rtol=1e-12, atol=1e-12)


def test_one_bandwidth_gives_the_documented_gains_and_is_capped(env):
    """``bandwidth`` λ: ``k_p = λ²``, ``k_d = 2λ``, ``k_i = λ³/50``, with λ lowered at reset to a third
    of the vehicle's attitude-loop gain where above (5/s on hummingbird). Checked on eq. (3)'s first
    step with position and velocity errors: ``a_des = λ²·e_p + 2λ·e_v + λ³/50·e_p·dt``."""
    vehicle = env.unwrapped.vehicle
    cap = AutopilotGains.for_vehicle(vehicle).attitude_p / 3.0
    assert cap == pytest.approx(5.0, abs=0.05)
    for asked, used in ((3.5, 3.5), (20.0, cap)):
        policy = PIDPolicy(bandwidth=asked)
        policy.reset(env)
        assert policy.bandwidth == pytest.approx(used, rel=1e-12)
        obs = _observation(env, (2.5, 0.0, 1.5), (0.25, -0.5, 0.125), (3.0, 0.25, 1.25))
        e_p, e_v = np.array((0.5, 0.25, -0.25)), -np.array((0.25, -0.5, 0.125))
        expected = used**2 * e_p + 2.0 * used * e_v + used**3 / 50.0 * e_p * DT
        np.testing.assert_allclose(policy.desired_acceleration(obs), expected, rtol=1e-12, atol=1e-12)


def test_the_tilt_limit_keeps_the_vertical_channel():
    """Where roll or pitch passes the limit, both are clipped to it and the thrust keeps the vertical
    force, ``T cos φ cos θ = m (a_z + g)`` (the body z axis's vertical part at any heading); below the
    limit the attitude is the unlimited one, to the bit."""
    from quad_wrench_env.control.guidance import attitude_from_acceleration

    mass, limit = 0.7, math.radians(30.0)
    for yaw in (0.0, 0.4, -2.0):
        for acceleration in (np.array((30.0, -20.0, 1.0)), np.array((0.0, -40.0, -2.0))):
            thrust, roll, pitch = attitude_from_acceleration(acceleration, yaw, mass, limit)
            assert max(abs(roll), abs(pitch)) <= limit + 1e-15
            assert thrust * math.cos(roll) * math.cos(pitch) == pytest.approx(
                mass * (acceleration[2] + GRAVITY)
            )
        small = np.array((1.0, 0.5, 0.2))
        assert attitude_from_acceleration(small, yaw, mass, limit) == attitude_from_acceleration(
            small, yaw, mass
        )

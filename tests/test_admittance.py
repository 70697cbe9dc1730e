"""McKinnon & Schoellig's (2016) admittance fan tracker with the true and the UKF-estimated wrench (Sec. V,
Fig. 7)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from quad_wrench_env.agents import make_agent
from quad_wrench_env.agents.admittance import TORQUE_SLOPES, AdmittancePolicy
from quad_wrench_env.agents.base import Policy
from quad_wrench_env.agents.evaluate import evaluate
from quad_wrench_env.engine.world import RigidBodyState
from quad_wrench_env.rotations import quat_from_euler_zyx
from quad_wrench_env.vehicle import PRESETS
from tests.conftest import FAN_TRACKING

GAINS = {"bandwidth": 2.1, "k_xy": 1.0, "k_z": 1.0, "k_yaw": 1.0}  # configs/fan_tracking.yaml


def test_conforms_to_the_policy_interface():
    assert isinstance(AdmittancePolicy(), Policy)


@pytest.mark.parametrize("estimator", ["oracle", "ukf"])
def test_reaches_the_axis_of_a_static_fan_from_0_8_m_within_15_s(estimator):
    result = evaluate(
        make_agent("admittance", **GAINS),
        FAN_TRACKING,
        seeds=[0, 1, 2],
        options={"fan_motion": "static", "offset_y": 0.8},
        estimator=estimator,
        episode_seconds=15.0,
    )
    for metrics in result.per_seed:
        assert metrics["time_to_0.15m"] <= 15.0
        assert metrics["terminated_early"] == 0.0


@pytest.mark.parametrize(("estimator", "offset_y"), [("oracle", 0.8), ("ukf", 0.8), ("ukf", -0.8)])
def test_follows_a_fan_moving_at_0_1_m_per_s(estimator, offset_y):
    result = evaluate(
        make_agent("admittance", **GAINS),
        FAN_TRACKING,
        seeds=[0, 1],
        options={"fan_motion": {"name": "constant_speed", "speed": 0.1, "y0": -1.5}, "offset_y": offset_y},
        estimator=estimator,
    )
    for metrics in result.per_seed:
        assert metrics["terminated_early"] == 0.0
        assert metrics["mean_abs_error_after_5s"] < 0.2


def test_without_the_torque_feedback_it_does_not_track():
    """The tracking comes from tau_z: with k_p = 0 the vehicle stays where it started."""
    result = evaluate(
        make_agent("admittance", **{**GAINS, "k_p": 0.0}),
        FAN_TRACKING,
        seeds=[0],
        options={"fan_motion": "static", "offset_y": 0.8},
        estimator="oracle",
        episode_seconds=15.0,
    )
    assert result.per_seed[0]["mean_abs_error_after_5s"] > 0.5
    assert math.isinf(result.per_seed[0]["time_to_0.15m"])


@pytest.mark.parametrize("vehicle", sorted(PRESETS))
def test_torque_slopes_match_the_jet_and_drag_model(make_env, vehicle):
    """The design slopes dτ_z/dy behind the derived gains, by central difference of the mean-flow
    loads 2 cm either side of the axis at the stand-off (the slope's curvature over ±2 cm is < 1 %)."""
    env = make_env(vehicle=vehicle, fan={"motion": "static"}).unwrapped
    env.reset(seed=0, options={"offset_y": 0.0})
    q = quat_from_euler_zyx(0.0, 0.0, math.pi)[None]
    tau_z = [
        env.fleet.external_loads(
            RigidBodyState.at_rest(np.array(((2.3, y, 1.0),)), q), np.array((0,)), mean=True
        )[0, 5]
        for y in (-0.02, 0.02)
    ]
    assert (tau_z[1] - tau_z[0]) / 0.04 == pytest.approx(TORQUE_SLOPES[vehicle], rel=0.02)


@pytest.mark.parametrize("vehicle", sorted(PRESETS))
def test_gain_is_derived_per_preset_for_one_loop_rate(make_env, vehicle):
    env = make_env(vehicle=vehicle)
    env.reset(seed=0)
    policy = AdmittancePolicy()
    policy.reset(env)
    assert policy.k_p * TORQUE_SLOPES[vehicle] == pytest.approx(-2.1)
    assert AdmittancePolicy(k_p=-5.0).k_p == -5.0


def test_refuses_other_action_types(make_env):
    env = make_env(action_type="attitude")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="'attitude'"):
        AdmittancePolicy().reset(env)


def test_bad_gain_names_are_refused():
    with pytest.raises(ValueError, match="'admittance.kp'"):
        make_agent("admittance", kp=1.0)
    with pytest.raises(ValueError, match="unknown agent 'lqr'"):
        make_agent("lqr")


def test_command_is_the_papers_law(make_env):
    env = make_env()
    obs, _ = env.reset(seed=0, options={"offset_y": 0.0, "fan_motion": "static"})
    policy = AdmittancePolicy(k_p=-20.0)
    policy.reset(env)
    policy.act(obs)  # latches the references at the start pose
    layout = env.unwrapped.obs_layout
    obs = obs.copy()
    obs[layout["torque"]] = (0.0, 0.0, 0.01)
    action = policy.act(obs)
    limits = env.unwrapped.cfg.action_limits
    assert action[1] * limits.max_speed_xy == pytest.approx(-20.0 * 0.01, rel=1e-6)
    np.testing.assert_allclose(action[[0, 2, 3]], 0.0, atol=1e-6)

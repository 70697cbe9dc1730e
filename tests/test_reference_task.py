"""FanTracking's reward, its episode ends and the vector env's autoreset against hand computations
(issue 21): every expected number is computed here from the task's docstring, not by the package."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from tests.conftest import FAN_TRACKING

STANDOFF = 2.3  # standoff_distance (m)
FAN_HEIGHT = 1.0  # FanConfig.height (m)
AXIS_SCALE, STANDOFF_WEIGHT, EFFORT_WEIGHT, CRASH_PENALTY = 0.5, 1.0, 0.01, 10.0  # FanTrackingReward
QUIET = {"estimator": "oracle", "kf_spread": 0.0}


def _expected_terms(position: np.ndarray, fan_y: float, action: np.ndarray, ended: bool) -> dict[str, float]:
    """The reward table of the task's docstring for a static fan at ``fan_y`` (its retarded axis is
    where the fan is), with d the y-z distance from the axis, height error included."""
    d = math.hypot(position[1] - fan_y, position[2] - FAN_HEIGHT)
    a = np.clip(action, -1.0, 1.0)
    return {
        "tracking": math.exp(-d / AXIS_SCALE),
        "standoff": -STANDOFF_WEIGHT * abs(position[0] - STANDOFF),
        "effort": -EFFORT_WEIGHT * float(np.mean(a * a)),
        "crash": -CRASH_PENALTY if ended else 0.0,
    }


def test_reward_terms_by_hand(make_env):
    """Off the axis sideways and in height and off the stand-off (a climb and a drift along x first),
    the four terms and the reward equal the table's formulas. Catches a tracking term that ignores the
    height error or uses y alone, a wrong axis scale, a stand-off term with the wrong sign or
    reference, an effort on the unclipped action or summed instead of averaged, a crash penalty
    outside an early end."""
    env = make_env(**QUIET, fan={"motion": "static"})
    fan_y = 0.3
    env.reset(seed=3, options={"fan_motion": {"name": "static", "y0": fan_y}, "offset_y": 0.5})
    climb = np.array((0.8, 0.3, 1.0, -0.2))
    for _ in range(40):  # 0.8 s: up ~0.3 m, along +x and +y
        env.step(climb)
    action = np.array((1.7, -0.4, 0.25, -1.2))  # two components beyond [-1, 1]: clipped
    _, reward, terminated, truncated, info = env.step(action)
    assert not (terminated or truncated)
    position = np.asarray(info["position"])
    # the case is off the axis in height and off the stand-off by more than rounding
    assert abs(position[2] - FAN_HEIGHT) > 0.1 and abs(position[0] - STANDOFF) > 0.05
    expected = _expected_terms(position, fan_y, action, ended=False)
    assert info["reward_terms"].keys() == expected.keys()
    for name, value in expected.items():
        # the same formulas on the same float64 numbers: rounding only
        assert info["reward_terms"][name] == pytest.approx(value, rel=1e-9, abs=1e-12), name
    assert reward == pytest.approx(sum(expected.values()), rel=1e-9)
    assert info["jet_axis_y"] == pytest.approx(fan_y, abs=1e-12)
    assert info["axis_error"] == pytest.approx(position[1] - fan_y, abs=1e-12)


def _run(env, action, steps: int):
    """Step until the episode ends or ``steps`` pass; the last step's return."""
    for _ in range(steps):
        out = env.step(np.asarray(action, dtype=float))
        if out[2] or out[3]:
            return out
    return out


@pytest.mark.parametrize(
    ("name", "settings", "options", "action", "steps"),
    [
        # velocity down at 0.5 m/s from 1 m: below crash_height (0.1 m) in ~2 s
        ("crash", {}, {}, (0.0, 0.0, -1.0, 0.0), 200),
        # a crash height of 0.6 m ends the same descent 0.5 m above the ground, before any contact
        ("crash", {"crash_height": 0.6}, {}, (0.0, 0.0, -1.0, 0.0), 200),
        # full roll torque: ~120 rad/s² tips past 30° in ~0.15 s, long before the height changes
        ("flip", {"action_type": "wrench", "flip_tilt_deg": 30.0}, {}, (0.0, 1.0, 0.0, 0.0), 50),
        # and past the default 90° (upside down), still before it falls the 0.9 m to the ground
        ("flip", {"action_type": "wrench"}, {}, (0.0, 0.0, -1.0, 0.0), 50),
        # +x at 1 m/s from 2.3 m out of x_max = 2.8 m
        ("out_of_arena", {"arena": {"x_max": 2.8}}, {}, (1.0, 0.0, 0.0, 0.0), 150),
        # +y at 1 m/s from y = 2.8 m out of y_half_width = 3.2 m (the smallest the task allows is 3.06)
        ("out_of_arena", {"arena": {"y_half_width": 3.2}}, {"offset_y": 2.8}, (0.0, 1.0, 0.0, 0.0), 150),
        # up at 0.5 m/s from 1 m out of z_max = 1.3 m
        ("out_of_arena", {"arena": {"z_max": 1.3}}, {}, (0.0, 0.0, 1.0, 0.0), 150),
    ],
    ids=["crash", "crash_high", "flip30", "flip90", "out_x", "out_y", "out_z"],
)
def test_each_termination_is_reached_and_named(make_env, name, settings, options, action, steps):
    """Each engine termination is reached by flying into it, with ``terminated`` and its name in
    ``info["termination_reason"]`` and the crash penalty (every early end is penalised, the table's
    "crash" row). Catches a reason under another name (a flip reported as a crash: the flips here end
    high above the ground), an arena bound not checked, a penalty missing on an early end."""
    env = make_env(**QUIET, fan={"enabled": False}, **settings)
    env.reset(seed=0, options={"fan_motion": {"name": "static", "y0": 0.0}, "offset_y": 0.0, **options})
    _, _, terminated, truncated, info = _run(env, action, steps)
    assert terminated and not truncated
    assert info["termination_reason"] == name
    assert info["reward_terms"]["crash"] == -CRASH_PENALTY
    position = np.asarray(info["position"])
    if name == "flip":
        assert position[2] > 0.5  # nowhere near the ground: a flip, not a crash
        tilt = math.degrees(math.acos(env.unwrapped.fleet.state.rotation[0, 2, 2]))
        assert tilt > settings.get("flip_tilt_deg", 90.0)
    if name == "crash":  # below crash_height, at most one policy step's descent (0.5 m/s) late
        height = settings.get("crash_height", 0.1)
        assert height - 0.5 / 50 <= position[2] < height


def test_vector_env_masks_only_the_vehicle_that_ended(make_env):
    """Three vehicles, vehicle 1 descending into the ground while 0 and 2 hover: on the step it crashes
    the ``_final_obs``/``_final_info`` masks are True for it alone, ``final_obs[1]`` is its last
    observation (the single env of seed + 1 flown alike ends with the same one), the returned
    observation is the new episode's first (the single env's next ``reset()``, which continues the
    same generator), and the others' ``final_obs`` are None. Catches masks over all vehicles, a final
    observation taken after the restart, an observation not restarted, a vehicle restarted twice."""
    settings = {**QUIET, "fan": {"enabled": False}}
    vec = gym.make_vec(FAN_TRACKING, num_envs=3, vectorization_mode="vector_entry_point", **settings)
    try:
        single = make_env(**settings)
        vec.reset(seed=10)
        single.reset(seed=11)
        actions = np.zeros((3, 4))
        actions[1, 2] = -1.0
        for _ in range(300):
            obs, _, terminated, truncated, info = vec.step(actions)
            single_obs, _, single_terminated, _, single_info = single.step(actions[1])
            if terminated.any() or truncated.any():
                break
        np.testing.assert_array_equal(terminated, (False, True, False))
        assert single_terminated and single_info["termination_reason"] == "crash"
        np.testing.assert_array_equal(info["_final_obs"], (False, True, False))
        np.testing.assert_array_equal(info["_final_info"], (False, True, False))
        assert info["final_obs"][0] is None and info["final_obs"][2] is None
        np.testing.assert_array_equal(info["final_obs"][1], single_obs)
        final_info = info["final_info"]
        assert final_info["termination_reason"][1] == "crash"
        np.testing.assert_array_equal(final_info["_termination_reason"], (False, True, False))
        assert final_info["reward_terms"]["crash"][1] == -CRASH_PENALTY
        first, _ = single.reset()
        np.testing.assert_array_equal(obs[1], first)
        layout = vec.unwrapped.obs_layout
        assert obs[1][layout["position"]][0] == pytest.approx(STANDOFF)  # back at the start
        np.testing.assert_array_equal(obs[1][layout["velocity"]], 0.0)
        np.testing.assert_array_equal(obs[1][layout["last_action"]], 0.0)
        for i in (0, 2):  # the hovering ones go on where they were
            assert obs[i][layout["position"]][2] == pytest.approx(FAN_HEIGHT, abs=0.05)
    finally:
        vec.close()

"""Each task's step and start on a fleet view built by hand, without PyBullet: the reward terms, the
observation blocks and the info entries against the module docstrings' formulas, computed here from
the view's numbers (the reference of DisturbanceRejection's jet crossing during its hover is its
start point, the tool tip of ForceExertion is the body point ``offset`` away)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from quad_wrench_env.config import build
from quad_wrench_env.engine.fleet_view import FleetView
from quad_wrench_env.engine.world import RigidBodyState
from quad_wrench_env.tasks.disturbance_rejection import DisturbanceRejection
from quad_wrench_env.tasks.fan_tracking import FanTracking
from quad_wrench_env.tasks.force_exertion import ForceExertion
from quad_wrench_env.vehicle import make_vehicle


def view_of(positions, time=0.5, contact_force=None, estimated_positions=None, rotation=None) -> FleetView:
    """A view of N vehicles at ``positions`` (N, 3), level unless ``rotation`` (3, 3), at rest."""
    positions = np.asarray(positions, dtype=float)
    count = len(positions)
    quaternion = np.tile((1.0, 0.0, 0.0, 0.0), (count, 1))
    rotations = np.tile(np.eye(3) if rotation is None else rotation, (count, 1, 1))
    zeros = np.zeros((count, 3))
    state = RigidBodyState(positions, quaternion, zeros, zeros, rotations, zeros)
    estimated = np.zeros((count, 13))
    estimated[:, :3] = positions if estimated_positions is None else estimated_positions
    estimated[:, 6] = 1.0
    contact = zeros if contact_force is None else np.asarray(contact_force, dtype=float)
    return FleetView(
        np.full(count, time), state, contact, np.zeros((count, 6)), estimated, np.zeros((count, 6))
    )


def make_task(task_class, **values):
    cfg = build(task_class.config_class, values)
    return task_class(cfg, make_vehicle(cfg.vehicle), 2), cfg


def test_fan_tracking_scores_the_distance_to_a_still_fans_axis():
    """A still fan at y0 = 0.3: the axis is at y0 whatever the air's transit time; tracking is
    exp(-d/axis_scale) of the distance in the y-z plane, standoff -w|x - x_ref|."""
    task, cfg = make_task(FanTracking)
    for index in (0, 1):
        task.reset_vehicle(index, np.random.default_rng(index), {"fan_motion": {"name": "static", "y0": 0.3}})
    height, x_ref = cfg.fan.height, cfg.standoff_distance
    positions = [(x_ref + 0.1, 0.3 + 0.2, height - 0.1), (x_ref - 0.05, 0.3, height)]
    actions = np.array([(0.5, -0.5, 0.0, 1.0), (0.0, 0.0, 0.0, 0.0)])
    record = task.step(view_of(positions), actions, np.array((False, True)))
    r = cfg.reward
    terms = record.reward_terms
    assert terms["tracking"] == pytest.approx(
        [math.exp(-math.hypot(0.2, 0.1) / r.axis_scale), 1.0], rel=1e-12
    )
    assert terms["standoff"] == pytest.approx([-0.1 * r.standoff_weight, -0.05 * r.standoff_weight], rel=1e-9)
    assert terms["effort"] == pytest.approx([-r.effort_weight * 1.5 / 4.0, 0.0], abs=1e-15)
    assert terms["crash"] == pytest.approx([0.0, -r.crash_penalty])
    assert record.codes is None and record.blocks is None
    assert record.info["axis_error"] == pytest.approx([0.2, 0.0], abs=1e-12)
    assert record.info["jet_axis_y"] == pytest.approx([0.3, 0.3])
    assert record.info["fan_position"] == pytest.approx(np.array([[0.0, 0.3, height]] * 2))
    assert record.info["standoff_error"] == pytest.approx([0.1, -0.05], abs=1e-12)
    start = task.start(view_of(positions), np.array((0,)))
    assert start.reward_terms == {} and start.info["axis_error"] == pytest.approx([0.2, 0.0], abs=1e-12)


def test_disturbance_rejection_scores_the_distance_to_its_reference():
    """During the jet crossing's hover the reference is the path's start; tracking is
    -c(1 - exp(-e/s)), alive +c, and the error blocks are p_ref - p̂ and v_ref - v̂ (v_ref = 0)."""
    task, cfg = make_task(DisturbanceRejection, observe_tracking_error=True)
    starts = [
        task.reset_vehicle(i, np.random.default_rng(i), {"scenario": "jet_crossing"})[0] for i in (0, 1)
    ]
    jc = cfg.jet_crossing
    assert starts[0] == pytest.approx((*jc.path, jc.start_height))
    positions = np.add(starts, [(0.03, 0.04, 0.0), (0.0, 0.0, -0.1)])
    estimated = np.add(positions, [(0.01, 0.0, 0.0), (0.0, 0.0, 0.0)])
    record = task.step(
        view_of(positions, estimated_positions=estimated), np.zeros((2, 4)), np.array((False, True))
    )
    r = cfg.reward
    c, s = r.tracking_cap, r.tracking_scale
    assert record.reward_terms["tracking"] == pytest.approx(
        [-c * (1 - math.exp(-0.05 / s)), -c * (1 - math.exp(-0.1 / s))]
    )
    assert record.reward_terms["alive"] == pytest.approx([c, 0.0])
    assert record.reward_terms["crash"] == pytest.approx([0.0, -r.crash_penalty])
    assert record.info["tracking_error"] == pytest.approx([0.05, 0.1])
    assert record.blocks[:, :3] == pytest.approx(np.array(starts) - estimated)
    assert record.blocks[:, 3:6] == pytest.approx(np.zeros((2, 3)), abs=1e-12)


def test_force_exertion_scores_the_exerted_force_and_the_tips_approach():
    """The contact term -min(|f_exerted - f*|, c) with f_exerted = -contact_force; the approach term
    γΦ(s') - Φ(s) with Φ = -w·gap, the gap from the level tip ``offset`` ahead of the centre."""
    offset, radius = (0.3, 0.0, 0.1), 0.015
    task, cfg = make_task(
        ForceExertion, tool={"enabled": True, "offset": list(offset), "tip_radius": radius}, roughness=0.0
    )
    for i in (0, 1):
        task.reset_vehicle(i, np.random.default_rng(i), {"surface": "wall", "target_force": 2.0, "push": 0.0})
    r = cfg.reward
    gaps = np.array((0.2, 0.0))
    positions = [(cfg.wall_x - g - radius - offset[0], 0.0, 1.2) for g in gaps]
    start = task.start(view_of(positions), np.array((0, 1)))
    assert start.blocks == pytest.approx(np.array([[2.0, 0.0, 0.0]] * 2))
    moved = [(x + 0.05, y, z) for x, y, z in positions[:1]] + positions[1:]
    touching = np.array([(0.0, 0.0, 0.0), (-1.5, 0.0, 0.0)])  # the wall pushes the second tip back
    record = task.step(view_of(moved, contact_force=touching), np.zeros((2, 4)), np.array((False, False)))
    w = r.approach_weight
    expected_approach = [r.discount * -w * 0.15 - (-w * 0.2), 0.0]
    assert record.reward_terms["approach"] == pytest.approx(expected_approach, abs=1e-12)
    assert record.reward_terms["contact"] == pytest.approx([-min(2.0, r.contact_cap), -0.5])
    assert record.info["contact_force"] == pytest.approx(touching)
    assert record.info["target_force"] == pytest.approx(np.array([[2.0, 0.0, 0.0]] * 2))


def test_a_tasks_record_holds_new_arrays():
    """A record's arrays are the task's own: the engine keeps a step's record beside the next start's."""
    task, _ = make_task(DisturbanceRejection)
    for i in (0, 1):
        task.reset_vehicle(i, np.random.default_rng(i), {"scenario": "table_pass"})
    view = view_of([(0.0, 0.0, 1.0), (0.0, 0.0, 1.0)])
    first = task.step(view, np.zeros((2, 4)), np.zeros(2, bool))
    second = task.start(view, np.array((0,)))
    for key in first.info:
        assert not np.shares_memory(first.info[key], second.info[key]), key


def test_the_fleets_view_refuses_writes():
    """What a task reads of a live fleet is read-only and shows the fleet's values after each step,
    the estimates read from the bank afresh."""
    import gymnasium as gym

    env = gym.make("QuadWrench/FanTracking-v1")
    try:
        env.reset(seed=0)
        fleet = env.unwrapped.fleet
        view = fleet.view()
        arrays = [view.time, *vars(view.state).values(), view.contact_force, view.wrench_true]
        for array in [*arrays, view.estimated_state, view.wrench_est]:
            with pytest.raises(ValueError, match="read-only"):
                array[0] = 0.0
        for _ in range(3):
            env.step(np.zeros(4))
            states, wrenches = fleet.estimator.estimates()  # what the step's view read
            np.testing.assert_array_equal(view.estimated_state, states)
            np.testing.assert_array_equal(view.wrench_est, wrenches)
        assert view.time[0] == pytest.approx(fleet.time[0]) and fleet.time[0] > 0.0
    finally:
        env.close()


def test_a_steps_outcome_counts_sums_and_codes_each_vehicle():
    """``step_outcome`` of four vehicles at step 9 of 10: one going on, one the engine ended (flip,
    code 2, over the task's own), one the task ended (its code 1 after the engine's three), one
    truncated at step 10; rewards summed in order from 0 (so -0.0 terms give +0.0, as NumPy's sum
    of a start of 0.0)."""
    from quad_wrench_env.envs.simulation import step_outcome

    engine = np.array([0, 2, 0, 0])
    own = np.array([0, 1, 1, 0])
    steps = np.array([8, 8, 8, 9])
    terms = (
        np.array([1.0, 0.5, -0.0, 1e16]),
        np.array([2.0, 0.25, -0.0, 1.0]),
        np.array([-4.0, 0.0, -0.0, -1e16]),
    )
    rewards, codes = np.full(4, np.nan), np.full(4, -1)
    terminated, truncated = np.zeros(4, dtype=bool), np.ones(4, dtype=bool)
    step_outcome(engine, own, steps, 10, terms, rewards, codes, terminated, truncated)
    np.testing.assert_array_equal(steps, [9, 9, 9, 10])
    np.testing.assert_array_equal(rewards, [-1.0, 0.75, 0.0, 0.0])  # (1e16 + 1) - 1e16: in order
    assert not np.signbit(rewards[2])
    np.testing.assert_array_equal(codes, [0, 2, 4, 0])
    np.testing.assert_array_equal(terminated, [False, True, True, False])
    np.testing.assert_array_equal(truncated, [False, False, False, True])
    step_outcome(engine, np.zeros(0, dtype=np.int64), steps, 10, terms, rewards, codes, terminated, truncated)
    np.testing.assert_array_equal(codes, [0, 2, 0, 0])  # no codes of the task's own
    np.testing.assert_array_equal(truncated, [True, False, True, True])  # at 10 or 11 of 10 steps, not ended

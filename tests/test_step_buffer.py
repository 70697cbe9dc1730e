"""The step buffer's layout (engine/step_buffer.py): every region where the declaration puts it, each part
of the fleet holding its own region, and the compiled step reading the same offsets."""

import gymnasium as gym
import numpy as np
import pytest

import quad_wrench_env  # noqa: F401  (registers the envs)
from quad_wrench_env.disturbances.base import CompiledForm
from quad_wrench_env.engine.compose import Slot, source
from quad_wrench_env.engine.step_buffer import StepBuffer, StepLayout

ENGINE_WIDTH = 118
"""Floats per vehicle of the engine's fields, counted by hand from their list: time 1, position 3,
quaternion 4, velocity 3, angular velocity 3, rotation 9, body rates 3, forces 3, torques 3, loads 6,
thrusts 1, body torques 3, measured position 3, measured quaternion 4, motion 6, truth 13, yaw set-point 1,
velocity integral 3, rate integral 3, speeds 4, allocations 16, sensed allocations 16, rotor wrench 4,
wind velocity 3."""


def test_regions_follow_each_other_in_the_declared_order():
    layout = StepLayout(state_widths=(0, 5, 2), points=9, noise_width=8, delay_width=15)
    e = ENGINE_WIDTH
    expected = {
        "state_0": e,
        "state_1": e,
        "state_2": e + 5,
        "point_offsets": e + 7,
        "points": e + 7 + 27,
        "air": e + 7 + 54,
        "normals": e + 7 + 81,
        "rotor_thrusts": e + 7 + 81 + 8,
        "added_thrust": e + 7 + 81 + 12,
        "centre": e + 7 + 81 + 16,
        "centre_air": e + 7 + 81 + 19,
        "delay_line": e + 7 + 81 + 22,
    }
    assert {name: layout.start[name] for name in expected} == expected
    assert layout.width == e + 7 + 81 + 22 + 15


def test_a_region_of_n_vehicles_is_one_block_of_rows():
    layout = StepLayout(state_widths=(2,), points=5, noise_width=3, delay_width=0)
    buffer = StepBuffer(layout, count=3)
    buffer.array[:] = np.arange(buffer.array.size)
    start = layout.start["state_0"]
    np.testing.assert_array_equal(buffer.region("state_0"), np.arange(3 * start, 3 * start + 6).reshape(3, 2))
    assert buffer.fields["rotation"].shape == (3, 3, 3) and buffer.fields["time"].shape == (3,)
    assert np.shares_memory(buffer.fields["position"], buffer.array)


def test_a_part_handed_its_region_keeps_its_numbers_and_lives_in_the_buffer():
    class Part:
        def __init__(self) -> None:
            self.state = np.array(((1.0, 2.0), (3.0, 4.0)))

    buffer = StepBuffer(StepLayout(state_widths=(2,), points=5, noise_width=3, delay_width=0), count=2)
    part = Part()
    buffer.hand_over(part, "state", "state_0")
    np.testing.assert_array_equal(part.state, ((1.0, 2.0), (3.0, 4.0)))
    part.state[1, 0] = 7.0
    assert buffer.region("state_0")[1, 0] == 7.0
    with pytest.raises(ValueError, match=r"Part.state has shape \(2, 2\); region 'centre'"):
        buffer.hand_over(Part(), "state", "centre")


def test_the_fleets_parts_hold_their_regions():
    env = gym.make("QuadWrench/FanTracking-v1", estimator="ekf", sensors={"latency_steps": 2})
    try:
        env.reset(seed=0)
        fleet = env.unwrapped.fleet
        buffer = fleet.step_buffer
        held = [
            (fleet.autopilot.yaw_setpoint, buffer.fields["yaw_setpoint"]),
            (fleet.autopilot.rate_integral, buffer.fields["rate_integral"]),
            (fleet.rotors.speeds, buffer.fields["speeds"]),
            (fleet.mocap.delay_line, buffer.region("delay_line")),
            (fleet.state.position, buffer.fields["position"]),
        ]
        for k, (_, component) in enumerate(fleet.components.ordered()):
            if component.compiled.state:
                held.append((getattr(component, component.compiled.state), buffer.region(f"state_{k}")))
        assert len(held) > 5  # the fan's turbulence has a state
        for array, region in held:
            assert array.base is buffer.array and array.__array_interface__ == region.__array_interface__
    finally:
        env.close()


def test_the_compiled_step_reads_the_layouts_offsets():
    form = CompiledForm("quad_wrench_env.disturbances.dryden", (("velocity", "v"), ("advance", "a")))
    slots = [Slot("wind", form, 6, (0, 3))]
    layout = StepLayout(state_widths=(6,), points=9, noise_width=9, delay_width=0)
    text = source(slots, layout)
    assert f"rows_view(buffer, {ENGINE_WIDTH} * n, n, 6)" in text
    assert f"air = point_rows(buffer, {ENGINE_WIDTH + 6 + 54}, n, 9)" in text
    assert f"normals = rows(buffer, {ENGINE_WIDTH + 6 + 81}, n, 9)" in text
    with pytest.raises(ValueError, match=r"state widths \[6\] are not the layout's \[4\]"):
        source(slots, StepLayout(state_widths=(4,), points=9, noise_width=9, delay_width=0))

"""Motion capture, motor-speed quantization and the hanging payload."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from quad_wrench_env.disturbances.base import resultant
from quad_wrench_env.disturbances.payload import Payload, PayloadConfig
from quad_wrench_env.disturbances.wrench_profile import WrenchProfile
from quad_wrench_env.rotations import quat_conjugate, quat_from_euler_zyx, quat_multiply, rotation_matrix
from quad_wrench_env.sensors import MotorSpeedSensor, SensorConfig
from quad_wrench_env.vehicle import GRAVITY


def test_motion_capture_noise_has_the_configured_spread(make_env):
    """The engine's ``sense`` kernel on 4000 draws: the measured position scatters with the configured
    sd about the truth and the measured attitude by a rotation of the configured sd per axis (its
    rotation vector read back here with the quaternion algebra of ``rotations``)."""
    from quad_wrench_env.engine.kernels import STEP_FIELDS, sense, step_views

    env = make_env(estimator="oracle", sensors={"position_noise": 0.01, "attitude_noise": 0.05})
    env.reset(seed=0)
    fleet = env.unwrapped.fleet
    buffer, constants = fleet.step_buffer.array.copy(), fleet.compiled.constants
    fields = dict(zip((name for name, _ in STEP_FIELDS), step_views(buffer, 1), strict=True))
    q = quat_from_euler_zyx(0.1, 0.2, 0.3)
    fields["position"][0], fields["quaternion"][0] = (1.0, 2.0, 3.0), q
    column = fleet.sensor_noise_column
    rng = np.random.default_rng(0)
    positions, angles = [], []
    for _ in range(4000):
        normals = np.zeros((1, column + 12))
        normals[:, column : column + 6] = rng.standard_normal((1, 6))
        sense(buffer, normals, constants)
        positions.append(fields["measured_position"][0].copy())
        error = quat_multiply(quat_conjugate(q), fields["measured_quaternion"][0])
        angles.append(2.0 * error[1:] * np.sign(error[0]))
    # 4000 samples: sample sds within ~3 % of the true ones
    np.testing.assert_allclose(np.std(positions, axis=0), 0.01, rtol=0.06)
    np.testing.assert_allclose(np.mean(positions, axis=0), (1.0, 2.0, 3.0), atol=0.001)
    np.testing.assert_allclose(np.std(angles, axis=0), 0.05, rtol=0.06)


def test_motor_speeds_are_quantized_to_8_bits():
    sensor = MotorSpeedSensor(550.0, 8)
    levels = sensor.measure(np.linspace(0.0, 550.0, 10001))
    assert len(np.unique(levels)) == 256
    assert np.abs(levels - np.linspace(0.0, 550.0, 10001)).max() <= 550.0 / 255 / 2 + 1e-12


def _at_rest(rotation: np.ndarray) -> SimpleNamespace:
    """Bodies at rest at the origin with attitudes ``rotation`` (n, 3, 3), as a point load reads them."""
    zeros = np.zeros((len(rotation), 3))
    return SimpleNamespace(position=zeros, velocity=zeros, angular_velocity=zeros, rotation=rotation)


def test_payload_under_a_rotor_gives_paper_000s_torque():
    payload = Payload(PayloadConfig(mass=0.053, point=(0.129, 0.129, 0.0), attach_time=7.0, release_time=9.0))
    times = np.array((6.9, 7.0, 9.0))
    offsets, forces = payload.point_load(times, _at_rest(np.tile(np.eye(3), (3, 1, 1))))
    np.testing.assert_array_equal(forces[[0, 2]], 0.0)  # before attaching and after the release
    offset, force = offsets[1, 0], forces[1, 0]
    torque = np.cross(offset, force)
    assert force[2] == pytest.approx(-0.053 * GRAVITY)
    np.testing.assert_allclose(np.abs(torque[:2]), 0.053 * GRAVITY * 0.129)  # 0.067 N·m, Sec. III
    tilted = rotation_matrix(quat_from_euler_zyx(0.0, 0.0, np.pi / 2))
    offsets, _ = payload.point_load(np.array((8.0,)), _at_rest(tilted[None]))
    np.testing.assert_allclose(offsets[0, 0], tilted @ (0.129, 0.129, 0.0))
    assert Payload(PayloadConfig()).point_load(times, _at_rest(np.tile(np.eye(3), (3, 1, 1)))) is None


def test_bad_sensor_and_payload_settings_are_named():
    with pytest.raises(ValueError, match="position_noise=-1"):
        SensorConfig(position_noise=-1.0)
    with pytest.raises(ValueError, match="latency_steps=0.5"):
        SensorConfig(latency_steps=0.5)
    with pytest.raises(ValueError, match="payload.mass=-0.1"):
        PayloadConfig(mass=-0.1)
    with pytest.raises(ValueError, match="attach_time=5"):
        PayloadConfig(attach_time=5.0, release_time=1.0)


def test_wrench_profile_applies_its_wrench_through_point_forces():
    profile = WrenchProfile(
        [[5, 10, 1, 0, 0, 0, 0, 0], [25, 30, 0, 0, 0, 1, 0, 0], [8, 9, 0, 0, -1, 0, 0.2, 0.3]]
    )
    times = np.array((4.9, 6.0, 8.5, 26.0))
    offsets, forces = profile.point_load(times, _at_rest(np.tile(np.eye(3), (4, 1, 1))))
    force, torque = resultant(offsets, forces)
    expected = ((0, 0, 0, 0, 0, 0), (1, 0, 0, 0, 0, 0), (1, 0, -1, 0, 0.2, 0.3), (0, 0, 0, 1, 0, 0))
    np.testing.assert_allclose(np.concatenate((force, torque), axis=1), expected, atol=1e-12)
    assert WrenchProfile([]).point_load(times, _at_rest(np.tile(np.eye(3), (4, 1, 1)))) is None
    with pytest.raises(ValueError, match="segment"):
        WrenchProfile([[3, 1, 0, 0, 0, 0, 0, 0]])

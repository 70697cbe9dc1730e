"""What a real vehicle measures: a motion-capture pose and its own motor speeds.

* Motion capture (McKinnon & Schoellig 2016, Sec. II-B): position and attitude every physics step
  (200 Hz, T = 5 ms), with additive zero-mean Gaussian noise on the position (``position_noise``, m) and a
  small random rotation on the attitude (rotation vector with ``attitude_noise`` rad per axis, applied in the
  body frame), optionally ``latency_steps`` physics steps old.
* Optionally (``state_estimator: true``) an onboard state estimator's velocity and body rates with
  Gaussian noise, as the vehicle of Hentzen et al. 2019 has (their EKF measures them; the UKF of
  McKinnon & Schoellig 2016 does not).
* Motor speeds (McKinnon & Schoellig 2016, Sec. II-A): quantized to ``motor_speed_bits`` bits over
  [0, max speed], as the AR.Drone reports them; the estimators get thrust and torque from these through the
  *nominal* mixer, while the world uses the true per-rotor coefficients.

Every random draw comes from the vehicle's own Generator (the env's ``np_random``), drawn in blocks
(:class:`quad_wrench_env.engine.noise.NoiseBlocks`) and handed in.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.rotations import quat_exp, quat_multiply_rows


@dataclass
class SensorConfig:
    """Noise of the motion-capture system and resolution of the motor-speed readings
    (``docs/physics.md``, "Sensors")."""

    position_noise: float = 5e-4
    attitude_noise: float = 2e-3
    latency_steps: int = 0
    motor_speed_bits: int = 8
    state_estimator: bool = False
    velocity_noise: float = 0.01
    """m/s, with ``state_estimator``"""
    body_rate_noise: float = 0.01
    """rad/s, with ``state_estimator``"""

    def __post_init__(self) -> None:
        noise = ("position_noise", "attitude_noise", "velocity_noise", "body_rate_noise")
        check_numbers("sensors", self, noise, positive=False)
        if not (isinstance(self.latency_steps, int) and self.latency_steps >= 0):
            raise ValueError(f"sensors.latency_steps={self.latency_steps!r} must be an integer >= 0")
        if not (isinstance(self.motor_speed_bits, int) and 1 <= self.motor_speed_bits <= 32):
            raise ValueError(
                f"sensors.motor_speed_bits={self.motor_speed_bits!r} must be an integer in [1, 32]"
            )


class MotionCapture:
    """Noisy, optionally delayed pose measurements of N vehicles.

    The noise comes in as standard normal draws (six per vehicle and step, from
    each vehicle's own generator), so that a batch of vehicles and the same vehicles flown one by
    one see the same noise.
    """

    def __init__(self, config: SensorConfig, count: int = 1) -> None:
        self.config = config
        latency = config.latency_steps
        self._positions = np.zeros((latency, count, 3))
        self._quaternions = np.zeros((latency, count, 4))
        self._head = 0

    def reset(self, index: int, position: np.ndarray, quaternion: np.ndarray) -> None:
        """Start an episode of vehicle ``index``; until ``latency_steps`` have passed its start
        pose is what is seen."""
        self._positions[:, index] = position
        self._quaternions[:, index] = quaternion

    def delayed(self, positions: np.ndarray, quaternions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The true poses ``latency_steps`` physics steps ago, given the poses now (one call per step)."""
        latency = self.config.latency_steps
        if not latency:
            return positions, quaternions
        head = self._head
        oldest = self._positions[head].copy(), self._quaternions[head].copy()
        self._positions[head], self._quaternions[head] = positions, quaternions
        self._head = (head + 1) % latency
        return oldest

    def measure(
        self, positions: np.ndarray, quaternions: np.ndarray, normals: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Measured ``(positions (N, 3), quaternions (N, 4) [w, x, y, z])`` for the true poses now;
        ``normals`` (N, 6) standard normal draws."""
        cfg = self.config
        positions, quaternions = self.delayed(positions, quaternions)
        measured_position = positions + cfg.position_noise * normals[:, :3]
        rotation_error = quat_exp(cfg.attitude_noise * normals[:, 3:6])
        measured = quat_multiply_rows(quaternions, rotation_error)
        return measured_position, measured / np.linalg.norm(measured, axis=1, keepdims=True)

    def measure_motion(
        self, velocity: np.ndarray, body_rates: np.ndarray, normals: np.ndarray
    ) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Velocities and body rates (N, 3) from the onboard state estimators, or ``(None, None)``
        without one; ``normals`` (N, 6) standard normal draws."""
        cfg = self.config
        if not cfg.state_estimator:
            return None, None
        return velocity + cfg.velocity_noise * normals[:, :3], body_rates + cfg.body_rate_noise * normals[
            :, 3:6
        ]


class MotorSpeedSensor:
    """Motor speeds as the vehicle reports them: rounded to ``bits`` bits over [0, max_speed]."""

    def __init__(self, max_speed: float, bits: int) -> None:
        self.levels = float(2**bits - 1)
        self.step = max_speed / self.levels

    def measure(self, speeds: np.ndarray) -> np.ndarray:
        return np.clip(np.round(speeds / self.step), 0.0, self.levels) * self.step

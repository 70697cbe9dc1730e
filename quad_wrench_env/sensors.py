"""What a real vehicle measures: a motion-capture pose and its own motor speeds.

* Motion capture (paper 000 Sec. II-B): position and attitude every physics step (200 Hz, T = 5 ms),
  with additive zero-mean Gaussian noise on the position (``position_noise``, m) and a small random
  rotation on the attitude (rotation vector with ``attitude_noise`` rad per axis, applied in the
  body frame), optionally ``latency_steps`` physics steps old.
* Optionally (``state_estimator: true``) an onboard state estimator's velocity and body rates with
  Gaussian noise, as paper 003's vehicle has (its EKF measures them; paper 000's UKF does not).
* Motor speeds (paper 000 Sec. II-A): quantized to ``motor_speed_bits`` bits over [0, max speed], as
  the AR.Drone reports them; the estimators get thrust and torque from these through the *nominal*
  mixer, while the world uses the true per-rotor coefficients.

Every random draw comes from the Generator handed to :meth:`MotionCapture.reset` (the env's).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.rotations import quat_exp, quat_multiply


@dataclass
class SensorConfig:
    """Noise of the motion-capture system and resolution of the motor-speed readings (PHYSICS.md)."""

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
    """Noisy, optionally delayed pose measurements."""

    def __init__(self, config: SensorConfig) -> None:
        self.config = config
        self._rng: np.random.Generator | None = None
        self._queue: deque[tuple[np.ndarray, np.ndarray]] = deque()

    def reset(self, rng: np.random.Generator, position: np.ndarray, quaternion: np.ndarray) -> None:
        """Start an episode; until ``latency_steps`` have passed the start pose is what is seen."""
        self._rng = rng
        self._queue = deque([(position.copy(), quaternion.copy())] * self.config.latency_steps)

    def measure(self, position: np.ndarray, quaternion: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Measured ``(position, quaternion [w, x, y, z])`` for the true pose now."""
        if self._rng is None:
            raise RuntimeError("MotionCapture.reset() must be called before measure()")
        cfg = self.config
        self._queue.append((position, quaternion))
        position, quaternion = self._queue.popleft()
        rng = self._rng
        measured_position = position + cfg.position_noise * rng.standard_normal(3)
        rotation_error = quat_exp(cfg.attitude_noise * rng.standard_normal(3))
        return measured_position, quaternion_normalised(quat_multiply(quaternion, rotation_error))

    def measure_motion(
        self, velocity: np.ndarray, body_rates: np.ndarray
    ) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Velocity and body rates from the onboard state estimator, or ``(None, None)`` without one."""
        cfg = self.config
        if not cfg.state_estimator:
            return None, None
        rng = self._rng
        return (
            velocity + cfg.velocity_noise * rng.standard_normal(3),
            body_rates + cfg.body_rate_noise * rng.standard_normal(3),
        )


def quaternion_normalised(q: np.ndarray) -> np.ndarray:
    return q / math.sqrt(float(q @ q))


class MotorSpeedSensor:
    """Motor speeds as the vehicle reports them: rounded to ``bits`` bits over [0, max_speed]."""

    def __init__(self, max_speed: float, bits: int) -> None:
        self._levels = float(2**bits - 1)
        self._step = max_speed / self._levels

    def measure(self, speeds: np.ndarray) -> np.ndarray:
        return np.clip(np.round(speeds / self._step), 0.0, self._levels) * self._step

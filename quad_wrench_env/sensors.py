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
(:class:`quad_wrench_env.engine.draws.NoiseBlocks`) and handed in.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from quad_wrench_env.config import check_counts, check_numbers
from quad_wrench_env.numerics import njit


@njit(inline=True)
def quantized_speed(speed, levels, step):
    """A motor speed as the vehicle reports it: the nearest of ``levels + 1`` steps of ``step`` from 0
    (McKinnon & Schoellig 2016, Sec. II-A: 8 bits over the motor's range on the AR.Drone)."""
    return min(max(np.rint(speed / step), 0.0), levels) * step


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
        check_counts("sensors", self, ("latency_steps",), minimum=0)
        if not (isinstance(self.motor_speed_bits, int) and 1 <= self.motor_speed_bits <= 32):
            raise ValueError(
                f"sensors.motor_speed_bits={self.motor_speed_bits!r} must be an integer in [1, 32]"
            )


class MotionCapture:
    """The motion capture's delay line of N vehicles (its numbers are measured by the compiled
    step's ``sense`` kernel, :mod:`quad_wrench_env.engine.kernels`): per vehicle the slot written
    next, then ``latency_steps`` poses ``[position, quaternion]``; empty without latency. The fleet
    makes :attr:`delay_line` a view of its step buffer."""

    def __init__(self, config: SensorConfig, count: int = 1) -> None:
        self.config = config
        latency = config.latency_steps
        self.delay_line = np.zeros((count, 1 + 7 * latency if latency else 0))

    def reset(self, index: int, position: np.ndarray, quaternion: np.ndarray) -> None:
        """Start an episode of vehicle ``index``; until ``latency_steps`` have passed its start
        pose is what is seen."""
        line = self.delay_line[index]
        for slot in range(self.config.latency_steps):
            line[1 + 7 * slot : 4 + 7 * slot] = position
            line[4 + 7 * slot : 8 + 7 * slot] = quaternion


class MotorSpeedSensor:
    """Motor speeds as the vehicle reports them: rounded to ``bits`` bits over [0, max_speed] (the
    ``sense`` kernel rounds them to :attr:`levels` steps of :attr:`step`)."""

    def __init__(self, max_speed: float, bits: int) -> None:
        self.levels = float(2**bits - 1)
        self.step = max_speed / self.levels

    def measure(self, speeds: np.ndarray) -> np.ndarray:
        """The reported speeds of (..., 4) true ``speeds`` (the kernel's rounding, element by element)."""
        reported = [quantized_speed(float(v), self.levels, self.step) for v in np.ravel(speeds)]
        return np.array(reported).reshape(np.shape(speeds))

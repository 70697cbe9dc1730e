"""A quasi-static wrench estimator: the residual of the rigid-body equations with measured accelerations."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from quad_wrench_env.config import build, check_numbers
from quad_wrench_env.estimators import MEASUREMENT_NOISE_KEYS, EstimatorEntry
from quad_wrench_env.estimators.bank import BankOfOne, EstimatorInputs, check_finite_batch
from quad_wrench_env.registry import register
from quad_wrench_env.rotations import rotation_matrices
from quad_wrench_env.vehicle import GRAVITY, VehicleParams


@dataclass
class QuasiStaticSettings:
    time_constant: float = 0.1
    """s: first-order low-pass on the velocity, the acceleration and the wrench."""

    def __post_init__(self) -> None:
        check_numbers("estimator_params", self, ("time_constant",))


class QuasiStaticBank:
    """``f = m (a + g e_z) - R c_t e_z`` and ``tau = -R tau_m`` (rotational acceleration neglected), with
    the velocity and the acceleration from low-passed finite differences of the measured positions."""

    name = "quasi_static"

    def __init__(
        self,
        vehicle: VehicleParams,
        dt: float,
        settings: QuasiStaticSettings | None,
        count: int,
    ) -> None:
        self.mass, self.dt, self.count = vehicle.mass, dt, count
        settings = settings or QuasiStaticSettings()
        self.alpha = 1.0 - math.exp(-dt / settings.time_constant)
        self._states = np.zeros((count, 13))  # position, velocity, quaternion [w, x, y, z], body rates
        self._states[:, 6] = 1.0
        self._acceleration = np.zeros((count, 3))
        self._wrenches = np.zeros((count, 6))

    def reset(self, index: int, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        self._states[index] = 0.0
        self._states[index, 0:3] = position
        self._states[index, 6:10] = quaternion_wxyz
        self._acceleration[index] = 0.0
        self._wrenches[index] = 0.0

    def step(self, inputs: EstimatorInputs) -> None:
        check_finite_batch(self.name, **inputs._asdict())
        thrusts, body_torques, positions, quaternions = inputs[:4]
        a, s = self.alpha, self._states
        velocity = s[:, 3:6] + a * ((positions - s[:, 0:3]) / self.dt - s[:, 3:6])
        self._acceleration += a * ((velocity - s[:, 3:6]) / self.dt - self._acceleration)
        s[:, 3:6] = velocity
        s[:, 0:3], s[:, 6:10] = positions, quaternions
        R = rotation_matrices(quaternions)
        force = self.mass * self._acceleration - thrusts[:, None] * R[:, :, 2]
        force[:, 2] += self.mass * GRAVITY
        torque = -np.einsum("nij,nj->ni", R, body_torques)
        self._wrenches += a * (np.concatenate((force, torque), axis=1) - self._wrenches)

    def wrenches(self) -> np.ndarray:
        return self._wrenches.copy()

    def states(self) -> np.ndarray:
        return self._states.copy()

    def estimates(self) -> tuple[np.ndarray, np.ndarray]:
        return self.states(), self.wrenches()

    def wrench_covariances(self) -> np.ndarray:  # it carries none: NaN, not an invented one
        return np.full((self.count, 6, 6), np.nan)

    def statuses(self) -> list[str]:
        return ["ok"] * self.count


class QuasiStaticEstimator(BankOfOne):
    """The single-vehicle form (the ``Estimator`` protocol): a bank of one."""

    name = "quasi_static"

    def __init__(self, vehicle, dt, settings=None) -> None:
        self.bank = QuasiStaticBank(vehicle, dt, settings, count=1)


def _settings(values):  # drop the motion-capture noise keys the env always passes
    values = {k: v for k, v in values.items() if k not in MEASUREMENT_NOISE_KEYS}
    return build(QuasiStaticSettings, values, prefix="estimator_params.")


register("estimator", "quasi_static", EstimatorEntry(_settings, QuasiStaticEstimator, QuasiStaticBank))

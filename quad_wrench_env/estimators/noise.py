"""Noise settings shared by the Kalman-type wrench estimators (the UKF and the EKF)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.kernels import njit
from quad_wrench_env.kernels.quaternions import matrix
from quad_wrench_env.vehicle import GRAVITY, Mixer, VehicleParams


@dataclass
class FilterNoise:
    """Standard deviations of a wrench filter's noise models: its only tuning knobs.

    Process noise is per step of ``dt`` (McKinnon & Schoellig 2016 eqs. 4, 5, 12, 14; the random walks of
    Hentzen et al. 2019); measurement noise (``G`` in McKinnon & Schoellig 2016 Sec. II-B, ``R`` in
    Hentzen et al. 2019) is that of the motion capture, and the env sets it from its sensor config unless
    given here. Initial standard deviations describe the belief at ``reset``. The UKF and the EKF share these,
    so that they can be compared with the same variance settings (Hentzen et al. 2019 Sec. V-C).
    """

    thrust: float = 0.05
    """η_ct (N): thrust model error and 8-bit speed quantization, per body axis."""
    motor_torque: float = 3e-3
    """η_τm (N·m): motor torque model error, per body axis."""
    force_walk: float = 4e-3
    """η_fe (N per step): random walk of the external force."""
    torque_walk: float = 2e-4
    """η_τe (N·m per step): random walk of the external torque."""
    position: float = 5e-4
    """Motion-capture position noise (m)."""
    attitude: float = 2e-3
    """Motion-capture attitude noise (rad)."""
    initial_attitude: float = 0.01
    initial_rates: float = 0.05
    initial_position: float = 0.01
    initial_velocity: float = 0.05
    initial_torque: float = 0.02
    initial_force: float = 0.2
    kappa: float = 2.0
    rotor_spread: float = 0.02
    """Relative sd of each rotor's thrust coefficient about the nominal (the env's ``kf_spread``, 0.02 by
    default): the filter cannot tell a rotor's error from an external wrench, so it enters the
    *reported* covariance of the wrench (:func:`rotor_spread_covariance`), never the estimate."""

    def __post_init__(self) -> None:
        check_numbers("estimator_params", self, tuple(k for k in vars(self) if k != "rotor_spread"))
        check_numbers("estimator_params", self, ("rotor_spread",), positive=False)


def rotor_spread_body(vehicle: VehicleParams, spread: float) -> np.ndarray:
    """(4, 4) covariance of ``[thrust, τ_body]`` that the rotors' thrust-coefficient errors make at hover:
    rotor i's coefficient ``k_f(1 + δ_i)``, ``δ_i ~ N(0, spread²)``, adds ``δ_i`` times its column of the
    mixer's allocation times ``ω_i²`` (McKinnon & Schoellig 2016 eq. 1: thrust along body z, the roll,
    pitch and yaw torques), with the hover's ``ω_i² = m g / (4 k_f)``."""
    per_rotor = Mixer(vehicle).allocation * (vehicle.mass * GRAVITY / (4.0 * vehicle.kf))  # (4, 4)
    return (spread * spread) * per_rotor @ per_rotor.T


def rotor_spread_covariance(body: np.ndarray, quaternions: np.ndarray) -> np.ndarray:
    """(N, 6, 6) world-frame covariance of the wrench whose body covariance is ``body``
    (:func:`rotor_spread_body`), for attitudes ``quaternions`` (N, 4) ``[w, x, y, z]``: ``J body Jᵀ`` with
    ``J = [R e_z, 0; 0, R]``. A filter sees the rotors' wrench as external; the env's ``wrench_true``
    leaves it out (it is the vehicle's own), so the covariance a filter reports for ``wrench_est -
    wrench_true`` adds it: a consider covariance (Schmidt 1966: a parameter the filter does not estimate,
    whose uncertainty it carries), exact at hover and a first-order one elsewhere."""
    out = np.empty((len(quaternions), 6, 6))
    _world_covariances(body, np.ascontiguousarray(quaternions, dtype=float), out)
    return out


@njit
def _world_covariances(body, quaternions, out):
    """``J body Jᵀ`` per vehicle into ``out`` (N, 6, 6), the upper triangle mirrored (symmetric to the
    bit)."""
    rotation = np.empty((3, 3))
    jacobian = np.zeros((6, 4))
    for n in range(quaternions.shape[0]):
        q = quaternions[n]
        matrix(q[0], q[1], q[2], q[3], rotation)
        for i in range(3):
            jacobian[i, 0] = rotation[i, 2]
            for k in range(3):
                jacobian[3 + i, 1 + k] = rotation[i, k]
        for i in range(6):
            for j in range(i, 6):
                total = 0.0
                for a in range(4):
                    for b in range(4):
                        total += jacobian[i, a] * body[a, b] * jacobian[j, b]
                out[n, i, j] = total
                out[n, j, i] = total


def mrp_std(angle_std: float) -> float:
    """Standard deviation in MRP units (``ρ = tan(θ/4)``) of a small rotation of ``angle_std`` rad."""
    return math.tan(angle_std / 4.0)


@dataclass
class EKFNoise(FilterNoise):
    """:class:`FilterNoise` plus the noise of the optional velocity and body-rate measurements that
    an onboard state estimator provides on Hentzen et al.'s (2019) vehicle."""

    velocity: float = 0.01
    """m/s"""
    body_rate: float = 0.01
    """rad/s"""

"""Noise settings shared by the Kalman-type wrench estimators (the UKF and the EKF)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from quad_wrench_env.config import check_numbers


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

    def __post_init__(self) -> None:
        check_numbers("estimator_params", self, tuple(vars(self)))


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

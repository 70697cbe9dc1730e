"""Noise settings shared by the Kalman-type wrench estimators (the UKF and the EKF)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TypeVar

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.estimators.walks import start_walks
from quad_wrench_env.numerics import njit
from quad_wrench_env.numerics.quaternions import matrix
from quad_wrench_env.vehicle import GRAVITY, PRESETS, Mixer, VehicleParams

NoiseT = TypeVar("NoiseT", bound="FilterNoise")


@dataclass
class FilterNoise:
    """Standard deviations of a wrench filter's noise models: its only tuning knobs.

    Process noise is per step of ``dt`` (McKinnon & Schoellig 2016 eqs. 4, 5, 12, 14; the random walks of
    Hentzen et al. 2019); measurement noise (``G`` in McKinnon & Schoellig 2016 Sec. II-B, ``R`` in
    Hentzen et al. 2019) is that of the motion capture, and the env sets it from its sensor config unless
    given here. Initial standard deviations describe the belief at ``reset``. The UKF and the EKF share these,
    so that they can be compared with the same variance settings (Hentzen et al. 2019 Sec. V-C).
    """

    thrust: float | None = None
    """η_ct (N): thrust model error and 8-bit speed quantization, per body axis; None: derived for the
    vehicle (:meth:`for_vehicle`)."""
    motor_torque: float | None = None
    """η_τm (N·m): motor torque model error, per body axis; None: derived for the vehicle."""
    force_walk: float | None = None
    """η_fe (N per step): random walk of the external force; None: derived for the vehicle."""
    torque_walk: float | None = None
    """η_τe (N·m per step): random walk of the external torque; None: derived for the vehicle."""
    position: float = 5e-4
    """Motion-capture position noise (m)."""
    attitude: float = 2e-3
    """Motion-capture attitude noise (rad)."""
    initial_attitude: float = 0.01
    initial_rates: float = 0.05
    initial_position: float = 0.01
    initial_velocity: float = 0.05
    initial_torque: float | None = None
    """N·m; None: derived for the vehicle."""
    initial_force: float | None = None
    """N; None: derived for the vehicle."""
    kappa: float = 2.0
    rotor_spread: float = 0.02
    """Relative sd of each rotor's thrust coefficient about the nominal (the env's ``kf_spread``, 0.02 by
    default): the filter cannot tell a rotor's error from an external wrench, so it enters the
    *reported* covariance of the wrench (:func:`rotor_spread_covariance`), never the estimate."""

    adaptive_walks: bool = False
    """True: covariance-matched walks (:mod:`~quad_wrench_env.estimators.walks`): each filter's force and
    torque walks (3x3 covariances per step) follow the outer product of the change each step makes to its
    own estimate, with forgetting, so that its reported covariance keeps up with the disturbance it meets
    (still air, a manoeuvre, a turbulent jet). False (the default): the fixed walks ``force_walk`` and
    ``torque_walk``, as the papers have them (why matched walks are not the default:
    ``docs/estimators.md``, "Covariance-matched walks")."""
    walk_forgetting: float = 0.98
    """α in (0, 1]: the weight of the last walk per step (0.98 at 200 Hz: a memory of about 0.25 s); 1
    keeps the walks where they start."""
    walk_ceiling: float = 30.0
    """The largest walk a matched filter keeps: a block's walk scaled down to ``walk_ceiling²`` times its
    default's trace (an RMS sd ``walk_ceiling`` times ``force_walk`` or ``torque_walk``; > 0). The fan's
    turbulence needs up to 11x (``fan_walks``); 30 leaves room and stops the runaway to ~200x seen on
    ``hummingbird`` under the admittance tracker."""
    walk_floor: float = 0.1
    """The smallest walk sd a matched filter reports in any direction, as a fraction (>= 0) of
    ``force_walk`` or ``torque_walk`` (its variance is added to the matched walk's diagonal)."""

    def __post_init__(self) -> None:
        unchecked = {"rotor_spread", *WALK_KEYS, *(k for k in REFERENCE_NOISE if getattr(self, k) is None)}
        check_numbers("estimator_params", self, tuple(k for k in vars(self) if k not in unchecked))
        check_numbers("estimator_params", self, ("rotor_spread", "walk_floor"), positive=False)
        if not isinstance(self.adaptive_walks, bool):
            raise ValueError(f"estimator_params.adaptive_walks={self.adaptive_walks!r} must be true or false")
        check_numbers("estimator_params", self, ("walk_forgetting", "walk_ceiling"))
        if self.walk_forgetting > 1.0:
            raise ValueError(
                f"estimator_params.walk_forgetting={self.walk_forgetting!r} must be in (0, 1] (the weight "
                "of the last walk variance per step)"
            )

    def walk_adaptation(self) -> tuple[float, float, float, float]:
        """``(on, α, floor², ceiling²)`` as the filters' kernels read them
        (:mod:`~quad_wrench_env.estimators.walks`)."""
        on, floor, ceiling = float(self.adaptive_walks), float(self.walk_floor), float(self.walk_ceiling)
        return on, float(self.walk_forgetting), floor**2, ceiling**2

    def for_vehicle(self: NoiseT, vehicle: VehicleParams) -> NoiseT:
        """These settings with every ``None`` replaced by its default for ``vehicle``
        (:data:`REFERENCE_NOISE` scaled by :func:`vehicle_scales`); given values stay as they are."""
        force_scale, torque_scale = vehicle_scales(vehicle)
        derived = {
            name: value * (force_scale if name in FORCE_KEYS else torque_scale)
            for name, value in REFERENCE_NOISE.items()
            if getattr(self, name) is None
        }
        return replace(self, **derived)


REFERENCE_VEHICLE = "ardrone2"
"""The preset the defaults were tuned on here: McKinnon & Schoellig's (2016) AR.Drone 2.0 (the paper
gives no covariance values)."""
REFERENCE_NOISE: dict[str, float] = {
    "thrust": 0.05,
    "force_walk": 4e-3,
    "initial_force": 0.2,
    "motor_torque": 3e-3,
    "torque_walk": 2e-4,
    "initial_torque": 0.02,
}
"""The vehicle-dependent settings on :data:`REFERENCE_VEHICLE` (N, N per step, N; N·m, N·m per step,
N·m): the thrust model's error and the external force's random walk and initial sd (about 1.2 %, 0.1 %
and 5 % of its weight), the motor-torque model's error and the external torque's walk and initial sd
(0.56 %, 0.04 % and 3.8 % of weight x arm)."""
WALK_KEYS = ("adaptive_walks", "walk_forgetting", "walk_floor", "walk_ceiling")
"""The settings of the covariance-matched walks (:func:`~quad_wrench_env.estimators.walks.match_walks`)."""
FORCE_KEYS = frozenset({"thrust", "force_walk", "initial_force"})
"""The settings that are forces (the rest of :data:`REFERENCE_NOISE` are torques)."""


def vehicle_scales(vehicle: VehicleParams) -> tuple[float, float]:
    """``(force scale, torque scale)`` of ``vehicle`` against :data:`REFERENCE_VEHICLE`: the ratio of the
    weights ``m g`` and of the moments ``m g l`` (l the rotor arm), exactly 1.0 on the reference.

    Every force a filter models scales with the thrust that holds the vehicle up: the thrust model's error
    (a relative error of the rotor coefficients and of the speed quantisation, McKinnon & Schoellig 2016
    eq. 4), the air and contact forces it meets (sized to hold it against them) and the belief at reset;
    every torque with a rotor's share of that thrust at its lever arm, the largest torque its rotors can
    make about the centre of mass. A filter tuned in absolute units on one vehicle is too wide by the
    ratio on a lighter one (on the 27 g crazyflie2, 16x in force and 71x in torque) and too narrow on a
    heavier one, which its NEES shows (``quad-wrench compare estimators --only nees``)."""
    reference = PRESETS[REFERENCE_VEHICLE]
    force_scale = vehicle.mass / reference.mass
    torque_scale = vehicle.mass * vehicle.arm / (reference.mass * reference.arm)
    return force_scale, torque_scale


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
    wrench_true`` adds it (:func:`add_rotor_spread`): a consider covariance (Schmidt 1966: a parameter
    the filter does not estimate, whose uncertainty it carries), exact at hover and a first-order one
    elsewhere."""
    out = np.zeros((len(quaternions), 6, 6))
    add_rotor_spread(body, quaternions, out)
    return out


def add_rotor_spread(body: np.ndarray, quaternions: np.ndarray, covariances: np.ndarray) -> None:
    """Add :func:`rotor_spread_covariance` to a filter's own (N, 6, 6) wrench ``covariances``, in place."""
    add_world_covariances(body, np.ascontiguousarray(quaternions, dtype=float), covariances)


@njit
def add_world_covariances(body, quaternions, out):
    """``J body Jᵀ`` per vehicle added to ``out`` (N, 6, 6), its upper triangle's sums mirrored."""
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
                out[n, i, j] += total
                if j != i:
                    out[n, j, i] += total


def walk_matrices(variances: np.ndarray) -> np.ndarray:
    """(2, 3, 3) walks, force then torque, diagonal with these six ``variances`` (where a filter starts)."""
    walks = np.empty((2, 3, 3))
    start_walks(walks, np.ascontiguousarray(variances, dtype=float))
    return walks


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

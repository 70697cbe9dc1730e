"""The extended Kalman disturbance estimator of Hentzen et al. (2019, Sec. III-A).

State (Sec. III-A-a), 18 components:

    index  0-2 p | 3-5 v | 6-8 (φ, θ, ψ) | 9-11 ω (body) | 12-14 f_ext (world) | 15-17 η_ext (body)

Input ``u = (T̂, η̂_prop)`` (Sec. III-A-b): collective thrust and body torque from the nominal mixer.
Dynamics (Sec. II-A with Euler angles, Sec. III-A-d), discretised with forward Euler:

    p' = p + T v
    v' = v + T ((R(φ,θ,ψ) e_z T̂ + f_ext)/m - g e_z)
    (φ,θ,ψ)' = (φ,θ,ψ) + T W(φ,θ) ω          W: body rates -> Euler-angle rates (ZYX)
    ω' = ω + T J⁻¹ (η̂_prop + η_ext - ω × J ω)
    f_ext' = f_ext + v_f,   η_ext' = η_ext + v_η          random walks

with the analytic Jacobian :func:`~quad_wrench_env.estimators.ekf_kernel.ekf_transition_jacobian` (the tests
check it against finite differences of :func:`~quad_wrench_env.estimators.ekf_kernel.ekf_transition`) and the
standard EKF equations (Sec. III-A-e). Measurements (Sec.
III-A-c): the motion-capture pose as Euler angles (the same data the UKF gets, for a fair
comparison), plus velocity and body rates when the env's sensors provide them (a state estimator,
as on Hentzen et al.'s (2019) vehicle). The yaw innovation is wrapped to [-π, π). The process noise uses the
same settings as the UKF (:class:`~quad_wrench_env.estimators.noise.FilterNoise`): thrust and
motor-torque noise enter v and ω through ``T/m`` and ``T/J``. The external torque is estimated in
the body frame, as in the paper, and reported in the world frame (``R η_ext``), like every estimator.

:class:`ExtendedFilterBank` runs N such filters as one batched computation (every array carries a
leading filter axis) by its kernel, :mod:`.ekf_kernel`, the one implementation of the
algebra; :class:`ExtendedWrenchEstimator`, the single-vehicle estimator, is a bank of one.
"""

from __future__ import annotations

import numpy as np

from quad_wrench_env.estimators.bank import BankOfOne, EstimatorInputs, FilterBank
from quad_wrench_env.estimators.ekf_kernel import (
    ekf_bank_step,
    ekf_constants,
    ekf_estimates,
    ekf_states,
    ekf_wrench_covariances,
    ekf_wrenches,
)
from quad_wrench_env.estimators.noise import (
    EKFNoise,
    add_rotor_spread,
    rotor_spread_body,
    walk_matrices,
)
from quad_wrench_env.rotations import euler_zyx_from_quat, quat_from_euler_zyx
from quad_wrench_env.vehicle import GRAVITY, VehicleParams

P, V, E, W, F, N = (slice(i, i + 3) for i in range(0, 18, 3))
STATE_DIM = 18
_TINY = 1e-10


class ExtendedFilterBank(FilterBank):
    """N Euler-angle EKFs with random-walk external force and torque (Hentzen et al. 2019), stepped together.

    State arrays: ``x`` (N, 18), ``P`` (N, 18, 18) and ``walks`` (N, 2, 3, 3), the force's and the body
    torque's random walks (:mod:`~quad_wrench_env.estimators.walks`).
    """

    name = "ekf"

    def __init__(self, vehicle: VehicleParams, dt: float, noise: EKFNoise | None, count: int) -> None:
        if count < 1:
            raise ValueError(f"count={count!r} must be at least 1 filter")
        self.vehicle = vehicle
        self.dt = dt
        self.count = count
        self.noise = (noise or EKFNoise()).for_vehicle(vehicle)
        self._rotor_spread = rotor_spread_body(vehicle, self.noise.rotor_spread)
        n = self.noise
        self.mass = vehicle.mass
        self.inertia = np.array(vehicle.inertia)
        q_diag = np.zeros(STATE_DIM)
        q_diag[P] = _TINY
        q_diag[V] = (dt * n.thrust / self.mass) ** 2
        q_diag[E] = _TINY
        q_diag[W] = (dt * n.motor_torque / self.inertia) ** 2
        q_diag[F] = n.force_walk**2
        q_diag[N] = n.torque_walk**2
        initial = (
            n.initial_position,
            n.initial_velocity,
            n.initial_attitude,
            n.initial_rates,
            n.initial_force,
            n.initial_torque,
        )
        self.P0 = np.diag(np.repeat(initial, 3) ** 2)
        noise_pose = np.repeat((n.position, n.attitude), 3) ** 2
        noise_motion = np.repeat((n.velocity, n.body_rate), 3) ** 2
        self.kernel_constants = ekf_constants(
            dt,
            self.mass,
            self.inertia,
            GRAVITY,
            q_diag,
            noise_pose,
            noise_motion,
            self.P0,
            n.walk_adaptation(),
        )
        """The step kernel's constants (:func:`~quad_wrench_env.estimators.ekf_kernel.ekf_constants`)."""
        self.x = np.zeros((count, STATE_DIM))
        self.P = np.tile(self.P0, (count, 1, 1))
        self.walk_defaults = walk_matrices(q_diag[12:18])
        """The walks (2, 3, 3) each filter starts from: force, body torque (per step)."""
        self.walks = np.tile(self.walk_defaults, (count, 1, 1, 1))
        """(N, 2, 3, 3) each filter's walks now (the defaults unless ``adaptive_walks`` matches them to
        its corrections)."""
        self.reinitialisations = np.zeros(count, dtype=int)

    # -- bank interface ----------------------------------------------------------------------------
    def reset(self, index: int | np.ndarray, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        """Start the filters ``index`` afresh at the given poses, at rest, with no external wrench."""
        self._restart(index, position, quaternion_wxyz)
        self.walks[index] = self.walk_defaults
        self.reinitialisations[index] = 0

    def _restart(self, index: int | np.ndarray, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        self.x[index] = 0.0
        self.x[index, P] = position
        self.x[index, E] = euler_zyx_from_quat(np.asarray(quaternion_wxyz, dtype=float))
        self.P[index] = self.P0

    def _kernel(self, inputs: EstimatorInputs) -> tuple:
        return ekf_bank_step, (
            self.x,
            self.P,
            self.walks,
            self.reinitialisations,
            *inputs,
            self.kernel_constants,
        )

    def quaternions(self) -> np.ndarray:
        """(N, 4) the estimated attitudes, from the ZYX Euler angles."""
        angles = self.x[:, E]
        return quat_from_euler_zyx(angles[:, 0], angles[:, 1], angles[:, 2])

    def wrenches(self) -> np.ndarray:
        """(N, 6) estimated ``[f_ext, R η_ext]``, world frame."""
        out = np.empty((self.count, 6))
        ekf_wrenches(self.x, out)
        return out

    def _estimates_kernel(self):
        return ekf_estimates, (self.x,)

    def wrench_covariances(self) -> np.ndarray:
        """(N, 6, 6) covariance of ``[f_ext, R η_ext]`` about the external wrench: the filter's own, plus
        the rotors' thrust-coefficient spread it cannot tell from an external wrench
        (:func:`~quad_wrench_env.estimators.noise.rotor_spread_covariance`)."""
        out = np.empty((self.count, 6, 6))
        ekf_wrench_covariances(self.x, self.P, out)
        add_rotor_spread(self._rotor_spread, self.quaternions(), out)
        return out

    def states(self) -> np.ndarray:
        """(N, 13) estimated position, velocity, quaternion and body rates."""
        out = np.empty((self.count, 13))
        ekf_states(self.x, out)
        return out

    def statuses(self) -> list[str]:
        return ["ok" if k == 0 else "reinitialised" for k in self.reinitialisations.tolist()]


class ExtendedWrenchEstimator(BankOfOne):
    """Hentzen et al.'s (2019) EKF for one vehicle: a bank of one filter."""

    name = "ekf"

    def __init__(self, vehicle: VehicleParams, dt: float, noise: EKFNoise | None = None) -> None:
        self.bank = ExtendedFilterBank(vehicle, dt, noise, count=1)

    @property
    def x(self) -> np.ndarray:
        return self.bank.x[0]

    @property
    def covariance(self) -> np.ndarray:
        """(18, 18) state covariance."""
        return self.bank.P[0]

    @property
    def quaternion(self) -> np.ndarray:
        return self.bank.quaternions()[0]

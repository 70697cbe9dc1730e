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

with the analytic Jacobian :meth:`ExtendedFilterBank.transition_jacobian` (the tests check it
against finite differences) and the standard EKF equations (Sec. III-A-e). Measurements (Sec.
III-A-c): the motion-capture pose as Euler angles (the same data the UKF gets, for a fair
comparison), plus velocity and body rates when the env's sensors provide them (a state estimator,
as on Hentzen et al.'s (2019) vehicle). The yaw innovation is wrapped to [-π, π). The process noise uses the
same settings as the UKF (:class:`~quad_wrench_env.estimators.noise.FilterNoise`): thrust and
motor-torque noise enter v and ω through ``T/m`` and ``T/J``. The external torque is estimated in
the body frame, as in the paper, and reported in the world frame (``R η_ext``), like every estimator.

:class:`ExtendedFilterBank` runs N such filters as one batched computation (every array carries a
leading filter axis); :class:`ExtendedWrenchEstimator`, the single-vehicle estimator, is a bank of
one, so there is one implementation of the algebra.
"""

from __future__ import annotations

import numpy as np

from quad_wrench_env.estimators.bank import BankOfOne, EulerAttitudes, FilterBank
from quad_wrench_env.estimators.noise import EKFNoise, rotor_spread_body, rotor_spread_covariance
from quad_wrench_env.kernels import resolve_backend
from quad_wrench_env.kernels.ekf import (
    ekf_bank_step,
    ekf_constants,
    ekf_estimates,
    ekf_states,
    ekf_wrench_covariances,
    ekf_wrenches,
)
from quad_wrench_env.rotations import (
    cross,
    euler_zyx_from_quat,
    quat_from_euler_zyx,
    rotation_matrices,
    wrap_angle,
)
from quad_wrench_env.vehicle import GRAVITY, VehicleParams

P, V, E, W, F, N = (slice(i, i + 3) for i in range(0, 18, 3))
STATE_DIM = 18
_TINY = 1e-10


def euler_rate_matrix(roll: np.ndarray, pitch: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """(n, 3, 3) ``W`` with ``(φ̇, θ̇, ψ̇) = W ω`` for ZYX Euler angles and body rates ω (n,);
    written into ``out`` (n, 3, 3, zero where W is) when given."""
    sr, cr = np.sin(roll), np.cos(roll)
    tp, cp = np.tan(pitch), np.cos(pitch)
    if out is None:
        out = np.zeros((len(roll), 3, 3))
    out[:, 0, 0] = 1.0
    out[:, 0, 1], out[:, 0, 2] = sr * tp, cr * tp
    out[:, 1, 1], out[:, 1, 2] = cr, -sr
    out[:, 2, 1], out[:, 2, 2] = sr / cp, cr / cp
    return out


class ExtendedFilterBank(FilterBank, EulerAttitudes):
    """N Euler-angle EKFs with random-walk external force and torque (Hentzen et al. 2019), stepped together.

    State arrays: ``x`` (N, 18) and ``P`` (N, 18, 18).
    """

    name = "ekf"

    def __init__(
        self, vehicle: VehicleParams, dt: float, noise: EKFNoise | None, count: int, backend: str = "numpy"
    ) -> None:
        if count < 1:
            raise ValueError(f"count={count!r} must be at least 1 filter")
        self.backend = resolve_backend(backend)
        self.vehicle = vehicle
        self.dt = dt
        self.count = count
        self.noise = noise or EKFNoise()
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
        self.Q = np.diag(q_diag)
        initial = (
            n.initial_position, n.initial_velocity, n.initial_attitude,
            n.initial_rates, n.initial_force, n.initial_torque,
        )  # fmt: skip
        self.P0 = np.diag(np.repeat(initial, 3) ** 2)
        self._noise_pose = np.repeat((n.position, n.attitude), 3) ** 2
        self._noise_motion = np.repeat((n.velocity, n.body_rate), 3) ** 2
        self.kernel_constants = ekf_constants(
            dt, self.mass, self.inertia, GRAVITY, q_diag, self._noise_pose, self._noise_motion, self.P0
        )
        """The compiled step's constants (:func:`~quad_wrench_env.kernels.ekf.ekf_constants`)."""
        self.x = np.zeros((count, STATE_DIM))
        self.P = np.tile(self.P0, (count, 1, 1))
        self.reinitialisations = np.zeros(count, dtype=int)
        self.version = 0

    # -- bank interface ----------------------------------------------------------------------------
    def reset(self, index: int | np.ndarray, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        """Start the filters ``index`` afresh at the given poses, at rest, with no external wrench."""
        self._restart(index, position, quaternion_wxyz)
        self.reinitialisations[index] = 0

    def _restart(self, index: int | np.ndarray, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        self.x[index] = 0.0
        self.x[index, P] = position
        self.x[index, E] = euler_zyx_from_quat(np.asarray(quaternion_wxyz, dtype=float))
        self.P[index] = self.P0
        self.version += 1

    def _kernel(self, thrusts, body_torques, positions, quaternions, velocities, body_rates):
        return ekf_bank_step, (
            self.x, self.P, self.reinitialisations, thrusts, body_torques, positions, quaternions,
            velocities, body_rates, self.kernel_constants,
        )  # fmt: skip

    def _numpy_step(self, thrusts, body_torques, positions, quaternions, velocities, body_rates) -> None:
        """Predict with (N,) thrusts and (N, 3) body torques, correct with the measured (N, 3)
        positions, (N, 4) attitudes and, where measured, (N, 3) velocities and body rates; restart
        any filter whose state became non-finite."""
        self.predict(np.column_stack((thrusts, body_torques)))
        self.correct(positions, quaternions, velocities, body_rates)
        broken = ~(np.isfinite(self.x).all(axis=1) & np.isfinite(self.P).all(axis=(1, 2)))
        if np.any(broken):
            self._restart(broken, positions[broken], quaternions[broken])
            self.reinitialisations[broken] += 1

    def euler_angles(self) -> np.ndarray:
        """(N, 3) the estimated roll, pitch, yaw."""
        return self.x[:, 6:9]

    def rotations(self) -> np.ndarray:
        """(N, 3, 3) body -> world matrices of the estimated attitudes."""
        return self.attitudes()[1]

    def quaternions(self) -> np.ndarray:
        return self.attitudes()[0]

    def wrenches(self) -> np.ndarray:
        """(N, 6) estimated ``[f_ext, R η_ext]``, world frame."""
        if self.backend == "numba":
            out = np.empty((self.count, 6))
            ekf_wrenches(self.x, out)
            return out
        torque = np.einsum("nij,nj->ni", self.rotations(), self.x[:, N])
        return np.concatenate((self.x[:, F], torque), axis=1)

    def _estimates_kernel(self):
        return ekf_estimates, (self.x,)

    def wrench_covariances(self) -> np.ndarray:
        """(N, 6, 6) covariance of ``[f_ext, R η_ext]`` about the external wrench: the filter's own, plus
        the rotors' thrust-coefficient spread it cannot tell from an external wrench
        (:func:`~quad_wrench_env.estimators.noise.rotor_spread_covariance`)."""
        spread = rotor_spread_covariance(self._rotor_spread, self.quaternions())
        if self.backend == "numba":
            out = np.empty((self.count, 6, 6))
            ekf_wrench_covariances(self.x, self.P, out)
            return out + spread
        rotate = np.tile(np.eye(6), (self.count, 1, 1))
        rotate[:, 3:, 3:] = self.rotations()
        block = self.P[:, 12:18, 12:18]
        return rotate @ block @ rotate.transpose(0, 2, 1) + spread

    def states(self) -> np.ndarray:
        """(N, 13) estimated position, velocity, quaternion and body rates."""
        if self.backend == "numba":
            out = np.empty((self.count, 13))
            ekf_states(self.x, out)
            return out
        return np.concatenate((self.x[:, P], self.x[:, V], self.quaternions(), self.x[:, W]), axis=1)

    def statuses(self) -> list[str]:
        return ["ok" if k == 0 else "reinitialised" for k in self.reinitialisations.tolist()]

    # -- model -----------------------------------------------------------------------------------
    def transition(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Forward-Euler step of the noise-free dynamics (module docstring) for (n, 18) states and
        (n, 4) inputs."""
        T, m = self.dt, self.mass
        roll, pitch, yaw = x[:, 6], x[:, 7], x[:, 8]
        omega = x[:, W]
        R = self.rotations() if x is self.x else rotation_matrices(quat_from_euler_zyx(roll, pitch, yaw))
        out = x.copy()
        accel = (R[:, :, 2] * u[:, :1] + x[:, F]) / m
        accel[:, 2] -= GRAVITY
        out[:, P] += T * x[:, V]
        out[:, V] += T * accel
        out[:, E] += T * np.einsum("nij,nj->ni", euler_rate_matrix(roll, pitch), omega)
        out[:, W] += T * (u[:, 1:] + x[:, N] - cross(omega, self.inertia * omega)) / self.inertia
        return out

    def transition_jacobian(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """``∂ transition / ∂ x`` (n, 18, 18), analytic."""
        T, m = self.dt, self.mass
        roll, pitch, yaw = x[:, 6], x[:, 7], x[:, 8]
        p_, q_, r_ = x[:, 9], x[:, 10], x[:, 11]
        sr, cr = np.sin(roll), np.cos(roll)
        sp, cp, tp = np.sin(pitch), np.cos(pitch), np.tan(pitch)
        sy, cy = np.sin(yaw), np.cos(yaw)
        A = np.zeros((len(x), STATE_DIM, STATE_DIM))
        A[:, P, V] = np.eye(3)
        # v' = (R e_z T + f)/m - g: columns of ∂(R e_z)/∂(φ, θ, ψ), times T̂/m
        c = u[:, 0] / m
        A[:, 3, 6], A[:, 4, 6], A[:, 5, 6] = (
            (-cy * sp * sr + sy * cr) * c,
            (-sy * sp * sr - cy * cr) * c,
            -cp * sr * c,
        )
        A[:, 3, 7], A[:, 4, 7], A[:, 5, 7] = cy * cp * cr * c, sy * cp * cr * c, -sp * cr * c
        A[:, 3, 8], A[:, 4, 8] = (-sy * sp * cr + cy * sr) * c, (cy * sp * cr + sy * sr) * c
        A[:, V, F] = np.eye(3) / m
        # Euler rates W(φ, θ) ω
        A[:, 6, 6], A[:, 6, 7] = cr * tp * q_ - sr * tp * r_, (sr * q_ + cr * r_) / cp**2
        A[:, 7, 6] = -sr * q_ - cr * r_
        A[:, 8, 6], A[:, 8, 7] = (cr * q_ - sr * r_) / cp, (sr * q_ + cr * r_) * sp / cp**2
        euler_rate_matrix(roll, pitch, out=A[:, E, W])
        # ω' : -J⁻¹ (ω × Jω), whose derivative is -J⁻¹ (skew(ω) J - skew(J ω)), and J⁻¹ η_ext
        jx, jy, jz = self.inertia
        A[:, 9, 10], A[:, 9, 11] = (jy - jz) / jx * r_, (jy - jz) / jx * q_
        A[:, 10, 9], A[:, 10, 11] = (jz - jx) / jy * r_, (jz - jx) / jy * p_
        A[:, 11, 9], A[:, 11, 10] = (jx - jy) / jz * q_, (jx - jy) / jz * p_
        A[:, W, N] = np.diag(1.0 / self.inertia)
        A *= T
        A += np.eye(STATE_DIM)
        return A

    # -- filter ----------------------------------------------------------------------------------
    def predict(self, u: np.ndarray) -> None:
        F_k = self.transition_jacobian(self.x, u)
        self.x = self.transition(self.x, u)
        self.P = F_k @ self.P @ F_k.transpose(0, 2, 1) + self.Q

    def correct(
        self,
        positions: np.ndarray,
        quaternions: np.ndarray,
        velocities: np.ndarray | None,
        body_rates: np.ndarray | None,
    ) -> None:
        indices = [np.r_[P], np.r_[E]]
        residuals = [positions - self.x[:, P], wrap_angle(euler_zyx_from_quat(quaternions) - self.x[:, E])]
        noise = [self._noise_pose]
        if velocities is not None:
            indices.append(np.r_[V])
            residuals.append(velocities - self.x[:, V])
            noise.append(self._noise_motion[:3])
        if body_rates is not None:
            indices.append(np.r_[W])
            residuals.append(body_rates - self.x[:, W])
            noise.append(self._noise_motion[3:])
        measured = np.concatenate(indices)
        PHt = self.P[:, :, measured]
        S = PHt[:, measured, :] + np.diag(np.concatenate(noise))
        K = np.linalg.solve(S, PHt.transpose(0, 2, 1)).transpose(0, 2, 1)
        self.x = self.x + (K @ np.concatenate(residuals, axis=1)[:, :, None])[:, :, 0]
        self.x[:, E] = wrap_angle(self.x[:, E])
        P_new = self.P - K @ PHt.transpose(0, 2, 1)
        self.P = 0.5 * (P_new + P_new.transpose(0, 2, 1))


class ExtendedWrenchEstimator(BankOfOne):
    """Hentzen et al.'s (2019) EKF for one vehicle: a bank of one filter."""

    name = "ekf"

    def __init__(
        self, vehicle: VehicleParams, dt: float, noise: EKFNoise | None = None, backend: str = "numpy"
    ) -> None:
        self.bank = ExtendedFilterBank(vehicle, dt, noise, count=1, backend=backend)

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

    def transition(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        return self.bank.transition(x[None], u[None])[0]

    def transition_jacobian(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        return self.bank.transition_jacobian(x[None], u[None])[0]

"""The extended Kalman disturbance estimator of Hentzen et al. (paper 003, Sec. III-A).

State (Sec. III-A-a), 18 components:

    index  0-2 p | 3-5 v | 6-8 (φ, θ, ψ) | 9-11 ω (body) | 12-14 f_ext (world) | 15-17 η_ext (body)

Input ``u = (T̂, η̂_prop)`` (Sec. III-A-b): collective thrust and body torque from the nominal mixer.
Dynamics (Sec. II-A with Euler angles, Sec. III-A-d), discretised with forward Euler:

    p' = p + T v
    v' = v + T ((R(φ,θ,ψ) e_z T̂ + f_ext)/m - g e_z)
    (φ,θ,ψ)' = (φ,θ,ψ) + T W(φ,θ) ω          W: body rates -> Euler-angle rates (ZYX)
    ω' = ω + T J⁻¹ (η̂_prop + η_ext - ω × J ω)
    f_ext' = f_ext + v_f,   η_ext' = η_ext + v_η          random walks

with the analytic Jacobian :meth:`ExtendedWrenchEstimator.transition_jacobian` (the tests check it
against finite differences) and the standard EKF equations (Sec. III-A-e). Measurements (Sec.
III-A-c): the motion-capture pose as Euler angles (the same data the UKF gets, for a fair
comparison), plus velocity and body rates when the env's sensors provide them (a state estimator,
as on paper 003's vehicle). The yaw innovation is wrapped to [-π, π). The process noise uses the
same settings as the UKF (:class:`~quad_wrench_env.estimators.noise.FilterNoise`): thrust and
motor-torque noise enter v and ω through ``T/m`` and ``T/J``. The external torque is estimated in
the body frame, as in the paper, and reported in the world frame (``R η_ext``), like every estimator.
"""

from __future__ import annotations

import math

import numpy as np

from quad_wrench_env.estimators.base import StateEstimate, WrenchEstimate, check_finite_inputs
from quad_wrench_env.estimators.noise import EKFNoise
from quad_wrench_env.rotations import (
    cross,
    euler_zyx_from_quat,
    quat_from_euler_zyx,
    rotation_matrix,
    skew,
    wrap_angle,
)
from quad_wrench_env.vehicle import GRAVITY, VehicleParams

P, V, E, W, F, N = (slice(i, i + 3) for i in range(0, 18, 3))
STATE_DIM = 18
_TINY = 1e-10


def euler_rate_matrix(roll: float, pitch: float) -> np.ndarray:
    """``W`` with ``(φ̇, θ̇, ψ̇) = W ω`` for ZYX Euler angles and body rates ω."""
    sr, cr = math.sin(roll), math.cos(roll)
    tp, cp = math.tan(pitch), math.cos(pitch)
    return np.array(((1.0, sr * tp, cr * tp), (0.0, cr, -sr), (0.0, sr / cp, cr / cp)))


class ExtendedWrenchEstimator:
    """Euler-angle EKF with random-walk external force and torque (paper 003)."""

    name = "ekf"

    def __init__(self, vehicle: VehicleParams, dt: float, noise: EKFNoise | None = None) -> None:
        self.vehicle = vehicle
        self.dt = dt
        self.noise = noise or EKFNoise()
        n = self.noise
        self.mass = vehicle.mass
        self.inertia = np.array(vehicle.inertia)
        self._J = np.diag(self.inertia)
        q_diag = np.zeros(STATE_DIM)
        q_diag[P] = _TINY
        q_diag[V] = (dt * n.thrust / self.mass) ** 2
        q_diag[E] = _TINY
        q_diag[W] = (dt * n.motor_torque / self.inertia) ** 2
        q_diag[F] = n.force_walk**2
        q_diag[N] = n.torque_walk**2
        self.Q = np.diag(q_diag)
        self.P0 = np.diag(
            np.repeat(
                (
                    n.initial_position,
                    n.initial_velocity,
                    n.initial_attitude,
                    n.initial_rates,
                    n.initial_force,
                    n.initial_torque,
                ),
                3,
            )
            ** 2
        )
        self._noise_pose = np.repeat((n.position, n.attitude), 3) ** 2
        self._noise_motion = np.repeat((n.velocity, n.body_rate), 3) ** 2
        self.x = np.zeros(STATE_DIM)
        self.P = self.P0.copy()
        self.status = "ok"

    # -- interface -------------------------------------------------------------------------------
    def reset(self, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        self.x = np.zeros(STATE_DIM)
        self.x[P] = position
        self.x[E] = euler_zyx_from_quat(np.asarray(quaternion_wxyz, dtype=float))
        self.P = self.P0.copy()
        self.status = "ok"

    def step(
        self,
        thrust: float,
        body_torque: np.ndarray,
        position: np.ndarray,
        quaternion_wxyz: np.ndarray,
        velocity: np.ndarray | None = None,
        body_rates: np.ndarray | None = None,
    ) -> WrenchEstimate:
        check_finite_inputs(
            self.name,
            thrust=thrust,
            body_torque=body_torque,
            position=position,
            quaternion=quaternion_wxyz,
            velocity=velocity,
            body_rates=body_rates,
        )
        u = np.concatenate(((thrust,), body_torque))
        self.predict(u)
        self.correct(
            np.asarray(position, dtype=float), np.asarray(quaternion_wxyz, dtype=float), velocity, body_rates
        )
        if not (np.all(np.isfinite(self.x)) and np.all(np.isfinite(self.P))):
            self.reset(np.asarray(position, dtype=float), np.asarray(quaternion_wxyz, dtype=float))
            self.status = "reinitialised"
        return self.estimate

    @property
    def estimate(self) -> WrenchEstimate:
        R = rotation_matrix(self.quaternion)
        block = np.r_[12:18]
        rotate = np.eye(6)
        rotate[3:, 3:] = R
        covariance = rotate @ self.P[np.ix_(block, block)] @ rotate.T
        return WrenchEstimate(self.x[F].copy(), R @ self.x[N], covariance)

    @property
    def quaternion(self) -> np.ndarray:
        return quat_from_euler_zyx(*self.x[E])

    @property
    def state(self) -> StateEstimate:
        return StateEstimate(self.x[P].copy(), self.x[V].copy(), self.quaternion, self.x[W].copy())

    # -- model -----------------------------------------------------------------------------------
    def transition(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Forward-Euler step of the noise-free dynamics (module docstring)."""
        T, m = self.dt, self.mass
        roll, pitch, yaw = x[E]
        omega = x[W]
        R = rotation_matrix(quat_from_euler_zyx(roll, pitch, yaw))
        out = x.copy()
        accel = (R[:, 2] * u[0] + x[F]) / m
        accel[2] -= GRAVITY
        out[P] += T * x[V]
        out[V] += T * accel
        out[E] += T * euler_rate_matrix(roll, pitch) @ omega
        out[W] += T * (u[1:] + x[N] - cross(omega, self.inertia * omega)) / self.inertia
        return out

    def transition_jacobian(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """``∂ transition / ∂ x`` (18 x 18), analytic."""
        T, m = self.dt, self.mass
        roll, pitch, yaw = x[E]
        _, q_, r_ = x[W]
        sr, cr = math.sin(roll), math.cos(roll)
        sp, cp, tp = math.sin(pitch), math.cos(pitch), math.tan(pitch)
        sy, cy = math.sin(yaw), math.cos(yaw)
        A = np.zeros((STATE_DIM, STATE_DIM))
        A[P, V] = np.eye(3)
        # v' = (R e_z T + f)/m - g: columns of ∂(R e_z)/∂(φ, θ, ψ)
        d_roll = (-cy * sp * sr + sy * cr, -sy * sp * sr - cy * cr, -cp * sr)
        d_pitch = (cy * cp * cr, sy * cp * cr, -sp * cr)
        d_yaw = (-sy * sp * cr + cy * sr, cy * sp * cr + sy * sr, 0.0)
        A[V, E] = np.column_stack((d_roll, d_pitch, d_yaw)) * (u[0] / m)
        A[V, F] = np.eye(3) / m
        # Euler rates W(φ, θ) ω
        A[E, E] = np.array(
            (
                (cr * tp * q_ - sr * tp * r_, (sr * q_ + cr * r_) / cp**2, 0.0),
                (-sr * q_ - cr * r_, 0.0, 0.0),
                ((cr * q_ - sr * r_) / cp, (sr * q_ + cr * r_) * sp / cp**2, 0.0),
            )
        )
        A[E, W] = euler_rate_matrix(roll, pitch)
        # ω' : -J⁻¹ (ω × Jω) and J⁻¹ η_ext
        omega = x[W]
        A[W, W] = -(skew(omega) @ self._J - skew(self.inertia * omega)) / self.inertia[:, None]
        A[W, N] = np.diag(1.0 / self.inertia)
        return np.eye(STATE_DIM) + T * A

    # -- filter ----------------------------------------------------------------------------------
    def predict(self, u: np.ndarray) -> None:
        F_k = self.transition_jacobian(self.x, u)
        self.x = self.transition(self.x, u)
        self.P = F_k @ self.P @ F_k.T + self.Q

    def correct(
        self,
        position: np.ndarray,
        quaternion: np.ndarray,
        velocity: np.ndarray | None,
        body_rates: np.ndarray | None,
    ) -> None:
        indices = [np.r_[P], np.r_[E]]
        residuals = [position - self.x[P], wrap_angle(euler_zyx_from_quat(quaternion) - self.x[E])]
        noise = [self._noise_pose]
        if velocity is not None:
            indices.append(np.r_[V])
            residuals.append(velocity - self.x[V])
            noise.append(self._noise_motion[:3])
        if body_rates is not None:
            indices.append(np.r_[W])
            residuals.append(body_rates - self.x[W])
            noise.append(self._noise_motion[3:])
        measured = np.concatenate(indices)
        PHt = self.P[:, measured]
        S = PHt[measured] + np.diag(np.concatenate(noise))
        K = np.linalg.solve(S, PHt.T).T
        self.x = self.x + K @ np.concatenate(residuals)
        self.x[E] = wrap_angle(self.x[E])
        P_new = self.P - K @ PHt.T
        self.P = 0.5 * (P_new + P_new.T)

"""The nonlinear wrench observer of Yüksel et al. (paper 001, Sec. II, eqs. 9-15).

In generalised coordinates ``q = (x, η)`` (position, ZYX Euler angles) the dynamics read
``w_e = B(q) q̈ + C(q, q̇) q̇ + g - G(q) ū`` (eqs. 1-3), with ``B = diag(m I, 𝕁(η))``,
``𝕁 = Tᵀ J T`` and ``ω = T(η) η̇``. With ``p(q̇) = c q̇`` (eq. 14) and ``L = c B⁻¹`` (eq. 15) the
observer (eq. 13)

    Ψ̇ = -L Ψ + L (C q̇ + g - G ū - p(q̇)),      ŵ_e = Ψ + p(q̇)

needs no acceleration, and its error obeys ``ė = -L e`` (eq. 8): ``exp(-c t / m)`` for the force.
The project's frames are used: z up (the paper's NED flips the signs of g and of the thrust),
``g = m g₀ e_z`` and ``G ū = (ρ R e_z, Tᵀ τ̄)`` with the body torque τ̄ mapped to generalised forces
by ``Tᵀ``. The Coriolis term is evaluated as ``C(η, η̇) η̇ = Tᵀ (J Ṫ η̇ + ω × J ω)``, which is what
the Lagrangian with ``𝕁 = TᵀJT`` gives. Separate gains ``c_force`` and ``c_torque`` (paper 001:
5 and 0.5). The force part is integrated exactly (``L = c/m`` is scalar), the torque part with
backward Euler (``L = c 𝕁⁻¹`` is stiff for light vehicles).

The velocities ``ẋ``, ``η̇`` come from the measured poses by finite differences, low-pass filtered
with time constants ``velocity_time_constant`` and ``rate_time_constant`` (paper 000 Sec. IV: the
observer needs filtering under noise); measured velocity and body rates are used instead when the
env provides them. The torque estimate ``τ̂_gen`` is in generalised (Euler) coordinates; it is
reported in the world frame like every estimator's: ``R T⁻ᵀ τ̂_gen``. The observer carries no
covariance: it reports zeros.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.estimators.base import StateEstimate, WrenchEstimate, check_finite_inputs
from quad_wrench_env.rotations import (
    cross,
    euler_zyx_from_quat,
    quat_from_euler_zyx,
    rotation_matrix,
    wrap_angle,
)
from quad_wrench_env.vehicle import GRAVITY, VehicleParams

_NO_COVARIANCE = np.zeros((6, 6))
_NO_COVARIANCE.flags.writeable = False


@dataclass
class ObserverGains:
    """Observer gains (paper 001) and the measurement filters (paper 000 Sec. IV)."""

    c_force: float = 5.0
    c_torque: float = 0.5
    velocity_time_constant: float = 0.05
    """s; first-order low-pass on the finite-difference velocity (0 = none)."""
    rate_time_constant: float = 0.05
    """s; first-order low-pass on the finite-difference Euler-angle rates (0 = none)."""

    def __post_init__(self) -> None:
        check_numbers("estimator_params", self, ("c_force", "c_torque"))
        check_numbers(
            "estimator_params", self, ("velocity_time_constant", "rate_time_constant"), positive=False
        )


def euler_kinematics(roll: float, pitch: float) -> np.ndarray:
    """``T(η)`` with ``ω = T η̇`` (body rates from ZYX Euler-angle rates), paper 001 Sec. II."""
    sr, cr = math.sin(roll), math.cos(roll)
    sp, cp = math.sin(pitch), math.cos(pitch)
    return np.array(((1.0, 0.0, -sp), (0.0, cr, sr * cp), (0.0, -sr, cr * cp)))


def euler_kinematics_rate(roll: float, pitch: float, roll_rate: float, pitch_rate: float) -> np.ndarray:
    """``Ṫ(η, η̇)``."""
    sr, cr = math.sin(roll), math.cos(roll)
    sp, cp = math.sin(pitch), math.cos(pitch)
    return np.array(
        (
            (0.0, 0.0, -cp * pitch_rate),
            (0.0, -sr * roll_rate, cr * cp * roll_rate - sr * sp * pitch_rate),
            (0.0, -cr * roll_rate, -sr * cp * roll_rate - cr * sp * pitch_rate),
        )
    )


class NonlinearWrenchObserver:
    """Momentum-type observer without acceleration (paper 001 eqs. 9-15)."""

    name = "observer"
    status = "ok"

    def __init__(self, vehicle: VehicleParams, dt: float, gains: ObserverGains | None = None) -> None:
        self.vehicle = vehicle
        self.dt = dt
        self.gains = gains or ObserverGains()
        self.mass = vehicle.mass
        self.inertia = np.array(vehicle.inertia)
        g = self.gains
        self._force_decay = math.exp(-g.c_force * dt / self.mass)
        self._velocity_alpha = _alpha(dt, g.velocity_time_constant)
        self._rate_alpha = _alpha(dt, g.rate_time_constant)
        self.reset(np.zeros(3), np.array((1.0, 0.0, 0.0, 0.0)))

    def reset(self, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        self._position = np.array(position, dtype=float)
        self._euler = euler_zyx_from_quat(np.asarray(quaternion_wxyz, dtype=float))
        self._velocity = np.zeros(3)
        self._euler_rate = np.zeros(3)
        # at rest with zero wrench: ŵ = Ψ + c q̇ = 0
        self._psi_force = np.zeros(3)
        self._psi_torque = np.zeros(3)
        self._force = np.zeros(3)
        self._torque_generalised = np.zeros(3)

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
        self._measure(
            np.asarray(position, dtype=float), np.asarray(quaternion_wxyz, dtype=float), velocity, body_rates
        )
        g, dt = self.gains, self.dt
        roll, pitch, _ = self._euler
        R = rotation_matrix(quat_from_euler_zyx(*self._euler))
        # force block (eq. 13 with L = c/m): Ψ' = e^{-cT/m} Ψ + (1 - e^{-cT/m}) (m g e_z - ρ R e_z - c ẋ)
        drive = -thrust * R[:, 2] - g.c_force * self._velocity
        drive[2] += self.mass * GRAVITY
        self._psi_force = self._force_decay * self._psi_force + (1.0 - self._force_decay) * drive
        self._force = self._psi_force + g.c_force * self._velocity
        # torque block (eq. 13 with L = c 𝕁⁻¹), backward Euler: (𝕁 + c T) Ψ' = 𝕁 Ψ + c T (C η̇ - Tᵀτ̄ - c η̇)
        T_eta = euler_kinematics(roll, pitch)
        J_gen = T_eta.T @ (self.inertia[:, None] * T_eta)
        eta_rate = self._euler_rate
        omega = T_eta @ eta_rate
        coriolis = T_eta.T @ (
            self.inertia * (euler_kinematics_rate(roll, pitch, *eta_rate[:2]) @ eta_rate)
            + cross(omega, self.inertia * omega)
        )
        drive_torque = coriolis - T_eta.T @ body_torque - g.c_torque * eta_rate
        gain = g.c_torque * dt
        self._psi_torque = np.linalg.solve(
            J_gen + gain * np.eye(3), J_gen @ self._psi_torque + gain * drive_torque
        )
        self._torque_generalised = self._psi_torque + g.c_torque * eta_rate
        return self.estimate

    def _measure(
        self,
        position: np.ndarray,
        quaternion: np.ndarray,
        velocity: np.ndarray | None,
        body_rates: np.ndarray | None,
    ) -> None:
        euler = euler_zyx_from_quat(quaternion)
        if velocity is not None:
            self._velocity = np.asarray(velocity, dtype=float)
        else:
            raw = (position - self._position) / self.dt
            self._velocity = self._velocity + self._velocity_alpha * (raw - self._velocity)
        if body_rates is not None:
            self._euler_rate = np.linalg.solve(euler_kinematics(*euler[:2]), body_rates)
        else:
            raw = wrap_angle(euler - self._euler) / self.dt
            self._euler_rate = self._euler_rate + self._rate_alpha * (raw - self._euler_rate)
        self._position = position
        self._euler = euler

    @property
    def estimate(self) -> WrenchEstimate:
        roll, pitch, _ = self._euler
        body = np.linalg.solve(euler_kinematics(roll, pitch).T, self._torque_generalised)
        R = rotation_matrix(quat_from_euler_zyx(*self._euler))
        return WrenchEstimate(self._force.copy(), R @ body, _NO_COVARIANCE)

    @property
    def state(self) -> StateEstimate:
        roll, pitch, _ = self._euler
        return StateEstimate(
            self._position.copy(),
            self._velocity.copy(),
            quat_from_euler_zyx(*self._euler),
            euler_kinematics(roll, pitch) @ self._euler_rate,
        )


def _alpha(dt: float, time_constant: float) -> float:
    """Step gain of a first-order low-pass with ``time_constant`` (1 = no filtering)."""
    return 1.0 if time_constant == 0 else 1.0 - math.exp(-dt / time_constant)

"""The nonlinear wrench observer of Yüksel et al. (2014, Sec. II, eqs. 9-15).

In generalised coordinates ``q = (x, η)`` (position, ZYX Euler angles) the dynamics read
``w_e = B(q) q̈ + C(q, q̇) q̇ + g - G(q) ū`` (eqs. 1-3), with ``B = diag(m I, 𝕁(η))``,
``𝕁 = Tᵀ J T`` and ``ω = T(η) η̇``. With ``p(q̇) = c q̇`` (eq. 14) and ``L = c B⁻¹`` (eq. 15) the
observer (eq. 13)

    Ψ̇ = -L Ψ + L (C q̇ + g - G ū - p(q̇)),      ŵ_e = Ψ + p(q̇)

needs no acceleration, and its error obeys ``ė = -L e`` (eq. 8): ``exp(-c t / m)`` for the force.
The project's frames are used: z up (the paper's NED flips the signs of g and of the thrust),
``g = m g₀ e_z`` and ``G ū = (ρ R e_z, Tᵀ τ̄)`` with the body torque τ̄ mapped to generalised forces
by ``Tᵀ``. The Coriolis term is evaluated as ``C(η, η̇) η̇ = Tᵀ (J Ṫ η̇ + ω × J ω)``, which is what
the Lagrangian with ``𝕁 = TᵀJT`` gives. Separate gains ``c_force`` and ``c_torque``: Yüksel et al.'s (2014)
5 N·s/m and 0.5 N·m·s/rad are for their 1 kg vehicle (J_x = 0.13 kg·m²); by default they are scaled to
the vehicle's mass and roll inertia, so that the error time constants ``m/c`` (0.2 s) and ``J/c``
(0.26 s) are those of Yüksel et al. 2014 on every vehicle (unscaled, a 0.003 kg·m² ardrone2 would get a
170 rad/s torque observer that passes the measurement noise straight through). The force part is integrated
exactly (``L = c/m`` is scalar), the torque part with backward Euler (``L = c 𝕁⁻¹`` is stiff for
light vehicles).

The velocities ``ẋ``, ``η̇`` come from the measured poses by finite differences, low-pass filtered
with time constants ``velocity_time_constant`` and ``rate_time_constant`` (McKinnon & Schoellig 2016 Sec. IV:
the observer needs filtering under noise); measured velocity and body rates are used instead when the
env provides them. The torque estimate ``τ̂_gen`` is in generalised (Euler) coordinates; it is
reported in the world frame like every estimator's: ``R T⁻ᵀ τ̂_gen``. The observer carries no
covariance (Yüksel et al. 2014 give none: its error dynamics ``ė = -L e`` are deterministic): it reports NaN,
not an invented one.

:class:`ObserverBank` runs N observers as one batched computation (every array carries a leading
vehicle axis); :class:`NonlinearWrenchObserver`, the single-vehicle estimator, is a bank of one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.estimators.bank import BankOfOne, EulerAttitudes, FilterBank
from quad_wrench_env.kernels import resolve_backend
from quad_wrench_env.kernels.observer import (
    observer_bank_step,
    observer_constants,
    observer_estimates,
    observer_states,
    observer_wrenches,
)
from quad_wrench_env.rotations import (
    cross,
    euler_zyx_from_quat,
    wrap_angle,
)
from quad_wrench_env.vehicle import GRAVITY, PRESETS, VehicleParams

PAPER_001_VEHICLE = "yuksel1kg"
"""The preset of the vehicle of Yüksel et al. 2014 (1 kg, J_x = 0.13 kg·m²), for which their gains 5 and
0.5 were chosen."""


@dataclass
class ObserverGains:
    """Observer gains (Yüksel et al. 2014) and the measurement filters (McKinnon & Schoellig 2016 Sec. IV)."""

    c_force: float | None = None
    """N·s/m; None: Yüksel et al.'s (2014) 5 N·s/m times ``m / 1 kg`` (the force error's time constant ``m/c``
    is then Yüksel et al.'s (2014) 0.2 s)."""
    c_torque: float | None = None
    """N·m·s/rad; None: Yüksel et al.'s (2014) 0.5 times ``J_x / 0.13 kg·m²`` (time constant
    ``J_x/c`` = 0.26 s)."""
    velocity_time_constant: float = 0.05
    """s; first-order low-pass on the finite-difference velocity (0 = none)."""
    rate_time_constant: float = 0.05
    """s; first-order low-pass on the finite-difference Euler-angle rates (0 = none)."""

    def __post_init__(self) -> None:
        check_numbers(
            "estimator_params",
            self,
            tuple(n for n in ("c_force", "c_torque") if getattr(self, n) is not None),
        )
        check_numbers(
            "estimator_params", self, ("velocity_time_constant", "rate_time_constant"), positive=False
        )

    def for_vehicle(self, vehicle: VehicleParams) -> tuple[float, float]:
        """``(c_force, c_torque)`` on ``vehicle``: the given gains, or those of Yüksel et al. 2014 scaled
        to it."""
        paper = PRESETS[PAPER_001_VEHICLE]
        c_force = self.c_force if self.c_force is not None else 5.0 * vehicle.mass / paper.mass
        c_torque = self.c_torque if self.c_torque is not None else 0.5 * vehicle.inertia[0] / paper.inertia[0]
        return c_force, c_torque


def euler_kinematics(roll: np.ndarray, pitch: np.ndarray) -> np.ndarray:
    """(n, 3, 3) ``T(η)`` with ``ω = T η̇`` (body rates from ZYX Euler-angle rates), Yüksel et al.
    2014, Sec. II."""
    sr, cr = np.sin(roll), np.cos(roll)
    sp, cp = np.sin(pitch), np.cos(pitch)
    out = np.zeros((len(roll), 3, 3))
    out[:, 0, 0], out[:, 0, 2] = 1.0, -sp
    out[:, 1, 1], out[:, 1, 2] = cr, sr * cp
    out[:, 2, 1], out[:, 2, 2] = -sr, cr * cp
    return out


def euler_kinematics_rate(
    roll: np.ndarray, pitch: np.ndarray, roll_rate: np.ndarray, pitch_rate: np.ndarray
) -> np.ndarray:
    """(n, 3, 3) ``Ṫ(η, η̇)``."""
    sr, cr = np.sin(roll), np.cos(roll)
    sp, cp = np.sin(pitch), np.cos(pitch)
    out = np.zeros((len(roll), 3, 3))
    out[:, 0, 2] = -cp * pitch_rate
    out[:, 1, 1], out[:, 1, 2] = -sr * roll_rate, cr * cp * roll_rate - sr * sp * pitch_rate
    out[:, 2, 1], out[:, 2, 2] = -cr * roll_rate, -sr * cp * roll_rate - cr * sp * pitch_rate
    return out


def _apply(matrices: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    return np.einsum("nij,nj->ni", matrices, vectors)


def _apply_transposed(matrices: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    return np.einsum("nji,nj->ni", matrices, vectors)


class ObserverBank(FilterBank, EulerAttitudes):
    """N momentum-type observers without acceleration (Yüksel et al. 2014 eqs. 9-15), stepped together."""

    name = "observer"

    def __init__(
        self,
        vehicle: VehicleParams,
        dt: float,
        gains: ObserverGains | None,
        count: int,
        backend: str = "numpy",
    ) -> None:
        if count < 1:
            raise ValueError(f"count={count!r} must be at least 1 observer")
        self.backend = resolve_backend(backend)
        self.vehicle = vehicle
        self.dt = dt
        self.count = count
        self.gains = gains or ObserverGains()
        self.mass = vehicle.mass
        self.inertia = np.array(vehicle.inertia)
        g = self.gains
        self.c_force, self.c_torque = g.for_vehicle(vehicle)
        self._force_decay = math.exp(-self.c_force * dt / self.mass)
        self._velocity_alpha = _alpha(dt, g.velocity_time_constant)
        self._rate_alpha = _alpha(dt, g.rate_time_constant)
        self.positions = np.zeros((count, 3))
        self.eulers = np.zeros((count, 3))
        self.velocities = np.zeros((count, 3))
        self.euler_rates = np.zeros((count, 3))
        self.psi_force = np.zeros((count, 3))
        self.psi_torque = np.zeros((count, 3))
        self.forces = np.zeros((count, 3))
        self.torques_generalised = np.zeros((count, 3))
        self.kernel_constants = observer_constants(
            dt, self.mass, self.inertia, GRAVITY,
            (self.c_force, self.c_torque, self._force_decay, self._velocity_alpha, self._rate_alpha),
        )  # fmt: skip
        """The compiled step's constants (:func:`~quad_wrench_env.kernels.observer.observer_constants`)."""
        self.version = 0

    def euler_angles(self) -> np.ndarray:
        """(N, 3) the measured roll, pitch, yaw."""
        return self.eulers

    def reset(self, index: int | np.ndarray, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        """Start the observers ``index`` at rest with zero wrench (``ŵ = Ψ + c q̇ = 0``)."""
        self.positions[index] = position
        self.eulers[index] = euler_zyx_from_quat(np.asarray(quaternion_wxyz, dtype=float))
        self.version += 1
        for state in (self.velocities, self.euler_rates, self.psi_force, self.psi_torque):
            state[index] = 0.0
        self.forces[index] = 0.0
        self.torques_generalised[index] = 0.0

    def _kernel(self, thrusts, body_torques, positions, quaternions, velocities, body_rates):
        return observer_bank_step, (
            self.positions, self.eulers, self.velocities, self.euler_rates, self.psi_force,
            self.psi_torque, self.forces, self.torques_generalised, thrusts, body_torques, positions,
            quaternions, velocities, body_rates, self.kernel_constants,
        )  # fmt: skip

    def _numpy_step(self, thrusts, body_torques, positions, quaternions, velocities, body_rates) -> None:
        self._measure(positions, quaternions, velocities, body_rates)
        dt = self.dt
        roll, pitch = self.eulers[:, 0], self.eulers[:, 1]
        R = self.attitudes()[1]
        # force block (eq. 13 with L = c/m): Ψ' = e^{-cT/m} Ψ + (1 - e^{-cT/m}) (m g e_z - ρ R e_z - c ẋ)
        drive = -np.asarray(thrusts, dtype=float)[:, None] * R[:, :, 2] - self.c_force * self.velocities
        drive[:, 2] += self.mass * GRAVITY
        self.psi_force = self._force_decay * self.psi_force + (1.0 - self._force_decay) * drive
        self.forces = self.psi_force + self.c_force * self.velocities
        # torque block (eq. 13 with L = c 𝕁⁻¹), backward Euler: (𝕁 + c T) Ψ' = 𝕁 Ψ + c T (C η̇ - Tᵀτ̄ - c η̇)
        T_eta = euler_kinematics(roll, pitch)
        J_gen = T_eta.transpose(0, 2, 1) @ (self.inertia[:, None] * T_eta)
        eta_rate = self.euler_rates
        omega = _apply(T_eta, eta_rate)
        T_dot = euler_kinematics_rate(roll, pitch, eta_rate[:, 0], eta_rate[:, 1])
        coriolis = _apply_transposed(
            T_eta, self.inertia * _apply(T_dot, eta_rate) + cross(omega, self.inertia * omega)
        )
        drive_torque = coriolis - _apply_transposed(T_eta, body_torques) - self.c_torque * eta_rate
        gain = self.c_torque * dt
        right = _apply(J_gen, self.psi_torque) + gain * drive_torque
        self.psi_torque = np.linalg.solve(J_gen + gain * np.eye(3), right[:, :, None])[:, :, 0]
        self.torques_generalised = self.psi_torque + self.c_torque * eta_rate

    def _measure(
        self,
        positions: np.ndarray,
        quaternions: np.ndarray,
        velocities: np.ndarray | None,
        body_rates: np.ndarray | None,
    ) -> None:
        euler = euler_zyx_from_quat(np.asarray(quaternions, dtype=float))
        if velocities is not None:
            self.velocities = np.array(velocities, dtype=float)
        else:
            raw = (positions - self.positions) / self.dt
            self.velocities = self.velocities + self._velocity_alpha * (raw - self.velocities)
        if body_rates is not None:
            kinematics = euler_kinematics(euler[:, 0], euler[:, 1])
            self.euler_rates = np.linalg.solve(kinematics, np.asarray(body_rates, dtype=float)[:, :, None])[
                :, :, 0
            ]
        else:
            raw = wrap_angle(euler - self.eulers) / self.dt
            self.euler_rates = self.euler_rates + self._rate_alpha * (raw - self.euler_rates)
        self.positions = np.array(positions, dtype=float)
        self.eulers = euler
        self.version += 1  # the cached attitudes belong to the old angles

    def quaternions(self) -> np.ndarray:
        return self.attitudes()[0]

    def wrenches(self) -> np.ndarray:
        """(N, 6) estimated ``[f, R T⁻ᵀ τ̂_gen]``, world frame."""
        if self.backend == "numba":
            out = np.empty((self.count, 6))
            observer_wrenches(self.eulers, self.forces, self.torques_generalised, out)
            return out
        kinematics = euler_kinematics(self.eulers[:, 0], self.eulers[:, 1])
        body = np.linalg.solve(kinematics.transpose(0, 2, 1), self.torques_generalised[:, :, None])[:, :, 0]
        return np.concatenate((self.forces, _apply(self.attitudes()[1], body)), axis=1)

    def states(self) -> np.ndarray:
        """(N, 13) position, velocity, quaternion and body rates ``T η̇``."""
        if self.backend == "numba":
            out = np.empty((self.count, 13))
            observer_states(self.positions, self.eulers, self.velocities, self.euler_rates, out)
            return out
        body_rates = _apply(euler_kinematics(self.eulers[:, 0], self.eulers[:, 1]), self.euler_rates)
        return np.concatenate((self.positions, self.velocities, self.quaternions(), body_rates), axis=1)

    def _estimates_kernel(self):
        return observer_estimates, (
            self.positions, self.eulers, self.velocities, self.euler_rates, self.forces,
            self.torques_generalised,
        )  # fmt: skip

    def wrench_covariances(self) -> np.ndarray:
        """The observer carries no covariance: NaN (module docstring)."""
        return np.full((self.count, 6, 6), np.nan)

    def statuses(self) -> list[str]:
        return ["ok"] * self.count


class NonlinearWrenchObserver(BankOfOne):
    """Yüksel et al.'s (2014) observer for one vehicle: a bank of one."""

    name = "observer"

    def __init__(
        self, vehicle: VehicleParams, dt: float, gains: ObserverGains | None = None, backend: str = "numpy"
    ) -> None:
        self.bank = ObserverBank(vehicle, dt, gains, count=1, backend=backend)


def _alpha(dt: float, time_constant: float) -> float:
    """Step gain of a first-order low-pass with ``time_constant`` (1 = no filtering)."""
    return 1.0 if time_constant == 0 else 1.0 - math.exp(-dt / time_constant)

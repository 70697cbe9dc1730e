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
vehicle axis) by its kernel, :mod:`quad_wrench_env.estimators.observer_kernel`, the one implementation of the
algebra; :class:`NonlinearWrenchObserver`, the single-vehicle estimator, is a bank of one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.estimators.bank import BankOfOne, EstimatorInputs, FilterBank
from quad_wrench_env.estimators.observer_kernel import (
    observer_bank_step,
    observer_constants,
    observer_estimates,
    observer_states,
    observer_wrenches,
)
from quad_wrench_env.rotations import euler_zyx_from_quat
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


class ObserverBank(FilterBank):
    """N momentum-type observers without acceleration (Yüksel et al. 2014 eqs. 9-15), stepped together."""

    name = "observer"

    def __init__(self, vehicle: VehicleParams, dt: float, gains: ObserverGains | None, count: int) -> None:
        if count < 1:
            raise ValueError(f"count={count!r} must be at least 1 observer")
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
            dt,
            self.mass,
            self.inertia,
            GRAVITY,
            (self.c_force, self.c_torque, self._force_decay, self._velocity_alpha, self._rate_alpha),
        )
        """The step kernel's constants (:func:`.observer_kernel.observer_constants`)."""

    def reset(self, index: int | np.ndarray, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        """Start the observers ``index`` at rest with zero wrench (``ŵ = Ψ + c q̇ = 0``)."""
        self.positions[index] = position
        self.eulers[index] = euler_zyx_from_quat(np.asarray(quaternion_wxyz, dtype=float))
        for state in (self.velocities, self.euler_rates, self.psi_force, self.psi_torque):
            state[index] = 0.0
        self.forces[index] = 0.0
        self.torques_generalised[index] = 0.0

    def _kernel(self, inputs: EstimatorInputs) -> tuple:
        return observer_bank_step, (
            self.positions,
            self.eulers,
            self.velocities,
            self.euler_rates,
            self.psi_force,
            self.psi_torque,
            self.forces,
            self.torques_generalised,
            *inputs,
            self.kernel_constants,
        )

    def wrenches(self) -> np.ndarray:
        """(N, 6) estimated ``[f, R T⁻ᵀ τ̂_gen]``, world frame."""
        out = np.empty((self.count, 6))
        observer_wrenches(self.eulers, self.forces, self.torques_generalised, out)
        return out

    def states(self) -> np.ndarray:
        """(N, 13) position, velocity, quaternion and body rates ``T η̇``."""
        out = np.empty((self.count, 13))
        observer_states(self.positions, self.eulers, self.velocities, self.euler_rates, out)
        return out

    def _estimates_kernel(self):
        return observer_estimates, (
            self.positions,
            self.eulers,
            self.velocities,
            self.euler_rates,
            self.forces,
            self.torques_generalised,
        )

    def wrench_covariances(self) -> np.ndarray:
        """The observer carries no covariance: NaN (module docstring)."""
        return np.full((self.count, 6, 6), np.nan)

    def statuses(self) -> list[str]:
        return ["ok"] * self.count


class NonlinearWrenchObserver(BankOfOne):
    """Yüksel et al.'s (2014) observer for one vehicle: a bank of one."""

    name = "observer"

    def __init__(self, vehicle: VehicleParams, dt: float, gains: ObserverGains | None = None) -> None:
        self.bank = ObserverBank(vehicle, dt, gains, count=1)


def _alpha(dt: float, time_constant: float) -> float:
    """Step gain of a first-order low-pass with ``time_constant`` (1 = no filtering)."""
    return 1.0 if time_constant == 0 else 1.0 - math.exp(-dt / time_constant)

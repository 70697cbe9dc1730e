"""The vehicles' true rotors: motor lag, per-rotor thrust coefficients and rotor drag.

This is the truth the physics uses, for N vehicles at once. Thrust ``c_i = k_i·Ω_i²`` and reaction
torque ``p_i·Ω_i²`` follow McKinnon & Schoellig 2016 eqs. (1), (8)-(10) with per-rotor
``k_i = k·(1 + ε_i)``, ``ε_i ~ N(0, spread²)`` drawn once per episode (``docs/physics.md``, "Rotors"),
so the nominal mixer that estimators use is not the truth (unless the vehicle is calibrated: then
the estimators' mixer has the true coefficients to a residual ``δ_i``,
:attr:`Rotors.sensed_allocations`). Each motor follows a first-order lag towards its commanded speed,
integrated exactly over a physics step, with separate time constants for spinning up and down, and
its command is limited to the motor's speed range. Linear rotor drag ("H-force") acts at each hub
against the in-plane airspeed: ``F = -k_d·Ω_i·v_⊥``.
"""

from __future__ import annotations

import math

import numpy as np

from quad_wrench_env.vehicle import Mixer, VehicleParams


class Rotors:
    """The four motors of each of ``count`` vehicles: speeds (N, 4), true allocation matrices (N, 4, 4)."""

    def __init__(self, vehicle: VehicleParams, dt: float, count: int = 1) -> None:
        self.vehicle = vehicle
        self.dt = dt
        self._alpha_up = 1.0 - math.exp(-dt / vehicle.motor_time_constant_up)
        self._alpha_down = 1.0 - math.exp(-dt / vehicle.motor_time_constant_down)
        self._drag_coefficient = vehicle.rotor_drag_coefficient
        self.speeds = np.full((count, 4), vehicle.hover_rotor_speed)
        self.allocations = np.tile(Mixer(vehicle).allocation, (count, 1, 1))
        self.inverses = np.tile(Mixer(vehicle).inverse, (count, 1, 1))
        self.sensed_allocations = self.allocations.copy()
        """(N, 4, 4) the allocation through which the estimators see the reported speeds: the nominal
        mixer, or a calibrated vehicle's."""

    def reset(
        self, index: int, rng: np.random.Generator, kf_spread: float, calibration: float | None = None
    ) -> None:
        """Draw the true thrust coefficients of vehicle ``index`` for a new episode and, for a vehicle
        calibrated to a relative residual of sd ``calibration``, the coefficients its estimators use
        (from a generator spawned off ``rng``'s seed sequence: the calibration moves none of the
        episode's other random numbers); its motors start at the nominal hover speed."""
        epsilon = kf_spread * rng.standard_normal(4) if kf_spread > 0 else np.zeros(4)
        mixer = Mixer(self.vehicle, self.vehicle.kf * (1.0 + epsilon))
        self.allocations[index] = mixer.allocation
        self.inverses[index] = mixer.inverse
        self.sensed_allocations[index] = Mixer(self.vehicle).allocation
        if calibration is not None:
            own = np.random.default_rng(rng.bit_generator.seed_seq.spawn(1)[0])
            residual = calibration * own.standard_normal(4) if calibration > 0 else np.zeros(4)
            calibrated = Mixer(self.vehicle, self.vehicle.kf * (1.0 + epsilon + residual))
            self.sensed_allocations[index] = calibrated.allocation
        self.speeds[index] = self.vehicle.hover_rotor_speed

    def kernel_parameters(self) -> np.ndarray:
        """Motor lag gains up and down, speed limits and the rotor drag coefficient, for the kernels."""
        v = self.vehicle
        return np.array(
            (self._alpha_up, self._alpha_down, v.min_rotor_speed, v.max_rotor_speed, self._drag_coefficient)
        )

    def thrusts(self, index: np.ndarray | slice = slice(None)) -> np.ndarray:
        """(n, 4) true thrust ``k_i·Ω_i²`` of each rotor of vehicles ``index`` (N)."""
        speeds = self.speeds[index]
        return self.allocations[index, 0, :] * (speeds * speeds)

    def speeds_for(self, index: np.ndarray, thrust_and_torque: np.ndarray) -> np.ndarray:
        """(n, 4) speeds of vehicles ``index`` that give (n, 4) ``[c_t, tau]``, clipped to the
        motors' range."""
        v = self.vehicle
        squared = np.einsum("nij,nj->ni", self.inverses[index], thrust_and_torque)
        return np.sqrt(np.clip(squared, v.min_rotor_speed**2, v.max_rotor_speed**2))

    def drag_forces(
        self, airspeed: np.ndarray, body_z: np.ndarray, index: np.ndarray | slice = slice(None)
    ) -> np.ndarray:
        """(n, 4, 3) world-frame rotor drag at the hubs of vehicles ``index`` for hub airspeeds
        ``v_hub - wind`` (n, 4, 3) and body z axes (n, 3)."""
        along = np.einsum("npi,ni->np", airspeed, body_z)
        in_plane = airspeed - along[:, :, None] * body_z[:, None, :]
        return -(self._drag_coefficient * self.speeds[index])[:, :, None] * in_plane

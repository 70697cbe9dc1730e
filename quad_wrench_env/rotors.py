"""The vehicle's true rotors: motor lag, per-rotor thrust coefficients and rotor drag.

This is the truth the physics uses. Thrust ``c_i = k_i·Ω_i²`` and reaction torque ``p_i·Ω_i²`` follow
paper 000 eqs. (1), (8)-(10) with per-rotor ``k_i = k·(1 + ε_i)``, ``ε_i ~ N(0, spread²)`` drawn once per
episode (PHYSICS.md), so the nominal mixer that estimators use is not the truth. Each motor follows a
first-order lag towards its commanded speed, integrated exactly over a physics step, with separate
time constants for spinning up and down, and its command is limited to the motor's speed range.
Linear rotor drag ("H-force") acts at each hub against the in-plane airspeed: ``F = -k_d·Ω_i·v_⊥``.
"""

from __future__ import annotations

import math

import numpy as np

from quad_wrench_env.vehicle import Mixer, VehicleParams


class Rotors:
    """Four motors with first-order lag, their true thrust coefficients and their drag."""

    def __init__(self, vehicle: VehicleParams, dt: float) -> None:
        self.vehicle = vehicle
        self.dt = dt
        self._alpha_up = 1.0 - math.exp(-dt / vehicle.motor_time_constant_up)
        self._alpha_down = 1.0 - math.exp(-dt / vehicle.motor_time_constant_down)
        self._drag_coefficient = vehicle.rotor_drag_coefficient
        self.speeds = np.full(4, vehicle.hover_rotor_speed)
        self.mixer = Mixer(vehicle)

    def reset(self, rng: np.random.Generator, kf_spread: float, speeds: np.ndarray | float) -> None:
        """Draw this episode's true thrust coefficients and set the motor speeds (rad/s)."""
        epsilon = kf_spread * rng.standard_normal(4) if kf_spread > 0 else np.zeros(4)
        self.mixer = Mixer(self.vehicle, self.vehicle.kf * (1.0 + epsilon))
        self.speeds = np.broadcast_to(np.asarray(speeds, dtype=float), (4,)).copy()

    def step(self, commanded: np.ndarray) -> np.ndarray:
        """Advance the motors one physics step towards ``commanded`` speeds (limited to their range)."""
        target = np.clip(commanded, self.vehicle.min_rotor_speed, self.vehicle.max_rotor_speed)
        error = target - self.speeds
        self.speeds += np.where(error >= 0.0, self._alpha_up, self._alpha_down) * error
        return self.speeds

    def thrust_and_torque(self) -> np.ndarray:
        """True ``[c_t, tau_x, tau_y, tau_z]`` in the body frame from the current speeds."""
        return self.mixer.wrench(self.speeds)

    def drag_forces(self, airspeed: np.ndarray, body_z: np.ndarray) -> np.ndarray:
        """(4, 3) world-frame rotor drag at the hubs for hub airspeeds ``v_hub - wind`` (4, 3)."""
        in_plane = airspeed - np.outer(airspeed @ body_z, body_z)
        return -(self._drag_coefficient * self.speeds)[:, None] * in_plane

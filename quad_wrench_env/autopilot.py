"""The vehicle's own flight firmware: velocity -> attitude -> body rates -> motor speeds.

What PX4 is to the vehicle of Hentzen et al. 2019 and the AR.Drone firmware to that of McKinnon & Schoellig
2016: a cascade of

* a velocity loop (2-DOF PI, world frame, stiffer vertically where thrust acts directly) giving a
  desired acceleration, hence a thrust vector whose tilt is limited to ``max_tilt`` (the integrator
  stops while the tilt limit is active),
* an attitude loop (proportional on the geometric error ``e_R = ½·vee(R_dᵀR - RᵀR_d)``),
* a body-rate loop (PI with inertia scaling and the gyroscopic term ``ω × Jω``; the integrator stops
  while the mixer saturates), and
* the mixer (eqs. 1, 8-10 of McKinnon & Schoellig 2016, nominal coefficients) with saturation handling that
  gives up yaw torque before thrust, roll and pitch, then clips speeds to the motors' range.

Gains follow from the vehicle: the rate-loop bandwidth is set by the motor time constant ``τ_m``
(``k_rate = 0.7/τ_m`` gives a damping ratio of 0.6 for the loop ``k/(s(τ_m s + 1))``; the integrator,
``0.1·k²``, puts the PI's zero a decade below the crossover and holds a constant torque disturbance
such as a mass hung under one rotor within ~1/(0.1·k) s; at ``0.6·k²`` the zero would sit at the
crossover and the attitude loop on top ring with a damping ratio of 0.025), bounded by the
torque authority α (``VehicleParams.max_angular_acceleration``): the largest rate step may ask for
at most :data:`AUTHORITY_SHARE` of it, ``k_rate·max_rate <= share·α``, by a lower rate limit first
(down to :data:`MIN_MAX_RATE`), then a lower gain (``yuksel1kg``: 9.4 instead of 35). Each outer loop
is slower than the one inside it. The autopilot reads the vehicle's true state, as the onboard
state estimate of a real vehicle under motion capture would give it to within sensor noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from quad_wrench_env.rotations import cross, rows_times
from quad_wrench_env.vehicle import GRAVITY, Mixer, VehicleParams

_E_Z = np.array((0.0, 0.0, 1.0))

AUTHORITY_SHARE = 0.5
"""Share of the roll/pitch torque authority (``VehicleParams.max_angular_acceleration``) that the
rate loop may ask for on its largest step, ``rate_p·max_rate``."""

RATE_INTEGRAL_SHARE = 0.1
"""``rate_i = share·rate_p²``: the rate PI's zero at ``share·rate_p``, a decade below the crossover."""

MIN_MAX_RATE = 1.0
"""rad/s: the body-rate limit is lowered towards this before the rate gain is."""


@dataclass(frozen=True)
class AutopilotGains:
    """Loop gains (all in 1/s) and limits of the cascade."""

    rate_p: float
    rate_i: float
    attitude_p: float
    yaw_p: float
    velocity_p: float
    velocity_i: float
    climb_p: float
    climb_i: float
    setpoint_weight: float = 0.7
    """Share of the commanded velocity in the proportional term (2-DOF PI): removes the overshoot
    that the integrator's zero would cause on a step command, leaves disturbance rejection as it is."""
    max_tilt: float = math.radians(35.0)
    max_rate: float = 4.0
    max_yaw_error: float = 0.5

    @classmethod
    def for_vehicle(cls, vehicle: VehicleParams) -> AutopilotGains:
        """Gains derived from the motor time constant and bounded by the torque authority (see the
        module docstring)."""
        tau_m = 0.5 * (vehicle.motor_time_constant_up + vehicle.motor_time_constant_down)
        alpha = AUTHORITY_SHARE * vehicle.max_angular_acceleration
        motor_rate_p = 0.7 / tau_m
        max_rate = min(cls.max_rate, max(MIN_MAX_RATE, alpha / motor_rate_p))
        rate_p = min(motor_rate_p, alpha / max_rate)
        climb_p = motor_rate_p / 3.0
        attitude_p = rate_p / 2.5
        velocity_p = attitude_p / 3.0
        # Rotor drag adds its own damping to the horizontal loop: v' = a - d·v. Size the integrator
        # and the set-point weight on k = k_p + d so every preset answers a step alike (~5 % overshoot).
        k = velocity_p + vehicle.rotor_drag_decel
        return cls(
            rate_p=rate_p,
            rate_i=RATE_INTEGRAL_SHARE * rate_p**2,
            attitude_p=attitude_p,
            yaw_p=0.5 * attitude_p,
            velocity_p=velocity_p,
            velocity_i=0.3 * k**2,
            climb_p=climb_p,
            climb_i=0.25 * climb_p**2,
            setpoint_weight=0.7 * k / velocity_p,
            max_rate=max_rate,
        )


class Autopilot:
    """The cascade's gains, mixer and state for ``count`` vehicles (each with a leading dimension N):
    the compiled ``controls`` kernel (:mod:`quad_wrench_env.engine.kernels`) flies it every physics
    step on these numbers; here are the episode start's reset and trim."""

    def __init__(
        self, vehicle: VehicleParams, dt: float, gains: AutopilotGains | None = None, count: int = 1
    ) -> None:
        self.vehicle = vehicle
        self.dt = dt
        self.gains = gains or AutopilotGains.for_vehicle(vehicle)
        g = self.gains
        self._velocity_p = np.array((g.velocity_p, g.velocity_p, g.climb_p))
        self._velocity_i = np.array((g.velocity_i, g.velocity_i, g.climb_i))
        self._attitude_p = np.array((g.attitude_p, g.attitude_p, g.yaw_p))
        self.mixer = Mixer(vehicle)
        self._inertia = np.array(vehicle.inertia)
        self._w2_min = vehicle.min_rotor_speed**2
        self._w2_max = vehicle.max_rotor_speed**2
        self.yaw_setpoint = np.zeros(count)
        self.velocity_integral = np.zeros((count, 3))
        self.rate_integral = np.zeros((count, 3))
        self.saturated = np.zeros(count, dtype=bool)

    def kernel_parameters(self) -> np.ndarray:
        """The gains and limits as the compiled kernel reads them
        (:func:`quad_wrench_env.engine.kernels.controls`): velocity P (3) and I (3), set-point
        weight, tan(max tilt), attitude P (3), max rate, max yaw error, rate P and I, mass, g, dt,
        squared speed limits (2), inertia (3)."""
        g = self.gains
        return np.concatenate(
            (
                self._velocity_p,
                self._velocity_i,
                (g.setpoint_weight, math.tan(g.max_tilt)),
                self._attitude_p,
                (g.max_rate, g.max_yaw_error, g.rate_p, g.rate_i, self.vehicle.mass, GRAVITY, self.dt),
                (self._w2_min, self._w2_max),
                self._inertia,
            )
        )

    def reset(self, index: np.ndarray, yaw: np.ndarray) -> None:
        """Zero the integrators of vehicles ``index`` and hold their ``yaw`` (rad)."""
        self.yaw_setpoint[index] = yaw
        self.velocity_integral[index] = 0.0
        self.rate_integral[index] = 0.0
        self.saturated[index] = False

    def trim(self, index: np.ndarray, rotation: np.ndarray, rotor_speeds: np.ndarray) -> None:
        """Preload the integrators of vehicles ``index`` so that, at rest in attitudes ``rotation``
        (n, 3, 3) with zero errors, the cascade commands ``rotor_speeds`` (n, 4): the state of a
        vehicle that has been hovering in equilibrium (used at the start of an episode)."""
        g = self.gains
        command = rows_times(rotor_speeds * rotor_speeds, self.mixer.allocation.T)
        self.rate_integral[index] = command[:, 1:] / (self._inertia * g.rate_i)
        thrust_vector = command[:, :1] * rotation[:, :, 2]
        self.velocity_integral[index] = (
            thrust_vector / self.vehicle.mass - GRAVITY * _E_Z
        ) / self._velocity_i


def attitude_from_thrust(thrust_vector: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations whose body z is along (N, 3) ``thrust_vector`` and whose body x heads
    to (N,) ``yaw``."""
    z_d = thrust_vector / np.linalg.norm(thrust_vector, axis=1, keepdims=True)
    heading = np.column_stack((np.cos(yaw), np.sin(yaw), np.zeros_like(yaw)))
    y_d = cross(z_d, heading)
    y_d /= np.linalg.norm(y_d, axis=1, keepdims=True)
    return np.stack((cross(y_d, z_d), y_d, z_d), axis=2)

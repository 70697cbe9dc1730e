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
such as a mass hung under one rotor within ~1/(0.1·k) s; at ``0.6·k²``, as before, the zero sat at the
crossover and the attitude loop on top rang with a damping ratio of 0.025), bounded by the
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

from quad_wrench_env.engine.world import RigidBodyState
from quad_wrench_env.rotations import cross, quat_from_euler_zyx, rotation_matrices, rows_times, wrap_angle
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
    """Cascaded controllers of ``count`` vehicles producing motor-speed commands from velocity,
    attitude or wrench setpoints; every argument and state carries a leading dimension N."""

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
        self._inverse_t = self.mixer.inverse.T.copy()
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
                self._velocity_p, self._velocity_i, (g.setpoint_weight, math.tan(g.max_tilt)),
                self._attitude_p,
                (g.max_rate, g.max_yaw_error, g.rate_p, g.rate_i, self.vehicle.mass, GRAVITY, self.dt),
                (self._w2_min, self._w2_max), self._inertia,
            )
        )  # fmt: skip

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

    # -- outer loops -------------------------------------------------------------------------
    def velocity_command(
        self, state: RigidBodyState, velocity: np.ndarray, yaw_rate: np.ndarray
    ) -> np.ndarray:
        """(N, 4) motor speeds that track (N, 3) world-frame velocities (m/s) and (N,) yaw rates (rad/s)."""
        error = velocity - state.velocity
        proportional = self.gains.setpoint_weight * velocity - state.velocity
        accel = self._velocity_p * proportional + self._velocity_i * self.velocity_integral
        thrust_vector = self.vehicle.mass * (accel + GRAVITY * _E_Z)
        thrust_vector, tilt_limited = self._limit_tilt(thrust_vector)
        integrate = ~(tilt_limited | self.saturated)
        self.velocity_integral += (error * self.dt) * integrate[:, None]
        self._advance_yaw(state, yaw_rate)
        desired = attitude_from_thrust(thrust_vector, self.yaw_setpoint)
        thrust = np.einsum("ni,ni->n", thrust_vector, state.rotation[:, :, 2])
        return self._attitude_to_motors(state, desired, thrust)

    def attitude_command(
        self,
        state: RigidBodyState,
        roll: np.ndarray,
        pitch: np.ndarray,
        yaw_rate: np.ndarray,
        thrust: np.ndarray,
    ) -> np.ndarray:
        """(N, 4) motor speeds for (N,) rolls and pitches (rad), yaw rates (rad/s) and collective
        thrusts (N)."""
        self._advance_yaw(state, yaw_rate)
        desired = rotation_matrices(quat_from_euler_zyx(roll, pitch, self.yaw_setpoint))
        return self._attitude_to_motors(state, desired, thrust)

    def wrench_command(self, thrust: np.ndarray, body_torque: np.ndarray) -> np.ndarray:
        """(N, 4) motor speeds for (N,) collective thrusts (N) and (N, 3) body torques (N·m), through
        the mixer."""
        return self._mix(np.column_stack((thrust, body_torque)))

    # -- inner loops -------------------------------------------------------------------------
    def _advance_yaw(self, state: RigidBodyState, yaw_rate: np.ndarray) -> None:
        r = state.rotation
        yaw = np.arctan2(r[:, 1, 0], r[:, 0, 0])
        ahead = wrap_angle(self.yaw_setpoint + yaw_rate * self.dt - yaw)
        limit = self.gains.max_yaw_error
        self.yaw_setpoint[:] = yaw + np.clip(ahead, -limit, limit)  # in place: the compiled step holds it

    def _limit_tilt(self, thrust_vector: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        vertical = np.maximum(thrust_vector[:, 2], 0.1 * self.vehicle.mass * GRAVITY)
        horizontal = thrust_vector[:, :2]
        max_horizontal = vertical * math.tan(self.gains.max_tilt)
        norm = np.hypot(horizontal[:, 0], horizontal[:, 1])
        too_wide = norm > max_horizontal
        limited = too_wide | (vertical != thrust_vector[:, 2])
        scale = np.where(too_wide, max_horizontal / np.where(too_wide, norm, 1.0), 1.0)
        return np.column_stack((horizontal * scale[:, None], vertical)), limited

    def _attitude_to_motors(
        self, state: RigidBodyState, desired: np.ndarray, thrust: np.ndarray
    ) -> np.ndarray:
        g = self.gains
        r = state.rotation
        e = np.swapaxes(desired, 1, 2) @ r
        e = e - np.swapaxes(e, 1, 2)  # R_dᵀR - RᵀR_d
        attitude_error = 0.5 * np.stack((e[:, 2, 1], e[:, 0, 2], e[:, 1, 0]), axis=1)
        rates = np.clip(-self._attitude_p * attitude_error, -g.max_rate, g.max_rate)
        return self._rates_to_motors(state, rates, thrust)

    def _rates_to_motors(self, state: RigidBodyState, rates: np.ndarray, thrust: np.ndarray) -> np.ndarray:
        g = self.gains
        omega = state.body_rates
        error = rates - omega
        self.rate_integral += (error * self.dt) * ~self.saturated[:, None]
        angular_accel = g.rate_p * error + g.rate_i * self.rate_integral
        torque = self._inertia * angular_accel + cross(omega, self._inertia * omega)
        return self._mix(np.column_stack((thrust, torque)))

    def _mix(self, thrust_and_torque: np.ndarray) -> np.ndarray:
        """(N, 4) rotor speeds for (N, 4) ``[c_t, tau]``; yaw torque is given up first, then speeds
        are clipped."""
        without_yaw = rows_times(thrust_and_torque[:, :3], self._inverse_t[:3])
        yaw_part = thrust_and_torque[:, 3:] * self._inverse_t[3]
        lo, hi = self._w2_min, self._w2_max
        unsaturated = without_yaw + yaw_part
        over = (yaw_part > 0.0) & (unsaturated > hi)
        under = (yaw_part < 0.0) & (unsaturated < lo)
        bound = np.where(over, hi, lo)
        safe_part = np.where(over | under, yaw_part, 1.0)
        ratios = np.where(over | under, np.maximum(0.0, (bound - without_yaw) / safe_part), 1.0)
        scale = np.minimum(1.0, ratios.min(axis=1))
        squared = without_yaw + scale[:, None] * yaw_part
        clipped = np.clip(squared, lo, hi)
        self.saturated[:] = (scale < 1.0) | np.any(clipped != squared, axis=1)
        return np.sqrt(clipped)


def attitude_from_thrust(thrust_vector: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations whose body z is along (N, 3) ``thrust_vector`` and whose body x heads
    to (N,) ``yaw``."""
    z_d = thrust_vector / np.linalg.norm(thrust_vector, axis=1, keepdims=True)
    heading = np.column_stack((np.cos(yaw), np.sin(yaw), np.zeros_like(yaw)))
    y_d = cross(z_d, heading)
    y_d /= np.linalg.norm(y_d, axis=1, keepdims=True)
    return np.stack((cross(y_d, z_d), y_d, z_d), axis=2)

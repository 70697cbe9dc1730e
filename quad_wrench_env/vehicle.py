"""Vehicle parameters, the papers' presets and the X-configuration mixer.

The mixer is McKinnon & Schoellig 2016 eqs. (1) and (8)-(10). Motor ``i`` sits at ``(x_i, y_i) = l·(±1, ±1)``
in the body frame (x forward, y left, z up), numbered as in McKinnon & Schoellig 2016 Fig. 2:

====== ============ ============ ===========================
motor  x_i          y_i          spin (reaction torque)
====== ============ ============ ===========================
1      +l (front)   +l (left)    about -z (torque +p·Ω²)
2      -l (back)    +l (left)    about +z (torque -p·Ω²)
3      -l (back)    -l (right)   about -z (torque +p·Ω²)
4      +l (front)   -l (right)   about +z (torque -p·Ω²)
====== ============ ============ ===========================

so that ``tau_x = l(c1 + c2 - c3 - c4)`` (eq. 8), ``tau_y = l(-c1 + c2 + c3 - c4)`` (eq. 9) and
``tau_z = p1Ω1² - p2Ω2² + p3Ω3² - p4Ω4²`` (eq. 10), with ``c_i = k_i Ω_i²`` (eq. 1).
Parameters and their sources are in ``docs/physics.md`` ("Vehicles").
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from quad_wrench_env.config import check_numbers

GRAVITY = 9.81
"""Standard gravity used everywhere in the project (m/s², McKinnon & Schoellig's (2016) ``g``)."""

MOTOR_X = np.array((1.0, -1.0, -1.0, 1.0))
MOTOR_Y = np.array((1.0, 1.0, -1.0, -1.0))
MOTOR_SPIN = np.array((1.0, -1.0, 1.0, -1.0))
"""Sign of each motor's reaction torque about body +z per unit ``p·Ω²`` (eq. 10)."""


@dataclass(frozen=True)
class VehicleParams:
    """Nominal physical parameters of one quadrotor (SI units, rotor speeds in rad/s)."""

    name: str
    mass: float
    inertia: tuple[float, float, float]
    arm: float
    """Rotor offset ``l`` from the body x and y axes (m), McKinnon & Schoellig 2016 Fig. 2."""
    kf: float
    """Thrust coefficient ``k`` (N/(rad/s)²), eq. (1)."""
    km_over_kf: float
    """Drag-torque coefficient over thrust coefficient, ``p/k`` (m), eq. (10)."""
    max_rotor_speed: float
    motor_time_constant_up: float
    motor_time_constant_down: float
    rotor_radius: float
    drag_area: float
    """Quadratic drag area ``C_d·A`` of the whole body (m²), spread over the drag points."""
    hull_radius: float
    """Radius of the ring of drag points around the body (m)."""
    hull_height: float = 0.06
    min_rotor_speed: float = 0.0
    rotor_drag_decel: float = 0.2
    """Hover deceleration per unit airspeed from linear rotor drag (1/s); ``docs/physics.md``, "Rotors"."""

    def __post_init__(self) -> None:
        owner = f"vehicle '{self.name}'"
        positive = (
            "mass",
            "arm",
            "kf",
            "km_over_kf",
            "max_rotor_speed",
            "rotor_radius",
            "hull_radius",
            "motor_time_constant_up",
            "motor_time_constant_down",
            "hull_height",
        )
        check_numbers(owner, self, positive)
        check_numbers(owner, self, ("drag_area", "min_rotor_speed", "rotor_drag_decel"), positive=False)
        if len(self.inertia) != 3 or not all(math.isfinite(j) and j > 0 for j in self.inertia):
            raise ValueError(f"vehicle '{self.name}': inertia={self.inertia!r} must be 3 numbers > 0")
        if self.min_rotor_speed >= self.max_rotor_speed:
            raise ValueError(
                f"vehicle '{self.name}': min_rotor_speed={self.min_rotor_speed} must be below "
                f"max_rotor_speed={self.max_rotor_speed}"
            )
        if self.max_thrust <= self.mass * GRAVITY:
            raise ValueError(
                f"vehicle '{self.name}': max thrust {self.max_thrust:.3g} N cannot lift "
                f"its weight {self.mass * GRAVITY:.3g} N"
            )

    @property
    def km(self) -> float:
        """Drag-torque coefficient ``p`` (N·m/(rad/s)²)."""
        return self.km_over_kf * self.kf

    @property
    def max_thrust(self) -> float:
        return 4.0 * self.kf * self.max_rotor_speed**2

    @property
    def hover_rotor_speed(self) -> float:
        return math.sqrt(self.mass * GRAVITY / (4.0 * self.kf))

    @property
    def max_angular_acceleration(self) -> float:
        """Roll/pitch torque authority at hover thrust (rad/s²): two rotors up and two down by the
        same ``ΔΩ²`` (the most that keeps both pairs within their speed range) give ``4·l·k·ΔΩ²``,
        over the larger of ``J_x`` and ``J_y``: ~178 rad/s² for ``ardrone2`` (about y; 237 about x),
        ~19 for ``yuksel1kg`` (``docs/physics.md``, "Vehicles")."""
        hover = self.hover_rotor_speed**2
        margin = min(self.max_rotor_speed**2 - hover, hover - self.min_rotor_speed**2)
        return 4.0 * self.arm * self.kf * margin / max(self.inertia[0], self.inertia[1])

    @property
    def rotor_positions(self) -> np.ndarray:
        """(4, 3) rotor hub positions in the body frame."""
        return np.column_stack((self.arm * MOTOR_X, self.arm * MOTOR_Y, np.zeros(4)))

    @property
    def rotor_drag_coefficient(self) -> float:
        """``k_d`` of ``F = -k_d·Ω·v_perp`` per rotor, so that hover deceleration is ``rotor_drag_decel``."""
        return self.rotor_drag_decel * self.mass / (4.0 * self.hover_rotor_speed)

    def drag_points(self, ring_points: int = 8) -> np.ndarray:
        """(4 + ring_points, 3) body points where aerodynamic drag acts: rotor hubs, then the hull ring."""
        angles = 2.0 * np.pi * (np.arange(ring_points) + 0.5) / ring_points
        ring = self.hull_radius * np.column_stack((np.cos(angles), np.sin(angles), np.zeros(ring_points)))
        return np.vstack((self.rotor_positions, ring))

    def replace(self, **changes) -> VehicleParams:
        """Copy with some fields changed; unknown names raise ``ValueError`` naming them."""
        allowed = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(changes) - allowed)
        if unknown:
            raise ValueError(f"unknown vehicle parameter(s) {unknown}; allowed: {sorted(allowed)}")
        return dataclasses.replace(self, **changes)


_RPM = 2.0 * math.pi / 60.0

PRESETS: dict[str, VehicleParams] = {
    "ardrone2": VehicleParams(
        name="ardrone2",
        mass=0.42,
        inertia=(2.24e-3, 2.99e-3, 4.80e-3),
        arm=0.129,
        kf=9.5e-6,
        km_over_kf=0.017,
        max_rotor_speed=550.0,
        motor_time_constant_up=0.05,
        motor_time_constant_down=0.05,
        rotor_radius=0.1,
        drag_area=0.04,
        hull_radius=0.26,
        hull_height=0.12,
    ),
    "crazyflie2": VehicleParams(
        name="crazyflie2",
        mass=0.027,
        inertia=(1.4e-5, 1.4e-5, 2.17e-5),
        arm=0.0397 / math.sqrt(2.0),
        kf=3.16e-10 / _RPM**2,
        km_over_kf=7.94e-12 / 3.16e-10,
        max_rotor_speed=21703.0 * _RPM,
        motor_time_constant_up=0.05,
        motor_time_constant_down=0.05,
        rotor_radius=0.0231,
        drag_area=0.003,
        hull_radius=0.05,
        hull_height=0.03,
    ),
    "hummingbird": VehicleParams(
        name="hummingbird",
        mass=0.716,
        inertia=(7e-3, 7e-3, 1.2e-2),
        arm=0.17 / math.sqrt(2.0),
        kf=8.55e-6,
        km_over_kf=0.016,
        max_rotor_speed=838.0,
        motor_time_constant_up=0.0125,
        motor_time_constant_down=0.025,
        rotor_radius=0.1,
        drag_area=0.02,
        hull_radius=0.17,
        hull_height=0.08,
    ),
    "yuksel1kg": VehicleParams(
        name="yuksel1kg",
        mass=1.0,
        inertia=(0.13, 0.13, 0.22),
        arm=0.25,
        kf=2.0 * GRAVITY / (4.0 * 600.0**2),
        km_over_kf=0.016,
        max_rotor_speed=600.0,
        motor_time_constant_up=0.02,
        motor_time_constant_down=0.02,
        rotor_radius=0.15,
        drag_area=0.05,
        hull_radius=0.3,
        hull_height=0.1,
    ),
}

CALIBRATED_ROTORS: dict[str, float] = {"crazyflie2": 0.002}
"""The presets whose rotors are calibrated by default (the env's ``rotor_calibration: "preset"``), with
the relative residual's sd: the 27 g ``crazyflie2``, whose rotors' 2 % thrust errors make a yaw torque of
the order of the fan's whole signal across the jet (``docs/estimators.md``, "What no tuning can fix");
0.2 %: each rotor's coefficient fitted on a thrust stand over its speed range (at 0.5 % the default
admittance tracker's miss grows to 1.3x the oracle's, ``docs/estimators.md``). The other presets fly the
nominal mixer."""


def make_vehicle(name: str, **overrides) -> VehicleParams:
    """A preset by name, optionally with fields overridden (validated)."""
    if name not in PRESETS:
        raise ValueError(f"unknown vehicle preset {name!r}; allowed: {sorted(PRESETS)}")
    return PRESETS[name].replace(**overrides) if overrides else PRESETS[name]


class Mixer:
    """Maps squared rotor speeds to collective thrust and body torque and back (eqs. 1, 8-10).

    ``kf`` may be omitted (the nominal value: what the autopilot and the estimators know) or four
    per-rotor values (the truth, ``k_i`` in eq. 1).
    """

    def __init__(self, vehicle: VehicleParams, kf: np.ndarray | None = None) -> None:
        kf = np.full(4, vehicle.kf) if kf is None else np.asarray(kf, dtype=float)
        if kf.shape != (4,) or not np.all(np.isfinite(kf) & (kf > 0)):
            raise ValueError(f"per-rotor thrust coefficients {kf!r} must be 4 finite numbers > 0")
        self.vehicle = vehicle
        self.kf = kf
        self.km = kf * vehicle.km_over_kf
        self.allocation = np.vstack(
            (kf, vehicle.arm * MOTOR_Y * kf, -vehicle.arm * MOTOR_X * kf, MOTOR_SPIN * self.km)
        )
        """(4, 4) matrix ``A`` with ``[c_t, tau_x, tau_y, tau_z] = A @ Omega²``."""
        self.inverse = np.linalg.inv(self.allocation)

    def wrench(self, rotor_speeds: np.ndarray) -> np.ndarray:
        """``[c_t, tau_x, tau_y, tau_z]`` (N, N·m, body frame) from rotor speeds (rad/s)."""
        return self.allocation @ (rotor_speeds * rotor_speeds)

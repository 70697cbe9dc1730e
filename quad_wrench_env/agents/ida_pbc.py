"""The IDA-PBC controller of Yüksel et al. 2014 (Secs. III-IV), fed by the estimated external wrench.

The controller reshapes the quadrotor into a port-Hamiltonian target system (eq. 32) of desired
inertia ``M_d = diag(m_d I, N)`` (eq. 33), potential ``V_d`` (eq. 35) and dissipation ``R_d``, and
(Sec. IV) lets the force the vehicle exerts, ``f_ne``, converge to a desired ``f*`` even under a
constant external torque. The external wrench comes from the observation's ``force`` and ``torque``
blocks (world frame), so any estimator feeds it (Yüksel et al. 2014 use their own observer, Sec. II:
``estimator="observer"``); the command goes out through the env's ``wrench`` action.

Frames
------
The paper writes NED world and FRD body frames (z down, thrust ``-ρ R e₃``, gravity ``+m g₀ e₃``).
This project has world z up and body x forward, y left, z up (FLU). The two are related by the
rotation ``P = diag(1, -1, -1)`` (π about x) applied to both frames: ``v = P v_paper`` for every world
or body vector, ``R = P R_paper P``, so the ZYX Euler angles map as ``(φ, θ, ψ) = (φ, -θ, -ψ)_paper``
and every equation keeps its form with the signs of ``g₀ e₃`` and of the thrust flipped:

* thrust ``+ρ R e₃`` (body z up), gravity ``-m g₀ e₃``, so eq. (36) reads ``f_ne = ρ R e₃ - m g₀ e₃``;
* ``η = (φ, θ, ψ)`` are the project's ZYX angles, ``R = R_z(ψ) R_y(θ) R_x(φ)``, whose third column has
  exactly the trigonometric form of eq. (37)'s left-hand side; ``ω = T(η) η̇`` with
  ``T = [[1, 0, -sθ], [0, cφ, sφ cθ], [0, -sφ, cφ cθ]]`` (the paper prints ``c_θ`` in the (2, 2)
  entry: a misprint, the body-rate map of ZYX angles has ``c_φ`` there);
* the external wrench of the observation is world-frame; the paper's ``τ_e`` of eq. (1) is the
  generalised (Euler-coordinate) torque ``τ_e = Tᵀ Rᵀ τ_world``, as the project's observer defines it.

Eq. (25), damping injection: ``τ̄ = C η̇ - k_d 𝕁 η̇ + 𝕁 τ + (𝕁 - I) τ̂_e`` with ``𝕁 = Tᵀ J T`` makes the
rotation ``η̈ = -k_d η̇ + τ + τ_e`` (eq. 26). It is evaluated without forming ``C``: the Lagrangian
of ``½ η̇ᵀ 𝕁 η̇`` gives ``𝕁 η̈ + C η̇ = Tᵀ (J ω̇ + ω × J ω)`` with ``ω̇ = T η̈ + Ṫ η̇``, so (25) is the
body torque ``τ_B = J (T η̈_c + Ṫ η̇) + ω × J ω - Rᵀ τ̂_world`` with ``η̈_c = -k_d η̇ + τ + τ̂_e``.

Eq. (31), the IDA-PBC law, with ``M = diag(m I, I)`` (eq. 30), ``G = diag(G₁, I)`` (eq. 29, ``G₁`` the
thrust direction, so ``GᵀG = I`` and ``(GᵀG)⁻¹Gᵀ = Gᵀ``):

* rotation: ``τ = -N⁻¹ ∂V̄_d/∂η - K_v,η N η̇ + (N⁻¹ - I) τ̂_e``, hence with (25)
  ``N η̈ = -R_d,η η̇ - ∂V̄_d/∂η + τ̂_e + N 𝕁⁻¹ (τ_e - τ̂_e)``: eq. (32)'s rotational rows with
  ``R_d,η = k_d N + N K_v,η N`` (the parameters give ``R_d,η``; ``K_v,η = N⁻¹(R_d,η - k_d N)N⁻¹`` must
  be >= 0, so ``R_d,η >= k_d N``) and the estimate's error acting through the true inertia;
* translation: the target (32) ``m_d ẍ = -∂V_d/∂x - R_d,x ẋ + f_e`` (the gravity term of eq. (35),
  ``-m_d g₀ q₃``, is cancelled by the high-level input ``u_h``, "chosen such as to scale the gravity
  effect", Sec. V-A) needs the force ``f_ne = (m/m_d)(-∂V_d/∂x - R_d,x ẋ + f̂_e) - f̂_e``, whose
  thrust-axis component is exactly (31)'s thrust row: ``(m/m_d)·(-∂V_d/∂x)`` from its first term,
  ``-(m/m_d) R_d,x ẋ = -K_v,ρ (m_d/m) ẋ`` (so ``K_v,ρ = (m/m_d)² R_d,x``) from its second, and
  ``(m/m_d - 1) f̂_e`` from its third, ``G⁺(M M_d⁻¹ - I) w_e``. The quadrotor is underactuated: (31)
  can only match along the thrust; here the two other components are produced by tilting, with the
  attitude machinery of Sec. IV (below), i.e. the full vector ``f_ne`` is treated as a desired ``f*``.
  ``V_d`` is eq. (35) plus a quadratic position term ``½ (x - x_r)ᵀ K_x (x - x_r)`` (the set-point of
  the free-flight case; ``K_x = 0`` is (35) as printed, which leaves the position free).

Sec. IV, force exertion. Imposing ``f_ne = f*`` (eq. 37, in project frames
``ρ R e₃ = f* + m g₀ e₃ =: F``) and rotating by ``R_z(-ψ)`` (eq. 38):
``ρ (cφ sθ, -sφ, cφ cθ) = (F_x cψ + F_y sψ, -F_x sψ + F_y cψ, F_z)``, solved by

* (39) ``ρ* = |F| = sqrt(f*_x² + f*_y² + (f*_z + m g₀)²)``;
* (40) ``φ* = arcsin((F_x sψ - F_y cψ)/ρ*)`` (the second row);
* (41) ``θ* = atan2(F_x cψ + F_y sψ, F_z)`` (first row over third; the printed
  ``arcsin(·/(ρ* cφ*))`` is the same angle for ``F_z > 0``).

The printed (40) and (41) swap the two right-hand sides: (40) gives φ* the first row of (38), which
is ``ρ cφ sθ``, and (41) gives θ* the second, ``-ρ sφ``; substituting them back into (37) fails (a
force along x would be made by rolling). The printed (37) also has ``m_d g₀`` in its third row, where
(36)'s definition of ``f_ne`` has ``m g₀``; ``f_ne = -f_e`` at rest, the point of Sec. IV, holds only
with the true mass ``m``, which is used here (the two agree when ``m_d = m``).

The rotational potential (42) ``V̄_d = ½ η_eᵀ K_p η_e`` with ``η_e = (φ - φ̄, θ - θ̄, ψ - ψ̄)`` (43) gives
(44) ``η̈ = -k_d η̇ + K_p(η̄ - η) + τ̃_e`` (per unit desired inertia). How (45)-(47) are read:

* (45) ``K_p (η_ss - η̄) = τ̃_e``: the steady state of (44), ``0 = K_p(η̄ - η_ss) + τ̃_e``; the printed
  ``K_n`` is ``K_p`` (no ``K_n`` is defined anywhere);
* ``ψ_ss = ψ̄ + τ̃_e,ψ / k_p^ψ``: the yaw row of (45) (the printed ``ψ_ss = τ̃_e/k_p^ψ`` takes ``ψ̄ = 0``
  as (43) does and drops the component index); ψ_ss is the ψ used in (40)-(41);
* (46) ``φ̄ = φ* - τ̃_e,φ / k_p^φ``: the roll row of (45) with ``η_ss = η*``; the printed
  ``ψ̄ = ψ* - τ̃_ex / k_r^φ`` names the wrong angle twice (ψ for φ, no ψ* exists) and misprints
  ``k_p`` (the gain k_p^φ divides the roll torque, so the row is the roll row);
* (47) ``θ̄ = θ* - τ̃_e,θ / k_p^θ`` (printed ``k_n^θ``).

Signs: from (44) at rest ``η_ss = η̄ + K_p⁻¹ τ̃_e``, so ``η̄ = η* - K_p⁻¹ τ̃_e`` puts ``η_ss`` at ``η*``.
The torque components are the generalised (Euler) ones, ``τ̃_e = Tᵀ Rᵀ τ̂_world``. With the shift
(``torque_shift``) and ``τ̂_e = τ_e`` the rotational target becomes ``N η̈ = -R_d,η η̇ - K_p (η - η*)``:
the constant torque is held by the shifted potential, and ``f_ne`` reaches ``f*``.

Modes (``mode``): ``"position"`` flies the free-flight target above (``f*`` from the target dynamics
and the set-point ``reference``); ``"force"`` exerts ``f*`` from the observation's ``target_force``
block (world frame, N) when the env has one, else from ``target_force``: Sec. IV as written, with no
translational feedback, so the vehicle floats at constant velocity once ``f_ne + f_e = 0``
(optionally ``- force_damping·ẋ``); ``"balance"`` is Sec. V-C, ``f* = -f̂_e``: the estimated
external force is counterbalanced; ``"auto"`` is ``"force"`` when the observation has
``target_force``, else ``"position"``.

Choices beyond the printed equations (each a switch; the paper's form is the other setting). On
Yüksel et al.'s (2014) Fig. 6 profile with the observer (QC4, seeds 0-2) the printed form leaves 0.06-0.09 N
of error in ``f_ne`` along z in every phase and up to 0.8 N in the torque phases; with these choices the
force-only phases stay within 0.03 N and the torque phases within 0.16 N:

* ``force_map_yaw="measured"``: (40)-(41) use the measured heading rather than (45)'s ψ_ss. They
  agree at rest; while the yaw is away from ψ_ss (slow: the yaw torque range is ±0.078 N·m, or
  saturated: a world torque about x on a tilted vehicle has a component along the thrust axis that
  the rotors cannot hold) the printed choice points ``f_ne`` elsewhere.
* ``rate_feedforward``: the dissipation of (25) and (31) acts on ``η̇ - η̇*`` with ``η̇*`` the rate of
  (40)-(41)'s set-point (:func:`equilibrium_rate`: the desired force's rate along the motion and the
  heading's), so the tilt follows ``η*`` without the damper's lag (a 1 N horizontal step with the
  true wrench deviates from (32) by 24 mm instead of 111 mm, of 0.45 m). The acceleration in that
  rate is the target's, ``(f* + f̂_e)/m``, not the one the measured tilt gives: the latter closes a
  fast loop through the measured attitude that doubled the tilt noise of ``m_d < m`` sets.
* ``yaw_torque_time_constant``: a low-pass on the body z torque (without it the estimates' noise,
  through the yaw damping, dithers the rotor speeds and costs ~0.08 N of mean thrust: field
  docstring), and whenever the z torque applied differs from (25)'s (filtered or at the action's
  limit) the roll and pitch rows of (26) are kept exact with the z acceleration it gives
  (``η̈ = T⁻¹(ω̇ - Ṫ η̇)`` couples them by ``tan θ``).
* ``thrust_law="projection"``: (31)'s ``(GᵀG)⁻¹Gᵀ``, ``ρ = F·b₃`` with ``b₃`` the current body z axis,
  rather than (39)'s ``ρ = |F|``: the same at rest, but it does not push in the wrong direction while
  the attitude is still turning (on Fig. 6 the settled forces differ by ~1 mN).
* the desired thrust vector is limited to ``max_tilt_deg`` and to ``F_z >= 0.1 m g₀``.

Action (``wrench``, :mod:`quad_wrench_env.engine.actions`): ``a = (ρ/(m g₀) - 1, τ_B / s)`` with
``s = ½ m g₀ (l, l, k_m/k_f)``, clipped to [-1, 1]: thrust in [0, 2 m g₀]; on ``yuksel1kg`` the torque
range is ±1.23 N·m about x and y (9.4 rad/s² on J = 0.13, half the rotors' 19 rad/s² authority) and
±0.078 N·m about z (half the rotors' authority at hover).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from quad_wrench_env.config import build, check_numbers, config_path, load_yaml
from quad_wrench_env.engine.actions import ActionScaling
from quad_wrench_env.registry import register
from quad_wrench_env.rotations import wrap_angle
from quad_wrench_env.vehicle import GRAVITY

MODES = ("auto", "position", "force", "balance")
THRUST_LAWS = ("projection", "norm")
FORCE_MAP_YAWS = ("measured", "steady_state")
CONFIG_NAME = "ida_pbc.yaml"
"""The shipped parameter sets (``configs/ida_pbc.yaml``): QC1-QC4 and the default."""

_E_Z = np.array((0.0, 0.0, 1.0))

Vector3 = tuple[float, float, float]


@dataclass
class IDAPBCParams:
    """Desired dynamics (eqs. 25, 31-35, 42) and switches; the defaults are the ``default`` set of
    ``configs/ida_pbc.yaml`` (derivation there)."""

    m_d: float = 1.0
    """Desired mass ``m_d`` (kg), eq. (33)."""
    k_x: Vector3 = (2.25, 2.25, 6.25)
    """Stiffness ``K_x`` (N/m, world x, y, z) of the position term added to ``V_d`` (eq. 35)."""
    r_x: Vector3 = (2.4, 2.4, 4.0)
    """Translational dissipation ``R_d,x`` (N·s/m), eq. (32)."""
    n_d: Vector3 = (1.0, 1.0, 1.0)
    """Desired rotational inertia ``N`` (diagonal, kg·m², in the unit-inertia coordinates of eq. 26)."""
    k_p: Vector3 = (36.0, 36.0, 1.0)
    """``K_p`` of the rotational potential, eq. (42) (N·m/rad)."""
    r_eta: Vector3 = (9.6, 9.6, 2.0)
    """Rotational dissipation ``R_d,η`` (N·m·s/rad), eq. (32); at least ``k_d·N``."""
    k_d: float = 2.0
    """Damping injection ``k_d`` of eq. (25) (1/s)."""
    mode: str = "auto"
    """``"position"``, ``"force"``, ``"balance"`` or ``"auto"`` (module docstring)."""
    target_force: Vector3 = (0.0, 0.0, 0.0)
    """``f*`` (N, world) in ``"force"`` mode when the observation has no ``target_force`` block."""
    hold_across: bool = True
    """In ``"force"`` mode, hold ``reference`` across ``f*`` with the position-mode law (32), projected
    on the plane normal to ``f*`` (a hybrid force/position extension, not in Yüksel et al. 2014): without it
    nothing regulates the position along the surface, and a small bias (the rotors' 2 % thrust
    spread, friction) lets a vehicle pressing on a wall slide down it at ~0.3 m/s until it crashes."""
    reference: Vector3 | None = None
    """Position set-point (m, world) of ``"position"`` mode; None: the position at the episode's start
    plus ``reference_offset``."""
    reference_offset: Vector3 = (0.0, 0.0, 0.0)
    """Added to the start position when ``reference`` is None (m, world): e.g. a set-point beyond a
    surface, so that the reshaped spring ``K_x`` presses the tool on it (Yüksel et al. 2014 Fig. 5)."""
    reference_velocity: Vector3 = (0.0, 0.0, 0.0)
    """The set-point moves at this velocity (m/s, world), and the damping acts on the velocity error:
    a tool sliding along a surface."""
    yaw_reference: float | None = None
    """``ψ̄`` (rad); None: the heading at the episode's start."""
    force_map_yaw: str = "measured"
    """The ψ of (40)-(41): ``"steady_state"`` is (45)'s ``ψ_ss`` as printed, ``"measured"`` the current
    heading (the same at rest; it keeps ``f_ne`` along ``f*`` while the yaw is off its rest value)."""
    yaw_torque_time_constant: float = 0.2
    """s: first-order low-pass on the body z torque (0: none). A yaw torque needs rotor speed
    differences ``l/(k_m/k_f)`` (16 on ``yuksel1kg``) times those of a roll torque; the noise of the
    estimated yaw rate and torque, through the yaw damping, dithers the rotor speeds, and since the
    motors filter ``Ω``, not ``Ω²``, the dither costs mean thrust (Jensen: ~0.08 N without the filter)."""
    rate_feedforward: bool = True
    """Damp ``η̇ - η̇*`` instead of ``η̇`` (eqs. 25, 31), with ``η̇*`` the rate of (40)-(41)'s set-point as
    the desired force and the measured heading move (:func:`equilibrium_rate`), so that the attitude
    follows ``η*`` without the lag of a damper pulling against the motion; False: the paper's ``η̇``."""
    thrust_law: str = "projection"
    """``"projection"`` (eq. 31, ``F·b₃``) or ``"norm"`` (eq. 39, ``|F|``)."""
    torque_shift: bool = True
    """Shift the attitude potential's minimum by the estimated torque, eqs. (46)-(47)."""
    use_wrench: bool = True
    """Feed the observed wrench to (25), (31), (46)-(47) and the balance mode; False: ``ŵ_e = 0``."""
    force_damping: float = 0.0
    """``D`` (N·s/m) of ``f* - D ẋ`` in the force and balance modes (0: the paper's, floating)."""
    max_tilt_deg: float = 35.0
    """Largest tilt of the desired thrust vector (deg)."""

    def __post_init__(self) -> None:
        for name in ("k_x", "r_x", "n_d", "k_p", "r_eta", "target_force"):
            setattr(self, name, _vector3(name, getattr(self, name)))
        if self.reference is not None:
            self.reference = _vector3("reference", self.reference)
        self.reference_offset = _vector3("reference_offset", self.reference_offset)
        self.reference_velocity = _vector3("reference_velocity", self.reference_velocity)
        check_numbers("ida_pbc", self, ("m_d", "max_tilt_deg"))
        check_numbers("ida_pbc", self, ("k_d", "force_damping", "yaw_torque_time_constant"), positive=False)
        if self.yaw_reference is not None:
            _finite("yaw_reference", self.yaw_reference)
        for name, positive in (("k_x", False), ("r_x", False), ("n_d", True), ("k_p", True)):
            values = np.array(getattr(self, name))
            if np.any(values <= 0.0 if positive else values < 0.0):
                raise ValueError(
                    f"ida_pbc.{name}={getattr(self, name)!r} must be {'> 0' if positive else '>= 0'}"
                )
        if np.any(np.array(self.r_eta) < self.k_d * np.array(self.n_d) - 1e-12):
            raise ValueError(
                f"ida_pbc.r_eta={self.r_eta!r} must be at least k_d·n_d = "
                f"{tuple(self.k_d * np.array(self.n_d))!r}: K_v = N⁻¹(R_d - k_d N)N⁻¹ (eq. 31) must be >= 0"
            )
        if self.mode not in MODES:
            raise ValueError(f"ida_pbc.mode={self.mode!r}; allowed: {list(MODES)}")
        if self.force_map_yaw not in FORCE_MAP_YAWS:
            raise ValueError(f"ida_pbc.force_map_yaw={self.force_map_yaw!r}; allowed: {list(FORCE_MAP_YAWS)}")
        if self.thrust_law not in THRUST_LAWS:
            raise ValueError(f"ida_pbc.thrust_law={self.thrust_law!r}; allowed: {list(THRUST_LAWS)}")
        if self.max_tilt_deg >= 90.0:
            raise ValueError(f"ida_pbc.max_tilt_deg={self.max_tilt_deg} must be below 90")
        for name in ("torque_shift", "use_wrench", "rate_feedforward"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"ida_pbc.{name}={getattr(self, name)!r} must be true or false")


def _finite(name: str, value: float) -> None:
    if not (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)):
        raise ValueError(f"ida_pbc.{name}={value!r} must be a finite number")


def _vector3(name: str, value: Any) -> Vector3:
    values = tuple(value) if isinstance(value, (list, tuple)) else None
    if (
        values is None
        or len(values) != 3
        or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in values
        )
    ):
        raise ValueError(f"ida_pbc.{name}={value!r} must be 3 finite numbers")
    return (float(values[0]), float(values[1]), float(values[2]))


# -- kinematics ---------------------------------------------------------------------------------------
def euler_zyx(rotation: np.ndarray) -> np.ndarray:
    """``(φ, θ, ψ)`` of ``R = R_z(ψ) R_y(θ) R_x(φ)`` (body-to-world, project frames)."""
    return np.array(
        (
            math.atan2(rotation[2, 1], rotation[2, 2]),
            -math.asin(max(-1.0, min(1.0, rotation[2, 0]))),
            math.atan2(rotation[1, 0], rotation[0, 0]),
        )
    )


def euler_rate_map(roll: float, pitch: float) -> np.ndarray:
    """``T(η)`` of ``ω = T η̇`` (body rates from ZYX Euler rates; Yüksel et al. 2014
    Sec. II, corrected (2, 2))."""
    sr, cr, sp, cp = math.sin(roll), math.cos(roll), math.sin(pitch), math.cos(pitch)
    return np.array(((1.0, 0.0, -sp), (0.0, cr, sr * cp), (0.0, -sr, cr * cp)))


def euler_rate_map_derivative(roll: float, pitch: float, roll_rate: float, pitch_rate: float) -> np.ndarray:
    """``Ṫ(η, η̇)``."""
    sr, cr, sp, cp = math.sin(roll), math.cos(roll), math.sin(pitch), math.cos(pitch)
    return np.array(
        (
            (0.0, 0.0, -cp * pitch_rate),
            (0.0, -sr * roll_rate, cr * cp * roll_rate - sr * sp * pitch_rate),
            (0.0, -cr * roll_rate, -sr * cp * roll_rate - cr * sp * pitch_rate),
        )
    )


# -- Sec. IV --------------------------------------------------------------------------------------------
def force_equilibrium(
    desired_force: np.ndarray, yaw: float, mass: float, gravity: float = GRAVITY
) -> tuple[float, float, float]:
    """Eqs. (39)-(41) in project frames: ``(ρ*, φ*, θ*)`` with ``ρ* R(φ*, θ*, ψ) e₃ - m g e₃ = f*``
    (eq. 37) for the desired exerted force ``f*`` (N, world) at heading ``ψ = yaw``."""
    thrust_vector = np.asarray(desired_force, dtype=float) + mass * gravity * _E_Z
    rho = float(np.linalg.norm(thrust_vector))  # (39)
    if rho == 0.0:
        return 0.0, 0.0, 0.0
    cy, sy = math.cos(yaw), math.sin(yaw)
    forward = thrust_vector[0] * cy + thrust_vector[1] * sy  # ρ cφ sθ, first row of (38)
    left = -thrust_vector[0] * sy + thrust_vector[1] * cy  # -ρ sφ, second row of (38)
    roll = math.asin(max(-1.0, min(1.0, -left / rho)))  # (40), corrected
    pitch = math.atan2(forward, thrust_vector[2])  # (41), corrected (= arcsin(forward/(ρ cφ)), F_z > 0)
    return rho, roll, pitch


def equilibrium_rate(
    thrust_vector: np.ndarray, thrust_vector_rate: np.ndarray, yaw: float, yaw_rate: float
) -> np.ndarray:
    """``(φ̇*, θ̇*, 0)``: the rate of (40)-(41)'s set-point as the thrust vector ``F = f* + m g e₃`` and
    the heading move. With ``a = F_x cψ + F_y sψ``, ``b = -F_x sψ + F_y cψ`` (so ``φ* = arcsin(-b/ρ)``,
    ``θ* = atan2(a, F_z)``): ``ȧ = cψ Ḟ_x + sψ Ḟ_y + b ψ̇``, ``ḃ = -sψ Ḟ_x + cψ Ḟ_y - a ψ̇``,
    ``ρ̇ = F·Ḟ/ρ``, ``φ̇* = (b ρ̇/ρ - ḃ)/(ρ cφ*)``, ``θ̇* = (F_z ȧ - a Ḟ_z)/(a² + F_z²)``."""
    rho = float(np.linalg.norm(thrust_vector))
    if rho == 0.0:
        return np.zeros(3)
    cy, sy = math.cos(yaw), math.sin(yaw)
    fx, fy, fz = thrust_vector
    dfx, dfy, dfz = thrust_vector_rate
    a = fx * cy + fy * sy
    b = -fx * sy + fy * cy
    a_dot = cy * dfx + sy * dfy + b * yaw_rate
    b_dot = -sy * dfx + cy * dfy - a * yaw_rate
    rho_dot = float(thrust_vector @ thrust_vector_rate) / rho
    cos_roll = max(math.sqrt(max(0.0, 1.0 - (b / rho) ** 2)), 1e-6)
    roll_rate = (b * rho_dot / rho - b_dot) / (rho * cos_roll)
    pitch_rate = (fz * a_dot - a * dfz) / (a * a + fz * fz)
    return np.array((roll_rate, pitch_rate, 0.0))


def attitude_shift(
    equilibrium: tuple[float, float], torque: np.ndarray, k_p: tuple[float, float, float]
) -> tuple[float, float]:
    """Eqs. (46)-(47): ``(φ̄, θ̄) = (φ* - τ̃_φ/k_p^φ, θ* - τ̃_θ/k_p^θ)`` for the generalised external
    torque ``τ̃_e`` (Euler coordinates), so that (44)'s rest attitude is ``(φ*, θ*)``."""
    return equilibrium[0] - float(torque[0]) / k_p[0], equilibrium[1] - float(torque[1]) / k_p[1]


def steady_yaw(yaw_bar: float, torque: np.ndarray, k_p: tuple[float, float, float]) -> float:
    """The yaw row of eq. (45): ``ψ_ss = ψ̄ + τ̃_ψ/k_p^ψ``."""
    return yaw_bar + float(torque[2]) / k_p[2]


def limit_tilt(thrust_vector: np.ndarray, max_tilt: float, weight: float) -> np.ndarray:
    """``thrust_vector`` with ``F_z >= 0.1·weight`` and its tilt at most ``max_tilt`` (rad)."""
    vertical = max(float(thrust_vector[2]), 0.1 * weight)
    horizontal = thrust_vector[:2]
    norm = float(np.hypot(horizontal[0], horizontal[1]))
    widest = vertical * math.tan(max_tilt)
    if norm > widest:
        horizontal = horizontal * (widest / norm)
    return np.array((horizontal[0], horizontal[1], vertical))


# -- the policy -------------------------------------------------------------------------------------------
@register("agent", "ida_pbc")
class IDAPBCPolicy:
    """Eqs. (25), (31), (39)-(47) through the ``wrench`` action (module docstring)."""

    def __init__(self, params: IDAPBCParams | str | None = None, **kwargs: Any) -> None:
        """``params``: a parameter set, or the name of one in ``configs/ida_pbc.yaml`` (what
        ``make_agent("ida_pbc", params="QC2")`` passes); or keyword parameters. With neither, the
        set is the file's default for the task flown (``task_defaults``), chosen at :meth:`reset`."""
        if params is not None and kwargs:
            raise ValueError("pass either params or keyword parameters, not both")
        self._by_task = params is None and not kwargs
        """Whether the set follows the task of each :meth:`reset` (none was given)."""
        if isinstance(params, str):
            params = load_param_set(params)
        self._use(params or build(IDAPBCParams, kwargs, prefix="ida_pbc."))
        self._layout: dict[str, slice] = {}
        self._mass = 1.0
        self._inertia = np.ones(3)
        self._scaling: ActionScaling | None = None
        self._dt = 0.02
        self._yaw_alpha = 1.0
        self._yaw_torque: float | None = None
        self._mode = "position"
        self._reference: np.ndarray | None = None
        self._yaw_bar: float | None = None
        self.last: dict[str, Any] = {}
        """Intermediate values of the last :meth:`act` (``f_star``, ``rho``, ``eta_star``, ``eta_bar``,
        ``eta``, ``torque_gen``, ``body_torque``), for inspection."""

    def _use(self, params: IDAPBCParams) -> None:
        """Fly ``params`` (and the gains derived from them)."""
        self.params = p = params
        self._k_x, self._r_x = np.array(p.k_x), np.array(p.r_x)
        self._n, self._k_p, self._r_eta = np.array(p.n_d), np.array(p.k_p), np.array(p.r_eta)
        self._k_v_eta = (self._r_eta - p.k_d * self._n) / (self._n * self._n)
        self._max_tilt = math.radians(p.max_tilt_deg)

    @classmethod
    def from_param_set(cls, name: str | None = None, path: str | Path | None = None) -> IDAPBCPolicy:
        """The policy with a named parameter set of ``configs/ida_pbc.yaml`` (its default if None)."""
        return cls(load_param_set(name, path))

    @property
    def mode(self) -> str:
        """The mode in use (``"auto"`` resolved at :meth:`reset`)."""
        return self._mode

    def reset(self, env: gym.Env) -> None:
        """Read ``env``'s layout, vehicle (mass, inertia, arm, ``k_m/k_f``: the action scales) and policy
        step, and clear the episode's state; the set-points are taken from the first observation
        unless given. Any action type but ``wrench`` is refused."""
        base = env.unwrapped
        if base.cfg.action_type != "wrench":
            raise ValueError(f"IDAPBCPolicy needs action_type='wrench', the env has {base.cfg.action_type!r}")
        self._layout = dict(base.obs_layout)
        missing = {"position", "velocity", "attitude", "body_rates", "force", "torque"} - set(self._layout)
        if missing:
            raise ValueError(
                f"IDAPBCPolicy needs the observation blocks {sorted(missing)}, which this env lacks"
            )
        if self._by_task:
            self._use(load_param_set(task_default_set(base.task.env_id)))
        vehicle = base.vehicle
        self._mass = float(vehicle.mass)
        self._inertia = np.array(vehicle.inertia, dtype=float)
        self._scaling = base.action_scaling
        self._dt = base.dt
        tau = self.params.yaw_torque_time_constant
        self._yaw_alpha = 1.0 if tau == 0.0 else 1.0 - math.exp(-self._dt / tau)
        self._yaw_torque = None
        mode = self.params.mode
        if mode == "auto":
            mode = "force" if "target_force" in self._layout else "position"
        self._mode = mode
        reference = self.params.reference
        self._reference = None if reference is None else np.array(reference, dtype=float)
        self._yaw_bar = self.params.yaw_reference
        self.last = {}

    # -- the two halves of the law -------------------------------------------------------------------
    def desired_force(
        self, position: np.ndarray, velocity: np.ndarray, force: np.ndarray, target: np.ndarray | None
    ) -> np.ndarray:
        """``f*`` (N, world): the force the vehicle must exert, ``f_ne = ρ R e₃ - m g e₃``, in the mode in
        use (``target``: the observation's ``target_force`` block, if any)."""
        p = self.params
        if self._mode == "position":
            assert self._reference is not None
            ratio = self._mass / p.m_d
            # target (32): m_d ẍ = -K_x (x - x_r) - R_d ẋ + f_e  <=>  m ẍ = f_ne + f_e with
            return ratio * (-self._k_x * (position - self._reference) - self._r_x * velocity + force) - force
        damping = p.force_damping * velocity
        if self._mode == "balance":
            return -force - damping  # Sec. V-C: f* = -f̂_e
        wanted = np.array(p.target_force) if target is None else target
        size = float(np.linalg.norm(wanted))
        if not (p.hold_across and size > 0.0 and self._reference is not None):
            return wanted - damping
        normal = wanted / size
        ratio = self._mass / p.m_d
        hold = ratio * (-self._k_x * (position - self._reference) - self._r_x * velocity + force) - force
        return wanted - normal * (normal @ damping) + hold - normal * (normal @ hold)

    def desired_force_rate(self, velocity: np.ndarray, acceleration: np.ndarray) -> np.ndarray:
        """``ḟ*`` (N/s) of :meth:`desired_force` for the velocity and the (desired) acceleration, with
        the estimated force held (its rate is not observed): ``(m/m_d)(-K_x ẋ - R_d ẍ)`` in
        ``"position"`` mode, ``-D ẍ`` else."""
        if self._mode == "position":
            return self._mass / self.params.m_d * (-self._k_x * velocity - self._r_x * acceleration)
        return -self.params.force_damping * acceleration

    def body_torque(
        self,
        rotation: np.ndarray,
        body_rates: np.ndarray,
        eta_bar: np.ndarray,
        torque_world: np.ndarray,
        eta_bar_rate: np.ndarray | None = None,
    ) -> np.ndarray:
        """Eq. (25) with (31)'s rotational rows: the body torque (N·m) towards ``η̄`` for the estimated
        world torque ``τ̂`` (zeros without the wrench); the dissipation acts on ``η̇ - η̄̇`` when the
        set-point's rate ``η̄̇`` is given (zeros: the paper's ``η̇``)."""
        p = self.params
        eta = euler_zyx(rotation)
        t_map = euler_rate_map(eta[0], eta[1])
        eta_rate = np.linalg.solve(t_map, body_rates)
        relative_rate = eta_rate if eta_bar_rate is None else eta_rate - eta_bar_rate
        torque_gen = t_map.T @ (rotation.T @ torque_world)  # τ̂_e = Tᵀ Rᵀ τ̂_world
        error = wrap_angle(eta - eta_bar)
        # (31): τ = -N⁻¹ K_p η_e - K_v N η̇ + (N⁻¹ - I) τ̂_e
        tau = (
            -self._k_p * error / self._n
            - self._k_v_eta * self._n * relative_rate
            + (1.0 / self._n - 1.0) * torque_gen
        )
        # (26): η̈ = -k_d η̇ + τ + τ_e, imposed by (25) in body form
        eta_accel = -p.k_d * relative_rate + tau + torque_gen
        t_dot = euler_rate_map_derivative(eta[0], eta[1], eta_rate[0], eta_rate[1])
        coriolis = t_dot @ eta_rate
        omega_dot = t_map @ eta_accel + coriolis
        inertia = self._inertia
        bias = np.cross(body_rates, inertia * body_rates) - rotation.T @ torque_world
        torque = inertia * omega_dot + bias
        demand = torque[2]
        if self._yaw_alpha < 1.0:
            self._yaw_torque = demand if self._yaw_torque is None else self._yaw_torque
            self._yaw_torque += self._yaw_alpha * (demand - self._yaw_torque)
            torque[2] = self._yaw_torque
        limit = self._scaling.torque[2]
        torque[2] = max(-limit, min(limit, torque[2]))
        if torque[2] != demand:
            # The yaw torque is filtered or saturates: keep the roll and pitch rows of (26) exact with
            # the body z acceleration it gives, u = ω̇ - Ṫη̇ = T η̈ (the φ̈, θ̈ rows of T⁻¹).
            u_z = (torque[2] - bias[2]) / inertia[2] - coriolis[2]
            sr, cr, tp = math.sin(eta[0]), math.cos(eta[0]), math.tan(eta[1])
            u_y = (eta_accel[1] + sr * u_z) / cr
            u_x = eta_accel[0] - sr * tp * u_y - cr * tp * u_z
            torque[:2] = inertia[:2] * (np.array((u_x, u_y)) + coriolis[:2]) + bias[:2]
        self.last.update(eta=eta, torque_gen=torque_gen)
        return torque

    def act(self, observation: np.ndarray) -> np.ndarray:
        """Eqs. (25), (31), (39)-(47): the ``wrench`` action (float32, clipped to [-1, 1]) for this
        observation (its estimated state and wrench; the target force when the env has that block)."""
        if self._scaling is None:
            raise RuntimeError("call reset(env) before act()")
        p, layout = self.params, self._layout
        obs = np.asarray(observation, dtype=float)
        position, velocity = obs[layout["position"]], obs[layout["velocity"]]
        attitude = obs[layout["attitude"]]
        body_x, body_y = attitude[:3], attitude[3:]
        rotation = np.column_stack((body_x, body_y, np.cross(body_x, body_y)))
        body_rates = obs[layout["body_rates"]]
        if p.use_wrench:
            force, torque_world = obs[layout["force"]], obs[layout["torque"]]
        else:
            force, torque_world = np.zeros(3), np.zeros(3)
        if self._reference is None:
            self._reference = position + np.array(p.reference_offset)
        else:
            self._reference = self._reference + np.array(p.reference_velocity) * self._dt
        velocity = velocity - np.array(p.reference_velocity)  # the damping acts on the velocity error
        if self._yaw_bar is None:
            self._yaw_bar = math.atan2(body_x[1], body_x[0])
        target = obs[layout["target_force"]] if "target_force" in layout else None
        f_star = self.desired_force(position, velocity, force, target)
        weight = self._mass * GRAVITY
        thrust_vector = limit_tilt(f_star + weight * _E_Z, self._max_tilt, weight)
        # (45): the steady yaw under the estimated yaw torque, the ψ of (40)-(41)
        eta = euler_zyx(rotation)
        torque_gen = euler_rate_map(eta[0], eta[1]).T @ (rotation.T @ torque_world)
        psi_ss = steady_yaw(self._yaw_bar, torque_gen, p.k_p)
        psi = psi_ss if p.force_map_yaw == "steady_state" else float(eta[2])
        rho_star, roll_star, pitch_star = force_equilibrium(thrust_vector - weight * _E_Z, psi, self._mass)
        if p.torque_shift:
            roll_bar, pitch_bar = attitude_shift((roll_star, pitch_star), torque_gen, p.k_p)  # (46)-(47)
        else:
            roll_bar, pitch_bar = roll_star, pitch_star
        eta_bar = np.array((roll_bar, pitch_bar, self._yaw_bar))
        eta_star_rate = None
        if p.rate_feedforward:
            yaw_rate = 0.0
            if p.force_map_yaw == "measured":
                yaw_rate = float(np.linalg.solve(euler_rate_map(eta[0], eta[1]), body_rates)[2])
            # the acceleration the target asks for now, (f* + f̂_e)/m
            acceleration = (f_star + force) / self._mass
            force_rate = self.desired_force_rate(velocity, acceleration)
            eta_star_rate = equilibrium_rate(thrust_vector, force_rate, psi, yaw_rate)
        tau_body = self.body_torque(rotation, body_rates, eta_bar, torque_world, eta_star_rate)
        rho = rho_star if p.thrust_law == "norm" else max(0.0, float(thrust_vector @ rotation[:, 2]))
        self.last.update(
            f_star=f_star,
            rho=rho,
            eta_star=np.array((roll_star, pitch_star, psi)),
            eta_bar=eta_bar,
            body_torque=tau_body,
        )
        return self._scaling.to_action((rho, *tau_body))


def load_param_set(name: str | None = None, path: str | Path | None = None) -> IDAPBCParams:
    """The parameter set ``name`` of ``path`` (default: the shipped ``configs/ida_pbc.yaml``), or the
    file's ``default`` set when ``name`` is None; unknown names and keys are refused."""
    data = load_yaml(path if path is not None else _config_file())
    sets = data.get("sets", {})
    chosen = data.get("default") if name is None else name
    if chosen not in sets:
        raise ValueError(f"no IDA-PBC parameter set {chosen!r}; available: {sorted(sets)}")
    return build(IDAPBCParams, sets[chosen], prefix=f"ida_pbc.{chosen}.")


def task_default_set(env_id: str, path: str | Path | None = None) -> str | None:
    """The name of the set flown on ``env_id`` when none is named: the file's ``task_defaults`` entry
    for it, else None (the file's ``default``)."""
    data = load_yaml(path if path is not None else _config_file())
    return data.get("task_defaults", {}).get(env_id)


def _config_file() -> Path:
    try:
        return config_path(CONFIG_NAME)
    except ValueError:  # not installed with the package: the repository's folder
        return Path(__file__).resolve().parents[2] / "configs" / CONFIG_NAME

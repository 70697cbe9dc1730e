"""The PID position controller with disturbance feed-forward of Hentzen et al. 2019 (Sec. IV-C).

Eq. (3), per world axis ``i``::

    a_des,i = k_p,i·e_p,i + k_d,i·e_v,i + k_i,i·∫e_p,i - f̂_ext,i/m  (+ a_ref,i)

with ``e_p = p_ref - p̂`` and ``e_v = v_ref - v̂`` from the observation's estimated state and reference
blocks, and ``f̂_ext`` the observation's estimated external force, used only with ``compensation``.
``a_ref`` is the reference acceleration, estimated from the observed reference velocity
(:class:`~quad_wrench_env.control.guidance.ReferenceExtrapolator`), as the guidance module of
Hentzen et al. 2019 provides it. ``a_des`` becomes a collective thrust and a roll and pitch
(:func:`~quad_wrench_env.control.guidance.attitude_from_acceleration`), flown by the autopilot through the
``attitude`` action; the heading is held at ``yaw_reference``.

The gains are either given per axis (``k_p_xy`` ...) or by one ``bandwidth`` λ (1/s): a critically
damped PD, ``k_p = λ²``, ``k_d = 2λ``, with a slow integrator, ``k_i = λ³/50`` (its pole ~50x slower:
a faster one overshoots every reference step by 5-15 %). As in every cascade, the position loop must
be slower than the attitude loop it commands, so at :meth:`PIDController.configure` λ is lowered to a third of
the vehicle's attitude-loop gain (``AutopilotGains.attitude_p``) where it is above: 5/s on
``hummingbird``, 1.9/s on ``ardrone2`` and ``crazyflie2``, 1.3/s on ``yuksel1kg``.

The integral term is clamped to ``max_integral_acceleration`` (m/s²) per axis, so that it cannot wind
up without bound while the tilt or thrust saturates; the default, g·tan 30°, lets it hold any force
the tilt limit can.

:class:`PIDController` runs it for a batch of vehicles, each with its own integrator and reference
history (restarted per vehicle): the PID agent (:class:`~quad_wrench_env.agents.pid.PIDPolicy`) is a
batch of one, the env's ``residual`` action type (:mod:`quad_wrench_env.control.residual`) a batch of
every vehicle of the env, so both fly the same numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from quad_wrench_env.autopilot import AutopilotGains
from quad_wrench_env.config import check_numbers
from quad_wrench_env.control.guidance import ReferenceExtrapolator, attitude_from_acceleration
from quad_wrench_env.engine.actions import ActionScaling
from quad_wrench_env.rotations import wrap_angle
from quad_wrench_env.vehicle import VehicleParams

NEEDED_BLOCKS = ("position", "velocity", "attitude", "force", "reference_position", "reference_velocity")
"""The observation blocks eq. (3) reads."""


@dataclass
class PIDGains:
    """Gains of eq. (3) (horizontal ``xy`` and vertical ``z``) and the controller's switches."""

    k_p_xy: float = 4.0
    """1/s²."""
    k_d_xy: float = 3.5
    """1/s."""
    k_i_xy: float = 1.5
    """1/s³."""
    k_p_z: float = 4.0
    k_d_z: float = 3.5
    k_i_z: float = 1.5
    max_integral_acceleration: float = 5.66
    """Bound on each axis' integral term ``k_i·∫e_p`` (m/s²)."""
    k_yaw: float = 1.0
    """Heading feedback (1/s) through the yaw-rate command."""
    yaw_reference: float = 0.0
    bandwidth: float | None = None
    """λ (1/s): when given, the six gains above follow from it (module docstring)."""
    compensation: bool = False
    """Subtract ``f̂_ext/m`` (the feed-forward of Hentzen et al. 2019, eq. (3))."""
    feedforward: bool = True
    """Add the reference acceleration estimated from the observed reference velocity."""

    def __post_init__(self) -> None:
        check_numbers(
            "pid",
            self,
            ("k_p_xy", "k_d_xy", "k_p_z", "k_d_z", "max_integral_acceleration", "k_yaw"),
        )
        check_numbers("pid", self, ("k_i_xy", "k_i_z"), positive=False)
        if self.bandwidth is not None:
            check_numbers("pid", self, ("bandwidth",))


def bandwidth_gains(bandwidth: float) -> tuple[float, float, float]:
    """``(k_p, k_d, k_i)`` of bandwidth λ: ``(λ², 2λ, λ³/50)``."""
    return bandwidth**2, 2.0 * bandwidth, 0.02 * bandwidth**3


class PIDController:
    """Eq. (3) for ``count`` vehicles from their observations, through the ``attitude`` action (module
    docstring); :meth:`configure` before the first step, :meth:`restart` at each vehicle's episode start."""

    def __init__(self, gains: PIDGains, count: int = 1) -> None:
        self.gains = gains
        g = gains
        self._k_p = np.array((g.k_p_xy, g.k_p_xy, g.k_p_z))
        self._k_d = np.array((g.k_d_xy, g.k_d_xy, g.k_d_z))
        self._k_i = np.array((g.k_i_xy, g.k_i_xy, g.k_i_z))
        self.bandwidth = g.bandwidth
        """λ in use (None with per-axis gains): ``gains.bandwidth`` capped at :meth:`configure`."""
        self.reference = ReferenceExtrapolator()
        self._integral = np.zeros((count, 3))
        """Each vehicle's integral term ``k_i·∫e_p`` (m/s²)."""
        self._layout: dict[str, slice] = {}
        self._mass = 1.0
        self._dt = 0.02
        self._scaling: ActionScaling | None = None
        self._max_tilt = math.radians(30.0)

    def configure(
        self,
        layout: dict[str, slice],
        vehicle: VehicleParams,
        dt: float,
        scaling: ActionScaling,
        max_tilt: float,
    ) -> None:
        """Fly an env of observation ``layout``, ``vehicle``, control period ``dt`` (s), attitude action
        ``scaling`` and roll and pitch limit ``max_tilt`` (rad); every vehicle starts afresh."""
        missing = sorted(set(NEEDED_BLOCKS) - set(layout))
        if missing:
            raise ValueError(f"the PID needs the observation blocks {missing}, which this env lacks")
        if scaling.action_type != "attitude":
            raise ValueError(f"the PID flies action_type='attitude', not {scaling.action_type!r}")
        self._layout, self._mass, self._dt = layout, vehicle.mass, dt
        self._scaling, self._max_tilt = scaling, max_tilt
        self._integral[:] = 0.0
        self.reference.reset()
        if self.gains.bandwidth is not None:
            attitude_p = AutopilotGains.for_vehicle(vehicle).attitude_p
            self.bandwidth = min(self.gains.bandwidth, attitude_p / 3.0)
            self._k_p[:], self._k_d[:], self._k_i[:] = bandwidth_gains(self.bandwidth)

    def restart(self, index: np.ndarray | slice) -> None:
        """Vehicles ``index`` begin an episode: their integrals and reference histories cleared."""
        self._integral[index] = 0.0
        self.reference.restart(index)

    def desired_accelerations(self, observations: np.ndarray) -> np.ndarray:
        """Eq. (3): (N, 3) ``a_des`` (m/s², world frame) for (N, width) observations; advances the
        integrators."""
        obs, layout, g = observations.astype(float), self._layout, self.gains
        reference = obs[:, layout["reference_position"]]
        reference_velocity = obs[:, layout["reference_velocity"]]
        acceleration = self.reference.update(reference, reference_velocity, self._dt)
        error = reference - obs[:, layout["position"]]
        limit = g.max_integral_acceleration
        self._integral = np.clip(self._k_i * error * self._dt + self._integral, -limit, limit)
        desired = self._k_p * error + self._k_d * (reference_velocity - obs[:, layout["velocity"]])
        desired += self._integral
        if g.feedforward:
            desired += acceleration
        if g.compensation:
            desired -= obs[:, layout["force"]] / self._mass
        return desired

    def actions(self, observations: np.ndarray, offsets: np.ndarray | None = None) -> np.ndarray:
        """(N, 4) float32 ``attitude`` actions for (N, width) observations, ``offsets`` (N, 3; m/s²,
        world frame) added to eq. (3)'s ``a_des`` before its conversion (the vertical channel first where
        the tilt saturates); advances the integrators."""
        if self._scaling is None:
            raise RuntimeError("call configure() before actions()")
        desired = self.desired_accelerations(observations)
        if offsets is not None:
            desired += offsets
        out = np.empty((len(desired), 4), dtype=np.float32)
        for n, body_x in enumerate(observations[:, self._layout["attitude"]]):
            yaw = math.atan2(float(body_x[1]), float(body_x[0]))
            thrust, roll, pitch = attitude_from_acceleration(desired[n], yaw, self._mass, self._max_tilt)
            yaw_rate = self.gains.k_yaw * wrap_angle(self.gains.yaw_reference - yaw)
            out[n] = self._scaling.to_action((roll, pitch, yaw_rate, thrust))
        return out

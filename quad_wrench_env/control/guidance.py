"""Guidance helpers shared by the position controllers of Hentzen et al. 2019 (Sec. IV-B to IV-D).

* :class:`ReferenceExtrapolator` turns the reference position and velocity that the observation
  carries into a reference over a prediction horizon, with the reference acceleration estimated by
  differencing the observed reference velocity between policy steps (the MPC's state and input
  references, and the PID controller's feed-forward acceleration).
* :func:`attitude_from_acceleration` maps a desired acceleration to the collective thrust and the roll
  and pitch that produce it (Hentzen et al. 2019 Sec. IV-A: "the desired acceleration vector is transformed
  into a collective thrust and a reference attitude"), for the project's Euler convention
  ``R = Rz(ψ)·Ry(θ)·Rx(φ)`` (:func:`quad_wrench_env.rotations.quat_from_euler_zyx`).
"""

from __future__ import annotations

import math

import numpy as np

from quad_wrench_env.vehicle import GRAVITY


class ReferenceExtrapolator:
    """Reference position, velocity and acceleration over a horizon, from the current reference alone.

    ``p_r(t_k) = p_r + v_r·t_k + a_r·t_k²/2`` and ``v_r(t_k) = v_r + a_r·t_k`` with the acceleration
    ``a_r = (v_r - v_r,prev)/dt`` held over the horizon (0 on the first step after :meth:`reset`, and for
    a batch's vehicles on their first step after :meth:`restart`). One vehicle's reference is (3,) arrays,
    a batch's (N, 3).
    """

    def __init__(self) -> None:
        self.position = np.zeros(3)
        self.velocity = np.zeros(3)
        self.acceleration = np.zeros(3)
        self._previous_velocity: np.ndarray | None = None
        self._fresh = np.zeros((), dtype=bool)
        """Per vehicle of a batch (a 0-d array for one): restarted since the last update."""
        self._restarted = False
        """Whether any vehicle of :attr:`_fresh` is."""

    def reset(self) -> None:
        """Forget the previous reference (call at the start of an episode)."""
        self.position = np.zeros(3)
        self.velocity = np.zeros(3)
        self.acceleration = np.zeros(3)
        self._previous_velocity = None

    def restart(self, index: np.ndarray | slice) -> None:
        """Forget the previous reference of a batch's vehicles ``index`` (their episodes restarting)."""
        if self._previous_velocity is not None:
            self._fresh[index] = True
            self._restarted = True

    def update(self, position: np.ndarray, velocity: np.ndarray, dt: float) -> np.ndarray:
        """Take the reference ``position`` (m) and ``velocity`` (m/s) of this policy step, ``dt`` (s)
        after the previous one; returns the estimated reference acceleration (m/s², world frame)."""
        velocity = np.array(velocity, dtype=float)
        self.position = np.array(position, dtype=float)
        if self._previous_velocity is None:
            self.acceleration = np.zeros_like(velocity)
            self._fresh, self._restarted = np.zeros(velocity.shape[:-1], dtype=bool), False
        else:
            self.acceleration = (velocity - self._previous_velocity) / dt
            if self._restarted:
                self.acceleration[self._fresh] = 0.0
                self._fresh[...], self._restarted = False, False
        self.velocity = velocity
        self._previous_velocity = velocity
        return self.acceleration.copy()

    def horizon(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(positions, velocities, accelerations)`` at ``times`` (s) from now: each (len(times), 3) for
        one vehicle, (N, len(times), 3) for a batch."""
        t = np.asarray(times, dtype=float)
        t = t.reshape(t.shape + (1,) * self.position.ndim)
        a = self.acceleration
        positions = self.position + self.velocity * t + 0.5 * a * t * t
        velocities = self.velocity + a * t
        accelerations = np.broadcast_to(a, velocities.shape).copy()
        if self.position.ndim == 1:
            return positions, velocities, accelerations
        return tuple(np.moveaxis(x, 0, 1) for x in (positions, velocities, accelerations))


def attitude_from_acceleration(
    acceleration: np.ndarray, yaw: float, mass: float, max_tilt: float | None = None
) -> tuple[float, float, float]:
    """``(thrust, roll, pitch)`` (N, rad, rad) that give the world-frame ``acceleration`` (m/s²).

    The thrust vector is ``F = m·(a + g·e_z)`` (``a`` already holds any ``-f̂/m`` term of a force to
    compensate). Rotated into the heading frame, ``f' = Rz(-ψ)·F``, the pitch is
    ``θ = atan2(f'_x, f'_z)`` and the roll ``φ = atan2(-f'_y, sqrt(f'_x² + f'_z²))``, so that
    ``R(φ, θ, ψ)·e_z`` is along ``F``. The thrust is ``|F|``, which equals ``F·z_body`` for this
    attitude.

    With ``max_tilt`` (rad), the limit the attitude action clips roll and pitch to, the vertical channel
    comes first, as an autopilot's does: where roll or pitch passes it, both are clipped to it and the
    thrust is the one whose vertical part is ``F_z``, ``T = F_z / (cos φ cos θ)`` (the body z axis's
    vertical component is ``cos φ cos θ`` at any heading), so that the height holds and the horizontal
    acceleration gets what the tilt allows. Without it, ``|F|`` through a clipped tilt climbs.
    """
    force = mass * (np.asarray(acceleration, dtype=float) + np.array((0.0, 0.0, GRAVITY)))
    c, s = math.cos(yaw), math.sin(yaw)
    fx = c * force[0] + s * force[1]
    fy = -s * force[0] + c * force[1]
    fz = float(force[2])
    pitch = math.atan2(fx, fz)
    roll = math.atan2(-fy, math.hypot(fx, fz))
    if max_tilt is not None and max(abs(roll), abs(pitch)) > max_tilt:
        roll, pitch = (min(max(angle, -max_tilt), max_tilt) for angle in (roll, pitch))
        return max(fz, 0.0) / (math.cos(roll) * math.cos(pitch)), roll, pitch
    return float(np.linalg.norm(force)), roll, pitch

"""A scheduled external wrench, as in the simulations of Yüksel et al. 2014 (Fig. 4) and McKinnon &
Schoellig 2016 (Fig. 5).

Each segment ``[start, end, f_x, f_y, f_z, τ_x, τ_y, τ_z]`` (s, N, N·m, world frame) adds its force
at the centre of mass and its torque as a couple: opposite forces ``±(τ × u)/(2a)`` at the points
``±a·u`` (``u`` a unit vector ⟂ τ), so that like every other load it acts through forces at points.
Overlapping segments add up.
"""

from __future__ import annotations

import math

import numpy as np

from quad_wrench_env.disturbances.base import BodyState, CompiledForm
from quad_wrench_env.numerics import njit
from quad_wrench_env.rotations import cross, rows_times
from quad_wrench_env.vehicle import GRAVITY, VehicleParams

_COUPLE_ARM = 0.1
"""m: half the distance between the two forces of a torque couple."""


def validate_segments(segments: list) -> np.ndarray:
    """(K, 8) array of segments, or ``ValueError`` naming the bad one."""
    rows = []
    for segment in segments:
        values = list(segment) if isinstance(segment, (list, tuple)) else None
        if (
            values is None
            or len(values) != 8
            or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values)
            or not values[0] < values[1]
        ):
            raise ValueError(
                f"external_wrench segment {segment!r} must be [start, end, fx, fy, fz, tx, ty, tz] "
                "with finite numbers and start < end"
            )
        rows.append(values)
    return np.array(rows, dtype=float).reshape(-1, 8)


def in_weights(segments: list, vehicle: VehicleParams) -> list[list[float]]:
    """``segments`` whose forces are in weights (``m g``) and torques in weight times arm, in N and N·m
    for ``vehicle`` (a schedule that means the same push on every preset)."""
    rows = validate_segments(segments)
    weight = vehicle.mass * GRAVITY
    rows[:, 2:8] *= weight
    rows[:, 5:8] *= vehicle.arm
    return rows.tolist()


class WrenchProfile:
    """Piecewise-constant external force and torque, applied as point forces: a
    :class:`~quad_wrench_env.disturbances.base.PointLoad`."""

    name = "external_wrench"
    compiled = CompiledForm("quad_wrench_env.disturbances.wrench_profile", (("load", "profile_load"),))

    def __init__(self, segments: list) -> None:
        self.segments = validate_segments(segments)

    def kernel_parameters(self) -> np.ndarray:
        """The segments, (K, 8) flattened."""
        return self.segments.ravel()

    def wrench(self, t: np.ndarray) -> np.ndarray:
        """(n, 6) ``[f, τ]`` (world) acting at times ``t`` (n,)."""
        t = np.asarray(t, dtype=float)[..., None]
        active = (self.segments[:, 0] <= t) & (t < self.segments[:, 1])
        return rows_times(active.astype(float), self.segments[:, 2:])

    def point_load(
        self, t: np.ndarray, body: BodyState, index: np.ndarray | slice = slice(None)
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """(offsets, forces), each (n, 3, 3), of the force at the centre of mass and the torque couple
        for n vehicles at times ``t`` (n,), or None without segments."""
        if not self.segments.size:
            return None
        w = self.wrench(t)
        force, torque = w[:, :3], w[:, 3:]
        norm = np.linalg.norm(torque, axis=1, keepdims=True)
        # a unit vector u ⟂ τ; forces ±F at ±a·u with 2a·(u × F) = τ  =>  F = (τ × u)/(2a)
        helper = np.where(np.abs(torque[:, :1]) < 0.9 * norm, (1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
        u = cross(torque, helper)
        u_norm = np.linalg.norm(u, axis=1, keepdims=True)
        u = np.where(norm > 0.0, u / np.where(norm > 0.0, u_norm, 1.0), 0.0)
        couple = cross(torque, u) / (2.0 * _COUPLE_ARM)
        offsets = np.stack((np.zeros_like(u), _COUPLE_ARM * u, -_COUPLE_ARM * u), axis=1)
        return offsets, np.stack((force, couple, -couple), axis=1)


@njit
def profile_load(segments, table, state, time, position, velocity, angular_velocity, rotation, out):
    """``WrenchProfile.point_load``'s resultant added to ``out`` (N, 6): the sum of the segments acting
    at each vehicle's time (``segments``: (K, 8) flattened)."""
    count = segments.shape[0] // 8
    w = np.empty(6)
    for n in range(time.shape[0]):
        w[:] = 0.0
        for k in range(count):
            if segments[8 * k] <= time[n] < segments[8 * k + 1]:
                for i in range(6):
                    w[i] += segments[8 * k + 2 + i]
        for i in range(6):
            out[n, i] += w[i]

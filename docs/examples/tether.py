"""A tether: an elastic line from an anchor to a point under the vehicle, with damping (a point load that
reads the vehicle's position, velocity and rates)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from quad_wrench_env.disturbances.base import CompiledForm
from quad_wrench_env.numerics import njit
from quad_wrench_env.registry import register


@dataclass
class TetherConfig:
    anchor: tuple[float, float, float] = (2.3, 0.0, 0.0)
    """m, world frame: where the line is tied."""
    length: float = 0.8
    """m: the line's rest length; slack (no force) while shorter."""
    stiffness: float = 20.0
    """N/m of stretch."""
    damping: float = 2.0
    """N·s/m along the line, while taut."""
    attachment: tuple[float, float, float] = (0.0, 0.0, -0.05)
    """m, body frame: where the line meets the vehicle."""


@register("load", "tether")  # gym.make(id, loads=[{"load": "tether", "length": 0.8}])
class Tether:
    """A :class:`~quad_wrench_env.disturbances.base.PointLoad`, registered: any env's ``loads`` takes it."""

    config_class = TetherConfig
    name = "tether"
    compiled = CompiledForm(__name__, (("load", "tether_load"),))

    def __init__(self, config: TetherConfig, count: int) -> None:
        self.config = config

    def kernel_parameters(self) -> np.ndarray:
        c = self.config
        return np.array((*c.anchor, c.length, c.stiffness, c.damping, *c.attachment))

    def point_load(self, t, body, index=slice(None)):
        """The line's pull at the attachment point (world frame): ``k·stretch + c·(stretch rate)``
        along the line towards the anchor, zero while slack."""
        p = self.kernel_parameters()
        anchor, length, k, c, attachment = p[0:3], p[3], p[4], p[5], p[6:9]
        offsets = np.einsum("nij,j->ni", body.rotation, attachment)
        point = body.position + offsets
        point_velocity = body.velocity + np.cross(body.angular_velocity, offsets)
        line = point - anchor
        distance = np.linalg.norm(line, axis=1, keepdims=True)
        along = line / np.maximum(distance, 1e-9)
        stretch = distance - length
        rate = np.sum(point_velocity * along, axis=1, keepdims=True)
        pull = np.where(stretch > 0.0, k * stretch + c * rate, 0.0)
        return offsets[:, None, :], (-np.maximum(pull, 0.0) * along)[:, None, :]


@njit
def tether_load(params, table, state, time, position, velocity, angular_velocity, rotation, out):
    """``Tether.point_load``'s resultant about the centre of mass added to ``out`` (N, 6)."""
    length, k, c = params[3], params[4], params[5]
    for n in range(time.shape[0]):
        r = np.zeros(3)
        for i in range(3):
            for j in range(3):
                r[i] += rotation[n, i, j] * params[6 + j]
        w = angular_velocity[n]
        v = (
            velocity[n, 0] + w[1] * r[2] - w[2] * r[1],
            velocity[n, 1] + w[2] * r[0] - w[0] * r[2],
            velocity[n, 2] + w[0] * r[1] - w[1] * r[0],
        )
        line = (
            position[n, 0] + r[0] - params[0],
            position[n, 1] + r[1] - params[1],
            position[n, 2] + r[2] - params[2],
        )
        distance = math.sqrt(line[0] ** 2 + line[1] ** 2 + line[2] ** 2)
        if distance <= length:
            continue
        u = (line[0] / distance, line[1] / distance, line[2] / distance)
        pull = max(k * (distance - length) + c * (v[0] * u[0] + v[1] * u[1] + v[2] * u[2]), 0.0)
        f = (-pull * u[0], -pull * u[1], -pull * u[2])
        out[n, 0] += f[0]
        out[n, 1] += f[1]
        out[n, 2] += f[2]
        out[n, 3] += r[1] * f[2] - r[2] * f[1]
        out[n, 4] += r[2] * f[0] - r[0] * f[2]
        out[n, 5] += r[0] * f[1] - r[1] * f[0]

"""A thermal: a steady vertical column of rising air, Gaussian across (a wind model, one file)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.disturbances.base import STILL, CompiledForm, Steady
from quad_wrench_env.numerics import njit
from quad_wrench_env.registry import register


@dataclass
class ThermalConfig:
    center: tuple[float, float] = (2.3, 0.0)
    """x, y (m, world frame) of the column's axis."""
    radius: float = 0.5
    """m: the speed falls to 1/e at this distance from the axis."""
    speed: float = 1.0
    """m/s upwards on the axis."""

    def __post_init__(self) -> None:
        self.center = tuple(self.center)
        check_numbers("wind.thermal", self, ("radius",))
        check_numbers("wind.thermal", self, ("speed",), positive=False)


@register("wind", "thermal")  # gym.make(id, wind=[{"model": "thermal", "speed": 2.0}])
class Thermal(Steady):  # Steady: no random draws, nothing to reset or advance
    config_class = ThermalConfig
    name = "thermal"
    compiled = CompiledForm(__name__, (("velocity", "thermal_velocity"), STILL))

    def __init__(self, config: ThermalConfig, count: int) -> None:
        self.config = config

    def kernel_parameters(self) -> np.ndarray:
        c = self.config
        return np.array((c.center[0], c.center[1], c.radius, c.speed))

    def velocity_at(self, points, t, index, mean=False) -> np.ndarray:
        x0, y0, radius, speed = self.kernel_parameters()
        r2 = (points[..., 0] - x0) ** 2 + (points[..., 1] - y0) ** 2
        out = np.zeros(points.shape)
        out[..., 2] = speed * np.exp(-r2 / radius**2)
        return out


@njit
def thermal_velocity(params, table, state, points, time, out):
    """``Thermal.velocity_at`` added to ``out`` (N, P, 3)."""
    x0, y0, radius, speed = params[0], params[1], params[2], params[3]
    for n in range(points.shape[0]):
        for p in range(points.shape[1]):
            dx, dy = points[n, p, 0] - x0, points[n, p, 1] - y0
            out[n, p, 2] += speed * math.exp(-(dx * dx + dy * dy) / (radius * radius))

"""A fixed, strong horizontal jet: paper 003's gust fan, which the vehicle descends through (centre
speed 3, 10 or 12 m/s). The fan's jet model (:mod:`.fan`: Gaussian profile, momentum-conserving
centre-line speed, half-width ``b = sqrt((D/2)² + (c·x)²)``) from a fixed outlet at ``position``
blowing along ``direction``, without turbulence or motion."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.disturbances.base import STILL, CompiledForm, Steady
from quad_wrench_env.disturbances.fan import centreline_speed, half_width
from quad_wrench_env.disturbances.registry import wind_model


@dataclass
class JetConfig:
    position: tuple[float, float, float] = (3.0, -2.0, 1.0)
    """The outlet's centre (m, world frame)."""
    direction: tuple[float, float, float] = (0.0, 1.0, 0.0)
    """Where it blows (normalised here)."""
    speed: float = 10.0
    """Outlet (core) speed ``U0`` (m/s): paper 003 uses 3, 10 and 12."""
    diameter: float = 0.5
    """Outlet diameter ``D`` (m)."""
    spread: float = 0.42
    """Growth ``c`` of the half-width, as the fan's."""

    def __post_init__(self) -> None:
        self.position, self.direction = tuple(self.position), tuple(self.direction)
        check_numbers("wind.jet", self, ("speed", "diameter", "spread"))
        for key in ("position", "direction"):
            value = getattr(self, key)
            if len(value) != 3 or not all(math.isfinite(v) for v in value):
                raise ValueError(f"wind.jet: {key}={list(value)!r} must be 3 finite numbers")
        if math.hypot(*self.direction) == 0.0:
            raise ValueError("wind.jet: direction=[0, 0, 0] has no direction; give a non-zero vector")


@wind_model("jet", JetConfig)
class Jet(Steady):
    """The same fixed jet for every vehicle: a :class:`~quad_wrench_env.disturbances.base.WindField`."""

    name = "jet"
    compiled = CompiledForm(
        "quad_wrench_env.disturbances.jet_kernels",
        (("velocity", "fixed_jet_velocity"), STILL),
        table="speed_scale",
    )

    def __init__(self, config: JetConfig, count: int = 1) -> None:
        self.config = config
        self.speed_scale = np.ones((count, 1))
        """(N, 1) each vehicle's multiple of the outlet speed ``U0`` (0 switches its jet off)."""
        self.origin = np.array(config.position, dtype=float)
        self.direction = np.array(config.direction, dtype=float) / math.hypot(*config.direction)
        self._radius2 = (0.5 * config.diameter) ** 2

    def kernel_parameters(self) -> np.ndarray:
        """On, U0, core length ``D/(2c)``, outlet radius, spread, origin (3), direction (3)."""
        c = self.config
        radius = 0.5 * c.diameter
        return np.array((1.0, c.speed, radius / c.spread, radius, c.spread, *self.origin, *self.direction))

    def velocity_at(
        self, points: np.ndarray, t: np.ndarray, index: np.ndarray | slice, mean: bool = False
    ) -> np.ndarray:
        c = self.config
        relative = points - self.origin
        x = relative @ self.direction
        radial = relative - x[..., None] * self.direction
        b = half_width(x, self._radius2, c.spread)
        u_c = centreline_speed(x, c.speed, self._radius2, c.spread)
        speed = np.where(x > 0.0, u_c * np.exp(-(radial * radial).sum(axis=-1) / (b * b)), 0.0)
        speed = speed * np.reshape(self.speed_scale[index, 0], (-1, 1))
        return speed[..., None] * self.direction

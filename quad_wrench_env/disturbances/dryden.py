"""Dryden turbulence (MIL-F-8785C, low altitude) on a mean wind, for the wind gusts of Hentzen et al. 2019
(``docs/physics.md``, "Dryden turbulence").

At altitude h (ft): ``L_w = h``, ``L_u = L_v = h/(0.177 + 0.000823·h)^1.2``, ``σ_w = 0.1·W20`` and
``σ_u = σ_v = σ_w/(0.177 + 0.000823·h)^0.4`` (W20: the wind speed at 20 ft). Each component is a
first-order (exponentially correlated) process with correlation length L, stepped with the exact
discrete filter ``u_{k+1} = a·u_k + σ·sqrt(1 - a²)·η_k``, ``a = exp(-V·T/L)``,
``V = max(airspeed, |mean wind|, 1 m/s)``: its variance is σ² and its autocorrelation at lag L/V is
e^-1 at any physics step T (uniform noise without the ``sqrt(1 - a²)`` scaling, as one peer has, gets
neither). The horizontal components are along world x and y (σ_u = σ_v, L_u = L_v: either pair of
horizontal axes gives the same statistics), the vertical along z. The gust is uniform over the
vehicle: it moves the body, the fan's jet makes the torques. Each vehicle has its own mean wind and
turbulence scale (:attr:`DrydenGust.weather`; the config's for every vehicle unless a task sets them
per episode).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.disturbances.base import CompiledForm
from quad_wrench_env.numerics import njit
from quad_wrench_env.registry import register

FEET = 0.3048
"""m per ft."""


@dataclass
class DrydenConfig:
    w20: float = 1.0
    """Wind speed (m/s) at 20 ft: ``σ_w = 0.1·w20``. Outdoor light turbulence is w20 = 7.7 m/s
    (σ_u ≈ 1.5 m/s at 2 m); indoors use far less."""
    altitude: float = 1.0
    """Height (m) the scales are taken at (the model's h, converted to ft)."""
    mean: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Mean wind (m/s, world frame)."""

    def __post_init__(self) -> None:
        self.mean = tuple(self.mean)
        check_numbers("wind.dryden", self, ("altitude",))
        check_numbers("wind.dryden", self, ("w20",), positive=False)
        if len(self.mean) != 3 or not all(math.isfinite(v) for v in self.mean):
            raise ValueError(f"wind.dryden: mean={list(self.mean)!r} must be 3 finite numbers (m/s)")

    def scales(self) -> tuple[np.ndarray, np.ndarray]:
        """(3,) σ (m/s) and (3,) correlation lengths L (m) of the x, y, z components."""
        h = self.altitude / FEET
        low = 0.177 + 0.000823 * h
        sigma_w = 0.1 * self.w20
        sigma_u = sigma_w / low**0.4
        length_u = h / low**1.2 * FEET
        return np.array((sigma_u, sigma_u, sigma_w)), np.array((length_u, length_u, h * FEET))


@register("wind", "dryden")
class DrydenGust:
    """The Dryden field of N vehicles: a :class:`~quad_wrench_env.disturbances.base.WindField`."""

    config_class = DrydenConfig
    name = "dryden"
    noise_width = 3
    compiled = CompiledForm(
        "quad_wrench_env.disturbances.dryden",
        (("velocity", "dryden_velocity"), ("advance", "dryden_advance")),
        state="gust",
        table="weather",
    )

    def __init__(self, config: DrydenConfig, count: int = 1) -> None:
        self.config = config
        self.sigma, self.length = config.scales()
        self.gust = np.zeros((count, 3))
        """(N, 3) turbulent part of each vehicle's wind at the config's σ (m/s)."""
        self.weather = np.tile((*config.mean, 1.0), (count, 1))
        """(N, 4) each vehicle's mean wind (3, m/s, world frame) and the factor on its turbulence."""

    def set_weather(self, index: int, mean: Sequence[float] = (0.0, 0.0, 0.0), factor: float = 0.0) -> None:
        """Vehicle ``index``'s mean wind (3, m/s, world frame) and the factor on its turbulence (0: none),
        e.g. drawn by a task per episode."""
        self.weather[index] = (*mean, factor)

    def kernel_parameters(self) -> np.ndarray:
        """σ (3), L (3)."""
        return np.concatenate((self.sigma, self.length))

    def reset(self, index: int, rng: np.random.Generator) -> None:
        self.gust[index] = self.sigma * rng.standard_normal(3)  # the stationary distribution

    def velocity_at(
        self, points: np.ndarray, t: np.ndarray, index: np.ndarray | slice, mean: bool = False
    ) -> np.ndarray:
        weather = self.weather[index]
        wind = weather[..., :3] if mean else weather[..., :3] + weather[..., 3:] * self.gust[index]
        return np.broadcast_to(np.reshape(wind, (-1, 1, 3)), points.shape).copy()


@njit
def dryden_velocity(params, weather, gust, points, time, out):
    """``DrydenGust.velocity_at`` added to ``out``: each vehicle's mean plus its scaled gust at every
    point."""
    for n in range(points.shape[0]):
        for p in range(points.shape[1]):
            for i in range(3):
                out[n, p, i] += weather[n, i] + weather[n, 3] * gust[n, i]


@njit
def dryden_advance(params, weather, gust, position, velocity, dt, normals):
    """The gusts one physics step on (the wind field's ``advance``): per vehicle and axis the exact
    discrete first-order (Dryden) filter of time scale L/V, V the airspeed (at least the mean wind and
    1 m/s): ``g' = a·g + σ·sqrt(1 - a²)·η``, ``a = exp(-V·dt/L)``."""
    for n in range(gust.shape[0]):
        m0, m1, m2 = weather[n, 0], weather[n, 1], weather[n, 2]
        mean_speed = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
        a0, a1, a2 = velocity[n, 0] - m0, velocity[n, 1] - m1, velocity[n, 2] - m2
        speed = max(max(math.sqrt(a0 * a0 + a1 * a1 + a2 * a2), mean_speed), 1.0)
        for i in range(3):
            decay = math.exp(-speed * dt / params[3 + i])
            gust[n, i] = decay * gust[n, i] + params[i] * math.sqrt(1.0 - decay * decay) * normals[n, i]

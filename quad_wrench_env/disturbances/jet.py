"""A fixed, strong horizontal jet: Hentzen et al.'s (2019) gust fan, which the vehicle descends through
(centre speed 3, 10 or 12 m/s; Sec. V-F). The fan's jet model (:mod:`.fan`: Gaussian
profile, momentum-conserving centre-line speed, half-width ``b = sqrt((D/2)² + (c·x)²)``) from a fixed
outlet at ``position`` blowing along ``direction``, without motion.

Turbulence is off by default (Hentzen et al. 2019 give none). With ``turbulence_intensity`` I > 0 it is the
fan's model (McKinnon & Schoellig 2016's fan, :mod:`.fan`): the local mean velocity ``u·d`` becomes
``u·(d + I·n(t))``, ``n`` a unit-variance Ornstein-Uhlenbeck process per vehicle and world axis
(:func:`~quad_wrench_env.disturbances.jet_kernels.turbulence_step`) of time scale ``L/u_c``, ``u_c`` the
centre-line speed at the vehicle's distance along the jet and ``L`` the ``turbulence_length`` (by
default the half-width ``b`` there, as the fan's). So each component's sd is ``I·u`` and its
autocorrelation time ``L/u_c``. A turbulent jet draws three normals per vehicle and physics step (and
three at each reset, the process's stationary distribution); without turbulence it draws none, so
flights without it keep their random numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.disturbances.base import STILL, CompiledForm, Outlet
from quad_wrench_env.disturbances.fan import centreline_speed, half_width
from quad_wrench_env.registry import register

_KERNELS = "quad_wrench_env.disturbances.jet_kernels"
STEADY = CompiledForm(_KERNELS, (("velocity", "fixed_jet_velocity"), STILL), table="speed_scale")
"""The compiled form of a jet without turbulence."""
TURBULENT = CompiledForm(
    _KERNELS,
    (("velocity", "fixed_jet_velocity"), ("advance", "fixed_jet_advance")),
    state="turbulence",
    table="speed_scale",
)
"""The compiled form of a turbulent jet: its turbulence is state, advanced every physics step."""


@dataclass
class JetConfig:
    position: tuple[float, float, float] = (3.0, -2.0, 1.0)
    """The outlet's centre (m, world frame)."""
    direction: tuple[float, float, float] = (0.0, 1.0, 0.0)
    """Where it blows (normalised here)."""
    speed: float = 10.0
    """Outlet (core) speed ``U0`` (m/s): Hentzen et al. 2019 use 3, 10 and 12."""
    diameter: float = 0.5
    """Outlet diameter ``D`` (m)."""
    spread: float = 0.42
    """Growth ``c`` of the half-width, as the fan's."""
    turbulence_intensity: float = 0.0
    """``I`` (1): each turbulent component's sd over the local mean speed; 0 (no turbulence) to < 1."""
    turbulence_length: float | None = None
    """``L`` (m): the eddies' length scale, the turbulence's time scale ``L/u_c``; None: the jet's
    half-width ``b`` at the vehicle's distance (the fan's)."""

    def __post_init__(self) -> None:
        self.position, self.direction = tuple(self.position), tuple(self.direction)
        check_numbers("wind.jet", self, ("speed", "diameter", "spread"))
        for key in ("position", "direction"):
            value = getattr(self, key)
            if len(value) != 3 or not all(math.isfinite(v) for v in value):
                raise ValueError(f"wind.jet: {key}={list(value)!r} must be 3 finite numbers")
        if math.hypot(*self.direction) == 0.0:
            raise ValueError("wind.jet: direction=[0, 0, 0] has no direction; give a non-zero vector")
        if not (0.0 <= self.turbulence_intensity < 1.0):
            raise ValueError(
                f"wind.jet: turbulence_intensity={self.turbulence_intensity!r} must be in [0, 1)"
            )
        if self.turbulence_length is not None:
            check_numbers("wind.jet", self, ("turbulence_length",))


@register("wind", "jet")
class Jet:
    """The same fixed jet for every vehicle, each with its own turbulence: a
    :class:`~quad_wrench_env.disturbances.base.WindField`."""

    config_class = JetConfig
    name = "jet"
    noise_width = 0
    """Normal draws per vehicle and physics step: 3 for a turbulent jet (set per instance)."""
    compiled = STEADY
    """:data:`STEADY`, or :data:`TURBULENT` for a turbulent jet (set per instance)."""

    def __init__(self, config: JetConfig, count: int = 1) -> None:
        self.config = config
        self.speed_scale = np.ones((count, 1))
        """(N, 1) each vehicle's multiple of the outlet speed ``U0`` (0 switches its jet off)."""
        self.turbulence = np.zeros((count, 3))
        """(N, 3) each vehicle's unit-variance turbulence ``n`` (world axes)."""
        if config.turbulence_intensity > 0.0:
            self.noise_width, self.compiled = 3, TURBULENT
        self.origin = np.array(config.position, dtype=float)
        self.direction = np.array(config.direction, dtype=float) / math.hypot(*config.direction)
        self._radius2 = (0.5 * config.diameter) ** 2

    def outlet(self, vehicle: int, time: float, position: np.ndarray) -> Outlet:
        """The fixed outlet along its direction (the :class:`~quad_wrench_env.disturbances.base.Visible`
        seam), active while the vehicle's ``speed_scale`` is above 0."""
        c = self.config
        active = float(self.speed_scale[vehicle, 0]) > 0.0
        return Outlet(self.origin, self.direction, self.direction, 0.5 * c.diameter, c.spread, active)

    def kernel_parameters(self) -> np.ndarray:
        """On, U0, core length ``D/(2c)``, outlet radius, spread, origin (3), direction (3), turbulence
        intensity, turbulence length (0: the half-width)."""
        c = self.config
        radius = 0.5 * c.diameter
        length = c.turbulence_length or 0.0
        return np.array(
            (
                1.0,
                c.speed,
                radius / c.spread,
                radius,
                c.spread,
                *self.origin,
                *self.direction,
                c.turbulence_intensity,
                length,
            )
        )

    def reset(self, index: int, rng: np.random.Generator) -> None:
        if self.noise_width:  # the stationary distribution of the process
            self.turbulence[index] = rng.standard_normal(3)

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
        if mean or not self.noise_width:
            return speed[..., None] * self.direction
        direction = self.direction + c.turbulence_intensity * self.turbulence[index]
        return speed[..., None] * direction[:, None, :]

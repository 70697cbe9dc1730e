"""A 1-cosine gust (``docs/physics.md``, "1-cosine gust"): ``V(t) = (V_m/2)·(1 - cos(π·(t - t0)/t_g))``
for ``0 <= t - t0 <= t_g``, then ``V_m`` (``hold``) or back down the same way over another ``t_g`` (a
bump); uniform in space, ``V_m`` a vector (m/s, world frame). Each vehicle has its own peak, start
and duration (:attr:`OneCosineGust.shape`; the config's unless a task draws them per episode)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.disturbances.base import STILL, CompiledForm, Steady
from quad_wrench_env.numerics import njit
from quad_wrench_env.registry import register


@dataclass
class OneCosineConfig:
    peak: tuple[float, float, float] = (1.0, 0.0, 0.0)
    """``V_m`` (m/s, world frame)."""
    start: float = 1.0
    """``t0`` (s)."""
    duration: float = 1.0
    """``t_g`` (s): rise time from 0 to the peak."""
    hold: bool = True
    """True: stay at the peak after ``t_g``; False: back to zero over another ``t_g``."""

    def __post_init__(self) -> None:
        self.peak = tuple(self.peak)
        check_numbers("wind.one_cosine", self, ("duration",))
        check_numbers("wind.one_cosine", self, ("start",), positive=False)
        if len(self.peak) != 3 or not all(math.isfinite(v) for v in self.peak):
            raise ValueError(f"wind.one_cosine: peak={list(self.peak)!r} must be 3 finite numbers (m/s)")


def gust_shape(
    t: np.ndarray, start: float | np.ndarray, duration: float | np.ndarray, hold: bool
) -> np.ndarray:
    """The gust's fraction of its peak at times ``t``."""
    phase = np.clip((np.asarray(t, dtype=float) - start) / duration, 0.0, 1.0 if hold else 2.0)
    return 0.5 * (1.0 - np.cos(math.pi * phase))


@register("wind", "one_cosine")
class OneCosineGust(Steady):
    """The gust of N vehicles, each at its own time: a
    :class:`~quad_wrench_env.disturbances.base.WindField`."""

    config_class = OneCosineConfig
    name = "one_cosine"
    compiled = CompiledForm(
        "quad_wrench_env.disturbances.one_cosine",
        (("velocity", "one_cosine_velocity"), STILL),
        table="shape",
    )

    def __init__(self, config: OneCosineConfig, count: int = 1) -> None:
        self.config = config
        self.shape = np.tile((*config.peak, config.start, config.duration), (count, 1))
        """(N, 5) each vehicle's gust: peak ``V_m`` (3, m/s), start ``t0`` (s), duration ``t_g`` (s)."""

    def set_gust(
        self, index: int, peak: Sequence[float] = (0.0, 0.0, 0.0), start: float = 0.0, duration: float = 1.0
    ) -> None:
        """Vehicle ``index``'s gust: peak ``V_m`` (3, m/s; zero: none), start ``t0`` and duration ``t_g``
        (s), e.g. drawn by a task per episode."""
        self.shape[index] = (*peak, start, duration)

    def kernel_parameters(self) -> np.ndarray:
        """Hold (1 or 0)."""
        return np.array((float(self.config.hold),))

    def velocity_at(
        self, points: np.ndarray, t: np.ndarray, index: np.ndarray | slice, mean: bool = False
    ) -> np.ndarray:
        shape = np.reshape(self.shape[index], (-1, 5))
        fraction = gust_shape(t, shape[:, 3], shape[:, 4], self.config.hold)
        wind = fraction[:, None] * shape[:, :3]
        return np.broadcast_to(wind[:, None, :], points.shape).copy()


@njit
def one_cosine_velocity(params, shape, state, points, time, out):
    """``OneCosineGust.velocity_at`` added to ``out``."""
    top = 1.0 if params[0] > 0.0 else 2.0
    for n in range(points.shape[0]):
        phase = min(max((time[n] - shape[n, 3]) / shape[n, 4], 0.0), top)
        fraction = 0.5 * (1.0 - math.cos(math.pi * phase))
        for p in range(points.shape[1]):
            for i in range(3):
                out[n, p, i] += fraction * shape[n, i]

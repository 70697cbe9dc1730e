"""A mass hung from a point of the body, attached or released at given times.

McKinnon & Schoellig 2016 (Sec. III) hang a 53 g test mass below the centre of mass and under one rotor
(Figs. 3-4); Hentzen et al. 2019 cut a 0.1 kg weight in flight. The mass hangs on a short string,
quasi-statically: its weight ``m_p·g`` pulls straight down at the attachment point, and the torque about
the centre of mass comes out of ``r × F`` like every other point load.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from quad_wrench_env.disturbances.base import BodyState, CompiledForm
from quad_wrench_env.numerics import njit
from quad_wrench_env.vehicle import GRAVITY


@dataclass
class PayloadConfig:
    mass: float = 0.0
    """kg; 0 disables the payload."""
    point: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Attachment point in the body frame (m)."""
    attach_time: float = 0.0
    """s; the mass hangs from this time on ..."""
    release_time: float = math.inf
    """... until this time (s)."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mass) and self.mass >= 0):
            raise ValueError(f"payload.mass={self.mass!r} must be a finite number >= 0 (kg)")
        if len(self.point) != 3 or not all(math.isfinite(c) for c in self.point):
            raise ValueError(f"payload.point={self.point!r} must be 3 finite numbers (m, body frame)")
        if not self.attach_time <= self.release_time:
            raise ValueError(
                f"payload.attach_time={self.attach_time} must not be after release_time={self.release_time}"
            )


class Payload:
    """Point load of a hanging mass (world frame), present between attach and release: a
    :class:`~quad_wrench_env.disturbances.base.PointLoad`."""

    name = "payload"
    compiled = CompiledForm("quad_wrench_env.disturbances.payload", (("load", "payload_load"),))

    def __init__(self, config: PayloadConfig) -> None:
        self.config = config
        self._point = np.array(config.point, dtype=float)
        self._weight = np.array((0.0, 0.0, -config.mass * GRAVITY))

    def kernel_parameters(self) -> np.ndarray:
        """Mass, attachment point (3), weight along z, attach and release times, for the kernels."""
        c = self.config
        return np.array((c.mass, *self._point, self._weight[2], c.attach_time, c.release_time))

    def attached(self, t: np.ndarray) -> np.ndarray:
        """Whether the mass hangs at times ``t`` (array)."""
        c = self.config
        return (c.mass > 0) & (c.attach_time <= t) & (t < c.release_time)

    def point_load(
        self, t: np.ndarray, body: BodyState, index: np.ndarray | slice = slice(None)
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """``(offsets (n, 1, 3) from the centres of mass, forces (n, 1, 3))``, world frame, for n
        vehicles at times ``t`` (n,) with attitudes ``body.rotation`` (n, 3, 3) (zero force while the
        mass does not hang), or None without a payload."""
        if self.config.mass <= 0:
            return None
        offsets = body.rotation @ self._point
        forces = self.attached(t)[:, None] * self._weight
        return offsets[:, None, :], forces[:, None, :]


@njit
def payload_load(payload, table, state, time, position, velocity, angular_velocity, rotation, out):
    """``Payload.point_load``'s resultant added to ``out`` (N, 6), numbers as
    ``Payload.kernel_parameters``."""
    if payload[0] <= 0.0:
        return
    for n in range(time.shape[0]):
        if payload[5] <= time[n] < payload[6]:
            r = rotation[n]
            o0 = r[0, 0] * payload[1] + r[0, 1] * payload[2] + r[0, 2] * payload[3]
            o1 = r[1, 0] * payload[1] + r[1, 1] * payload[2] + r[1, 2] * payload[3]
            out[n, 2] += payload[4]
            out[n, 3] += o1 * payload[4]
            out[n, 4] += -(o0 * payload[4])

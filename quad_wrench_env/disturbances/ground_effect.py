"""Ground effect, rotor by rotor (``docs/physics.md``, "Ground effect"; the table pass of Hentzen et al.
2019).

Cheeseman-Bennett: a rotor of radius R at height z above a surface gives ``T_IGE/T_OGE =
1/(1 - (R/4z)²)``, capped at 1.4 (the formula diverges at ``z = R/4``). The height of each rotor is
measured to the surface below its hub: the highest horizontal top (the ground at z = 0, a table's
top, :func:`~quad_wrench_env.scene.surface_tops`) whose footprint holds the hub and which is not above
it. Rotors over a table gain more than those beyond its edge, so crossing the edge also pitches the
vehicle. The gain is the environment acting on the vehicle: the engine applies it along body z at the
hubs as an external load (it is in ``wrench_true``), which the estimators see as an external force.
"""

from __future__ import annotations

import numpy as np

from quad_wrench_env.disturbances.base import CompiledForm
from quad_wrench_env.numerics import njit

CAP = 1.4
"""Largest thrust ratio in ground effect (``docs/physics.md``, "Ground effect")."""


def surface_below(points: np.ndarray, tops: np.ndarray) -> np.ndarray:
    """(...,) height of the highest surface under each of the (..., 3) ``points``: the ground (0) or a
    top of ``tops`` (K, 5) whose footprint holds the point and which is not above it."""
    x, y, z = points[..., 0], points[..., 1], points[..., 2]
    height = np.zeros(x.shape)
    for x0, x1, y0, y1, top in tops:
        under = (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1) & (top <= z)
        height = np.where(under, np.maximum(height, top), height)
    return height


def thrust_ratio(height: np.ndarray, radius: float, cap: float = CAP) -> np.ndarray:
    """``T_IGE/T_OGE = 1/(1 - (R/4z)²)`` at heights ``z`` above the surface, capped at ``cap``."""
    ratio2 = (radius / (4.0 * np.maximum(height, 1e-9))) ** 2
    limit = 1.0 - 1.0 / cap  # where the formula reaches the cap; the clamp keeps the other branch finite
    return np.where(ratio2 >= limit, cap, 1.0 / (1.0 - np.minimum(ratio2, limit)))


class GroundEffect:
    """Added thrust of every rotor near a surface: a
    :class:`~quad_wrench_env.disturbances.base.RotorModifier`."""

    name = "ground_effect"
    compiled = CompiledForm(
        "quad_wrench_env.disturbances.ground_effect", (("thrust", "ground_effect_thrust"),)
    )

    def __init__(self, rotor_radius: float, tops: np.ndarray, cap: float = CAP) -> None:
        self.radius = rotor_radius
        self.tops = np.asarray(tops, dtype=float).reshape(-1, 5)
        self.cap = cap

    def kernel_parameters(self) -> np.ndarray:
        """Rotor radius, cap, then the tops (K, 5) flattened."""
        return np.concatenate(((self.radius, self.cap), self.tops.ravel()))

    def added_thrust(self, hubs: np.ndarray, rotation: np.ndarray, thrusts: np.ndarray) -> np.ndarray:
        height = hubs[..., 2] - surface_below(hubs, self.tops)
        return (thrust_ratio(height, self.radius, self.cap) - 1.0) * thrusts


@njit
def ground_effect_thrust(params, table, state, hubs, rotation, thrusts, out):
    """``GroundEffect.added_thrust`` added to ``out`` (N, 4)."""
    radius, cap = params[0], params[1]
    count = (params.shape[0] - 2) // 5
    limit = 1.0 - 1.0 / cap
    for n in range(hubs.shape[0]):
        for i in range(4):
            x, y, z = hubs[n, i, 0], hubs[n, i, 1], hubs[n, i, 2]
            surface = 0.0
            for k in range(count):
                t = params[2 + 5 * k : 7 + 5 * k]
                if t[0] <= x <= t[1] and t[2] <= y <= t[3] and t[4] <= z:
                    surface = max(surface, t[4])
            ratio2 = (radius / (4.0 * max(z - surface, 1e-9))) ** 2
            factor = cap if ratio2 >= limit else 1.0 / (1.0 - ratio2)
            out[n, i] += (factor - 1.0) * thrusts[n, i]

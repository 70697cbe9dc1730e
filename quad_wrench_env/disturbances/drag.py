"""Quadratic aerodynamic drag of the body, spread over points (``docs/physics.md``, "Body drag").

``F_j = ½·ρ·(C_d A / N)·|v_rel,j|·v_rel,j`` with ``v_rel,j = w(p_j) - (v + ω × r_j)``: each of the N drag
points (rotor hubs and points on the hull ring) carries an equal share of the body's drag area, so
a wind that differs across the body produces a torque through ``r_j × F_j``.
"""

from __future__ import annotations

import numpy as np

AIR_DENSITY = 1.2
"""kg/m³"""


class QuadraticDrag:
    """Drag forces at the body's drag points for given relative air velocities."""

    def __init__(self, drag_area: float, num_points: int, air_density: float = AIR_DENSITY) -> None:
        if drag_area < 0 or num_points < 1:
            raise ValueError(f"drag_area={drag_area} must be >= 0 and num_points={num_points} >= 1")
        self.coefficient = 0.5 * air_density * drag_area / num_points
        """``½ ρ C_d A / N`` of each point (kg/m)."""

    def forces(self, relative_air_velocity: np.ndarray) -> np.ndarray:
        """(..., P, 3) world forces for (..., P, 3) air velocities relative to the points (wind - point
        velocity)."""
        speed = np.sqrt((relative_air_velocity * relative_air_velocity).sum(axis=-1))
        return (self.coefficient * speed)[..., None] * relative_air_velocity

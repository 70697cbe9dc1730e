"""Interfaces of the wind fields and of the loads they cause on the body.

A :class:`WindField` gives the air velocity at world points; the body's drag (:mod:`.drag`) turns it
into forces at body points, and the resultant about the centre of mass (:func:`resultant`) is what the
world applies. Torques are never written as formulas: they come out of ``Σ r_j × F_j``.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from quad_wrench_env.rotations import cross


@runtime_checkable
class WindField(Protocol):
    """Air velocity over the world, possibly moving and turbulent, as each of N vehicles meets it
    (every vehicle flies in a copy of the field of its own, with its own time and random state)."""

    def reset(self, index: int, rng: np.random.Generator) -> None:
        """Start a new episode of vehicle ``index``; its random draws at reset come from ``rng``."""

    def advance(self, dt: float, positions: np.ndarray, normals: np.ndarray) -> None:
        """Advance internal random processes by ``dt`` (s); ``positions`` (N, 3) are where the
        vehicles are and ``normals`` (N, 3) standard normal draws from each vehicle's generator."""

    def velocity_at(
        self, points: np.ndarray, t: np.ndarray, index: np.ndarray | slice, mean: bool = False
    ) -> np.ndarray:
        """(n, P, 3) air velocity (m/s, world frame) at (n, P, 3) world points of the vehicles
        ``index`` at their times ``t`` (n,) (s); ``mean=True`` leaves out the turbulent part."""


def resultant(offsets: np.ndarray, forces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Total force and torque about the centre of mass of forces applied at world offsets ``r_j``.

    Both arrays are (..., P, 3) in the world frame; returns ``(Σ F_j, Σ r_j × F_j)``, each (..., 3).
    """
    return forces.sum(axis=-2), cross(offsets, forces).sum(axis=-2)

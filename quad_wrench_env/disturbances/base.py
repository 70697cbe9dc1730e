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
    """Air velocity over the world, possibly moving and turbulent."""

    def reset(self, rng: np.random.Generator) -> None:
        """Start a new episode; every random draw comes from ``rng``."""

    def advance(self, dt: float, position: np.ndarray) -> None:
        """Advance internal random processes by ``dt`` (s); ``position`` is where the vehicle is."""

    def velocity_at(self, points: np.ndarray, t: float, mean: bool = False) -> np.ndarray:
        """(N, 3) air velocity (m/s, world frame) at (N, 3) world points at time ``t`` (s);
        ``mean=True`` leaves out the turbulent part."""


def resultant(offsets: np.ndarray, forces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Total force and torque about the centre of mass of forces applied at world offsets ``r_j``.

    Both arrays are (N, 3) in the world frame; returns ``(Σ F_j, Σ r_j × F_j)``.
    """
    return forces.sum(axis=0), cross(offsets, forces).sum(axis=0)

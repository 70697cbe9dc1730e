"""What a task reads of the fleet: :class:`FleetView`, read-only arrays of N vehicles after a step
or a start."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from quad_wrench_env.engine.world import RigidBodyState


class FleetView(NamedTuple):
    """N vehicles as a task sees them after a control step or a start (every array read-only, with a
    leading vehicle axis). A test builds one by hand to step a task without PyBullet."""

    time: np.ndarray
    """(N,) each vehicle's episode time (s)."""
    state: RigidBodyState
    """The true states (world frame)."""
    contact_force: np.ndarray
    """(N, 3) force of the scene on each tool's tip in the last physics step (world frame, N)."""
    wrench_true: np.ndarray
    """(N, 6) the external wrench ``[f, τ]`` on each vehicle (world frame)."""
    estimated_state: np.ndarray
    """(N, 13) the estimator's position, velocity, quaternion ``[w, x, y, z]`` and body rates."""
    wrench_est: np.ndarray
    """(N, 6) the estimator's wrench ``[f_e, τ_e]`` (world frame)."""

    @property
    def count(self) -> int:
        """N."""
        return self.time.shape[0]


def read_only(array: np.ndarray) -> np.ndarray:
    """A view of ``array`` that refuses writes (it still shows the array's later values)."""
    view = array.view()
    view.flags.writeable = False
    return view

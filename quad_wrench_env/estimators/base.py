"""What every wrench estimator returns and the interface it implements (``docs/architecture.md``,
"Contracts").

Estimators see only what a real vehicle sees: the thrust and body torque that the *nominal* mixer
computes from the measured motor speeds, and the measured pose. Force and torque are in the world
frame (McKinnon & Schoellig 2016 Fig. 1), SI units.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np


@dataclass(frozen=True)
class WrenchEstimate:
    """External force (N) and torque (N·m) in the world frame and their 6x6 covariance, world frame
    (zeros for the oracle, NaN for an estimator that carries none: the observer)."""

    force: np.ndarray
    torque: np.ndarray
    covariance: np.ndarray


@dataclass(frozen=True)
class StateEstimate:
    """The estimator's belief about the vehicle's motion (world frame; rates in the body frame)."""

    position: np.ndarray
    velocity: np.ndarray
    quaternion: np.ndarray
    """``[w, x, y, z]``, body -> world."""
    body_rates: np.ndarray


@runtime_checkable
class Estimator(Protocol):
    """A wrench estimator stepped at the motion-capture rate."""

    name: str

    def reset(self, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        """Start from a known pose, at rest, with no external wrench."""

    def step(
        self,
        thrust: float,
        body_torque: np.ndarray,
        position: np.ndarray,
        quaternion_wxyz: np.ndarray,
        velocity: np.ndarray | None = None,
        body_rates: np.ndarray | None = None,
    ) -> WrenchEstimate:
        """One step of ``dt``: inputs over the step and the pose measured at its end; velocity and
        body rates when an onboard state estimator measures them (estimators may ignore them)."""

    @property
    def estimate(self) -> WrenchEstimate:
        """The wrench estimate after the last step (zero wrench after ``reset``)."""

    @property
    def state(self) -> StateEstimate:
        """The estimated motion after the last step."""

    @property
    def status(self) -> str:
        """``"ok"``, or what the estimator had to do to stay sound (e.g. ``"reinitialised"``)."""


@runtime_checkable
class TruthFed(Protocol):
    """An estimator that is handed the truth before each step (only the ``oracle``)."""

    def observe_truth(self, state: StateEstimate, force: np.ndarray, torque: np.ndarray) -> None: ...

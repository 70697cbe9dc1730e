"""N wrench estimators of one kind stepped together: what the environments run.

An :class:`EstimatorBank` holds one estimator per vehicle and steps them all at once as one batched
computation, arrays with a leading dimension N in and out: ``UnscentedFilterBank``,
``ExtendedFilterBank``, ``ObserverBank`` and :class:`OracleBank` (a copy of the truth). Each
single-vehicle estimator (the :class:`~quad_wrench_env.estimators.base.Estimator` protocol) is a bank
of one, so there is one implementation of each algorithm.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class EstimatorBank(Protocol):
    """N estimators stepped at the motion-capture rate."""

    name: str
    count: int

    def reset(self, index: int, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        """Restart estimator ``index`` from a known pose, at rest, with no external wrench."""

    def step(
        self,
        thrusts: np.ndarray,
        body_torques: np.ndarray,
        positions: np.ndarray,
        quaternions: np.ndarray,
        velocities: np.ndarray | None = None,
        body_rates: np.ndarray | None = None,
    ) -> None:
        """One step of every estimator: (N,) thrusts, (N, 3) body torques, the (N, 3) positions and
        (N, 4) attitudes measured at the step's end, and the (N, 3) velocities and body rates where
        an onboard state estimator measures them."""

    def wrenches(self) -> np.ndarray:
        """(N, 6) estimated ``[f, τ]``, world frame."""

    def states(self) -> np.ndarray:
        """(N, 13) estimated position, velocity, quaternion ``[w, x, y, z]`` and body rates."""

    def statuses(self) -> list[str]:
        """Each estimator's status, ``"ok"`` or ``"reinitialised"``."""


def check_finite_batch(name: str, **inputs: np.ndarray | None) -> None:
    """Refuse non-finite inputs to a bank, naming them (one sum per input: NaN and inf propagate)."""
    given = {key: value for key, value in inputs.items() if value is not None}
    if not np.isfinite(sum(float(np.sum(value)) for value in given.values())):
        bad = [key for key, value in given.items() if not np.all(np.isfinite(value))]
        raise ValueError(f"{name} bank step got non-finite input(s) {bad}; allowed: finite numbers")


class OracleBank:
    """The truth for N vehicles, handed over by the env before each step (see ``OracleEstimator``)."""

    name = "oracle"

    def __init__(self, count: int) -> None:
        self.count = count
        self._states = np.zeros((count, 13))
        self._states[:, 6] = 1.0
        self._wrenches = np.zeros((count, 6))

    def reset(self, index: int, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        self._states[index] = 0.0
        self._states[index, 0:3] = position
        self._states[index, 6:10] = quaternion_wxyz
        self._wrenches[index] = 0.0

    def observe_truth(self, states: np.ndarray, wrenches: np.ndarray) -> None:
        """(N, 13) true states (as :meth:`states`) and (N, 6) true external wrenches."""
        self._states = states
        self._wrenches = wrenches

    def step(self, thrusts, body_torques, positions, quaternions, velocities=None, body_rates=None) -> None:
        """The truth needs no step."""

    def wrenches(self) -> np.ndarray:
        return self._wrenches

    def states(self) -> np.ndarray:
        return self._states

    def statuses(self) -> list[str]:
        return ["ok"] * self.count

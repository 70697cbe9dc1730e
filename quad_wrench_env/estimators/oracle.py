"""The ground truth posing as an estimator: the reference every real estimator is scored against.

It ignores the sensor inputs of :meth:`step` and returns the true external wrench and the true
state that the environment handed it through :meth:`observe_truth` (zero covariance).
"""

from __future__ import annotations

import numpy as np

from quad_wrench_env.estimators.base import StateEstimate, WrenchEstimate

_ZERO_COVARIANCE = np.zeros((6, 6))
_ZERO_COVARIANCE.flags.writeable = False


class OracleEstimator:
    """Returns the truth; use it as an upper bound, never as a claim about a real vehicle."""

    name = "oracle"
    status = "ok"

    def __init__(self) -> None:
        self._state = StateEstimate(np.zeros(3), np.zeros(3), np.array((1.0, 0.0, 0.0, 0.0)), np.zeros(3))
        self._estimate = WrenchEstimate(np.zeros(3), np.zeros(3), _ZERO_COVARIANCE)

    def reset(self, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        self._state = StateEstimate(
            np.array(position, dtype=float), np.zeros(3), np.array(quaternion_wxyz, dtype=float), np.zeros(3)
        )
        self._estimate = WrenchEstimate(np.zeros(3), np.zeros(3), _ZERO_COVARIANCE)

    def observe_truth(self, state: StateEstimate, force: np.ndarray, torque: np.ndarray) -> None:
        self._state = state
        self._estimate = WrenchEstimate(force, torque, _ZERO_COVARIANCE)

    def step(
        self,
        thrust: float,
        body_torque: np.ndarray,
        position: np.ndarray,
        quaternion_wxyz: np.ndarray,
        velocity: np.ndarray | None = None,
        body_rates: np.ndarray | None = None,
    ) -> WrenchEstimate:
        return self._estimate

    @property
    def estimate(self) -> WrenchEstimate:
        return self._estimate

    @property
    def state(self) -> StateEstimate:
        return self._state

"""Wrench estimators behind one interface; build them with :func:`make_estimator`."""

from __future__ import annotations

import math

from quad_wrench_env.estimators.base import Estimator, StateEstimate, TruthFed, WrenchEstimate
from quad_wrench_env.estimators.oracle import OracleEstimator
from quad_wrench_env.vehicle import VehicleParams

ESTIMATORS = ("oracle",)
"""Names accepted by :func:`make_estimator` (the UKF, EKF and observer follow in later issues)."""


def make_estimator(name: str, vehicle: VehicleParams, dt: float, **noise) -> Estimator:
    """Build the estimator called ``name`` for ``vehicle``, stepped every ``dt`` seconds."""
    if name not in ESTIMATORS:
        raise ValueError(f"unknown estimator {name!r}; allowed: {list(ESTIMATORS)}")
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"estimator time step dt={dt!r} must be a finite number > 0")
    if name == "oracle":
        if noise:
            raise ValueError(f"the oracle takes no noise settings, got {sorted(noise)}")
        return OracleEstimator()
    raise AssertionError(name)


__all__ = [
    "ESTIMATORS",
    "Estimator",
    "OracleEstimator",
    "StateEstimate",
    "TruthFed",
    "WrenchEstimate",
    "make_estimator",
]

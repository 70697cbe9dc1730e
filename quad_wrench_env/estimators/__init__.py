"""Wrench estimators behind one interface; build them with :func:`make_estimator`."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from quad_wrench_env.config import build
from quad_wrench_env.estimators.base import Estimator, StateEstimate, TruthFed, WrenchEstimate
from quad_wrench_env.estimators.oracle import OracleEstimator
from quad_wrench_env.estimators.ukf import UKFNoise, UnscentedWrenchEstimator
from quad_wrench_env.vehicle import VehicleParams

MEASUREMENT_NOISE_KEYS = ("position", "attitude")
"""Noise settings the env fills from its motion-capture config unless they are given."""


def _oracle(vehicle: VehicleParams, dt: float, **noise: Any) -> Estimator:
    return OracleEstimator()


def _ukf(vehicle: VehicleParams, dt: float, **noise: Any) -> Estimator:
    return UnscentedWrenchEstimator(vehicle, dt, build(UKFNoise, noise, prefix="estimator_params."))


FACTORIES: dict[str, Callable[..., Estimator]] = {"ukf": _ukf, "oracle": _oracle}
ESTIMATORS = tuple(FACTORIES)
"""Names accepted by :func:`make_estimator` (EKF and observer follow in a later issue)."""


def make_estimator(name: str, vehicle: VehicleParams, dt: float, **noise: Any) -> Estimator:
    """Build the estimator called ``name`` for ``vehicle``, stepped every ``dt`` seconds.

    ``noise`` holds the estimator's noise settings (for the UKF the fields of :class:`UKFNoise`);
    the oracle ignores the measurement-noise keys and takes no others.
    """
    if name not in FACTORIES:
        raise ValueError(f"unknown estimator {name!r}; allowed: {list(ESTIMATORS)}")
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"estimator time step dt={dt!r} must be a finite number > 0")
    if name == "oracle":
        unknown = sorted(set(noise) - set(MEASUREMENT_NOISE_KEYS))
        if unknown:
            raise ValueError(f"the oracle takes no noise settings, got {unknown}")
    return FACTORIES[name](vehicle, dt, **noise)


__all__ = [
    "ESTIMATORS",
    "MEASUREMENT_NOISE_KEYS",
    "Estimator",
    "OracleEstimator",
    "StateEstimate",
    "TruthFed",
    "UKFNoise",
    "UnscentedWrenchEstimator",
    "WrenchEstimate",
    "make_estimator",
]

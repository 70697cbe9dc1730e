"""Wrench estimators behind one interface; build them with :func:`make_estimator`."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from quad_wrench_env.config import build
from quad_wrench_env.estimators.bank import EstimatorBank, OracleBank
from quad_wrench_env.estimators.base import Estimator, StateEstimate, TruthFed, WrenchEstimate
from quad_wrench_env.estimators.ekf import ExtendedFilterBank, ExtendedWrenchEstimator
from quad_wrench_env.estimators.noise import EKFNoise, FilterNoise
from quad_wrench_env.estimators.observer import NonlinearWrenchObserver, ObserverBank, ObserverGains
from quad_wrench_env.estimators.oracle import OracleEstimator
from quad_wrench_env.estimators.ukf import UnscentedFilterBank, UnscentedWrenchEstimator
from quad_wrench_env.vehicle import VehicleParams

MEASUREMENT_NOISE_KEYS = ("position", "attitude", "velocity", "body_rate")
"""Noise settings the env fills from its sensor config; an estimator drops those it does not use."""


def _oracle(vehicle: VehicleParams, dt: float, backend: str, **noise: Any) -> Estimator:
    return OracleEstimator()


def _ukf_noise(noise: dict[str, Any]) -> FilterNoise:
    noise = {k: v for k, v in noise.items() if k not in ("velocity", "body_rate")}  # pose only
    return build(FilterNoise, noise, prefix="estimator_params.")


def _ukf(vehicle: VehicleParams, dt: float, backend: str, **noise: Any) -> Estimator:
    return UnscentedWrenchEstimator(vehicle, dt, _ukf_noise(noise), backend)


def _ekf_noise(noise: dict[str, Any]) -> EKFNoise:
    return build(EKFNoise, noise, prefix="estimator_params.")


def _ekf(vehicle: VehicleParams, dt: float, backend: str, **noise: Any) -> Estimator:
    return ExtendedWrenchEstimator(vehicle, dt, _ekf_noise(noise), backend)


def _observer_gains(settings: dict[str, Any]) -> ObserverGains:
    gains = {k: v for k, v in settings.items() if k not in MEASUREMENT_NOISE_KEYS}
    return build(ObserverGains, gains, prefix="estimator_params.")


def _observer(vehicle: VehicleParams, dt: float, backend: str, **settings: Any) -> Estimator:
    return NonlinearWrenchObserver(vehicle, dt, _observer_gains(settings), backend)


FACTORIES: dict[str, Callable[..., Estimator]] = {
    "ukf": _ukf,
    "ekf": _ekf,
    "observer": _observer,
    "oracle": _oracle,
}
ESTIMATORS = tuple(FACTORIES)
"""Names accepted by :func:`make_estimator`."""


def _check(name: str, dt: float, noise: dict[str, Any]) -> None:
    if name not in FACTORIES:
        raise ValueError(f"unknown estimator {name!r}; allowed: {list(ESTIMATORS)}")
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"estimator time step dt={dt!r} must be a finite number > 0")
    if name == "oracle":
        unknown = sorted(set(noise) - set(MEASUREMENT_NOISE_KEYS))
        if unknown:
            raise ValueError(f"the oracle takes no noise settings, got {unknown}")


def make_estimator(
    name: str, vehicle: VehicleParams, dt: float, backend: str = "numpy", **noise: Any
) -> Estimator:
    """Build the estimator called ``name`` for ``vehicle``, stepped every ``dt`` seconds.

    ``noise`` holds the estimator's settings: for the UKF the fields of :class:`FilterNoise`, for the
    EKF those of :class:`EKFNoise`, for the observer those of :class:`ObserverGains`; the observer
    and the oracle ignore the measurement-noise keys, which the env always passes. ``backend``
    picks the arithmetic (numpy reference or compiled, see :mod:`quad_wrench_env.kernels`).
    """
    _check(name, dt, noise)
    return FACTORIES[name](vehicle, dt, backend, **noise)


def make_estimator_bank(
    name: str, vehicle: VehicleParams, dt: float, count: int, backend: str = "numpy", **noise: Any
) -> EstimatorBank:
    """``count`` estimators called ``name`` (settings and ``backend`` as :func:`make_estimator`),
    stepped together as one batched computation."""
    _check(name, dt, noise)
    if not (isinstance(count, int) and count >= 1):
        raise ValueError(f"count={count!r} must be an integer >= 1")
    if name == "ukf":
        return UnscentedFilterBank(vehicle, dt, _ukf_noise(noise), count, backend)
    if name == "ekf":
        return ExtendedFilterBank(vehicle, dt, _ekf_noise(noise), count, backend)
    if name == "observer":
        return ObserverBank(vehicle, dt, _observer_gains(noise), count, backend)
    return OracleBank(count)


__all__ = [
    "ESTIMATORS",
    "MEASUREMENT_NOISE_KEYS",
    "EKFNoise",
    "Estimator",
    "EstimatorBank",
    "ExtendedFilterBank",
    "ExtendedWrenchEstimator",
    "FilterNoise",
    "NonlinearWrenchObserver",
    "ObserverBank",
    "ObserverGains",
    "OracleBank",
    "OracleEstimator",
    "StateEstimate",
    "TruthFed",
    "UnscentedFilterBank",
    "UnscentedWrenchEstimator",
    "WrenchEstimate",
    "make_estimator",
    "make_estimator_bank",
]

"""Wrench estimators behind one interface; build them with :func:`make_estimator`."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from quad_wrench_env.config import build
from quad_wrench_env.estimators.bank import EstimatorBank, EstimatorInputs, OracleBank
from quad_wrench_env.estimators.base import Estimator, StateEstimate, TruthFed, WrenchEstimate
from quad_wrench_env.estimators.ekf import ExtendedFilterBank, ExtendedWrenchEstimator
from quad_wrench_env.estimators.learned import (
    LearnedBank,
    LearnedModel,
    LearnedSettings,
    LearnedWrenchEstimator,
)
from quad_wrench_env.estimators.noise import EKFNoise, FilterNoise
from quad_wrench_env.estimators.observer import NonlinearWrenchObserver, ObserverBank, ObserverGains
from quad_wrench_env.estimators.oracle import OracleEstimator
from quad_wrench_env.estimators.ukf import UnscentedFilterBank, UnscentedWrenchEstimator
from quad_wrench_env.registry import lookup, register, registered
from quad_wrench_env.vehicle import VehicleParams

MEASUREMENT_NOISE_KEYS = ("position", "attitude", "velocity", "body_rate")
"""Noise settings the env fills from its sensor config; an estimator drops those it does not use."""
KALMAN_FILTERS = ("ukf", "ekf")
"""The estimators with :class:`FilterNoise` settings: the env fills their ``rotor_spread`` from a
calibrated vehicle's residual (``rotor_calibration``) unless given."""


@dataclass(frozen=True)
class EstimatorEntry:
    """One estimator of the registry: how its settings are read, its single form and its batch form.

    ``settings(noise)`` turns the keyword settings of :func:`make_estimator` into the settings object
    (dropping the measurement-noise keys it does not use; unknown keys raise ``ValueError``);
    ``single(vehicle, dt, settings)`` builds one estimator and ``bank(vehicle, dt, settings, count)`` a
    batch of ``count``.
    """

    settings: Callable[[dict[str, Any]], Any]
    single: Callable[[VehicleParams, float, Any], Estimator]
    bank: Callable[[VehicleParams, float, Any, int], EstimatorBank]


def _ukf_noise(noise: dict[str, Any]) -> FilterNoise:
    noise = {k: v for k, v in noise.items() if k not in ("velocity", "body_rate")}  # pose only
    return build(FilterNoise, noise, prefix="estimator_params.")


def _ekf_noise(noise: dict[str, Any]) -> EKFNoise:
    return build(EKFNoise, noise, prefix="estimator_params.")


def _observer_gains(settings: dict[str, Any]) -> ObserverGains:
    gains = {k: v for k, v in settings.items() if k not in MEASUREMENT_NOISE_KEYS}
    return build(ObserverGains, gains, prefix="estimator_params.")


def _learned_settings(settings: dict[str, Any]) -> LearnedSettings:
    given = {k: v for k, v in settings.items() if k not in MEASUREMENT_NOISE_KEYS}
    return build(LearnedSettings, given, prefix="estimator_params.")


def _oracle_settings(noise: dict[str, Any]) -> None:
    unknown = sorted(set(noise) - set(MEASUREMENT_NOISE_KEYS))
    if unknown:
        raise ValueError(f"the oracle takes no noise settings, got {unknown}")


register("estimator", "ukf", EstimatorEntry(_ukf_noise, UnscentedWrenchEstimator, UnscentedFilterBank))
register("estimator", "ekf", EstimatorEntry(_ekf_noise, ExtendedWrenchEstimator, ExtendedFilterBank))
register("estimator", "observer", EstimatorEntry(_observer_gains, NonlinearWrenchObserver, ObserverBank))
register("estimator", "learned", EstimatorEntry(_learned_settings, LearnedWrenchEstimator, LearnedBank))
register(
    "estimator",
    "oracle",
    EstimatorEntry(
        _oracle_settings,
        lambda vehicle, dt, settings: OracleEstimator(),
        lambda vehicle, dt, settings, count: OracleBank(count),
    ),
)
ESTIMATORS = registered("estimator")
"""Every estimator's :class:`EstimatorEntry` by name (the registry's live, read-only view): the names
:func:`make_estimator` and :func:`make_estimator_bank` accept. Adding one is one ``register`` call."""

NAMED_SETTINGS: dict[str, dict[str, dict[str, Any]]] = {
    "ukf": {"paper": {"force_walk": 5e-4, "torque_walk": 4e-5, "adaptive_walks": False}},
    "observer": {"paper": {"c_force": 5.0, "c_torque": 0.5}},
}
"""Settings sets by name, per estimator (the env's ``estimator_params="paper"``):

- ``ukf``, ``paper``: McKinnon & Schoellig 2016 give no covariance values, only that the estimate
  rises "in about 1 second" to a 53 g mass hung under a rotor (their Fig. 4 and Sec. V). These fixed random
  walks (N and N·m per 5 ms step; the other noise as :class:`FilterNoise`'s defaults) were fitted to
  that: ``quad-wrench reproduce mckinnon --only fig4`` with them gives 10-90 % rise times of 0.96-1.10 s
  for f_z and 0.78-0.92 s for the torques (seeds 0-2), against 0.16 s and 0.22-0.30 s with the
  defaults, which follow the faster disturbances of the tasks.
- ``observer``, ``paper``: Yüksel et al.'s (2014) gains of their Figs. 4 and 6, ``c = 5`` (force) and
  ``0.5`` (torque) as they are; the defaults scale them to the vehicle's mass and inertia.

The EKF has none: Hentzen et al. 2019 give no covariance values."""


def estimator_settings(name: str, params: Mapping[str, Any] | str) -> dict[str, Any]:
    """The settings of estimator ``name``: ``params`` as given, or the set it names
    (:data:`NAMED_SETTINGS`); an unknown name is refused, listing the estimator's sets."""
    if isinstance(params, str):
        named = NAMED_SETTINGS.get(name, {})
        if params not in named:
            raise ValueError(
                f"estimator_params={params!r}: the {name} has no settings of that name; allowed: "
                f"{sorted(named)} or a mapping of its keys"
            )
        return dict(named[params])
    return dict(params)


def _entry(name: str, dt: float) -> EstimatorEntry:
    entry = lookup("estimator", name)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"estimator time step dt={dt!r} must be a finite number > 0")
    return entry


def make_estimator(name: str, vehicle: VehicleParams, dt: float, **noise: Any) -> Estimator:
    """Build the estimator called ``name`` for ``vehicle``, stepped every ``dt`` seconds.

    ``noise`` holds the estimator's settings: for the UKF the fields of :class:`FilterNoise`, for the
    EKF those of :class:`EKFNoise`, for the observer those of :class:`ObserverGains`; the observer
    and the oracle ignore the measurement-noise keys, which the env always passes. The filters run
    their kernels (compiled, or plain Python under ``NUMBA_DISABLE_JIT=1``, see
    :mod:`quad_wrench_env.numerics`).
    """
    entry = _entry(name, dt)
    return entry.single(vehicle, dt, entry.settings(noise))


def make_estimator_bank(
    name: str, vehicle: VehicleParams, dt: float, count: int, **noise: Any
) -> EstimatorBank:
    """``count`` estimators called ``name`` (settings as :func:`make_estimator`), stepped together as
    one batched computation."""
    entry = _entry(name, dt)
    settings = entry.settings(noise)
    if not (isinstance(count, int) and count >= 1):
        raise ValueError(f"count={count!r} must be an integer >= 1")
    return entry.bank(vehicle, dt, settings, count)


__all__ = [
    "ESTIMATORS",
    "KALMAN_FILTERS",
    "MEASUREMENT_NOISE_KEYS",
    "NAMED_SETTINGS",
    "EKFNoise",
    "Estimator",
    "EstimatorBank",
    "EstimatorEntry",
    "EstimatorInputs",
    "ExtendedFilterBank",
    "ExtendedWrenchEstimator",
    "FilterNoise",
    "LearnedBank",
    "LearnedModel",
    "LearnedSettings",
    "LearnedWrenchEstimator",
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
    "estimator_settings",
    "make_estimator",
    "make_estimator_bank",
]

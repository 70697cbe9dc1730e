"""A learned wrench estimator: a small recurrent network over the filters' own sensor stream.

It reads what the UKF reads, at the same rate: every physics step's thrust and motor torque (the
nominal mixer of the quantised motor speeds), the measured pose and, where an onboard state estimator
measures them, the velocity and body rates. A gated recurrent unit over frames of per-step features
of these and of the force that moved the vehicle beyond its thrust and weight over baselines of up to
1.3 s (:mod:`quad_wrench_env.estimators.learned_kernel`; a frame per four physics steps) gives the
world-frame force, the body-frame external torque (turned into the world frame by the measured
attitude), the velocity and the body rates, and a heteroscedastic Gaussian's variance for each wrench
component (Nix & Weigend 1994; Kendall & Gal 2017), so that ``info["wrench_cov"]`` and the NEES checks
apply as to the filters. The pose reported is the one measured. Fitted by ``quad-wrench
fit-estimator`` (:mod:`quad_wrench_env.estimators.fitting`) on flights with the true wrench as its
target, one model per vehicle preset; the shipped ones are loaded by name (``docs/estimators.md``,
"The learned estimator").

A model refuses, by name, a vehicle, a time step or a sensor set (the onboard state estimator's
velocity and body rates, or not) other than those it was fitted on: its features would mean something
else. Other noise levels are not refused (the outside conditions of the studies).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from quad_wrench_env.estimators.bank import BankOfOne, EstimatorInputs, FilterBank
from quad_wrench_env.estimators.learned_kernel import (
    FORCES,
    LOGITS,
    OUTPUTS,
    TRACKER_WALKS,
    TRAIL,
    frame_width,
    learned_bank_step,
    learned_covariances,
    learned_estimates,
    restart_memory,
    tracker_gains,
)
from quad_wrench_env.vehicle import VehicleParams

MODELS = resources.files("quad_wrench_env.estimators") / "models"
"""Where the shipped models live: ``<preset>.npz`` each, beside the ``<preset>.yaml`` that made it."""
WEIGHTS = ("weights_in", "weights_hidden", "bias_in", "bias_hidden", "head", "head_bias", "skip")
"""The network's arrays, as :func:`~quad_wrench_env.estimators.learned_kernel.learned_bank_step` takes
them."""
SCALES = ("feature_mean", "feature_scale", "target_scale", "variance_scale")
"""The standardisation of the features and targets and the held-out calibration of the variances."""


@dataclass(frozen=True)
class FittedFor:
    """What a model was fitted on: it refuses anything else (module docstring)."""

    vehicle: str
    dt: float
    measured_motion: bool
    """Whether its features hold an onboard state estimator's velocity and body rates."""


@dataclass
class LearnedModel:
    """A fitted network (:data:`WEIGHTS`, :data:`SCALES`), what it was fitted for and how it was made
    (the fitting config, the commit, the held-out losses)."""

    fitted_for: FittedFor
    arrays: dict[str, np.ndarray]
    provenance: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        missing = sorted(set(WEIGHTS + SCALES) - set(self.arrays))
        if missing:
            raise ValueError(f"a learned estimator's model lacks the arrays {missing}")
        width = frame_width(self.fitted_for.measured_motion)
        hidden = self.arrays["weights_hidden"].shape[0]
        shapes = {
            "weights_in": (width, 3 * hidden),
            "weights_hidden": (hidden, 3 * hidden),
            "bias_in": (3 * hidden,),
            "bias_hidden": (3 * hidden,),
            "head": (hidden, OUTPUTS + LOGITS),
            "head_bias": (OUTPUTS + LOGITS,),
            "skip": (FORCES, 3),
            "feature_mean": (width,),
            "feature_scale": (width,),
            "target_scale": (12,),
            "variance_scale": (2,),
        }
        for name, shape in shapes.items():
            array = np.ascontiguousarray(self.arrays[name], dtype=float)
            if array.shape != shape or not np.all(np.isfinite(array)):
                raise ValueError(
                    f"a learned estimator's {name} has shape {array.shape} (finite: "
                    f"{bool(np.all(np.isfinite(array)))}); allowed: finite, shape {shape}"
                )
            self.arrays[name] = array

    @property
    def hidden_size(self) -> int:
        return self.arrays["weights_hidden"].shape[0]

    def save(self, path: Path) -> None:
        """One ``.npz``: the arrays and, as JSON, what it was fitted for and its provenance."""
        meta = json.dumps({"fitted_for": asdict(self.fitted_for), "provenance": self.provenance})
        np.savez(path, meta=np.array(meta), **self.arrays)

    @classmethod
    def load(cls, path: Path | str) -> LearnedModel:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            arrays = {name: data[name] for name in data.files if name != "meta"}
        return cls(FittedFor(**meta["fitted_for"]), arrays, meta["provenance"])

    def check(self, **asked: Any) -> None:
        """Refuse, by name, a ``vehicle`` (preset name), ``dt`` or ``measured_motion`` other than the
        model's (module docstring)."""
        fitted = self.fitted_for
        for key, value in asked.items():
            if getattr(fitted, key) != value:
                raise ValueError(
                    f"the learned estimator was fitted for {key}={getattr(fitted, key)!r}, asked for "
                    f"{value!r}; allowed: {getattr(fitted, key)!r} (fit one with "
                    "quad-wrench fit-estimator, docs/estimators.md)"
                )


def shipped_models() -> list[str]:
    """The presets with a shipped model."""
    return sorted(p.name[: -len(".npz")] for p in MODELS.iterdir() if p.name.endswith(".npz"))


@dataclass
class LearnedSettings:
    """``estimator_params`` of the learned estimator."""

    model: str | None = None
    """A ``.npz`` file from ``quad-wrench fit-estimator``; None: the shipped model of the env's vehicle."""

    def resolve(self, vehicle: VehicleParams) -> LearnedModel:
        """The model to run on ``vehicle``: the file named, or the shipped one of the vehicle's preset."""
        if self.model is not None:
            if not Path(self.model).is_file():
                raise ValueError(f"estimator_params.model={self.model!r} is not a file; allowed: a .npz")
            return LearnedModel.load(self.model)
        shipped = shipped_models()
        if vehicle.name not in shipped:
            raise ValueError(
                f"no learned estimator is shipped for vehicle {vehicle.name!r}; allowed: {shipped}, or "
                "estimator_params.model naming a fitted one"
            )
        with resources.as_file(MODELS / f"{vehicle.name}.npz") as path:
            return LearnedModel.load(path)


class LearnedBank(FilterBank):
    """N learned estimators stepped together (module docstring)."""

    name = "learned"

    def __init__(
        self, vehicle: VehicleParams, dt: float, settings: LearnedSettings | None, count: int
    ) -> None:
        settings = settings or LearnedSettings()
        self.model = settings.resolve(vehicle)
        self.model.check(vehicle=vehicle.name, dt=dt)
        self.count = count
        arrays = self.model.arrays
        self._weights = tuple(arrays[name] for name in WEIGHTS)
        self._scales = (arrays["feature_mean"], arrays["feature_scale"], arrays["target_scale"])
        self._target_scale, self._variance_scale = arrays["target_scale"], arrays["variance_scale"]
        self.constants = np.array((dt, vehicle.mass))
        self.previous = np.zeros((count, 7))
        self.previous[:, 3] = 1.0
        self.trail = np.zeros((count, TRAIL, 6))
        self.trackers = np.zeros((count, len(TRACKER_WALKS), 3, 3))
        self.gains = tracker_gains(dt)
        self.seen = np.zeros(count, dtype=np.int64)
        self.frames = np.zeros((count, arrays["feature_mean"].size))
        self.hidden = np.zeros((count, self.model.hidden_size))
        self.outputs = np.zeros((count, OUTPUTS))
        self._prior = arrays["head_bias"][6:12]
        self.outputs[:, 6:12] = self._prior

    def reset(self, index: int | slice, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        """Restart estimator ``index`` (or a slice of them) at the measured pose: an empty memory, zero
        wrench, velocity and rates, the head's variances of an empty memory."""
        self.previous[index, :3] = position
        self.previous[index, 3:] = quaternion_wxyz
        rows = np.atleast_1d(np.arange(self.count)[index])
        for n, start in zip(rows, np.broadcast_to(position, (rows.size, 3)), strict=True):
            restart_memory(self.trail[n], self.trackers[n], np.array(start, dtype=float))
        self.seen[index] = 0
        self.frames[index] = 0.0
        self.hidden[index] = 0.0
        self.outputs[index] = 0.0
        self.outputs[index, 6:12] = self._prior

    def _kernel(self, inputs: EstimatorInputs) -> tuple:
        self.model.check(measured_motion=inputs.velocities.shape[0] > 0)
        return learned_bank_step, (
            self.previous,
            self.trail,
            self.trackers,
            self.gains,
            self.seen,
            self.frames,
            self.hidden,
            self.outputs,
            *inputs,
            *self._weights,
            *self._scales,
            self.constants,
        )

    def _estimates_kernel(self):
        return learned_estimates, (self.previous, self.outputs, self._target_scale)

    def wrenches(self) -> np.ndarray:
        return self.estimates()[1]

    def states(self) -> np.ndarray:
        return self.estimates()[0]

    def wrench_covariances(self) -> np.ndarray:
        out = np.empty((self.count, 6, 6))
        learned_covariances(self.previous, self.outputs, self._target_scale, self._variance_scale, out)
        return out

    def statuses(self) -> list[str]:
        return ["ok"] * self.count


class LearnedWrenchEstimator(BankOfOne):
    """The learned estimator for one vehicle: a bank of one."""

    name = "learned"

    def __init__(self, vehicle: VehicleParams, dt: float, settings: LearnedSettings | None = None) -> None:
        self.bank = LearnedBank(vehicle, dt, settings, count=1)

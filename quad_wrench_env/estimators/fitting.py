"""Fitting the learned wrench estimator (:mod:`quad_wrench_env.estimators.learned`) to recorded flights.

The network is PyTorch's ``GRU`` and a linear head, the kernel's network
(:mod:`quad_wrench_env.estimators.learned_kernel`); its loss per step (:func:`loss`) is the squared
error of the six wrench components' means and of the velocity and body rates, plus the Gaussian
negative log-likelihood of the wrench under the head's log-variances (a heteroscedastic Gaussian, Nix
& Weigend 1994), all in standardised units. It trains on windows of the fitting flights (half of them from the
episode's start, where the memory is empty, as after a reset), evaluates every epoch on the held-out
flights flown whole, and keeps the weights with the lowest held-out loss. The variances are then scaled
per block (force, torque) so that no held-out flight's mean NEES exceeds its dimension (3): the
network's variances are calibrated on flights it did not fit.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch

from quad_wrench_env.config import check_counts, check_numbers
from quad_wrench_env.estimators.learned_kernel import FORCES, LOGITS, OUTPUTS, SOURCES

TARGETS = 12
"""Force (world), external torque (body), velocity (world), body rates: the targets per step."""


@dataclass
class Flights:
    """Recorded flights, one entry per run: (T, W) frames of features, (T, 12) targets, the flight's
    name (T frames, :func:`~quad_wrench_env.estimators.learned_kernel.stream_frames`)."""

    features: list[np.ndarray] = field(default_factory=list)
    targets: list[np.ndarray] = field(default_factory=list)
    names: list[str] = field(default_factory=list)

    def add(self, features: np.ndarray, targets: np.ndarray, name: str) -> None:
        self.features.append(features)
        self.targets.append(targets)
        self.names.append(name)

    @property
    def steps(self) -> int:
        return sum(len(f) for f in self.features)


@dataclass
class TrainingSettings:
    """How the network is fitted (``training`` in a ``fit-estimator`` config)."""

    hidden: int = 64
    """Units of the recurrent layer."""
    epochs: int = 30
    window_seconds: float = 3.0
    """Length of the training windows."""
    batch: int = 32
    """Windows per gradient step."""
    learning_rate: float = 3e-3
    """Adam's, falling by cosine to a tenth over the epochs."""
    settle_seconds: float = 1.0
    """Left out of the held-out NEES that scales the variances (the memory fills after a reset)."""
    balance_floor: float = 0.1
    """Each flight's windows weigh ``1 / max(s, balance_floor)²`` in the loss, ``s`` the flight's RMS
    force in standardised units: a flight of small forces (hover) counts for its relative error as
    one of large forces does, not for its share of the squared newtons; 0 turns the balance off
    (:func:`flight_weights`)."""
    seed: int = 0

    def __post_init__(self) -> None:
        check_numbers("training", self, ("window_seconds", "learning_rate"))
        check_numbers("training", self, ("settle_seconds", "balance_floor"), positive=False)
        check_counts("training", self, ("hidden", "epochs", "batch"))


class Network(torch.nn.Module):
    """The GRU, its head, the skip connection from the window and tracker forces (the frame's last
    features) to the force and their mixture (:mod:`quad_wrench_env.estimators.learned_kernel`);
    ``feature_mean``, ``feature_scale`` and ``target_scale`` the standardisation (:func:`_standardise`),
    which the mixture undoes to weigh forces in newtons."""

    def __init__(
        self, feature_mean: np.ndarray, feature_scale: np.ndarray, target_scale: np.ndarray, hidden: int
    ) -> None:
        super().__init__()
        self.gru = torch.nn.GRU(feature_mean.size, hidden, batch_first=True)
        self.head = torch.nn.Linear(hidden, OUTPUTS + LOGITS)
        self.skip = torch.nn.Linear(FORCES, 3, bias=False)
        for name, value in (
            ("force_mean", feature_mean[-FORCES:]),
            ("force_scale", feature_scale[-FORCES:]),
            ("target_force_scale", target_scale[:3]),
        ):
            self.register_buffer(name, torch.as_tensor(value, dtype=torch.float32), persistent=False)

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        read = self.head(self.gru(features)[0])
        x_f = features[..., -FORCES:]
        forces = (x_f * self.force_scale + self.force_mean).unflatten(-1, (SOURCES, 3))
        weights = torch.softmax(read[..., OUTPUTS:].unflatten(-1, (3, SOURCES)), dim=-1)
        mixed = torch.einsum("...is,...si->...i", weights, forces) / self.target_force_scale
        return read[..., :OUTPUTS] + torch.nn.functional.pad(self.skip(x_f) + mixed, (0, OUTPUTS - 3))

    def arrays(self) -> dict[str, np.ndarray]:
        """The weights as the kernel takes them (transposed, float64)."""

        def plain(tensor: torch.Tensor) -> np.ndarray:
            return tensor.detach().double().numpy().copy()

        return {
            "weights_in": plain(self.gru.weight_ih_l0).T.copy(),
            "weights_hidden": plain(self.gru.weight_hh_l0).T.copy(),
            "bias_in": plain(self.gru.bias_ih_l0),
            "bias_hidden": plain(self.gru.bias_hh_l0),
            "head": plain(self.head.weight).T.copy(),
            "head_bias": plain(self.head.bias),
            "skip": plain(self.skip.weight).T.copy(),
        }


def loss(outputs: torch.Tensor, targets: torch.Tensor, weights: torch.Tensor | None = None) -> torch.Tensor:
    """Mean over steps, standardised (module docstring): the squared error of the wrench's and the
    state's means, and the Gaussian NLL (without its constant) of the variances given the means held
    fixed, so that the means are fitted for the least squared error, not the least NLL (which
    discounts the errors where the variance is large; Seitzer et al. 2022). ``weights`` (one per
    window of a batch): the windows' shares of the mean."""
    mean, log_variance, state = outputs[..., :6], outputs[..., 6:12], outputs[..., 12:]
    squared = (targets[..., :6] - mean) ** 2
    nll = 0.5 * (log_variance + squared.detach() * torch.exp(-log_variance))
    per_step = squared.mean(-1) + nll.mean(-1) + ((targets[..., 6:] - state) ** 2).mean(-1)
    if weights is None:
        return per_step.mean()
    return (per_step.mean(-1) * weights).sum() / weights.sum()


def _standardise(flights: Flights) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Feature means and sds, and the targets' scale: per block of three (force, torque, velocity,
    body rates) one RMS over its components (zero-mean wrenches keep a zero), so that the loss weighs
    an error of one newton alike along every axis, as the vector's RMSE does."""
    features = np.concatenate(flights.features)
    targets = np.concatenate(flights.targets)
    scale = np.maximum(features.std(axis=0), 1e-6)
    blocks = np.sqrt(np.mean(targets.reshape(len(targets), -1, 3) ** 2, axis=(0, 2)))
    return features.mean(axis=0), scale, np.maximum(np.repeat(blocks, 3), 1e-9)


def flight_weights(flights: Flights, target_scale: np.ndarray, floor: float) -> dict[str, float]:
    """Per flight name, its loss weight (``TrainingSettings.balance_floor``): ``1 / max(s, floor)²``
    with ``s`` the RMS of its force targets over ``target_scale`` (all 1 where ``floor`` is 0)."""
    squares: dict[str, list[np.ndarray]] = {}
    for targets, name in zip(flights.targets, flights.names, strict=True):
        squares.setdefault(name, []).append(((targets[:, :3] / target_scale[:3]) ** 2).sum(axis=1))
    if floor == 0.0:
        return dict.fromkeys(squares, 1.0)
    return {
        name: 1.0 / max(math.sqrt(np.concatenate(v).mean() / 3.0), floor) ** 2 for name, v in squares.items()
    }


def _windows(flights: Flights, length: int, count: int, rng: np.random.Generator) -> list[tuple[int, int]]:
    """``count`` (run, start) windows: half from the run's start, half anywhere, runs drawn by length."""
    lengths = np.array([len(f) for f in flights.features])
    runs = rng.choice(len(lengths), size=count, p=lengths / lengths.sum())
    starts = [
        0 if rng.random() < 0.5 or lengths[r] <= length else int(rng.integers(0, lengths[r] - length))
        for r in runs
    ]
    return list(zip(runs.tolist(), starts, strict=True))


def _held_out(
    network: Network,
    flights: Flights,
    tensors: list[tuple[torch.Tensor, torch.Tensor]],
    weights: dict[str, float],
) -> tuple[float, list[np.ndarray]]:
    """The mean loss over the held-out runs flown whole, each weighted as its flight, and each run's
    outputs."""
    total, steps, outputs = 0.0, 0.0, []
    with torch.no_grad():
        for (x, y), name in zip(tensors, flights.names, strict=True):
            out = network(x[None])[0]
            total += float(loss(out, y)) * len(y) * weights[name]
            steps += len(y) * weights[name]
            outputs.append(out.double().numpy())
    return total / steps, outputs


def calibration(
    outputs: list[np.ndarray], flights: Flights, settle_steps: int
) -> tuple[np.ndarray, dict[str, list[float]]]:
    """Per block (force, torque), the factor on the variances that brings every held-out flight's
    mean NEES (over its runs and the steps after ``settle_steps``; standardised units, the variances
    diagonal) to at most 3, and each flight's NEES before it."""
    per_flight: dict[str, list[list[float]]] = {}
    for out, targets, name in zip(outputs, flights.targets, flights.names, strict=True):
        kept = slice(min(settle_steps, len(out) - 1), None)  # a run shorter than that: its last step
        error = (out[kept, :6] - targets[kept, :6]) ** 2 * np.exp(-out[kept, 6:12])
        per_flight.setdefault(name, []).append(
            [error[:, :3].sum(axis=1).mean(), error[:, 3:].sum(axis=1).mean()]
        )
    means = {name: np.mean(values, axis=0).tolist() for name, values in per_flight.items()}
    worst = np.max(np.array(list(means.values())), axis=0)
    return np.maximum(worst / 3.0, 1e-3), means


def fit(
    training: Flights,
    held_out: Flights,
    settings: TrainingSettings,
    frame_seconds: float,
    progress: Callable[[int, float, float], None] | None = None,
) -> tuple[dict[str, np.ndarray], dict[str, object]]:
    """The network fitted to ``training``, chosen and calibrated on ``held_out`` (module docstring):
    the model's arrays (:data:`~quad_wrench_env.estimators.learned.WEIGHTS` and
    :data:`~quad_wrench_env.estimators.learned.SCALES`) and a record of the fit (losses per epoch, the
    epoch kept, each held-out flight's NEES before the scaling). ``progress(epoch, training loss,
    held-out loss)`` after each epoch."""
    if not training.features or not held_out.features:
        raise ValueError("fitting needs recorded runs to fit and held-out runs to choose on; got none")
    torch.manual_seed(settings.seed)
    rng = np.random.default_rng(settings.seed)
    mean, scale, target_scale = _standardise(training)

    def tensors(flights: Flights) -> list[tuple[torch.Tensor, torch.Tensor]]:
        return [
            (
                torch.as_tensor((f - mean) / scale, dtype=torch.float32),
                torch.as_tensor(t / target_scale, dtype=torch.float32),
            )
            for f, t in zip(flights.features, flights.targets, strict=True)
        ]

    train_tensors, held_tensors = tensors(training), tensors(held_out)
    weights = flight_weights(training, target_scale, settings.balance_floor)
    network = Network(mean, scale, target_scale, settings.hidden)
    optimiser = torch.optim.Adam(network.parameters(), lr=settings.learning_rate)
    length = max(2, round(settings.window_seconds / frame_seconds))
    batches = max(1, math.ceil(training.steps / (length * settings.batch)))
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(
        optimiser, settings.epochs * batches, eta_min=0.1 * settings.learning_rate
    )
    best, best_loss, history = None, math.inf, []
    for epoch in range(1, settings.epochs + 1):
        network.train()
        total = 0.0
        for _ in range(batches):
            picked = _windows(training, length, settings.batch, rng)
            span = min(length, min(len(train_tensors[r][0]) - s for r, s in picked))
            x = torch.stack([train_tensors[r][0][s : s + span] for r, s in picked])
            y = torch.stack([train_tensors[r][1][s : s + span] for r, s in picked])
            shares = torch.tensor([weights[training.names[r]] for r, _ in picked])
            value = loss(network(x), y, shares)
            optimiser.zero_grad()
            value.backward()
            torch.nn.utils.clip_grad_norm_(network.parameters(), 1.0)
            optimiser.step()
            schedule.step()
            total += value.item()
        network.eval()
        held, _ = _held_out(network, held_out, held_tensors, weights)
        history.append({"epoch": epoch, "training_loss": total / batches, "held_out_loss": held})
        if held < best_loss:
            best_loss, best = held, {k: v.clone() for k, v in network.state_dict().items()}
            kept = epoch
        if progress is not None:
            progress(epoch, total / batches, held)
    network.load_state_dict(best)
    network.eval()
    _, outputs = _held_out(network, held_out, held_tensors, weights)
    variance_scale, nees_before = calibration(
        outputs, held_out, round(settings.settle_seconds / frame_seconds)
    )
    arrays = {
        **network.arrays(),
        "feature_mean": mean,
        "feature_scale": scale,
        "target_scale": target_scale,
        "variance_scale": variance_scale,
    }
    record = {
        "flight_weights": weights,
        "history": history,
        "kept_epoch": kept,
        "held_out_loss": best_loss,
        "held_out_nees": nees_before,
    }
    return arrays, record

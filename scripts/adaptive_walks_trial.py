"""A trial, not a feature: would covariance-matched random walks make the filters consistent everywhere?

    python scripts/adaptive_walks_trial.py [--estimator ukf] [--beta 0.02] [--floor 0.1]

Each filter's six wrench walk variances ``q`` (torque, force; per axis) start at the vehicle's defaults
and, after every step, follow the squared correction ``d = ŵ⁺ - ŵ⁻`` that the step made to the wrench
estimate (covariance matching, Mohamed & Schwarz 1999, with exponential forgetting, Akhlaghi, Zhou &
Huang 2017: ``q <- max(floor² q₀, (1 - β) q + β d²)``; for a consistent filter in steady state ``E[d²]``
is the walk itself, ``P⁻ - P⁺ = K S Kᵀ``). The filters' kernels are called one filter at a time with
that filter's walks in its constants (the kernels are unchanged; the adaptation wraps them), on the
config's ``nees`` flights ``hover``, ``manoeuvre``, ``fan`` and ``fan, position hold`` (``quad-wrench
compare estimators --only nees``, same runs and seeds), every preset of ``nees.vehicles``. Prints force
/ torque NEES per flight. Slow (a Python loop over the filters): minutes. Not part of CI.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

import numpy as np
import yaml

from quad_wrench_cli.consistency import fly
from quad_wrench_env.estimators.ekf import ExtendedFilterBank
from quad_wrench_env.estimators.ukf import UnscentedFilterBank

ROOT = Path(__file__).resolve().parents[1]
FLIGHTS = ("hover", "manoeuvre", "fan", "fan, position hold")
WRENCH = {  # bank class: (its mean's array, the wrench's entries there, the walks' entries in its constants)
    UnscentedFilterBank: ("rests", np.r_[9:15], np.r_[12:15, 18:21]),
    ExtendedFilterBank: ("x", np.r_[12:18], np.r_[18:24]),
}


def _per_filter(argument: object, count: int) -> bool:
    """Whether a kernel argument holds one row per filter (the state and the inputs)."""
    return isinstance(argument, np.ndarray) and argument.ndim > 0 and len(argument) == count


def adapt(bank_class: type, beta: float, floor: float) -> None:
    """Replace ``bank_class``'s step kernel by the adapting one of the module docstring (for this run)."""
    mean_name, entries, walk_entries = WRENCH[bank_class]
    plain_kernel, plain_reset = bank_class._kernel, bank_class.reset

    def _kernel(bank, *inputs) -> tuple[Callable[..., bool], tuple]:
        kernel, arguments = plain_kernel(bank, *inputs)
        constants = bank.kernel_constants
        defaults = constants[walk_entries]
        if not hasattr(bank, "walks"):  # the env binds the kernel again at every reset: keep the walks
            bank.walks = np.tile(defaults, (bank.count, 1))
        at = next(i for i, argument in enumerate(arguments) if argument is constants)

        def step(*given) -> bool:
            mean = getattr(bank, mean_name)
            before = mean[:, entries].copy()
            finite = True
            for n in range(bank.count):
                own = [a[n : n + 1] if _per_filter(a, bank.count) else a for a in given]
                own[at] = constants.copy()
                own[at][walk_entries] = bank.walks[n]
                finite &= kernel(*own)
            change = mean[:, entries] - before
            bank.walks = np.maximum(floor**2 * defaults, (1.0 - beta) * bank.walks + beta * change**2)
            return finite

        return step, arguments

    def reset(bank, index, *pose) -> None:
        plain_reset(bank, index, *pose)
        if hasattr(bank, "walks"):
            bank.walks[index] = bank.kernel_constants[walk_entries]

    bank_class._kernel, bank_class.reset = _kernel, reset


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--estimator", choices=("ukf", "ekf"), default="ukf")
    parser.add_argument(
        "--beta", type=float, default=0.02, help="forgetting per step (0.02: 0.25 s at 200 Hz)"
    )
    parser.add_argument(
        "--floor", type=float, default=0.1, help="smallest walk sd, a fraction of the default"
    )
    parser.add_argument("--config", type=Path, default=ROOT / "configs" / "compare_estimators.yaml")
    args = parser.parse_args()
    bank_class = UnscentedFilterBank if args.estimator == "ukf" else ExtendedFilterBank
    adapt(bank_class, args.beta, args.floor)
    config = yaml.safe_load(args.config.read_text())
    print(f"force / torque NEES with walks matched to the corrections, beta {args.beta}, floor {args.floor}")
    print(f"| vehicle | filter | {' | '.join(FLIGHTS)} |")
    print("|---|---|" + "---|" * len(FLIGHTS))
    for vehicle in config["nees"]["vehicles"]:
        cells = []
        for flight in FLIGHTS:
            force, torque, ended = fly(config, vehicle, args.estimator, flight)
            cells.append(f"{force.mean():.3g} / {torque.mean():.3g}" + (f" ({ended} ended)" if ended else ""))
        print(f"| {vehicle} | {args.estimator} | {' | '.join(cells)} |", flush=True)


if __name__ == "__main__":
    main()

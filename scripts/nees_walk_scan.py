"""Is there one tuning of the filters that is consistent in hover and in manoeuvring flight?

    python scripts/nees_walk_scan.py [--estimator ukf] [--config configs/compare_estimators.yaml]

Flies the config's ``nees`` flights ``hover`` and ``manoeuvre`` (``quad-wrench compare estimators --only
nees``, the same runs and seeds) on every preset of ``nees.vehicles``, with the filter's noise settings
scaled from each vehicle's defaults (:data:`~quad_wrench_env.estimators.noise.REFERENCE_NOISE` times
:func:`~quad_wrench_env.estimators.noise.vehicle_scales`): the random walks of the external force and
torque at 1, 1/2, 1/4 and 1/40, and the walks at 1/40 with the thrust and motor-torque model errors at
1/50. Prints one Markdown row per preset and setting: the force / torque NEES (averaged over the runs
and the steps after ``settle``) in hover and in the manoeuvre. The table in ``docs/estimators.md``
("No fixed tuning is consistent everywhere") comes from it. Not part of CI: it takes minutes.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import yaml

from quad_wrench_cli.consistency import fly
from quad_wrench_env.estimators.noise import FORCE_KEYS, REFERENCE_NOISE, vehicle_scales
from quad_wrench_env.vehicle import PRESETS

ROOT = Path(__file__).resolve().parents[1]
SETTINGS = {
    "defaults": {},
    "walks x1/2": {"force_walk": 0.5, "torque_walk": 0.5},
    "walks x1/4": {"force_walk": 0.25, "torque_walk": 0.25},
    "walks x1/40": {"force_walk": 0.025, "torque_walk": 0.025},
    "walks x1/40, thrust and motor torque x1/50": {
        "force_walk": 0.025,
        "torque_walk": 0.025,
        "thrust": 0.02,
        "motor_torque": 0.02,
    },
}
"""Each setting's factors on the vehicle's default of the named ``estimator_params``."""
FLIGHTS = ("hover", "manoeuvre")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--estimator", choices=("ukf", "ekf"), default="ukf")
    parser.add_argument("--config", type=Path, default=ROOT / "configs" / "compare_estimators.yaml")
    args = parser.parse_args()
    config = yaml.safe_load(args.config.read_text())
    print("| vehicle | filter | setting | hover: force / torque | manoeuvre: force / torque |")
    print("|---|---|---|---|---|")
    for vehicle in config["nees"]["vehicles"]:
        force_scale, torque_scale = vehicle_scales(PRESETS[vehicle])
        for label, factors in SETTINGS.items():
            params = {
                key: factor * REFERENCE_NOISE[key] * (force_scale if key in FORCE_KEYS else torque_scale)
                for key, factor in factors.items()
            }
            cells = []
            for flight in FLIGHTS:
                config["nees"]["flights"][flight].setdefault("env", {})["estimator_params"] = params
                force, torque, _ = fly(config, vehicle, args.estimator, flight)
                cells.append(f"{force.mean():.3g} / {torque.mean():.3g}")
            print(f"| {vehicle} | {args.estimator} | {label} | {' | '.join(cells)} |", flush=True)


if __name__ == "__main__":
    main()

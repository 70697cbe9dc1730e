"""Train a stable-baselines3 policy (PPO or SAC) on any QuadWrench env id from one YAML config.

    quad-wrench train configs/train_fan_tracking.yaml [--set key=value ...] [--run-dir runs/NAME]
    quad-wrench train --resume runs/NAME [--set total_steps=8000000]

``--set`` overrides a config key (dots reach into sections, values are read as YAML), e.g.
``--set env.observe_wrench=false --set hyperparameters.learning_rate=1e-4``. The run folder holds the
config it ran with, the commit, checkpoints, the best and final models with their observation
scaling, ``curve.csv`` and TensorBoard logs (``tensorboard --logdir runs/``).
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

from quad_wrench_cli.common import UsageError, add_key_value_argument, usage_errors
from quad_wrench_env.config import build, load_yaml


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "config", nargs="?", metavar="CONFIG", help="a training config (configs/train_*.yaml)"
    )
    add_key_value_argument(
        parser,
        "--set",
        "override a config key (repeatable; dots reach into sections, the value is read as YAML)",
    )
    parser.add_argument(
        "--run-dir", metavar="DIR", help="the run folder (default: runs/<config name>-<time>)"
    )
    parser.add_argument(
        "--resume", metavar="RUN", help="continue the run folder RUN from its last checkpoint"
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    from quad_wrench_env.agents.sb3 import (  # torch: only to train
        TrainConfig,
        TrainingConfigError,
        check_training,
        train,
    )
    from quad_wrench_env.config import apply_overrides

    if (args.config is None) == (args.resume is None):
        raise UsageError("give a config to start a run, or --resume RUN to continue one")
    source = Path(args.resume) / "config.yaml" if args.resume else Path(args.config)
    with usage_errors():
        config = build(TrainConfig, apply_overrides(load_yaml(source), args.set))
    if args.resume:
        folder = Path(args.resume)
    else:
        folder = Path(args.run_dir or f"runs/{source.stem}-{time.strftime('%Y%m%d-%H%M%S')}")
    try:
        check_training(config, folder, resume=bool(args.resume))
    except TrainingConfigError as error:
        raise UsageError(str(error)) from None
    started = time.perf_counter()
    train(config, folder, resume=bool(args.resume), progress=not args.no_progress)
    print(summary(folder, time.perf_counter() - started))
    return 0


def summary(folder: Path, seconds: float) -> str:
    """One line: the run's steps and time, and the model it kept as ``best/`` with the step and the
    evaluation that chose it (``best/evaluation.yaml``)."""
    with (folder / "curve.csv").open() as handle:
        steps = list(csv.DictReader(handle))[-1]["steps"]
    line = f"{folder}: {steps} steps in {seconds:.0f} s"
    kept = folder / "best" / "evaluation.yaml"
    if not kept.is_file():
        return line + "; no trained model was evaluated, final/ only"
    best = load_yaml(kept)
    chosen = f"{best['metric']} {best['value']:.4g} at {best['steps']} steps on seeds {best['seeds']}"
    return f"{line}; kept best/: {chosen}"

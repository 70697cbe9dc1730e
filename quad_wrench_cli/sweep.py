"""Sweep training hyperparameters on Ray Tune: grid, random or Optuna search (the tune extra).

    quad-wrench sweep configs/sweep_fan_tracking.yaml [--set num_samples=4] [--folder runs/NAME]
    quad-wrench sweep configs/sweep_fan_tracking.yaml --address auto          # on a running Ray cluster

Each trial is an ordinary training run under ``<folder>/runs/``; the folder gets ``results.csv`` and
``results.md`` (all trials, best first) and ``best_config.yaml`` (``quad-wrench train`` retrains it).
Needs ``pip install "quad-wrench-env[tune]"``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from quad_wrench_cli.common import UsageError, add_key_value_argument, show, usage_errors


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("config", metavar="CONFIG", help="a sweep config (configs/sweep_*.yaml)")
    add_key_value_argument(
        parser, "--set", "override a sweep-config key (repeatable; e.g. num_samples=4, search=optuna)"
    )
    parser.add_argument(
        "--folder", metavar="DIR", help="the sweep folder, new or empty (default: runs/<config name>-<time>)"
    )
    parser.add_argument(
        "--address",
        metavar="ADDR",
        help="a running Ray cluster (auto, or ray://HEAD:10001; default: a local one)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no Tune status table")


def run(args: argparse.Namespace) -> int:
    from quad_wrench_env.agents.sweep import load_sweep_config, sweep  # with torch: loaded only to sweep

    with usage_errors():
        config = load_sweep_config(args.config, args.set)
    folder = Path(args.folder or f"runs/{Path(args.config).stem}-{time.strftime('%Y%m%d-%H%M%S')}")
    try:
        result = sweep(config, folder, address=args.address, progress=not args.no_progress)
    except (FileExistsError, ConnectionError) as error:  # refused before any trial (no cluster there)
        raise UsageError(str(error)) from None
    except ImportError as error:  # the tune extra is missing: not a bad argument
        print(f"quad-wrench sweep: {error}", file=sys.stderr)
        return 1
    show(
        f"{(result.folder / 'results.md').read_text()}\nbest: trial {result.best['trial']}, {result.metric} "
        f"{result.best[result.metric]:.4g}; its config: {result.folder / 'best_config.yaml'}"
    )
    return 0

"""Train and compare arms of learned policies beside the classical controllers: does knowing the wrench help?

    quad-wrench study configs/study_fan_tracking.yaml [--set seeds=[0,1,2]] [--folder runs/NAME]
    quad-wrench study configs/study_fan_tracking.yaml --folder runs/NAME     # continues an interrupted study

Each arm (overrides of a base training config: no wrench, a history, another estimator, the oracle ...)
is trained once per training seed on Ray (a local Ray on this machine's cores, one run per core, or
``--address`` for a cluster whose nodes see the folder at the same path); finished runs are kept and
interrupted ones resume from their last checkpoint. Then every run's kept model and the config's
classical agents fly the same held-out seeds and cases: ``results.md`` (mean ± sd across training seeds,
and which arms differ by more than their spread), ``results.csv`` and ``results.png`` in the folder.
Needs ``pip install "quad-wrench-env[tune]"`` (Ray).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from quad_wrench_cli.common import UsageError, add_key_value_argument, save_figure, show, usage_errors


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("config", metavar="CONFIG", help="a study config (configs/study_*.yaml)")
    add_key_value_argument(parser, "--set", "override a study-config key (repeatable; e.g. seeds=[0,1,2])")
    parser.add_argument(
        "--folder",
        metavar="DIR",
        help="the study folder, new or one to continue (default: runs/<config name>-<time>)",
    )
    parser.add_argument(
        "--address",
        metavar="ADDR",
        help="a running Ray cluster (auto, or ray://HEAD:10001; default: a local one)",
    )


def run(args: argparse.Namespace) -> int:
    from quad_wrench_env.agents.sb3 import TrainingConfigError
    from quad_wrench_env.agents.study import figure, load_study_config, study  # torch, Ray: only to run

    with usage_errors():
        config = load_study_config(args.config, args.set)
    folder = Path(args.folder or f"runs/{Path(args.config).stem}-{time.strftime('%Y%m%d-%H%M%S')}")
    try:
        rows = study(config, folder, address=args.address)
    except (ConnectionError, TrainingConfigError) as error:  # no cluster, an arm refused: before any run
        raise UsageError(str(error)) from None
    save_figure(figure(rows, config.comparison_values()["env_id"]), folder / "results.png")
    show(f"{(folder / 'results.md').read_text()}\nwrote {folder / 'results.md'}, results.csv and results.png")
    return 0

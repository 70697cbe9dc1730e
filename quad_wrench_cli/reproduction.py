"""The command line every ``quad-wrench reproduce <paper>`` shares: ``--config``, ``--only``, ``--seeds``;
each part returns its markdown lines and writes its figures under the config's ``output``;
``report.md`` there collects them (rewritten after each part)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

from quad_wrench_cli.common import UsageError, add_config_argument, load_config, seed, show, usage_errors

Part = Callable[[dict, Path], list[str]]


def add_arguments(parser: argparse.ArgumentParser, parts: dict[str, Any], config_name: str) -> None:
    """``--config`` (default: the shipped ``configs/<config_name>``), ``--only`` (names of ``parts``) and
    ``--seeds``."""
    add_config_argument(parser, config_name)
    parser.add_argument("--only", nargs="+", choices=list(parts), help="run only these parts (default: all)")
    parser.add_argument("--seeds", nargs="+", type=seed, metavar="SEED", help="override the config's seeds")


def load(args: argparse.Namespace, config_name: str) -> tuple[dict[str, Any], str]:
    """The config of ``args`` with ``--seeds`` applied, and its label."""
    config, label = load_config(args.config, config_name)
    if args.seeds:
        config["seeds"] = args.seeds
    if "seeds" not in config:
        raise UsageError(f"{label}: missing config key 'seeds'")
    return config, label


def run_parts(args: argparse.Namespace, parts: dict[str, Part], config_name: str, title: str) -> int:
    """Run the chosen ``parts`` (all by default) in order; prints the report."""
    config, label = load(args, config_name)
    with usage_errors():
        out = Path(config["output"])
    out.mkdir(parents=True, exist_ok=True)
    report = [f"# {title} in simulation: {label}, seeds {config['seeds']}", ""]
    for name, part in parts.items():
        if not args.only or name in args.only:
            report += [*part(config, out), ""]
            (out / "report.md").write_text("\n".join(report))
    show("\n".join(report))
    return 0

"""quad-wrench: wrench-aware quadrotor control in PyBullet, from the command line.

    quad-wrench demo                                     # the main job (make run)
    quad-wrench list                                     # env ids, estimators, vehicles, agents, ...
    quad-wrench evaluate admittance QuadWrench/FanTracking-v1 --seeds 0 1 2
    quad-wrench COMMAND --help                           # a command's options

Bad arguments get a message and exit code 2; results go to the terminal and under results/ (training
runs under runs/).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from types import ModuleType

from quad_wrench_cli import (
    bench,
    compare_agents,
    compare_estimators,
    demo,
    estimate,
    evaluate,
    fit_estimator,
    listing,
    reproduce_hentzen,
    reproduce_mckinnon,
    reproduce_yuksel,
    study,
    sweep,
    train,
    tune_hentzen,
)
from quad_wrench_cli.common import UsageError

Group = tuple[str, dict[str, ModuleType]]
"""A command with subcommands: its one-line help and its subcommands' modules by name."""

COMMANDS: dict[str, ModuleType | Group] = {
    "demo": demo,
    "train": train,
    "evaluate": evaluate,
    "estimate": estimate,
    "fit-estimator": fit_estimator,
    "compare": (
        "Compare agents, or the wrench estimators, on the same seeds",
        {"agents": compare_agents, "estimators": compare_estimators},
    ),
    "reproduce": (
        "Reproduce a paper's figures and tables in simulation",
        {
            "mckinnon": reproduce_mckinnon,
            "yuksel": reproduce_yuksel,
            "hentzen": reproduce_hentzen,
            "tune-hentzen": tune_hentzen,
        },
    ),
    "bench": bench,
    "sweep": sweep,
    "study": study,
    "list": listing,
}
"""Every command: a module (``add_arguments(parser)``, ``run(args) -> int``, its docstring the help) or a
group of them."""


def build_parser(prog: str = "quad-wrench") -> argparse.ArgumentParser:
    """The parser of every command and option."""
    parser = argparse.ArgumentParser(
        prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    _add_commands(parser, COMMANDS, "command")
    return parser


def _add_commands(
    parser: argparse.ArgumentParser, commands: dict[str, ModuleType | Group], dest: str
) -> None:
    subparsers = parser.add_subparsers(
        title="commands", dest=dest, metavar=dest.upper(), required=True, help="(each with --help of its own)"
    )
    for name, command in commands.items():
        if isinstance(command, tuple):
            summary, members = command
            group = subparsers.add_parser(name, help=summary, description=summary + ".")
            _add_commands(group, members, f"{name}_command")
            continue
        doc = command.__doc__ or ""
        sub = subparsers.add_parser(
            name,
            help=" ".join(doc.split("\n\n")[0].split()),
            description=doc,
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        command.add_arguments(sub)
        sub.set_defaults(run=command.run, parser=sub)


def main(argv: Sequence[str] | None = None, prog: str = "quad-wrench") -> int:
    """Run the command line ``argv`` (default: ``sys.argv[1:]``); returns the exit code. Bad arguments
    exit with code 2 and a message (``SystemExit``), as argparse's own errors do."""
    args = build_parser(prog).parse_args(argv)
    try:
        return args.run(args)
    except UsageError as error:
        args.parser.error(str(error))
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130

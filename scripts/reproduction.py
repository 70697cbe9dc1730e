"""The command line every ``reproduce_<paper>.py`` with named parts shares: ``--config``, ``--only``,
``--seeds``; each part returns its markdown lines and writes its figures under the config's
``output``; ``report.md`` there collects them (rewritten after each part)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

from quad_wrench_env.config import load_yaml

Part = Callable[[dict, Path], list[str]]


def run_parts(parts: dict[str, Part], description: str, default_config: str, title: str) -> None:
    """Parse the command line and run the chosen ``parts`` (all by default) in order."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--config", default=default_config)
    parser.add_argument("--only", nargs="*", choices=sorted(parts), help="run only these parts")
    parser.add_argument("--seeds", nargs="*", type=int, help="override the config's seeds")
    args = parser.parse_args()
    config = load_yaml(args.config)
    if args.seeds:
        config["seeds"] = args.seeds
    out = Path(config["output"])
    out.mkdir(parents=True, exist_ok=True)
    report = [f"# {title} in simulation: {args.config}, seeds {config['seeds']}", ""]
    for name, part in parts.items():
        if not args.only or name in args.only:
            report += [*part(config, out), ""]
            (out / "report.md").write_text("\n".join(report))
    print("\n".join(report))

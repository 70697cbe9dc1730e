"""List env ids, estimators, vehicle presets, agents, shipped policies and configs, and named settings.

The named settings: FanTracking's fan motions, DisturbanceRejection's scenarios, ForceExertion's
surfaces and IDA-PBC's parameter sets.

    quad-wrench list            # tables
    quad-wrench list --json     # the same as one JSON object, for tools

Everything is read from the code's own registries (gymnasium's registry, ``ESTIMATORS``, ``PRESETS``,
``AGENTS``, the shipped policies and configs, the fan's ``MOTIONS``, ``SCENARIOS``, ``SURFACES``,
``configs/ida_pbc.yaml``).
"""

from __future__ import annotations

import argparse
import inspect
from typing import Any

from quad_wrench_cli.common import env_ids, markdown_table, show, to_json
from quad_wrench_env.agents import AGENTS, SHIPPED, shipped_agents
from quad_wrench_env.agents.ida_pbc import CONFIG_NAME as IDA_PBC_CONFIG
from quad_wrench_env.config import config_path, load_yaml, shipped_configs
from quad_wrench_env.disturbances.fan import MOTIONS
from quad_wrench_env.estimators import ESTIMATORS
from quad_wrench_env.tasks.disturbance_rejection import SCENARIOS
from quad_wrench_env.tasks.force_exertion import SURFACES
from quad_wrench_env.vehicle import PRESETS


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of tables")


def catalogue() -> dict[str, Any]:
    """Everything :func:`run` lists, by section."""
    ida_pbc = load_yaml(config_path(IDA_PBC_CONFIG))
    return {
        "env_ids": env_ids(),
        "estimators": list(ESTIMATORS),
        "vehicles": {name: {"mass_kg": v.mass, "arm_m": v.arm} for name, v in PRESETS.items()},
        "agents": {name: _summary(inspect.getmodule(cls).__doc__) for name, cls in AGENTS.items()},
        "policies": {name: _policy(name) for name in shipped_agents()},
        "configs": shipped_configs(),
        "fan_motions": sorted(MOTIONS),
        "scenarios": list(SCENARIOS),
        "surfaces": list(SURFACES),
        "ida_pbc_sets": sorted(ida_pbc["sets"]),
        "ida_pbc_default": ida_pbc.get("default"),
        "ida_pbc_task_defaults": dict(ida_pbc.get("task_defaults", {})),
    }


def _summary(doc: str | None) -> str:
    """The first sentence of a docstring."""
    return " ".join((doc or "").split("\n\n")[0].split())


def _policy(name: str) -> str:
    """A shipped policy in one line: its algorithm, env id and env settings."""
    config = load_yaml(SHIPPED / name / "config.yaml")
    return f"{config.get('algorithm', 'ppo').upper()} on {config['env_id']}, env {config.get('env', {})}"


def _ida_pbc_defaults(data: dict[str, Any]) -> str:
    """The set flown when none is named: the config's default, and a task's own where it names one."""
    own = "; ".join(f"{set_name} on {env_id}" for env_id, set_name in data["ida_pbc_task_defaults"].items())
    return f"{data['ida_pbc_default']}" + (f"; {own}" if own else "")


def run(args: argparse.Namespace) -> int:
    data = catalogue()
    if args.json:
        print(to_json(data))
        return 0
    rows = [
        ["env ids", ", ".join(data["env_ids"])],
        ["estimators", ", ".join(data["estimators"])],
        ["shipped configs", ", ".join(data["configs"])],
        ["FanTracking fan motions", ", ".join(data["fan_motions"])],
        ["DisturbanceRejection scenarios", ", ".join(data["scenarios"])],
        ["ForceExertion surfaces", ", ".join(data["surfaces"])],
        ["IDA-PBC parameter sets", f"{', '.join(data['ida_pbc_sets'])} (default: {_ida_pbc_defaults(data)})"],
    ]
    vehicles = [[name, f"{v['mass_kg']:g}", f"{v['arm_m']:g}"] for name, v in data["vehicles"].items()]
    agents = [[name, text] for name, text in (data["agents"] | data["policies"]).items()]
    show(
        "\n\n".join(
            [
                markdown_table(["what", "names"], rows),
                markdown_table(["vehicle preset", "mass (kg)", "arm (m)"], vehicles),
                markdown_table(["agent (classical, then shipped policies)", "what it is"], agents),
            ]
        )
    )
    return 0

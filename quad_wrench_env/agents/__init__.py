"""Policies that map an observation to an action, and the code that evaluates them.

:func:`make_agent` builds an agent by the name used in ``configs/`` files: a classical controller of
:data:`AGENTS` (each registered where it is defined, ``@register("agent", name)``), a learned policy
shipped with the package (:func:`shipped_agents`, under ``quad_wrench_env/agents/policies/``), or the
path of a user's own training run folder (``quad-wrench train``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from quad_wrench_env.agents import admittance, hover, ida_pbc, mpc, pid  # noqa: F401 (they register)
from quad_wrench_env.agents.base import Policy
from quad_wrench_env.registry import registered, resolve

AGENTS = registered("agent")
"""The classical agents by name (the registry's live, read-only view)."""

SHIPPED = Path(__file__).resolve().parent / "policies"
"""Shipped learned policies: one folder each, laid out as a run folder's ``config.yaml`` and ``best/``."""


def shipped_agents() -> list[str]:
    """Names of the learned policies shipped with the package."""
    return (
        sorted(p.name for p in SHIPPED.iterdir() if (p / "config.yaml").is_file()) if SHIPPED.is_dir() else []
    )


def make_agent(name: str, **params: Any) -> Policy:
    """The agent called ``name`` with its parameters (gains) from a config; a shipped learned policy
    or a run folder takes no parameters."""
    key = resolve(name) if ":" in name and not Path(name).exists() else name
    if key in AGENTS:
        return AGENTS[key](**params)
    folder = SHIPPED / name if name in shipped_agents() else Path(name)
    if (folder / "config.yaml").is_file():
        if params:
            raise ValueError(f"the learned policy {name!r} takes no parameters, got {sorted(params)}")
        from quad_wrench_env.agents.sb3_policy import load_policy

        return load_policy(folder)
    raise ValueError(
        f"unknown agent {name!r}; allowed: {sorted(AGENTS) + shipped_agents()} or a training run folder"
    )


__all__ = ["AGENTS", "Policy", "make_agent", "shipped_agents"]

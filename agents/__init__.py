"""Policies that map an observation to an action, and the code that evaluates them.

:func:`make_agent` builds an agent by the name used in ``configs/`` files.
"""

from __future__ import annotations

from typing import Any

from agents.admittance import AdmittancePolicy
from agents.base import Policy
from agents.hover import PositionHoldPolicy

AGENTS: dict[str, type] = {"admittance": AdmittancePolicy, "hold": PositionHoldPolicy}


def make_agent(name: str, **params: Any) -> Policy:
    """The agent called ``name`` with its parameters (gains) from a config."""
    if name not in AGENTS:
        raise ValueError(f"unknown agent {name!r}; allowed: {sorted(AGENTS)}")
    return AGENTS[name](**params)


__all__ = ["AGENTS", "Policy", "make_agent"]

"""The interface every agent implements: ``policy.reset(env)``, ``policy.act(obs)`` (``docs/architecture.md``,
"Contracts")."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import gymnasium as gym
import numpy as np


@runtime_checkable
class Policy(Protocol):
    """Maps observations to actions in the env's action space; reads nothing but the observation."""

    def reset(self, env: gym.Env) -> None:
        """Prepare for a new episode of ``env`` (read its layout and limits, clear internal state)."""

    def act(self, observation: np.ndarray) -> np.ndarray:
        """The action for this observation."""

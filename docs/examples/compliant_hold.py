"""A compliant hover: hold the start position, but give way to the estimated external force."""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from quad_wrench_env.config import build
from quad_wrench_env.registry import register


@dataclass
class CompliantHoldGains:
    k: float = 1.0
    """1/s: position feedback."""
    admittance: float = 0.5
    """m/s per N: velocity given way along the estimated external force."""


@register("agent", "compliant_hold")  # make_agent("compliant_hold", k=1.0)
class CompliantHoldPolicy:
    """``v_cmd = k·(p_0 - p̂) + admittance·f̂`` through the ``velocity`` action."""

    def __init__(self, gains: CompliantHoldGains | None = None, **kwargs: float) -> None:
        self.gains = gains or build(CompliantHoldGains, kwargs, prefix="compliant_hold.")
        self._layout: dict[str, slice] = {}
        self._scaling = None
        self._reference: np.ndarray | None = None

    def reset(self, env: gym.Env) -> None:
        base = env.unwrapped
        if base.action_scaling.action_type != "velocity":
            raise ValueError(
                f"CompliantHoldPolicy needs action_type='velocity', the env has {base.cfg.action_type!r}"
            )
        self._layout = base.obs_layout  # read observations by name, never by index
        self._scaling = base.action_scaling  # SI commands to actions, as the env flies them
        self._reference = None

    def act(self, observation: np.ndarray) -> np.ndarray:
        position = observation[self._layout["position"]].astype(float)
        if self._reference is None:
            self._reference = position.copy()
        force = observation[self._layout["force"]].astype(float)
        velocity = self.gains.k * (self._reference - position) + self.gains.admittance * force
        return self._scaling.to_action((*velocity, 0.0))  # (v_x, v_y, v_z, yaw rate)

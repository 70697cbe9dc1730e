"""Hold a pose with proportional feedback on the estimated position and heading (velocity action).

The vehicle's autopilot flies velocity; this policy closes the position loop around it, as the
ground station of McKinnon & Schoellig 2016 did for their hover experiments (Figs. 3, 4 and 6). The pose held
is the one at the start of the episode unless references are given.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from quad_wrench_env.config import build
from quad_wrench_env.engine.actions import ActionScaling
from quad_wrench_env.registry import register
from quad_wrench_env.rotations import wrap_angle


@dataclass
class HoldGains:
    k_xy: float = 1.0
    k_z: float = 1.0
    k_yaw: float = 1.0
    """Position and heading feedback gains (1/s)."""
    reference: tuple[float, float, float, float] | None = None
    """``(x, y, z, yaw)`` to hold; None holds the pose at the start of the episode."""


@register("agent", "hold")
class PositionHoldPolicy:
    """``v_cmd = k·(p_ref - p̂)``, ``yaw_rate_cmd = k_yaw·wrap(ψ_ref - ψ̂)`` through the velocity action."""

    gains_class: type = HoldGains

    def __init__(self, gains: HoldGains | None = None, **kwargs: float) -> None:
        if gains is not None and kwargs:
            raise ValueError("pass either gains or keyword gains, not both")
        name = type(self).__name__.removesuffix("Policy").lower()
        self.gains = gains or build(self.gains_class, kwargs, prefix=f"{name}.")
        self._layout: dict[str, slice] = {}
        self._scaling: ActionScaling | None = None
        self._reference: np.ndarray | None = None

    def reset(self, env: gym.Env) -> None:
        base = env.unwrapped
        if base.cfg.action_type != "velocity":
            raise ValueError(
                f"{type(self).__name__} needs action_type='velocity', the env has {base.cfg.action_type!r}"
            )
        self._layout = base.obs_layout
        self._scaling = base.action_scaling
        reference = self.gains.reference
        self._reference = None if reference is None else np.array(reference, dtype=float)

    def velocity_command(self, observation: np.ndarray) -> np.ndarray:
        """``(v_x, v_y, v_z, yaw rate)`` in SI units that pull the estimated pose to the reference."""
        g = self.gains
        position = observation[self._layout["position"]].astype(float)
        body_x = observation[self._layout["attitude"]][:3]  # the body x axis in the world frame
        yaw = math.atan2(float(body_x[1]), float(body_x[0]))
        if self._reference is None:
            self._reference = np.array((*position, yaw))
        error = self._reference[:3] - position
        yaw_error = wrap_angle(self._reference[3] - yaw)
        return np.array((g.k_xy * error[0], g.k_xy * error[1], g.k_z * error[2], g.k_yaw * yaw_error))

    def act(self, observation: np.ndarray) -> np.ndarray:
        if self._scaling is None:
            raise RuntimeError("call reset(env) before act()")
        return self._scaling.to_action(self.velocity_command(observation))

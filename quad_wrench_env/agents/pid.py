"""The PID position controller with disturbance feed-forward of Hentzen et al. 2019 (Sec. IV-C), eq. (3),
as an agent: :class:`~quad_wrench_env.control.pid_controller.PIDController` (the equations, the gains
and their bandwidth form) for one vehicle, through the ``attitude`` action; the env's ``residual``
action type flies the same controller under a policy's correction.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np

from quad_wrench_env.config import build
from quad_wrench_env.control.pid_controller import PIDController, PIDGains
from quad_wrench_env.registry import register


@register("agent", "pid")
class PIDPolicy:
    """Eq. (3) with the disturbance feed-forward, through the ``attitude`` action (module docstring)."""

    def __init__(self, gains: PIDGains | None = None, **kwargs: float) -> None:
        if gains is not None and kwargs:
            raise ValueError("pass either gains or keyword gains, not both")
        self.gains = gains or build(PIDGains, kwargs, prefix="pid.")
        self.controller = PIDController(self.gains)

    @property
    def bandwidth(self) -> float | None:
        """λ in use (None with per-axis gains): ``gains.bandwidth`` capped at :meth:`reset`."""
        return self.controller.bandwidth

    def reset(self, env: gym.Env) -> None:
        base = env.unwrapped
        if base.cfg.action_type != "attitude":
            raise ValueError(f"PIDPolicy needs action_type='attitude', the env has {base.cfg.action_type!r}")
        max_tilt = math.radians(base.cfg.action_limits.max_tilt_deg)
        self.controller.configure(base.obs_layout, base.vehicle, base.dt, base.action_scaling, max_tilt)

    def desired_acceleration(self, observation: np.ndarray) -> np.ndarray:
        """Eq. (3): ``a_des`` (m/s², world frame) for this observation; advances the integrator."""
        return self.controller.desired_accelerations(observation[None])[0]

    def act(self, observation: np.ndarray) -> np.ndarray:
        return self.controller.actions(observation[None])[0]

"""Paper 000's fan tracker (Sec. V): an admittance controller on the estimated yaw torque.

``ẏ_cmd = k_p·τ̂_z^e`` moves the vehicle sideways towards the jet's centre, since the yaw torque of the
jet's drag is anti-symmetric about the axis (Fig. 6). x, z and yaw are held by proportional position
feedback on the estimated pose. Everything goes through the ``velocity`` action.

Sign: with the world z up, a vehicle on the +y side of the jet feels ``τ_z > 0`` (the air is faster
on its -y side, pushing that side downstream harder), so ``k_p < 0`` moves it back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from quad_wrench_env.config import build
from quad_wrench_env.rotations import yaw_of


@dataclass
class AdmittanceGains:
    k_p: float = -20.0
    """Lateral admittance gain (m/s per N·m); negative for the sign convention above."""
    k_x: float = 1.0
    k_z: float = 1.0
    k_yaw: float = 1.0
    """Position and heading feedback gains (1/s)."""
    x_ref: float | None = None
    z_ref: float | None = None
    yaw_ref: float | None = None
    """Where to hold x (m), z (m) and heading (rad); None holds the pose at the episode's start."""


class AdmittancePolicy:
    """``ẏ_cmd = k_p·τ̂_z`` with x, z and yaw held by position feedback (velocity action)."""

    def __init__(self, gains: AdmittanceGains | None = None, **kwargs: float) -> None:
        if gains is not None and kwargs:
            raise ValueError("pass either gains or keyword gains, not both")
        self.gains = gains or build(AdmittanceGains, kwargs, prefix="admittance.")
        self._layout: dict[str, slice] = {}
        self._scale = np.ones(4)
        self._reference: np.ndarray | None = None

    def reset(self, env: gym.Env) -> None:
        base = env.unwrapped
        if base.cfg.action_type != "velocity":
            raise ValueError(
                "the admittance controller needs action_type='velocity', "
                f"the env has {base.cfg.action_type!r}"
            )
        limits = base.cfg.action_limits
        self._layout = base.obs_layout
        self._scale = np.array(
            (limits.max_speed_xy, limits.max_speed_xy, limits.max_speed_z, limits.max_yaw_rate)
        )
        self._reference = None

    def act(self, observation: np.ndarray) -> np.ndarray:
        g = self.gains
        layout = self._layout
        position = observation[layout["position"]].astype(float)
        yaw = yaw_of(observation[layout["quaternion"]].astype(float))
        if self._reference is None:
            self._reference = np.array(
                (
                    position[0] if g.x_ref is None else g.x_ref,
                    position[2] if g.z_ref is None else g.z_ref,
                    yaw if g.yaw_ref is None else g.yaw_ref,
                )
            )
        x_ref, z_ref, yaw_ref = self._reference
        tau_z = float(observation[layout["torque"]][2])
        yaw_error = (yaw_ref - yaw + math.pi) % (2.0 * math.pi) - math.pi
        command = np.array(
            (
                g.k_x * (x_ref - position[0]),
                g.k_p * tau_z,
                g.k_z * (z_ref - position[2]),
                g.k_yaw * yaw_error,
            )
        )
        return np.clip(command / self._scale, -1.0, 1.0).astype(np.float32)

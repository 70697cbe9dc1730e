"""McKinnon & Schoellig's (2016) fan tracker (Sec. V): an admittance controller on the estimated yaw torque.

``ẏ_cmd = k_p·τ̂_z^e`` moves the vehicle sideways towards the jet's centre, since the yaw torque of the
jet's drag is anti-symmetric about the axis (Fig. 6). x, z and yaw are held by proportional position
feedback on the estimated pose (:class:`~quad_wrench_env.agents.hover.PositionHoldPolicy`). Everything goes
through the ``velocity`` action.

Sign: with the world z up, a vehicle on the +y side of the jet feels ``τ_z > 0`` (the air is faster
on its -y side, pushing that side downstream harder), so ``k_p < 0`` moves it back.

Gain: near the axis ``τ_z ≈ s·(y - y_axis)``, so the lateral loop is ``ẏ = k_p·s·(y - y_axis)`` and
``k_p = -λ/s`` gives it the rate ``λ`` (1/s). The slope ``s`` depends on the vehicle's drag (area,
hull and rotor positions) and on the jet at the stand-off, so each preset has its own
(:data:`TORQUE_SLOPES`); one ``λ`` then serves every preset. ``λ = 2.1/s`` is the rate of the gain
that McKinnon & Schoellig's (2016) setting used here before (k_p = -20 m/s per N·m on the v0 jet, whose slope
for ``ardrone2`` was 0.107 N·m/m), and it keeps the largest command, ``k_p·max τ_z``, near 0.7 m/s on
every preset.
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from quad_wrench_env.agents.hover import HoldGains, PositionHoldPolicy
from quad_wrench_env.registry import register

TORQUE_SLOPES: dict[str, float] = {
    "ardrone2": 7.53e-2,
    "crazyflie2": 2.33e-4,
    "hummingbird": 3.61e-2,
    "yuksel1kg": 2.56e-1,
}
"""``dτ_z/dy`` (N·m/m) on the axis of FanTracking's default jet at the 2.3 m stand-off, each preset
hovering at yaw = π in the mean flow (design values; ``tests/test_admittance.py`` checks them
against the jet and drag model, so a change of either shows here)."""


@dataclass
class AdmittanceGains(HoldGains):
    k_p: float | None = None
    """Lateral admittance gain (m/s per N·m); negative for the sign convention above. None derives it
    from ``bandwidth`` and the vehicle's torque slope (module docstring)."""
    bandwidth: float = 2.1
    """``λ`` (1/s), the rate of the lateral loop near the axis, when ``k_p`` is None."""


@register("agent", "admittance")
class AdmittancePolicy(PositionHoldPolicy):
    """``ẏ_cmd = k_p·τ̂_z`` with x, z and yaw held by position feedback (velocity action)."""

    gains_class = AdmittanceGains
    gains: AdmittanceGains

    def __init__(self, gains: AdmittanceGains | None = None, **kwargs: float) -> None:
        super().__init__(gains, **kwargs)
        self.k_p = self.gains.k_p
        """The gain in use (derived at :meth:`reset` when ``gains.k_p`` is None)."""

    def reset(self, env: gym.Env) -> None:
        super().reset(env)
        if self.gains.k_p is None:
            vehicle = env.unwrapped.cfg.vehicle
            if vehicle not in TORQUE_SLOPES:
                raise ValueError(
                    f"no torque slope for vehicle {vehicle!r} to derive k_p from; pass k_p, or use one of "
                    f"{sorted(TORQUE_SLOPES)}"
                )
            self.k_p = -self.gains.bandwidth / TORQUE_SLOPES[vehicle]

    def velocity_command(self, observation: np.ndarray) -> np.ndarray:
        command = super().velocity_command(observation)
        command[1] = self.k_p * float(observation[self._layout["torque"]][2])
        return command

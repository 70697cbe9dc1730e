"""Paper 000's fan tracker (Sec. V): an admittance controller on the estimated yaw torque.

``ẏ_cmd = k_p·τ̂_z^e`` moves the vehicle sideways towards the jet's centre, since the yaw torque of the
jet's drag is anti-symmetric about the axis (Fig. 6). x, z and yaw are held by proportional position
feedback on the estimated pose (:class:`~agents.hover.PositionHoldPolicy`). Everything goes through
the ``velocity`` action.

Sign: with the world z up, a vehicle on the +y side of the jet feels ``τ_z > 0`` (the air is faster
on its -y side, pushing that side downstream harder), so ``k_p < 0`` moves it back.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from agents.hover import HoldGains, PositionHoldPolicy


@dataclass
class AdmittanceGains(HoldGains):
    k_p: float = -20.0
    """Lateral admittance gain (m/s per N·m); negative for the sign convention above."""


class AdmittancePolicy(PositionHoldPolicy):
    """``ẏ_cmd = k_p·τ̂_z`` with x, z and yaw held by position feedback (velocity action)."""

    gains_class = AdmittanceGains
    gains: AdmittanceGains

    def velocity_command(self, observation: np.ndarray) -> np.ndarray:
        command = super().velocity_command(observation)
        command[1] = self.gains.k_p * float(observation[self._layout["torque"]][2])
        return command

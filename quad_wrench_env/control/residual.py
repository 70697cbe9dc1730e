"""The ``residual`` action type: a policy's bounded correction to a classical controller's command.

Each control step, every vehicle's base controller (:data:`BASES`, e.g. the PID of Hentzen et al. 2019,
eq. (3), with its gains from ``residual.params``, as the ``pid`` agent takes them) computes its action
``b`` from the observation the policy saw, and the vehicle flies ``clip(b + s·a, -1, 1)`` in the base's
action type, ``a`` the policy's action in [-1, 1]⁴ and ``s`` = ``residual.scale``. At ``a = 0`` it flies
exactly as the classical agent; the policy learns on top of a good controller (residual RL, Johannink et
al. 2019; over a cascaded PID in wind, Ishihara et al. 2023). The base reads the observation's blocks and
the estimated wrench even where ``observe_wrench: false`` leaves it out of the policy's observation.

With ``residual.level: acceleration`` (base ``pid``) the correction enters one loop further out:
``s·g·a_1..3`` (m/s², world frame) is added to eq. (3)'s desired acceleration before the PID turns it
into tilt and thrust, the vertical channel first where the tilt saturates, and ``s·a_4`` to its yaw-rate
action. Added to the attitude action instead, a correction meets the tilt limit after the saturation:
where the base is at its limit it can only take tilt away, and it cannot trade tilt for thrust as the
saturation does.
"""

from __future__ import annotations

import numpy as np

from quad_wrench_env.config import build
from quad_wrench_env.control.mpc_controller import MPCController, MPCGains
from quad_wrench_env.control.pid_controller import PIDController, PIDGains
from quad_wrench_env.engine.actions import ActionScaling, ResidualSettings
from quad_wrench_env.vehicle import GRAVITY, VehicleParams

BASES = {"pid": (PIDController, PIDGains), "mpc": (MPCController, MPCGains)}
"""Base controller name -> (its batched controller, its gains' dataclass)."""
YAW_RATE = 2
"""The yaw-rate entry of an ``attitude`` action (``(roll, pitch, yaw rate, thrust)``)."""


class ResidualActions:
    """Every vehicle's flown action from the policy's (module docstring)."""

    def __init__(
        self,
        settings: ResidualSettings,
        count: int,
        layout: dict[str, slice],
        vehicle: VehicleParams,
        dt: float,
        scaling: ActionScaling,
        max_tilt: float,
    ) -> None:
        if settings.base not in BASES:
            raise ValueError(
                f"residual.base={settings.base!r} is not a base controller; allowed: {sorted(BASES)}"
            )
        if settings.level == "acceleration" and settings.base != "pid":
            raise ValueError(
                f"residual.level='acceleration' corrects the PID's desired acceleration; base "
                f"{settings.base!r} has none (allowed with that level: ['pid'])"
            )
        controller, gains = BASES[settings.base]
        self.scale = settings.scale
        self.level = settings.level
        self.base = controller(build(gains, settings.params, prefix="residual.params."), count)
        self.base.configure(layout, vehicle, dt, scaling, max_tilt)

    def restart(self, index: np.ndarray | slice) -> None:
        """Vehicles ``index`` begin an episode: their base controllers start afresh."""
        self.base.restart(index)

    def flown(self, observations: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """(N, 4) actions flown for the policy's (N, 4) ``actions`` (in [-1, 1]) taken on
        ``observations``; advances the base controllers."""
        if self.level == "acceleration":
            flown = self.base.actions(observations, self.scale * GRAVITY * actions[:, :3])
            flown[:, YAW_RATE] += self.scale * actions[:, 3]
            return np.clip(flown, -1.0, 1.0)
        return np.clip(self.base.actions(observations) + self.scale * actions, -1.0, 1.0)

"""Hentzen et al.'s (2019) MPC position controller (Sec. IV-D) as an agent:
:class:`~quad_wrench_env.control.mpc_controller.MPCController` (the model, the QP and its DAQP solve) for
one vehicle, through the ``attitude`` action; the env's ``residual`` action type flies the same
controller under a policy's correction.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np

from quad_wrench_env.config import build
from quad_wrench_env.control.mpc_controller import MPCController, MPCGains, PositionMPC
from quad_wrench_env.registry import register


@register("agent", "mpc")
class MPCPolicy:
    """The MPC through the ``attitude`` action (:class:`MPCController`, a batch of one): roll and pitch
    references and collective thrust from :class:`PositionMPC`, yaw held at ``gains.yaw`` by a
    proportional yaw-rate command. The observation must carry ``reference_position`` and
    ``reference_velocity``.

    The first-order attitude model ignores the autopilot's attitude-loop resonance (attitude P on a PI
    rate loop with motor lag: damping ratio ≈ 0.35 on ``ardrone2``, ``crazyflie2`` and
    ``hummingbird``, 0.7 on ``yuksel1kg``); the tilt weight in ``input_weight`` keeps the feedback of
    the measured attitude low enough (0.23 rad per rad on ``hummingbird``) not to excite it.
    """

    gains_class: type = MPCGains

    def __init__(self, gains: MPCGains | None = None, **kwargs: Any) -> None:
        if gains is not None and kwargs:
            raise ValueError("pass either gains or keyword gains, not both")
        self.gains: MPCGains = gains or build(MPCGains, kwargs, prefix="mpc.")
        self.controller = MPCController(self.gains)

    @property
    def mpc(self) -> PositionMPC:
        """The vehicle's QP (after :meth:`reset`)."""
        if not self.controller.qps:
            raise RuntimeError("call reset(env) first")
        return self.controller.qps[0]

    def reset(self, env: gym.Env) -> None:
        base = env.unwrapped
        if base.cfg.action_type != "attitude":
            raise ValueError(
                f"{type(self).__name__} needs action_type='attitude', the env has {base.cfg.action_type!r}"
            )
        max_tilt = math.radians(base.cfg.action_limits.max_tilt_deg)
        self.controller.configure(base.obs_layout, base.vehicle, base.dt, base.action_scaling, max_tilt)

    def act(self, observation: np.ndarray) -> np.ndarray:
        if not self.controller.qps:
            raise RuntimeError("call reset(env) before act()")
        return self.controller.actions(np.asarray(observation)[None])[0]

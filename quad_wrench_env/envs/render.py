"""Drawing the scene: the fan, its jet and a camera that follows the vehicle.

The fan is a disc at its current position and the jet's axis a thin rod along +x that follows the
fan's retarded position; both are visual-only bodies (no collision),
created only when rendering is asked for, so training runs never pay for them.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import pybullet as p

if TYPE_CHECKING:
    from quad_wrench_env.envs.base import QuadWrenchEnv

_ALONG_X = p.getQuaternionFromEuler((0.0, math.pi / 2.0, 0.0))


class SceneRenderer:
    """Camera images (``rgb_array``) or a followed view in the GUI (``human``) of one env."""

    def __init__(self, env: QuadWrenchEnv, width: int = 480, height: int = 360) -> None:
        self.env = env
        self.width = width
        self.height = height
        self._fan = -1
        self._jet = -1
        self._jet_length = 0.0

    def build(self) -> None:
        """Create the fan's visual bodies in the world (once: the world is built once per env)."""
        env = self.env
        fan = getattr(env.task, "fan", None)
        if fan is None or self._fan >= 0:
            return
        cid = env.world.client
        radius = 0.5 * fan.config.outlet_diameter
        disc = p.createVisualShape(
            p.GEOM_CYLINDER, radius=radius, length=0.05, rgbaColor=(0.3, 0.3, 0.9, 1.0), physicsClientId=cid
        )
        self._fan = p.createMultiBody(0.0, -1, disc, baseOrientation=_ALONG_X, physicsClientId=cid)
        x = float(env.cfg.standoff_distance)
        self._jet_length = x
        jet = p.createVisualShape(
            p.GEOM_CYLINDER, radius=0.015, length=x, rgbaColor=(0.4, 0.7, 1.0, 1.0), physicsClientId=cid
        )
        self._jet = p.createMultiBody(0.0, -1, jet, baseOrientation=_ALONG_X, physicsClientId=cid)

    def _place_fan(self) -> None:
        env = self.env
        if self._fan < 0:
            return
        cid = env.world.client
        fan = env.task.fan
        z = fan.config.height
        p.resetBasePositionAndOrientation(
            self._fan, (0.0, float(fan.fan_y(env.fleet.time[:1])[0]), z), _ALONG_X, physicsClientId=cid
        )
        axis_y = float(fan.axis_y(np.array((0.5 * self._jet_length,)), env.fleet.time[:1])[0])
        p.resetBasePositionAndOrientation(
            self._jet, (0.5 * self._jet_length, axis_y, z), _ALONG_X, physicsClientId=cid
        )

    def render(self) -> np.ndarray | None:
        env = self.env
        self._place_fan()
        cid = env.world.client
        target = env.world.state().position[0] * np.array((0.5, 1.0, 1.0))  # between fan and vehicle
        if env.render_mode == "human":
            p.resetDebugVisualizerCamera(3.0, 30.0, -30.0, tuple(target), physicsClientId=cid)
            return None
        view = p.computeViewMatrixFromYawPitchRoll(
            tuple(target), 3.0, 30.0, -30.0, 0.0, 2, physicsClientId=cid
        )
        projection = p.computeProjectionMatrixFOV(
            60.0, self.width / self.height, 0.05, 20.0, physicsClientId=cid
        )
        _, _, rgba, _, _ = p.getCameraImage(
            self.width, self.height, view, projection, renderer=p.ER_TINY_RENDERER, physicsClientId=cid
        )
        return np.asarray(rgba, dtype=np.uint8).reshape(self.height, self.width, 4)[:, :, :3]

"""A task in one file: hold a point while a body-fixed push, drawn per episode, acts off the centre."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.disturbances.base import CompiledForm
from quad_wrench_env.engine.components import Components
from quad_wrench_env.engine.env_config import EnvConfig
from quad_wrench_env.numerics import njit
from quad_wrench_env.registry import register
from quad_wrench_env.tasks.base import TaskDefaults, TaskRecord, ended_early


class BodyPush:
    """A force fixed in the body frame at a body point (a PointLoad); each vehicle's force in its table."""

    name = "body_push"
    compiled = CompiledForm(__name__, (("load", "body_push_load"),), table="force_body")

    def __init__(self, count: int, offset=(0.1, 0.0, 0.0)) -> None:
        self.offset = np.array(offset, dtype=float)
        self.force_body = np.zeros((count, 3))
        """(N, 3) each vehicle's push (N, body frame); a task sets it per episode."""

    def kernel_parameters(self) -> np.ndarray:
        return self.offset.copy()

    def point_load(self, t, body, index=slice(None)):
        rotation = body.rotation
        forces = np.reshape(self.force_body[index], (-1, 3))
        world_offsets = np.einsum("nij,j->ni", rotation, self.offset)
        world_forces = np.einsum("nij,nj->ni", rotation, forces)
        return world_offsets[:, None, :], world_forces[:, None, :]


@njit
def body_push_load(params, force_body, state, time, position, velocity, angular_velocity, rotation, out):
    """``BodyPush.point_load``'s resultant about the centre of mass added to ``out`` (N, 6)."""
    for n in range(time.shape[0]):
        r, f = np.zeros(3), np.zeros(3)
        for i in range(3):
            for j in range(3):
                r[i] += rotation[n, i, j] * params[j]
                f[i] += rotation[n, i, j] * force_body[n, j]
        out[n, 0] += f[0]
        out[n, 1] += f[1]
        out[n, 2] += f[2]
        out[n, 3] += r[1] * f[2] - r[2] * f[1]
        out[n, 4] += r[2] * f[0] - r[0] * f[2]
        out[n, 5] += r[0] * f[1] - r[1] * f[0]


@dataclass
class HoldPointConfig(EnvConfig):
    target: tuple[float, float, float] = (2.0, 0.0, 1.0)
    """m, world frame."""
    max_push: float = 0.5
    """N: each episode's push is uniform in [-max_push, max_push] along body y."""
    radius: float = 0.5
    """m from the target that ends the episode as "drifted"."""

    def __post_init__(self) -> None:
        super().__post_init__()
        self.target = tuple(self.target)
        check_numbers("env", self, ("radius",))
        check_numbers("env", self, ("max_push",), positive=False)


@register("task")  # its env_id, with both entry points; the harness scores with its metrics
class HoldPoint(TaskDefaults):
    env_id: ClassVar[str] = "QuadWrench/HoldPoint-v0"
    config_class: ClassVar[type[EnvConfig]] = HoldPointConfig
    reset_options: ClassVar[tuple[str, ...]] = ("push",)
    observation_blocks: ClassVar[tuple[tuple[str, int, float], ...]] = (("reference_position", 3, 20.0),)
    termination_reasons: ClassVar[tuple[str, ...]] = ("drifted",)
    trace_keys: ClassVar[tuple[str, ...]] = ("distance",)

    def __init__(self, cfg: HoldPointConfig, vehicle, count: int) -> None:
        self.cfg = cfg
        self.target = np.array(cfg.target)
        self.push = BodyPush(count)

    def components(self) -> Components:
        return Components(loads=[self.push])

    def reset_vehicle(self, index: int, rng: np.random.Generator, options: Mapping[str, Any]):
        push = options.get("push", rng.uniform(-self.cfg.max_push, self.cfg.max_push))
        self.push.force_body[index] = (0.0, float(push), 0.0)
        return self.target.copy(), 0.0  # start on the target, yaw 0

    def start(self, view, index) -> TaskRecord:
        """Nothing to read of the start: the blocks and ``info`` of every vehicle now."""
        return TaskRecord({}, blocks=self._blocks(view), info={"distance": self._distance(view)})

    def step(self, view, actions, ended) -> TaskRecord:
        distance = self._distance(view)
        codes = (distance > self.cfg.radius).astype(int)  # 1: termination_reasons[0]
        ended = ended_early(ended, codes)  # the engine's crash or the task's drift
        reward_terms = {"distance": -distance, "crash": -10.0 * ended.astype(float)}
        return TaskRecord(reward_terms, codes, self._blocks(view), {"distance": distance})

    def _distance(self, view) -> np.ndarray:
        return np.linalg.norm(view.state.position - self.target, axis=1)

    def _blocks(self, view) -> np.ndarray:
        return np.tile(self.target, (view.count, 1))  # the block "reference_position"

    @staticmethod
    def metrics(trace: Mapping[str, np.ndarray]) -> dict[str, float]:
        return {"max_distance": float(np.max(trace["distance"]))}

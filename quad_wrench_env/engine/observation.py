"""The observation's layout, declared once by name: the engine's blocks, then the task's.

The compiled kernel (:func:`~quad_wrench_env.engine.kernels.assemble_observations`) fills the engine's
blocks through :attr:`ObservationLayout.kernel_starts`, the tasks theirs through the slices;
``env.unwrapped.obs_layout`` is :attr:`ObservationLayout.slices`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from gymnasium import spaces

from quad_wrench_env.engine.kernels import SENSOR_READING_WIDTH
from quad_wrench_env.vehicle import GRAVITY, VehicleParams

if TYPE_CHECKING:
    from quad_wrench_env.engine.env_config import ArenaConfig

ENGINE_BLOCKS: tuple[tuple[str, int], ...] = (
    ("position", 3),
    ("velocity", 3),
    ("attitude", 6),
    ("body_rates", 3),
    ("force", 3),
    ("torque", 3),
    ("last_action", 4),
)
"""The engine's observation blocks in order: the estimator's state and wrench, and the previous action.
The attitude is the first two columns of the rotation matrix (body x and y axes in the world frame), a
representation without the jumps of a quaternion kept to one hemisphere."""
PRIVILEGED_BLOCKS = ENGINE_BLOCKS[:6]
"""What the ``privileged`` block holds, from the truth: the engine's blocks before the last action."""


class ObservationLayout:
    """The engine's blocks followed by a task's ``(name, width, bound)`` blocks: one frame; then, with
    ``history`` K > 0, the frames of the K previous steps (``history``, and ``history_1`` ...
    ``history_K`` each one frame, ``history_1`` the last); then, with ``sensor_history`` S > 0, the
    estimators' sensor readings of the S last physics steps (``sensors``, and ``sensors_1`` the newest ...
    ``sensors_S``, each ``sensor_width`` numbers:
    :func:`~quad_wrench_env.engine.kernels.record_sensor_readings`); then, with ``privileged``, the
    true state and wrench in the form of the engine's first blocks (``privileged``,
    :data:`PRIVILEGED_BLOCKS`: for a critic or a teacher, never an actor)."""

    def __init__(
        self,
        task_blocks: tuple[tuple[str, int, float], ...] = (),
        history: int = 0,
        sensor_history: int = 0,
        sensor_width: int = 0,
        privileged: bool = False,
    ) -> None:
        names = [name for name, _ in ENGINE_BLOCKS]
        clashes = sorted({name for name, _, _ in task_blocks} & {*names, "wrench"})
        if clashes:
            raise ValueError(f"task observation blocks {clashes} clash with the engine's {names}")
        self.fields = ENGINE_BLOCKS + tuple((name, width) for name, width, _ in task_blocks)
        self.task_bounds = {name: bound for name, _, bound in task_blocks}
        self.slices: dict[str, slice] = {}
        start = 0
        for name, width in self.fields:
            self.slices[name] = slice(start, start + width)
            start += width
        self.frame = start
        """Width of one frame (the observation without its history)."""
        self.history = history
        for k in range(1, history + 1):
            self.slices[f"history_{k}"] = slice(k * start, (k + 1) * start)
        if history:
            self.slices["history"] = slice(start, (history + 1) * start)
        self.size = (history + 1) * start
        self.sensor_history, self.sensor_width = sensor_history, sensor_width
        for k in range(1, sensor_history + 1):
            first = self.size + (k - 1) * sensor_width
            self.slices[f"sensors_{k}"] = slice(first, first + sensor_width)
        if sensor_history:
            self.slices["sensors"] = slice(self.size, self.size + sensor_history * sensor_width)
        self.size += sensor_history * sensor_width
        self.privileged = privileged
        if privileged:
            width = sum(w for _, w in PRIVILEGED_BLOCKS)
            self.slices["privileged"] = slice(self.size, self.size + width)
            self.size += width
        self.slices["wrench"] = slice(self.slices["force"].start, self.slices["torque"].stop)
        self.kernel_starts = np.array([self.slices[name].start for name in names], dtype=np.int64)
        self.task_columns = slice(self.slices[ENGINE_BLOCKS[-1][0]].stop, self.frame)

    def space(self, vehicle: VehicleParams, arena: ArenaConfig) -> spaces.Box:
        """Finite bounds far outside anything a flight that has not ended can reach (SI units): the
        position's 100 m, or twice the arena's farthest wall where that is farther (leaving the arena
        ends the episode)."""
        weight = vehicle.mass * GRAVITY
        reach = max(abs(arena.x_min), abs(arena.x_max), arena.y_half_width, arena.z_max)
        bound = {
            "position": max(100.0, 2.0 * reach),
            "velocity": 100.0,
            "attitude": 1.0,
            "body_rates": 100.0,
            "force": 100.0 * weight,
            "torque": 100.0 * weight * vehicle.hull_radius,
            "last_action": 1.0,
            **self.task_bounds,
        }
        frame = np.concatenate([np.full(n, bound[name]) for name, n in self.fields])
        reading = np.concatenate(  # motor speeds over the top speed, position, attitude, [velocity, rates]
            (
                np.ones(4),
                np.full(3, bound["position"]),
                np.ones(6),
                np.full(self.sensor_width - SENSOR_READING_WIDTH, 100.0),
            )
        )
        readings = np.tile(reading, self.sensor_history) if self.sensor_history else np.zeros(0)
        truth = frame[: self.slices[PRIVILEGED_BLOCKS[-1][0]].stop] if self.privileged else np.zeros(0)
        high = np.concatenate((np.tile(frame, self.history + 1), readings, truth)).astype(np.float32)
        return spaces.Box(-high, high, dtype=np.float32)


class ObservationHistory:
    """Each vehicle's last ``layout.history`` frames, written into the history columns of its
    observations (:class:`ObservationLayout`): an env records every observation it returns, once."""

    def __init__(self, layout: ObservationLayout, count: int) -> None:
        self.layout = layout
        self.frames = np.zeros((count, layout.history, layout.frame), dtype=np.float32)
        """(N, K, frame): ``frames[:, 0]`` the last step's frame."""

    def restart(self, index: np.ndarray | slice) -> None:
        """Vehicles ``index`` start an episode: nothing before it."""
        self.frames[index] = 0.0

    def record(self, observations: np.ndarray, index: np.ndarray | slice) -> None:
        """Fill the history columns of rows ``index`` of ``observations`` (whose frames are new) with
        those vehicles' earlier frames, then keep their new frames."""
        if not self.layout.history:
            return
        if not isinstance(index, slice):
            index = np.atleast_1d(index)
        frame = self.layout.frame
        rows = self.frames[index]
        observations[index, frame:] = rows.reshape(len(rows), -1)
        rows[:, 1:] = rows[:, :-1].copy()
        rows[:, 0] = observations[index, :frame]
        self.frames[index] = rows

"""Per-vehicle random draws taken in blocks, so that N vehicles stepped together see exactly the
noise each would see flown alone (randomness only from the env's ``np_random``: ``docs/architecture.md``,
"Conventions")."""

from __future__ import annotations

import numpy as np

BLOCK_STEPS = 200
"""Physics steps of standard normal draws taken from a vehicle's generator at a time (1 s at 200 Hz)."""


class NoiseBlocks:
    """Standard normal draws, ``width`` per vehicle and physics step, for N vehicles, each from its
    own generator; a vehicle's block is drawn when it runs out, and dropped when its episode restarts."""

    def __init__(self, count: int, width: int, block_steps: int = BLOCK_STEPS) -> None:
        self.buffer = np.zeros((count, block_steps, width))
        self.cursor = np.full(count, block_steps)
        """Each vehicle's next row in its block."""
        self._rngs: list[np.random.Generator | None] = [None] * count
        self._rows = np.arange(count)
        self._block_steps = block_steps
        self._steps_left = 0
        """Steps until the first vehicle runs out of draws."""

    def reset(self, index: int, rng: np.random.Generator) -> None:
        """Vehicle ``index`` starts an episode and draws from ``rng`` from now on."""
        self._rngs[index] = rng
        self.cursor[index] = self._block_steps
        self._steps_left = 0

    def ready(self) -> None:
        """Make sure every vehicle has a row for the coming step (drawing new blocks as needed)."""
        if self._steps_left > 0:
            self._steps_left -= 1
            return
        for i in np.flatnonzero(self.cursor >= self._block_steps).tolist():
            rng = self._rngs[i]
            if rng is None:
                raise RuntimeError(f"vehicle {i} has no generator: reset it before stepping")
            self.buffer[i] = rng.standard_normal(self.buffer.shape[1:])
            self.cursor[i] = 0
        self._steps_left = self._block_steps - int(self.cursor.max()) - 1

    def take(self) -> np.ndarray:
        """(N, width) draws for one physics step of every vehicle."""
        self.ready()
        draws = self.buffer[self._rows, self.cursor]
        self.cursor += 1
        return draws

"""Per-vehicle random draws taken in blocks, so that N vehicles stepped together see exactly the
noise each would see flown alone (ARCHITECTURE.md: randomness only from the env's ``np_random``)."""

from __future__ import annotations

import numpy as np

BLOCK_STEPS = 200
"""Physics steps of standard normal draws taken from a vehicle's generator at a time (1 s at 200 Hz)."""


class NoiseBlocks:
    """Standard normal draws, ``width`` per vehicle and physics step, for N vehicles, each from its
    own generator; a vehicle's block is drawn when it runs out, and dropped when its episode restarts."""

    def __init__(self, count: int, width: int, block_steps: int = BLOCK_STEPS) -> None:
        self._buffer = np.zeros((count, block_steps, width))
        self._cursor = np.full(count, block_steps)
        self._rngs: list[np.random.Generator | None] = [None] * count
        self._rows = np.arange(count)
        self._block_steps = block_steps

    def reset(self, index: int, rng: np.random.Generator) -> None:
        """Vehicle ``index`` starts an episode and draws from ``rng`` from now on."""
        self._rngs[index] = rng
        self._cursor[index] = self._block_steps

    def take(self) -> np.ndarray:
        """(N, width) draws for one physics step of every vehicle."""
        for i in np.flatnonzero(self._cursor >= self._block_steps).tolist():
            rng = self._rngs[i]
            if rng is None:
                raise RuntimeError(f"vehicle {i} has no generator: reset it before stepping")
            self._buffer[i] = rng.standard_normal(self._buffer.shape[1:])
            self._cursor[i] = 0
        draws = self._buffer[self._rows, self._cursor]
        self._cursor += 1
        return draws

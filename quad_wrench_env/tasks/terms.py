"""Reward terms the tasks share, each a function of (N,) arrays that returns an (N,) term, with its
weight from the task's reward config (in the spirit of Isaac Lab's reward terms). A task's reward is
the sum of its terms, each reported in ``info["reward_terms"]``.

- :func:`capped_cost` or :func:`saturating_cost`, and :func:`alive` together: a cost ``-min(e, c)``
  or ``-c·(1 - exp(-e/s))`` and ``+c`` on every step that does not end the episode early, so a step
  flown is worth ``[0, c]`` and ending early never pays (ForceExertion's contact force,
  DisturbanceRejection's tracking);
- :func:`effort`: ``-w·mean(a²)`` over the action's components;
- :func:`crash`: ``-penalty`` on the step that ends an episode early;
- :func:`closeness` and :func:`linear_cost`: FanTracking's ``exp(-d/s)`` and ``-w·|e|``.
"""

from __future__ import annotations

import math

import numpy as np

from quad_wrench_env.numerics import njit


def capped_cost(error: np.ndarray, cap: float) -> np.ndarray:
    """``-min(error, cap)``: a cost that stops growing at ``cap``."""
    return -np.minimum(error, cap)


def saturating_cost(error: np.ndarray, cap: float, scale: float) -> np.ndarray:
    """``-cap·(1 - exp(-error/scale))``: steepest at zero error (slope ``cap/scale``), tending to
    ``-cap`` far away; with :func:`alive` a step earns ``cap·exp(-error/scale)``, the exponential
    tracking kernel of Isaac Lab's reward terms."""
    return -cap * (1.0 - np.exp(-error / scale))


def alive(ended: np.ndarray, cap: float) -> np.ndarray:
    """``cap`` on every step that does not end the episode early (``ended`` (N,) bool), else 0."""
    return cap * (~ended)


def effort(actions: np.ndarray, weight: float) -> np.ndarray:
    """``-weight·mean(a²)`` of (N, 4) normalised actions."""
    return -weight * (np.add.reduce(actions * actions, axis=1) / actions.shape[1])  # np.mean's numbers


def crash(ended: np.ndarray, penalty: float) -> np.ndarray:
    """``-penalty`` where the episode ended early (``ended`` (N,) bool), else 0."""
    return -penalty * ended  # a float array: -penalty, or -0.0


def linear_cost(error: np.ndarray, weight: float) -> np.ndarray:
    """``-weight·|error|``."""
    return -weight * np.abs(error)


def closeness(distance: np.ndarray, scale: float) -> np.ndarray:
    """``exp(-distance/scale)`` in (0, 1]: 1 at zero distance. Compiled, so that its exponential is
    the C library's, as in the kernels (NumPy's vectorised one differs in the last bit on some inputs)."""
    out = np.empty_like(distance)
    _closeness(distance, scale, out)
    return out


@njit
def _closeness(distance, scale, out):
    for n in range(distance.shape[0]):
        out[n] = math.exp(-distance[n] / scale)

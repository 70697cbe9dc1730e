"""Reward terms the tasks share, each with its weight from the task's reward config (in the spirit of
Isaac Lab's reward terms). A task's reward is the sum of its terms, each reported in
``info["reward_terms"]``.

- :func:`capped_cost` or :func:`saturating_cost`, and :func:`alive` together: a cost ``-min(e, c)``
  or ``-c·(1 - exp(-e/s))`` and ``+c`` on every step that does not end the episode early, so a step
  flown is worth ``[0, c]`` and ending early never pays (ForceExertion's contact force,
  DisturbanceRejection's tracking);
- :func:`effort`: ``-w·mean(a²)`` over the action's components;
- :func:`crash`: ``-penalty`` on the step that ends an episode early;
- :func:`closeness` and :func:`linear_cost`: FanTracking's ``exp(-d/s)`` and ``-w·|e|``;
- :func:`peak_rise`: ``-w·`` the rise of an episode's running maximum, whose sum over the episode is
  ``-w·`` its maximum (DisturbanceRejection's score, Hentzen et al.'s (2019) Table I);
- :func:`action_rate`: ``-w·mean((a_t - a_{t-1})²)``, the change of the action from the step before.

:func:`effort`, :func:`crash`, :func:`closeness` and :func:`linear_cost` are compiled functions of one
vehicle, for a task's compiled step to call (FanTracking's); :func:`efforts` and :func:`crashes` are
them over every vehicle, for a task that composes its terms with NumPy. :func:`capped_cost`,
:func:`saturating_cost` and :func:`alive` are NumPy functions of (N,) arrays (``saturating_cost``'s
exponential is NumPy's, whose last bit differs from the C library's on some inputs).
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


def peak_rise(error: np.ndarray, peak: np.ndarray, weight: float | np.ndarray) -> np.ndarray:
    """``-weight·(max(peak, error) - peak)`` of (N,) arrays (``weight`` a number or (N,)), and ``peak``
    raised in place to ``max(peak, error)``: summed over an episode whose ``peak`` started at the first
    step's error, the terms telescope to ``-weight·(max_t error_t - error_0)``, so the return scores the
    episode's largest error and not its mean."""
    raised = np.maximum(peak, error)
    cost = -weight * (raised - peak)
    peak[...] = raised
    return cost


def action_rate(actions: np.ndarray, previous: np.ndarray, weight: float) -> np.ndarray:
    """(N,) ``-weight·mean((a - a_prev)²)`` of (N, 4) normalised actions and the (N, 4) ``previous``
    ones, which then become ``actions`` in place: the temporal smoothness that CAPS (Mysore et al. 2021,
    its temporal loss) asks of a quadrotor's policy, as a reward term. A policy answering its sensors'
    noise with an action that changes every step pays; one that holds its action still does not,
    however large the action."""
    cost = -weight * np.mean((actions - previous) ** 2, axis=1)
    previous[...] = actions
    return cost


def alive(ended: np.ndarray, cap: float) -> np.ndarray:
    """``cap`` on every step that does not end the episode early (``ended`` (N,) bool), else 0."""
    return cap * (~ended)


@njit(inline=True)
def effort(action, weight):
    """``-weight·mean(a²)`` of one vehicle's normalised action, its squares summed in order (NumPy's
    mean of so few numbers)."""
    total = 0.0
    for a in action:
        total += a * a
    return -weight * (total / action.shape[0])


@njit(inline=True)
def crash(ended, penalty):
    """``-penalty`` where the episode ended early, else ``-0.0``."""
    return -penalty * (1.0 if ended else 0.0)


@njit(inline=True)
def linear_cost(error, weight):
    """``-weight·|error|``."""
    return -weight * abs(error)


@njit(inline=True)
def closeness(distance, scale):
    """``exp(-distance/scale)`` in (0, 1]: 1 at zero distance."""
    return math.exp(-distance / scale)


def efforts(actions: np.ndarray, weight: float) -> np.ndarray:
    """(N,) :func:`effort` of (N, 4) normalised actions."""
    out = np.empty(actions.shape[0])
    _efforts(actions, weight, out)
    return out


def crashes(ended: np.ndarray, penalty: float) -> np.ndarray:
    """(N,) :func:`crash` of ``ended`` (N,) bool."""
    out = np.empty(ended.shape[0])
    _crashes(ended, penalty, out)
    return out


@njit
def _efforts(actions, weight, out):
    for n in range(actions.shape[0]):
        out[n] = effort(actions[n], weight)


@njit
def _crashes(ended, penalty, out):
    for n in range(ended.shape[0]):
        out[n] = crash(ended[n], penalty)

"""Covariance-matched random walks of the wrench filters (``FilterNoise.adaptive_walks``): what the UKF's
and the EKF's step kernels call after each filter's step, and the walk noise they add before it.

A filter's walks are two 3x3 covariances per step, ``walks[0]`` of the external force and ``walks[1]`` of
the external torque (each in its filter's frame of that block), full matrices so that the filter turns
with the world: a yawed flight gives the yawed estimate.
"""

from __future__ import annotations

from quad_wrench_env.numerics import njit


@njit(inline=True)
def match_walks(walks, before, after, defaults, adaptation):
    """One filter's walks ``walks`` (2, 3, 3) matched to the change its step made to its wrench estimate,
    ``d = after - before`` (force, torque: 6 each): ``M <- α M + (1 - α) d dᵀ`` per block, scaled down to
    the ceiling's trace ``c² tr(Q₀)`` where it is above (``Q₀`` the block's ``defaults``, force then torque
    variances), ``adaptation`` = ``(on, α, floor², c²)``; nothing moves when ``on`` is 0.

    Covariance matching (Mohamed & Schwarz 1999, eq. 20: the process noise from the state corrections,
    ``Q ≈ E[K ν νᵀ Kᵀ]``) with exponential forgetting (Akhlaghi, Zhou & Huang 2017, eq. 21): for a random
    walk the filter's steady state has ``P⁻ - P⁺ = Q`` on that block, and ``P⁻ - P⁺ = K S Kᵀ`` is the
    covariance of the correction, so a filter whose walk is the mean outer product of its corrections
    reports what its estimate actually moves. A disturbance that changes faster than the walk (a jet's
    turbulence) raises it; still air lowers it towards the floor (:func:`walk_noise`). The ceiling keeps a
    filter out of the matching's other fixed point (Mohamed & Schwarz 1999 Sec. 5 warn of it): a walk so
    large that the wrench follows the motion capture's noise through the twice-differentiated pose, whose
    corrections then hold the walk up."""
    if adaptation[0] == 0.0:
        return
    forgetting = adaptation[1]
    for block in range(2):
        for i in range(3):
            change_i = after[3 * block + i] - before[3 * block + i]
            for j in range(i, 3):  # the upper triangle, mirrored: symmetric to the bit
                change_j = after[3 * block + j] - before[3 * block + j]
                value = forgetting * walks[block, i, j] + (1.0 - forgetting) * change_i * change_j
                walks[block, i, j] = value
                walks[block, j, i] = value
        ceiling = adaptation[3] * (defaults[3 * block] + defaults[3 * block + 1] + defaults[3 * block + 2])
        trace = walks[block, 0, 0] + walks[block, 1, 1] + walks[block, 2, 2]
        if trace > ceiling:
            walks[block] *= ceiling / trace


@njit(inline=True)
def walk_noise(walks, block, i, j, defaults, adaptation):
    """Entry ``(i, j)`` of the matched walk covariance a filter adds to its ``block`` (0 force, 1 torque)
    this step: the walks' entry and the floor ``floor² q₀`` on the diagonal, so that no
    direction's walk falls below the floor's fraction of its default sd ``q₀`` (``defaults``, force then
    torque variances). Fixed walks do not come here: the kernels add their constants' diagonal."""
    value = walks[block, i, j]
    if i == j:
        value += adaptation[2] * defaults[3 * block + i]
    return value


@njit(inline=True)
def start_walks(walks, defaults):
    """``walks`` (2, 3, 3) where a filter starts: diagonal, the ``defaults`` (force, torque variances)."""
    walks[:, :, :] = 0.0
    for block in range(2):
        for i in range(3):
            walks[block, i, i] = defaults[3 * block + i]

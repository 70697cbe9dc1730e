"""The step of a bank of unscented wrench filters, eight filters at a time on SIMD lanes (numba).

The same filter as :func:`~quad_wrench_env.estimators.ukf_kernel.ukf_bank_step`, with the same shortcuts
(see that module's docstring), written on :mod:`~quad_wrench_env.numerics.lanes`: every number of
the step is a value of eight lanes, one lane per filter, so each arithmetic step runs on eight
filters at once: faster per filter than the filter-by-filter kernel in a large bank
(``python scripts/bench_estimators.py``), but a block costs as much as eight filters, so
:class:`~quad_wrench_env.estimators.ukf.UnscentedFilterBank` runs banks of fewer than
:data:`LANES_FROM` filters filter by filter.

Each block of eight filters is copied into lane layout (a short last block repeats its last
filter in the spare lanes, whose results are dropped), stepped, and copied back. Each lane does the
filter-by-filter kernel's operations in the same order, with IEEE rounding lane by lane, and no
branch of one lane depends on another's numbers: a filter gives the same bits on lanes as filter by
filter, whatever its neighbours, on CPUs of any vector width (``tests/test_lanes.py``,
``tests/test_determinism.py``).
"""

from __future__ import annotations

import numpy as np

from quad_wrench_env.estimators.ukf_kernel import _MEASURED, _NONLINEAR, unpack_ukf_constants, wrench_of_rest
from quad_wrench_env.estimators.walks import match_walks, start_walks, walk_noise
from quad_wrench_env.numerics import njit
from quad_wrench_env.numerics.lanes import (
    WIDTH,
    all_less,
    empty,
    finite_mask,
    greater_mask,
    lane,
    load,
    splat,
    sqrt,
    store,
    with_lane,
)
from quad_wrench_env.numerics.linalg import inputs_finite
from quad_wrench_env.numerics.quaternions import (
    exp,
    exp_small,
    from_mrp,
    half_angle_squared,
    qmul,
    rotation_entries,
    to_mrp,
)

LANES_FROM = 3
"""Smallest bank that runs on lanes: from three filters a block of eight costs less than filter by filter
(``ukf_bank_step``; docs/architecture.md, "Measurements behind the hot paths")."""

_ALL = (1 << WIDTH) - 1


@njit(inline=True)
def _at(row, column, width):
    """Offset of entry ``(row, column)`` of a lane-layout matrix ``width`` wide."""
    return (row * width + column) * WIDTH


@njit(inline=True)
def _four(array, entry):
    """The lanes of entries ``entry`` to ``entry + 3`` (a quaternion) of a lane-layout array."""
    return (
        load(array, entry * WIDTH),
        load(array, (entry + 1) * WIDTH),
        load(array, (entry + 2) * WIDTH),
        load(array, (entry + 3) * WIDTH),
    )


@njit(inline=True)
def _cholesky(a, out, n):
    """Lower Cholesky factor of each lane's (n, n) matrix ``a`` into ``out`` (lane layout), with
    :func:`~quad_wrench_env.numerics.linalg.cholesky`'s operations; bit ``l`` of the result is set
    where lane ``l`` is positive definite (the others hold NaNs)."""
    positive = _ALL
    zero = splat(0.0)
    for j in range(n):
        s = load(a, _at(j, j, n))
        for k in range(j):
            r = load(out, _at(j, k, n))
            s -= r * r
        positive &= greater_mask(s, zero)
        d = sqrt(s)
        store(out, _at(j, j, n), d)
        for i in range(j + 1, n):
            t = load(a, _at(i, j, n))
            for k in range(j):
                t -= load(out, _at(i, k, n)) * load(out, _at(j, k, n))
            store(out, _at(i, j, n), t / d)
        for i in range(j):
            store(out, _at(i, j, n), zero)
    return positive


@njit(inline=True)
def _exp(v0, v1, v2):
    """:func:`~quad_wrench_env.numerics.quaternions.exp` lane by lane: its Taylor series on the lanes
    when every lane's half angle is small, its scalar form lane by lane otherwise."""
    h2 = half_angle_squared(v0, v1, v2)
    if all_less(h2, 1e-4):
        return exp_small(h2, v0, v1, v2)
    ew, ex, ey, ez = v0, v0, v0, v0
    for i in range(WIDTH):
        w, x, y, z = exp(lane(v0, i), lane(v1, i), lane(v2, i))
        ew, ex, ey, ez = with_lane(ew, i, w), with_lane(ex, i, x), with_lane(ey, i, y), with_lane(ez, i, z)
    return ew, ex, ey, ez


@njit
def ukf_lanes_step(
    quaternions,
    rests,
    covariances,
    walks,
    reinitialisations,
    thrusts,
    body_torques,
    positions,
    measured_quaternions,
    constants,
):
    """One predict-correct step of every filter, in place, with the arguments of
    :func:`~quad_wrench_env.estimators.ukf_kernel.ukf_bank_step`; returns False, touching nothing, when an
    input is not finite."""
    count = quaternions.shape[0]
    unmeasured = positions[:0]
    if not inputs_finite(thrusts, body_torques, positions, measured_quaternions, unmeasured, unmeasured):
        return False
    dt, mass, inertia, gravity, spread, w_centre, w, q_diagonal, g_diagonal, p0, walks0, adaptation = (
        unpack_ukf_constants(constants)
    )
    n_points = 1 + 2 * _NONLINEAR
    n_columns = n_points + 18 - _NONLINEAR
    p = empty(18 * 18)
    root = empty(18 * 18)
    deviations = empty(18 * n_columns)
    weighted = empty(18 * n_columns)
    q_points = empty(n_points * 4)
    rest_points = empty(n_points * 15)
    rest = empty(15)
    e = empty(18)
    mean = empty(18)
    rotation0 = empty(9)
    pht = empty(18 * 6)
    s = empty(6 * 6)
    s_root = empty(6 * 6)
    whitened = empty(18 * 6)
    innovation = empty(6)
    delta = empty(18)
    given = empty(15)  # quaternion, thrust, body torque, position, measured quaternion
    walk_lanes = empty(18)  # the walks (2, 3, 3), force then torque, with the floor where matched
    matched = adaptation[0] != 0.0
    before = np.empty(6)
    after = np.empty(6)
    zero = splat(0.0)
    for first in range(0, count, WIDTH):
        # -- the block's filters into lanes (lower triangle of P: all the Cholesky reads) --
        for i in range(WIDTH):
            n = min(first + i, count - 1)
            for a in range(18):
                for c in range(a + 1):
                    p[_at(a, c, 18) + i] = covariances[n, a, c]
            for k in range(15):
                rest[k * WIDTH + i] = rests[n, k]
            for block in range(2 if matched else 0):  # fixed walks: the constants' (below)
                for a in range(3):
                    for c in range(3):
                        value = walk_noise(walks[n], block, a, c, walks0, adaptation)
                        walk_lanes[(9 * block + 3 * a + c) * WIDTH + i] = value
            for k in range(4):
                given[k * WIDTH + i] = quaternions[n, k]
                given[(11 + k) * WIDTH + i] = measured_quaternions[n, k]
            given[4 * WIDTH + i] = thrusts[n]
            for k in range(3):
                given[(5 + k) * WIDTH + i] = body_torques[n, k]
                given[(8 + k) * WIDTH + i] = positions[n, k]
        positive = _cholesky(p, root, 18)
        if positive != _ALL:  # lost positive definiteness: keep the mean, restart the covariance
            for i in range(WIDTH):
                if not (positive >> i) & 1:
                    for a in range(18):
                        for c in range(a + 1):
                            p[_at(a, c, 18) + i] = p0[a, c]
                    if first + i < count:
                        reinitialisations[first + i] += 1
            _cholesky(p, root, 18)
        qw, qx, qy, qz = _four(given, 0)
        thrust = load(given, 4 * WIDTH)
        body_torque = (load(given, 5 * WIDTH), load(given, 6 * WIDTH), load(given, 7 * WIDTH))
        # -- the centre and the sigma points along columns 0-5 through the motion model
        # (eqs. 19-24, 2-5, 11-14) --
        for j in range(n_points):
            for i in range(18):
                store(e, i * WIDTH, zero)
            if j > 0:
                sign = 1.0 if j <= _NONLINEAR else -1.0
                col = (j - 1) % _NONLINEAR
                for i in range(col, 18):
                    store(e, i * WIDTH, sign * spread * load(root, _at(i, col, 18)))
            dw, dx, dy, dz = from_mrp(load(e, 0), load(e, WIDTH), load(e, 2 * WIDTH))
            pw, px, py, pz = qmul(qw, qx, qy, qz, dw, dx, dy, dz)
            rotation = rotation_entries(pw, px, py, pz)
            if j == 0:
                for k in range(9):
                    store(rotation0, k * WIDTH, rotation[k])
            point = j * 15 * WIDTH
            for i in range(15):
                store(rest_points, point + i * WIDTH, load(rest, i * WIDTH) + load(e, (3 + i) * WIDTH))
            om0, om1, om2 = _four(rest_points, 15 * j)[:3]
            tau0, tau1, tau2 = _four(rest_points, 15 * j + 9)[:3]
            j0, j1, j2 = om0 * inertia[0], om1 * inertia[1], om2 * inertia[2]
            gyroscopic = (om1 * j2 - om2 * j1, om2 * j0 - om0 * j2, om0 * j1 - om1 * j0)
            for i in range(3):  # ẋ is read before it is advanced
                force = load(rest_points, point + (12 + i) * WIDTH)
                accel = (thrust / mass) * rotation[3 * i + 2] + force / mass
                if i == 2:
                    accel -= gravity
                torque = rotation[i] * tau0 + rotation[3 + i] * tau1 + rotation[6 + i] * tau2
                torque = torque + body_torque[i] - gyroscopic[i]
                x, v, om = point + (3 + i) * WIDTH, point + (6 + i) * WIDTH, point + i * WIDTH
                advance = dt * load(rest_points, v) + (0.5 * dt * dt) * accel
                store(rest_points, x, load(rest_points, x) + advance)
                store(rest_points, v, load(rest_points, v) + dt * accel)
                store(rest_points, om, load(rest_points, om) + (dt / inertia[i]) * torque)
            ew, ex, ey, ez = _exp(om0 * dt, om1 * dt, om2 * dt)
            rw, rx, ry, rz = qmul(pw, px, py, pz, ew, ex, ey, ez)
            point = j * 4 * WIDTH
            store(q_points, point, rw)
            store(q_points, point + WIDTH, rx)
            store(q_points, point + 2 * WIDTH, ry)
            store(q_points, point + 3 * WIDTH, rz)
        # -- the points along columns 6-17 move the centre's by ±(the model's linear map of the column) --
        for k in range(18 - _NONLINEAR):
            col, column = _NONLINEAR + k, n_points + k
            for i in range(18):
                store(e, i * WIDTH, zero)
            for i in range(col, 18):
                store(e, i * WIDTH, spread * load(root, _at(i, col, 18)))
            tau0, tau1, tau2 = load(e, 12 * WIDTH), load(e, 13 * WIDTH), load(e, 14 * WIDTH)
            for i in range(3):
                force = load(e, (15 + i) * WIDTH) / mass
                shift = (
                    zero,
                    (dt / inertia[i])
                    * (
                        load(rotation0, i * WIDTH) * tau0
                        + load(rotation0, (3 + i) * WIDTH) * tau1
                        + load(rotation0, (6 + i) * WIDTH) * tau2
                    ),
                    load(e, (6 + i) * WIDTH) + dt * load(e, (9 + i) * WIDTH) + (0.5 * dt * dt) * force,
                    load(e, (9 + i) * WIDTH) + dt * force,
                    load(e, (12 + i) * WIDTH),
                    load(e, (15 + i) * WIDTH),
                )
                for block in range(6):
                    store(deviations, _at(3 * block + i, column, n_columns), shift[block])
                    store(weighted, _at(3 * block + i, column, n_columns), (2.0 * w) * shift[block])
        # -- recombination (eqs. 25-27) --
        cw, cx, cy, cz = _four(q_points, 0)
        cx, cy, cz = -cx, -cy, -cz
        for i in range(18):
            store(mean, i * WIDTH, zero)
        for j in range(n_points):
            pw, px, py, pz = _four(q_points, 4 * j)
            rw, rx, ry, rz = qmul(cw, cx, cy, cz, pw, px, py, pz)
            m0, m1, m2 = to_mrp(rw, rx, ry, rz)
            store(deviations, _at(0, j, n_columns), m0)
            store(deviations, _at(1, j, n_columns), m1)
            store(deviations, _at(2, j, n_columns), m2)
            for i in range(15):
                store(deviations, _at(3 + i, j, n_columns), load(rest_points, (j * 15 + i) * WIDTH))
            weight = w_centre if j == 0 else w
            for i in range(18):
                deviation = load(deviations, _at(i, j, n_columns))
                store(mean, i * WIDTH, load(mean, i * WIDTH) + weight * deviation)
        for i in range(18):
            centre = load(mean, i * WIDTH)
            for j in range(n_points):
                d = load(deviations, _at(i, j, n_columns)) - centre
                store(deviations, _at(i, j, n_columns), d)
                store(weighted, _at(i, j, n_columns), (w_centre if j == 0 else w) * d)
        for a in range(18):
            for c in range(a + 1):
                t = zero
                for j in range(n_columns):
                    t += load(weighted, _at(a, j, n_columns)) * load(deviations, _at(c, j, n_columns))
                store(p, _at(a, c, 18), t)
                store(p, _at(c, a, 18), t)
        dw, dx, dy, dz = from_mrp(load(mean, 0), load(mean, WIDTH), load(mean, 2 * WIDTH))
        cw, cx, cy, cz = _four(q_points, 0)
        qw, qx, qy, qz = qmul(cw, cx, cy, cz, dw, dx, dy, dz)
        for i in range(15):
            store(rest, i * WIDTH, load(mean, (3 + i) * WIDTH))
        # -- process noise: + B Q Bᵀ, B at the prior mean attitude (ukf_bank_step) --
        for i in range(3):
            rate_gain = dt / inertia[i]
            at = _at(3 + i, 3 + i, 18)
            store(p, at, load(p, at) + rate_gain * q_diagonal[i] * rate_gain)
            if matched:  # each lane's walks (ukf_bank_step): torque, force
                for j in range(3):
                    for row, block in ((12, 1), (15, 0)):
                        at = _at(row + i, row + j, 18)
                        store(p, at, load(p, at) + load(walk_lanes, (9 * block + 3 * i + j) * WIDTH))
            else:  # the fixed walks, every lane's the same
                for index, walk in ((12 + i, q_diagonal[3 + i]), (15 + i, q_diagonal[9 + i])):
                    at = _at(index, index, 18)
                    store(p, at, load(p, at) + walk)
        for a in range(6, 12):
            for c in range(a, 12):
                total = zero
                gain_a = 0.5 * dt * dt / mass if a < 9 else dt / mass  # B's rows: [T²/2m; T/m]·R
                gain_c = 0.5 * dt * dt / mass if c < 9 else dt / mass
                for k in range(3):
                    b_a = gain_a * load(rotation0, ((a % 3) * 3 + k) * WIDTH)
                    b_c = gain_c * load(rotation0, ((c % 3) * 3 + k) * WIDTH)
                    total += b_a * q_diagonal[6 + k] * b_c
                store(p, _at(a, c, 18), load(p, _at(a, c, 18)) + total)
                if c != a:
                    store(p, _at(c, a, 18), load(p, _at(c, a, 18)) + total)
        # -- correction as a Kalman update (eqs. 29-37), as in ukf_bank_step --
        for a in range(18):
            for c in range(6):
                store(pht, _at(a, c, 6), load(p, _at(a, _MEASURED[c], 18)))
        for c in range(6):
            for d in range(6):
                store(s, _at(c, d, 6), load(pht, _at(_MEASURED[c], d, 6)))
            store(s, _at(c, c, 6), load(s, _at(c, c, 6)) + g_diagonal[c])
        _cholesky(s, s_root, 6)
        for r in range(18):  # M = P Hᵀ L⁻ᵀ (linalg.forward_solve_rows)
            for c in range(6):
                t = load(pht, _at(r, c, 6))
                for m in range(c):
                    t -= load(s_root, _at(c, m, 6)) * load(whitened, _at(r, m, 6))
                store(whitened, _at(r, c, 6), t / load(s_root, _at(c, c, 6)))
        for i in range(3):
            store(innovation, i * WIDTH, load(given, (8 + i) * WIDTH) - load(rest, (3 + i) * WIDTH))
        mw, mx, my, mz = _four(given, 11)
        rw, rx, ry, rz = qmul(qw, -qx, -qy, -qz, mw, mx, my, mz)
        m0, m1, m2 = to_mrp(rw, rx, ry, rz)
        store(innovation, 3 * WIDTH, m0)
        store(innovation, 4 * WIDTH, m1)
        store(innovation, 5 * WIDTH, m2)
        for c in range(6):  # L⁻¹ ν, in place
            t = load(innovation, c * WIDTH)
            for m in range(c):
                t -= load(s_root, _at(c, m, 6)) * load(innovation, m * WIDTH)
            store(innovation, c * WIDTH, t / load(s_root, _at(c, c, 6)))
        for a in range(18):
            t = zero
            for c in range(6):
                t += load(whitened, _at(a, c, 6)) * load(innovation, c * WIDTH)
            store(delta, a * WIDTH, t)
        for a in range(18):
            for c in range(a, 18):
                t = zero
                for k in range(6):
                    t += load(whitened, _at(a, k, 6)) * load(whitened, _at(c, k, 6))
                value = load(p, _at(a, c, 18)) - t
                store(p, _at(a, c, 18), value)
                store(p, _at(c, a, 18), value)
        dw, dx, dy, dz = from_mrp(load(delta, 0), load(delta, WIDTH), load(delta, 2 * WIDTH))
        qw, qx, qy, qz = qmul(qw, qx, qy, qz, dw, dx, dy, dz)
        norm = sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        qw, qx, qy, qz = qw / norm, qx / norm, qy / norm, qz / norm
        finite = _ALL
        for i in range(15):
            value = load(rest, i * WIDTH) + load(delta, (3 + i) * WIDTH)
            store(rest, i * WIDTH, value)
            finite &= finite_mask(value)
        for a in range(18 * 18):
            finite &= finite_mask(load(p, a * WIDTH))
        # -- the lanes back into the filters; a non-finite one restarts from the measured pose at rest --
        for i in range(min(WIDTH, count - first)):
            n = first + i
            if (finite >> i) & 1:
                quaternions[n, 0], quaternions[n, 1] = lane(qw, i), lane(qx, i)
                quaternions[n, 2], quaternions[n, 3] = lane(qy, i), lane(qz, i)
                if matched:
                    wrench_of_rest(rests[n], before)
                for k in range(15):
                    rests[n, k] = rest[k * WIDTH + i]
                if matched:
                    wrench_of_rest(rests[n], after)
                    match_walks(walks[n], before, after, walks0, adaptation)
                for a in range(18):
                    for c in range(18):
                        covariances[n, a, c] = p[_at(a, c, 18) + i]
            else:
                quaternions[n] = measured_quaternions[n]
                rests[n] = 0.0
                rests[n, 3:6] = positions[n]
                covariances[n] = p0
                start_walks(walks[n], walks0)
                reinitialisations[n] += 1
    return True

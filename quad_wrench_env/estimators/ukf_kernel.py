"""The step of a bank of unscented wrench filters: the filter of
:class:`quad_wrench_env.estimators.ukf.UnscentedFilterBank` (McKinnon & Schoellig 2016 eqs. 18-37), its only
implementation, filter by filter, with its shortcuts (noise-only sigma points as ``B Q Bᵀ``, correction as a
Kalman update) and two more rewrites that are exact in real arithmetic (``tests/test_ukf.py`` holds it, step
by step, to a plain unscented filter with none of them, ``tests/reference_ukf.py``):

* Sigma points are ``x ± √(L+κ) Lₚ[:, c]`` with ``Lₚ`` the lower Cholesky factor, so a column
  ``c ≥ 6`` leaves the attitude and the rates (error state 0-5) at the mean. Given those, the model
  (eqs. 2-5, 11-14) is affine in the rest of the state, so the pair ``±c`` moves to the propagated
  centre ``± A Lₚ[:, c]`` with ``A`` its linear map: only the centre and the 12 points along columns
  0-5 go through the model; a pair adds ``2w`` times the centre to the mean and
  ``2w (c₀ c₀ᵀ + δ δᵀ)`` to the covariance (``c₀`` the centre's deviation from the mean). The
  covariance (eq. 27) is then one weighted Gram matrix of 25 deviation columns (the 13 points' and
  the 12 pairs' ``δ``) (:func:`~quad_wrench_env.numerics.linalg.weighted_gram`), each sum in the
  order of the columns, as on the SIMD lanes (:mod:`~quad_wrench_env.estimators.ukf_lanes_kernel`): a filter
  gives the same bits in a bank of any size.
* With ``S = L Lᵀ`` (eq. 31) and ``M = P Hᵀ L⁻ᵀ``, the gain is ``K = M L⁻¹`` (29), the update
  ``K ν = M (L⁻¹ ν)`` and ``P - K S Kᵀ = P - M Mᵀ`` (30, 37), symmetric by construction.
"""

from __future__ import annotations

import math

import numpy as np

from quad_wrench_env.estimators.noise import add_world_covariances
from quad_wrench_env.estimators.walks import match_walks, start_walks, walk_noise
from quad_wrench_env.numerics import njit
from quad_wrench_env.numerics.linalg import (
    all_finite,
    cholesky,
    forward_solve_rows,
    inputs_finite,
    rows_view,
    weighted_gram,
)
from quad_wrench_env.numerics.quaternions import exp, from_mrp, matrix, qmul, to_mrp

_MEASURED = np.array((6, 7, 8, 0, 1, 2))
"""Error-state indices of the measurement ``(x, δρ)``."""
_NONLINEAR = 6
"""Columns of the lower Cholesky factor that move the attitude or the rates (error state 0-5)."""


def ukf_constants(
    dt, mass, inertia, gravity, spread, weight_centre, weight_other, q_diagonal, g_diagonal, p0, adaptation
):
    """:func:`ukf_bank_step`'s constants in one array, in the order it reads them: ``dt``, ``mass``,
    ``inertia`` (3), ``gravity``, ``spread`` (``√(L+κ)``), the centre's mean weight (the noise-only
    points' included) and every other point's, the diagonals of ``Q`` (12) and ``G`` (6), ``P₀`` (18, 18),
    the walks' variances a filter starts from (force, torque: ``Q``'s entries 9-11 and 3-5) and the
    walks' ``adaptation`` ``(on, α, floor², ceiling²)``
    (:func:`~quad_wrench_env.estimators.walks.match_walks`)."""
    head = (dt, mass, *inertia, gravity, spread, weight_centre, weight_other)
    walks = np.concatenate((q_diagonal[9:12], q_diagonal[3:6]))  # force, torque
    return np.concatenate((head, q_diagonal, g_diagonal, np.ravel(p0), walks, adaptation)).astype(float)


@njit(inline=True)
def unpack_ukf_constants(constants):
    """:func:`ukf_constants` as the step kernels read them: ``dt``, ``mass``, ``inertia`` (3),
    ``gravity``, ``spread``, the centre's weight with the linear pairs' share (module docstring), every
    other point's weight ``w``, the diagonals of ``Q`` and ``G``, ``P₀`` (18, 18), the walks' variances
    a filter starts from and their adaptation."""
    w = constants[8]
    w_centre = constants[7] + 2 * (18 - _NONLINEAR) * w
    q_diagonal, g_diagonal, p0 = constants[9:21], constants[21:27], rows_view(constants, 27, 18, 18)
    inertia = (constants[2], constants[3], constants[4])
    return (
        constants[0],
        constants[1],
        inertia,
        constants[5],
        constants[6],
        w_centre,
        w,
        q_diagonal,
        g_diagonal,
        p0,
        constants[351:357],
        constants[357:361],
    )


@njit
def ukf_bank_step(
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
    """One predict-correct step of every filter, in place (see the module docstring), with the
    constants of :func:`ukf_constants` and each filter's walks ``walks`` (N, 2, 3, 3) (force, torque
    covariances per step, :mod:`~quad_wrench_env.estimators.walks`), matched to its step afterwards;
    returns False, touching nothing, when an input is not finite."""
    count = quaternions.shape[0]
    unmeasured = positions[:0]
    if not inputs_finite(thrusts, body_torques, positions, measured_quaternions, unmeasured, unmeasured):
        return False
    dt, mass, inertia, gravity, spread, w_centre, w, q_diagonal, g_diagonal, p0, walks0, adaptation = (
        unpack_ukf_constants(constants)
    )
    n_points = 1 + 2 * _NONLINEAR
    before = np.empty(6)
    matched = adaptation[0] != 0.0
    root = np.empty((18, 18))
    q_points = np.empty((n_points, 4))
    rest_points = np.empty((n_points, 15))
    deviations = np.empty((18, n_points + 18 - _NONLINEAR))  # a column per point (module docstring)
    weighted = np.empty_like(deviations)
    mean = np.empty(18)
    rotation = np.empty((3, 3))
    rotation0 = np.empty((3, 3))
    b = np.empty((18, 12))
    pht = np.empty((18, 6))
    s = np.empty((6, 6))
    s_root = np.empty((6, 6))
    whitened = np.empty((18, 6))
    innovation = np.empty((1, 6))
    e = np.empty(18)
    accel = np.empty(3)
    torque = np.empty(3)
    delta = np.empty(18)
    for n in range(count):
        p = covariances[n]
        if not cholesky(p, root):  # lost positive definiteness: keep the mean, restart the covariance
            p[:, :] = p0
            reinitialisations[n] += 1
            cholesky(p, root)
        qw, qx, qy, qz = quaternions[n, 0], quaternions[n, 1], quaternions[n, 2], quaternions[n, 3]
        thrust = thrusts[n]
        if matched:
            wrench_of_rest(rests[n], before)
        # -- the centre and the sigma points along columns 0-5 through the motion model
        # (eqs. 19-24, 2-5, 11-14) --
        for j in range(n_points):
            e[:] = 0.0
            if j > 0:
                sign = 1.0 if j <= _NONLINEAR else -1.0
                col = (j - 1) % _NONLINEAR
                for i in range(col, 18):
                    e[i] = sign * spread * root[i, col]
            dw, dx, dy, dz = from_mrp(e[0], e[1], e[2])
            pw, px, py, pz = qmul(qw, qx, qy, qz, dw, dx, dy, dz)
            matrix(pw, px, py, pz, rotation)
            if j == 0:
                rotation0[:, :] = rotation
            rest = rest_points[j]
            for i in range(15):
                rest[i] = rests[n, i] + e[3 + i]
            om0, om1, om2 = rest[0], rest[1], rest[2]
            for i in range(3):
                accel[i] = (thrust / mass) * rotation[i, 2] + rest[12 + i] / mass
                torque[i] = (
                    rotation[0, i] * rest[9] + rotation[1, i] * rest[10] + rotation[2, i] * rest[11]
                ) + body_torques[n, i]
            accel[2] -= gravity
            j0, j1, j2 = om0 * inertia[0], om1 * inertia[1], om2 * inertia[2]
            torque[0] -= om1 * j2 - om2 * j1
            torque[1] -= om2 * j0 - om0 * j2
            torque[2] -= om0 * j1 - om1 * j0
            for i in range(3):  # ẋ is read before it is advanced
                rest[3 + i] += dt * rest[6 + i] + (0.5 * dt * dt) * accel[i]
                rest[6 + i] += dt * accel[i]
                rest[i] += (dt / inertia[i]) * torque[i]
            ew, ex, ey, ez = exp(om0 * dt, om1 * dt, om2 * dt)
            q_points[j, 0], q_points[j, 1], q_points[j, 2], q_points[j, 3] = qmul(
                pw, px, py, pz, ew, ex, ey, ez
            )
        # -- the points along columns 6-17 move the centre's by ±(the model's linear map of the
        # column), exactly (module docstring) --
        for k in range(18 - _NONLINEAR):
            col = _NONLINEAR + k
            shift = deviations[:, n_points + k]
            e[:] = 0.0
            for i in range(col, 18):
                e[i] = spread * root[i, col]
            for i in range(3):
                shift[i] = 0.0
                shift[3 + i] = (dt / inertia[i]) * (
                    rotation0[0, i] * e[12] + rotation0[1, i] * e[13] + rotation0[2, i] * e[14]
                )
                force = e[15 + i] / mass
                shift[6 + i] = e[6 + i] + dt * e[9 + i] + (0.5 * dt * dt) * force
                shift[9 + i] = e[9 + i] + dt * force
                shift[12 + i] = e[12 + i]
                shift[15 + i] = e[15 + i]
            for i in range(18):
                weighted[i, n_points + k] = (2.0 * w) * shift[i]
        # -- recombination (eqs. 25-27); a ± pair of the linear points adds 2w (centre) to the mean
        # and 2w (δ δᵀ + c cᵀ) to the covariance, c the centre's deviation --
        cw, cx, cy, cz = q_points[0, 0], -q_points[0, 1], -q_points[0, 2], -q_points[0, 3]
        mean[:] = 0.0
        for j in range(n_points):
            rw, rx, ry, rz = qmul(
                cw, cx, cy, cz, q_points[j, 0], q_points[j, 1], q_points[j, 2], q_points[j, 3]
            )
            deviations[0, j], deviations[1, j], deviations[2, j] = to_mrp(rw, rx, ry, rz)
            for i in range(15):
                deviations[3 + i, j] = rest_points[j, i]
            weight = w_centre if j == 0 else w
            for i in range(18):
                mean[i] += weight * deviations[i, j]
        for i in range(18):
            for j in range(n_points):
                deviations[i, j] -= mean[i]
                weighted[i, j] = (w_centre if j == 0 else w) * deviations[i, j]
        weighted_gram(weighted, deviations, p)
        dw, dx, dy, dz = from_mrp(mean[0], mean[1], mean[2])
        qw, qx, qy, qz = qmul(q_points[0, 0], q_points[0, 1], q_points[0, 2], q_points[0, 3], dw, dx, dy, dz)
        rests[n] = mean[3:]
        # -- process noise: + B Q Bᵀ, B at the prior mean attitude; B is block sparse: diagonal blocks
        # for the rates, the torque and the force, and [T²/2m; T/m]·R for position and velocity --
        for i in range(3):
            rate_gain = dt / inertia[i]
            p[3 + i, 3 + i] += rate_gain * q_diagonal[i] * rate_gain
            if matched:  # each filter's walks (:mod:`~quad_wrench_env.estimators.walks`): torque, force
                for j in range(3):
                    p[12 + i, 12 + j] += walk_noise(walks[n], 1, i, j, walks0, adaptation)
                    p[15 + i, 15 + j] += walk_noise(walks[n], 0, i, j, walks0, adaptation)
            else:  # the fixed walks
                p[12 + i, 12 + i] += q_diagonal[3 + i]
                p[15 + i, 15 + i] += q_diagonal[9 + i]
            for k in range(3):
                b[6 + i, 6 + k] = (0.5 * dt * dt / mass) * rotation0[i, k]
                b[9 + i, 6 + k] = (dt / mass) * rotation0[i, k]
        for a in range(6, 12):
            for c in range(a, 12):
                total = 0.0
                for k in range(6, 9):
                    total += b[a, k] * q_diagonal[k] * b[c, k]
                p[a, c] += total
                if c != a:
                    p[c, a] += total
        # -- correction as a Kalman update (eqs. 29-37) --
        for a in range(18):
            for c in range(6):
                pht[a, c] = p[a, _MEASURED[c]]
        for c in range(6):
            for d in range(6):
                s[c, d] = pht[_MEASURED[c], d]
            s[c, c] += g_diagonal[c]
        cholesky(s, s_root)
        # with S = L Lᵀ and M = P Hᵀ L⁻ᵀ: K = M L⁻¹ (29), K ν = M (L⁻¹ ν) (36), K S Kᵀ = M Mᵀ (30)
        forward_solve_rows(s_root, pht, whitened)
        for i in range(3):
            innovation[0, i] = positions[n, i] - rests[n, 3 + i]
        mw, mx, my, mz = (
            measured_quaternions[n, 0],
            measured_quaternions[n, 1],
            measured_quaternions[n, 2],
            measured_quaternions[n, 3],
        )
        rw, rx, ry, rz = qmul(qw, -qx, -qy, -qz, mw, mx, my, mz)
        innovation[0, 3], innovation[0, 4], innovation[0, 5] = to_mrp(rw, rx, ry, rz)
        forward_solve_rows(s_root, innovation, innovation)  # L⁻¹ ν, in place
        for a in range(18):
            t = 0.0
            for c in range(6):
                t += whitened[a, c] * innovation[0, c]
            delta[a] = t
        for a in range(18):
            for c in range(a, 18):
                t = 0.0
                for k in range(6):
                    t += whitened[a, k] * whitened[c, k]
                value = p[a, c] - t
                p[a, c] = value
                p[c, a] = value
        dw, dx, dy, dz = from_mrp(delta[0], delta[1], delta[2])
        qw, qx, qy, qz = qmul(qw, qx, qy, qz, dw, dx, dy, dz)
        norm = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        quaternions[n, 0], quaternions[n, 1], quaternions[n, 2], quaternions[n, 3] = (
            qw / norm,
            qx / norm,
            qy / norm,
            qz / norm,
        )
        for i in range(15):
            rests[n, i] += delta[3 + i]
        finite = all_finite(rests[n])
        for a in range(18):
            finite &= all_finite(p[a])
        if finite:
            if matched:
                wrench_of_rest(rests[n], e)
                match_walks(walks[n], before, e, walks0, adaptation)
        else:  # restart from the measured pose at rest
            quaternions[n] = measured_quaternions[n]
            rests[n] = 0.0
            rests[n, 3:6] = positions[n]
            p[:, :] = p0
            start_walks(walks[n], walks0)
            reinitialisations[n] += 1
    return True


@njit(inline=True)
def wrench_of_rest(rest, out):
    """The wrench ``[f_e, τ_e]`` of a filter's ``rest`` (15,) into ``out`` (its first 6 entries)."""
    for i in range(3):
        out[i], out[3 + i] = rest[12 + i], rest[9 + i]


@njit
def ukf_estimates(quaternions, rests, states, wrenches):
    """``UnscentedFilterBank.estimates`` into (N, 13) ``states`` (position, velocity, quaternion, body
    rates) and (N, 6) ``wrenches`` (``[f_e, τ_e]``), from the filters' means."""
    for n in range(quaternions.shape[0]):
        for i in range(3):
            states[n, i], states[n, 3 + i], states[n, 10 + i] = rests[n, 3 + i], rests[n, 6 + i], rests[n, i]
            wrenches[n, i], wrenches[n, 3 + i] = rests[n, 12 + i], rests[n, 9 + i]
        for i in range(4):
            states[n, 6 + i] = quaternions[n, i]


@njit
def ukf_wrench_covariances(covariances, quaternions, spread, out):
    """Each filter's covariance of ``[f_e, τ_e]`` (error states 15-17, 12-14) into ``out`` (N, 6, 6), plus
    the rotors' ``spread`` (:func:`~quad_wrench_env.estimators.noise.rotor_spread_covariance`) at its
    attitude ``quaternions`` (N, 4)."""
    for n in range(covariances.shape[0]):
        for i in range(6):
            a = 15 + i if i < 3 else 9 + i
            for j in range(6):
                out[n, i, j] = covariances[n, a, 15 + j if j < 3 else 9 + j]
    add_world_covariances(spread, quaternions, out)

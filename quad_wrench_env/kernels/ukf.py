"""The step of a bank of unscented wrench filters, compiled: the arithmetic of
:class:`quad_wrench_env.estimators.ukf.UnscentedFilterBank` (paper 000 eqs. 18-37), filter by filter,
with the same shortcuts (noise-only sigma points as ``B Q Bᵀ``, correction as a Kalman update)."""

from __future__ import annotations

import math

import numpy as np

from quad_wrench_env.kernels import njit
from quad_wrench_env.kernels.linalg import cholesky, cholesky_solve_rows, inputs_finite
from quad_wrench_env.kernels.quaternions import exp, from_mrp, matrix, qmul, to_mrp

_MEASURED = np.array((6, 7, 8, 0, 1, 2))
"""Error-state indices of the measurement ``(x, δρ)``."""


@njit
def ukf_bank_step(
    quaternions, rests, covariances, reinitialisations,
    thrusts, body_torques, positions, measured_quaternions,
    dt, mass, inertia, gravity, spread, weights, q_diagonal, g_diagonal, p0, b_base,
):  # fmt: skip
    """One predict-correct step of every filter, in place (see the module docstring); returns False,
    touching nothing, when an input is not finite."""
    count = quaternions.shape[0]
    unmeasured = np.empty((0, 3))
    if not inputs_finite(thrusts, body_torques, positions, measured_quaternions, unmeasured, unmeasured):
        return False
    n_points = 2 * 18 + 1
    root = np.zeros((18, 18))
    q_points = np.zeros((n_points, 4))
    rest_points = np.zeros((n_points, 15))
    errors = np.zeros((n_points, 18))
    mean = np.zeros(18)
    rotation = np.zeros((3, 3))
    rotation0 = np.zeros((3, 3))
    b = b_base.copy()
    pht = np.zeros((18, 6))
    s = np.zeros((6, 6))
    s_root = np.zeros((6, 6))
    gain = np.zeros((18, 6))
    innovation = np.zeros(6)
    e = np.zeros(18)
    accel = np.zeros(3)
    torque = np.zeros(3)
    delta = np.zeros(18)
    for n in range(count):
        p = covariances[n]
        if not cholesky(p, root):  # lost positive definiteness: keep the mean, restart the covariance
            p[:, :] = p0
            reinitialisations[n] += 1
            cholesky(p, root)
        qw, qx, qy, qz = quaternions[n, 0], quaternions[n, 1], quaternions[n, 2], quaternions[n, 3]
        thrust = thrusts[n]
        # -- sigma points through the motion model (eqs. 19-24, 2-5, 11-14) --
        for j in range(n_points):
            e[:] = 0.0
            if j > 0:
                sign = 1.0 if j <= 18 else -1.0
                col = (j - 1) % 18
                for i in range(18):
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
        # -- recombination (eqs. 25-27) --
        cw, cx, cy, cz = q_points[0, 0], -q_points[0, 1], -q_points[0, 2], -q_points[0, 3]
        mean[:] = 0.0
        for j in range(n_points):
            rw, rx, ry, rz = qmul(
                cw, cx, cy, cz, q_points[j, 0], q_points[j, 1], q_points[j, 2], q_points[j, 3]
            )
            errors[j, 0], errors[j, 1], errors[j, 2] = to_mrp(rw, rx, ry, rz)
            errors[j, 3:] = rest_points[j]
            for i in range(18):
                mean[i] += weights[j] * errors[j, i]
        for j in range(n_points):
            for i in range(18):
                errors[j, i] -= mean[i]
        p[:, :] = 0.0
        for j in range(n_points):
            for a in range(18):
                w = weights[j] * errors[j, a]
                for c in range(a, 18):
                    p[a, c] += w * errors[j, c]
        for a in range(18):
            for c in range(a + 1, 18):
                p[c, a] = p[a, c]
        dw, dx, dy, dz = from_mrp(mean[0], mean[1], mean[2])
        qw, qx, qy, qz = qmul(q_points[0, 0], q_points[0, 1], q_points[0, 2], q_points[0, 3], dw, dx, dy, dz)
        rests[n] = mean[3:]
        # -- process noise: + B Q Bᵀ, B at the prior mean attitude; B is block sparse: diagonal blocks
        # for the rates, the torque and the force, and [T²/2m; T/m]·R for position and velocity --
        for i in range(3):
            p[3 + i, 3 + i] += b[3 + i, i] * q_diagonal[i] * b[3 + i, i]
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
        cholesky_solve_rows(s_root, pht, gain)  # K = P Hᵀ S⁻¹ (29)
        for i in range(3):
            innovation[i] = positions[n, i] - rests[n, 3 + i]
        mw, mx, my, mz = (
            measured_quaternions[n, 0], measured_quaternions[n, 1],
            measured_quaternions[n, 2], measured_quaternions[n, 3],
        )  # fmt: skip
        rw, rx, ry, rz = qmul(qw, -qx, -qy, -qz, mw, mx, my, mz)
        innovation[3], innovation[4], innovation[5] = to_mrp(rw, rx, ry, rz)
        for a in range(18):
            t = 0.0
            for c in range(6):
                t += gain[a, c] * innovation[c]
            delta[a] = t
        for a in range(18):
            for c in range(a, 18):
                t = 0.0
                for k in range(6):
                    t += gain[a, k] * pht[c, k]
                u = 0.0
                for k in range(6):
                    u += gain[c, k] * pht[a, k]
                value = 0.5 * ((p[a, c] - t) + (p[c, a] - u))
                p[a, c] = value
                p[c, a] = value
        dw, dx, dy, dz = from_mrp(delta[0], delta[1], delta[2])
        qw, qx, qy, qz = qmul(qw, qx, qy, qz, dw, dx, dy, dz)
        norm = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        quaternions[n, 0], quaternions[n, 1], quaternions[n, 2], quaternions[n, 3] = (
            qw / norm, qx / norm, qy / norm, qz / norm,
        )  # fmt: skip
        for i in range(15):
            rests[n, i] += delta[3 + i]
        finite = True
        for i in range(15):
            finite = finite and math.isfinite(rests[n, i])
        for a in range(18):
            for c in range(18):
                finite = finite and math.isfinite(p[a, c])
        if not finite:  # restart from the measured pose at rest
            quaternions[n] = measured_quaternions[n]
            rests[n] = 0.0
            rests[n, 3:6] = positions[n]
            p[:, :] = p0
            reinitialisations[n] += 1
    return True

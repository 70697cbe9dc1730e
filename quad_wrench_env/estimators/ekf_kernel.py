"""The step of a bank of extended Kalman wrench filters: the filter of
:class:`quad_wrench_env.estimators.ekf.ExtendedFilterBank` (Hentzen et al. 2019, Sec. III-A), its only
implementation, filter by filter."""

from __future__ import annotations

import math

import numpy as np

from quad_wrench_env.estimators.walks import match_walks, start_walks, walk_noise
from quad_wrench_env.numerics import njit
from quad_wrench_env.numerics.linalg import cholesky, cholesky_solve_rows, inputs_finite, rows_view
from quad_wrench_env.numerics.quaternions import matrix


@njit
def euler_from_quaternion(w, x, y, z):
    """ZYX ``(roll, pitch, yaw)`` (``rotations.euler_zyx_from_quat``)."""
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(min(1.0, max(-1.0, 2.0 * (w * y - z * x))))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


@njit
def quaternion_from_euler(roll, pitch, yaw):
    """``rotations.quat_from_euler_zyx``."""
    cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
    cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    cy, sy = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


@njit(inline=True)
def euler_matrix(roll, pitch, yaw, out):
    """Body -> world rotation matrix of ZYX Euler angles into ``out`` (3, 3)
    (``rotations.rotation_matrices(quat_from_euler_zyx(...))``)."""
    qw, qx, qy, qz = quaternion_from_euler(roll, pitch, yaw)
    matrix(qw, qx, qy, qz, out)


@njit
def wrap(angle):
    """``rotations.wrap_angle``."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@njit(inline=True)
def ekf_transition_jacobian(x, thrust, dt, mass, inertia, out):
    """``F = ∂ transition/∂x = I + T A`` (18, 18) into ``out``, analytic, at the state ``x`` (18,)
    with collective ``thrust`` (Hentzen et al. 2019, Sec. III-A; :func:`ekf_transition` is the
    transition; the tests check this against its finite differences)."""
    roll, pitch, yaw = x[6], x[7], x[8]
    p_, q_, r_ = x[9], x[10], x[11]
    jx, jy, jz = inertia[0], inertia[1], inertia[2]
    sr, cr = math.sin(roll), math.cos(roll)
    sp, cp, tp = math.sin(pitch), math.cos(pitch), math.tan(pitch)
    sy, cy = math.sin(yaw), math.cos(yaw)
    c = thrust / mass
    out[:, :] = 0.0
    for i in range(3):
        out[i, 3 + i] = 1.0
        out[3 + i, 12 + i] = 1.0 / mass
        out[9 + i, 15 + i] = 1.0 / inertia[i]
    # v' = (R e_z T + f)/m - g: columns of ∂(R e_z)/∂(φ, θ, ψ), times T̂/m
    out[3, 6], out[4, 6] = (-cy * sp * sr + sy * cr) * c, (-sy * sp * sr - cy * cr) * c
    out[5, 6] = -cp * sr * c
    out[3, 7], out[4, 7], out[5, 7] = cy * cp * cr * c, sy * cp * cr * c, -sp * cr * c
    out[3, 8], out[4, 8] = (-sy * sp * cr + cy * sr) * c, (cy * sp * cr + sy * sr) * c
    # Euler rates W(φ, θ) ω: their derivatives in the angles, and W itself
    out[6, 6], out[6, 7] = cr * tp * q_ - sr * tp * r_, (sr * q_ + cr * r_) / cp**2
    out[7, 6] = -sr * q_ - cr * r_
    out[8, 6], out[8, 7] = (cr * q_ - sr * r_) / cp, (sr * q_ + cr * r_) * sp / cp**2
    out[6, 9], out[6, 10], out[6, 11] = 1.0, sr * tp, cr * tp
    out[7, 10], out[7, 11] = cr, -sr
    out[8, 10], out[8, 11] = sr / cp, cr / cp
    # ω': -J⁻¹ (ω × Jω), whose derivative is -J⁻¹ (skew(ω) J - skew(J ω)), and J⁻¹ η_ext (above)
    out[9, 10], out[9, 11] = (jy - jz) / jx * r_, (jy - jz) / jx * q_
    out[10, 9], out[10, 11] = (jz - jx) / jy * r_, (jz - jx) / jy * p_
    out[11, 9], out[11, 10] = (jx - jy) / jz * q_, (jx - jy) / jz * p_
    for i in range(18):
        for j in range(18):
            out[i, j] *= dt
        out[i, i] += 1.0


@njit(inline=True)
def ekf_transition(x, thrust, body_torque, dt, mass, inertia, gravity, r):
    """The forward-Euler step of the noise-free dynamics (Hentzen et al. 2019, Sec. III-A; the module
    docstring of :mod:`quad_wrench_env.estimators.ekf`) of the state ``x`` (18,), in place, with
    collective ``thrust`` and ``body_torque`` (3,); ``r`` (3, 3) is scratch."""
    roll, pitch, yaw = x[6], x[7], x[8]
    p_, q_, r_ = x[9], x[10], x[11]
    jx, jy, jz = inertia[0], inertia[1], inertia[2]
    euler_matrix(roll, pitch, yaw, r)
    sr, cr = math.sin(roll), math.cos(roll)
    cp, tp = math.cos(pitch), math.tan(pitch)
    accel0 = (r[0, 2] * thrust + x[12]) / mass
    accel1 = (r[1, 2] * thrust + x[13]) / mass
    accel2 = (r[2, 2] * thrust + x[14]) / mass - gravity
    euler_rate0 = p_ + sr * tp * q_ + cr * tp * r_
    euler_rate1 = cr * q_ - sr * r_
    euler_rate2 = sr / cp * q_ + cr / cp * r_
    c0 = q_ * (jz * r_) - r_ * (jy * q_)
    c1 = r_ * (jx * p_) - p_ * (jz * r_)
    c2 = p_ * (jy * q_) - q_ * (jx * p_)
    for i in range(3):
        x[i] += dt * x[3 + i]
    x[3] += dt * accel0
    x[4] += dt * accel1
    x[5] += dt * accel2
    x[6] += dt * euler_rate0
    x[7] += dt * euler_rate1
    x[8] += dt * euler_rate2
    x[9] += dt * (body_torque[0] + x[15] - c0) / jx
    x[10] += dt * (body_torque[1] + x[16] - c1) / jy
    x[11] += dt * (body_torque[2] + x[17] - c2) / jz


def ekf_constants(
    dt, mass, inertia, gravity, q_diagonal, noise_pose, noise_motion, p0, adaptation
) -> np.ndarray:
    """:func:`ekf_bank_step`'s constants in one array, in the order it reads them: ``dt``, ``mass``,
    ``inertia`` (3), ``gravity``, the diagonal of ``Q`` (18), the pose measurement variances (6), the
    velocity and body-rate measurement variances (6), ``P₀`` (18, 18), and the walks' ``adaptation``
    ``(on, α, floor², ceiling²)`` (:func:`~quad_wrench_env.estimators.walks.match_walks`; the walks a
    filter starts from are ``Q``'s last six entries)."""
    head = (dt, mass, *inertia, gravity)
    return np.concatenate((head, q_diagonal, noise_pose, noise_motion, np.ravel(p0), adaptation)).astype(
        float
    )


@njit
def ekf_bank_step(
    x,
    p,
    walks,
    reinitialisations,
    thrusts,
    body_torques,
    positions,
    quaternions,
    velocities,
    body_rates,
    constants,
):
    """One predict-correct step of every filter, in place, with the constants of
    :func:`ekf_constants` and each filter's walks ``walks`` (N, 2, 3, 3) (force, body torque covariances
    per step: ``Q``'s entries 12-17, :mod:`.walks`), matched to its step afterwards;
    ``velocities`` and ``body_rates`` are (N, 3) where measured, else (0, 3). Returns False, touching
    nothing, when an input is not finite."""
    dt, mass, inertia, gravity = constants[0], constants[1], constants[2:5], constants[5]
    q_diagonal, noise_pose, noise_motion = constants[6:24], constants[24:30], constants[30:36]
    p0 = rows_view(constants, 36, 18, 18)
    walks0, adaptation = q_diagonal[12:18], constants[360:364]
    count = x.shape[0]
    with_velocity, with_rates = velocities.shape[0] > 0, body_rates.shape[0] > 0
    if not inputs_finite(thrusts, body_torques, positions, quaternions, velocities, body_rates):
        return False
    size = 6 + 3 * with_velocity + 3 * with_rates
    measured = np.empty(size, dtype=np.int64)
    noise = np.empty(size)
    for i in range(3):
        measured[i], measured[3 + i] = i, 6 + i
        noise[i], noise[3 + i] = noise_pose[i], noise_pose[3 + i]
    k = 6
    if with_velocity:
        for i in range(3):
            measured[k + i], noise[k + i] = 3 + i, noise_motion[i]
        k += 3
    if with_rates:
        for i in range(3):
            measured[k + i], noise[k + i] = 9 + i, noise_motion[3 + i]
    a = np.empty((18, 18))
    fp = np.empty((18, 18))
    r = np.empty((3, 3))
    residual = np.empty(size)
    pht = np.empty((18, size))
    s = np.empty((size, size))
    s_root = np.empty((size, size))
    gain = np.empty((18, size))
    before = np.empty(6)
    matched = adaptation[0] != 0.0
    for n in range(count):
        xn, pn = x[n], p[n]
        if matched:
            before[:] = xn[12:18]
        # -- predict: F at the prior state, P' = F P Fᵀ + Q, then the forward-Euler step --
        ekf_transition_jacobian(xn, thrusts[n], dt, mass, inertia, a)
        for i in range(18):
            for j in range(18):
                t = 0.0
                for m in range(18):
                    t += a[i, m] * pn[m, j]
                fp[i, j] = t
        for i in range(18):
            for j in range(18):
                t = 0.0
                for m in range(18):
                    t += fp[i, m] * a[j, m]
                pn[i, j] = t + (q_diagonal[i] if i == j and (i < 12 or not matched) else 0.0)
        for block in range(2 if matched else 0):  # each filter's walks (:mod:`.walks`)
            first = 12 + 3 * block
            for i in range(3):
                for j in range(3):
                    pn[first + i, first + j] += walk_noise(walks[n], block, i, j, walks0, adaptation)
        ekf_transition(xn, thrusts[n], body_torques[n], dt, mass, inertia, gravity, r)
        # -- correct (Kalman update with the measured components) --
        mroll, mpitch, myaw = euler_from_quaternion(
            quaternions[n, 0], quaternions[n, 1], quaternions[n, 2], quaternions[n, 3]
        )
        for i in range(3):
            residual[i] = positions[n, i] - xn[i]
        residual[3], residual[4], residual[5] = wrap(mroll - xn[6]), wrap(mpitch - xn[7]), wrap(myaw - xn[8])
        k = 6
        if with_velocity:
            for i in range(3):
                residual[k + i] = velocities[n, i] - xn[3 + i]
            k += 3
        if with_rates:
            for i in range(3):
                residual[k + i] = body_rates[n, i] - xn[9 + i]
        for i in range(18):
            for j in range(size):
                pht[i, j] = pn[i, measured[j]]
        for i in range(size):
            for j in range(size):
                s[i, j] = pht[measured[i], j]
            s[i, i] += noise[i]
        ok = cholesky(s, s_root)
        if ok:
            cholesky_solve_rows(s_root, pht, gain)  # K = P Hᵀ S⁻¹
        for i in range(18):
            t = 0.0
            for j in range(size):
                t += gain[i, j] * residual[j]
            xn[i] += t
        for i in range(6, 9):
            xn[i] = wrap(xn[i])
        for i in range(18):
            for j in range(i, 18):
                t, u = 0.0, 0.0
                for m in range(size):
                    t += gain[i, m] * pht[j, m]
                    u += gain[j, m] * pht[i, m]
                value = 0.5 * ((pn[i, j] - t) + (pn[j, i] - u))
                pn[i, j] = value
                pn[j, i] = value
        finite = ok
        for i in range(18):
            finite = finite and math.isfinite(xn[i])
            for j in range(18):
                finite = finite and math.isfinite(pn[i, j])
        if finite:
            if matched:
                match_walks(walks[n], before, xn[12:18], walks0, adaptation)
        else:  # restart from the measured pose at rest
            xn[:] = 0.0
            for i in range(3):
                xn[i] = positions[n, i]
            xn[6], xn[7], xn[8] = mroll, mpitch, myaw
            pn[:, :] = p0
            start_walks(walks[n], walks0)
            reinitialisations[n] += 1
    return True


@njit
def ekf_states(x, out):
    """``ExtendedFilterBank.states`` into ``out`` (N, 13): position, velocity, the quaternion of the
    ZYX Euler angles, body rates."""
    for n in range(x.shape[0]):
        for i in range(3):
            out[n, i], out[n, 3 + i], out[n, 10 + i] = x[n, i], x[n, 3 + i], x[n, 9 + i]
        out[n, 6], out[n, 7], out[n, 8], out[n, 9] = quaternion_from_euler(x[n, 6], x[n, 7], x[n, 8])


@njit
def ekf_wrenches(x, out):
    """``ExtendedFilterBank.wrenches`` into ``out`` (N, 6): the force and the body torque turned into
    the world frame, ``[f, R η]``."""
    r = np.empty((3, 3))
    for n in range(x.shape[0]):
        euler_matrix(x[n, 6], x[n, 7], x[n, 8], r)
        for i in range(3):
            out[n, i] = x[n, 12 + i]
            out[n, 3 + i] = r[i, 0] * x[n, 15] + r[i, 1] * x[n, 16] + r[i, 2] * x[n, 17]


@njit
def ekf_estimates(x, states, wrenches):
    """:func:`ekf_states` and :func:`ekf_wrenches` in one call (``ExtendedFilterBank.estimates``)."""
    ekf_states(x, states)
    ekf_wrenches(x, wrenches)


@njit
def ekf_wrench_covariances(x, p, out):
    """``ExtendedFilterBank.wrench_covariances`` into ``out`` (N, 6, 6): the covariance of the force
    and the body torque, the torque rows and columns turned into the world frame (``Rot P Rotᵀ`` with
    ``Rot = diag(I, R)``)."""
    r = np.empty((3, 3))
    for n in range(x.shape[0]):
        euler_matrix(x[n, 6], x[n, 7], x[n, 8], r)
        for i in range(6):
            for j in range(6):
                out[n, i, j] = p[n, 12 + i, 12 + j]
        for i in range(3):  # the force-torque block P_fτ Rᵀ, and its transpose (P is symmetric)
            for j in range(3):
                fr = 0.0
                for k in range(3):
                    fr += p[n, 12 + i, 15 + k] * r[j, k]
                out[n, i, 3 + j], out[n, 3 + j, i] = fr, fr
        for i in range(3):  # the torque block: R P_ττ Rᵀ
            for j in range(3):
                total = 0.0
                for k in range(3):
                    for m in range(3):
                        total += r[i, k] * p[n, 15 + k, 15 + m] * r[j, m]
                out[n, 3 + i, 3 + j] = total

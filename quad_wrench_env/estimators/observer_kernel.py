"""The step of a bank of nonlinear wrench observers: the observer of
:class:`quad_wrench_env.estimators.observer.ObserverBank` (Yüksel et al. 2014, eqs. 9-15), its only
implementation, vehicle by vehicle."""

from __future__ import annotations

import math

import numpy as np

from quad_wrench_env.estimators.ekf_kernel import (
    euler_from_quaternion,
    euler_matrix,
    quaternion_from_euler,
    wrap,
)
from quad_wrench_env.numerics import njit
from quad_wrench_env.numerics.linalg import inputs_finite


@njit
def _kinematics(roll, pitch, out):
    """``T(η)`` with ``ω = T η̇`` (body rates from ZYX Euler-angle rates, Yüksel et al. 2014, Sec. II)
    into ``out``."""
    sr, cr = math.sin(roll), math.cos(roll)
    sp, cp = math.sin(pitch), math.cos(pitch)
    out[0, 0], out[0, 1], out[0, 2] = 1.0, 0.0, -sp
    out[1, 0], out[1, 1], out[1, 2] = 0.0, cr, sr * cp
    out[2, 0], out[2, 1], out[2, 2] = 0.0, -sr, cr * cp


@njit
def _solve3(m, b, out):
    """``out = m⁻¹ b`` for a 3x3 ``m`` (Gaussian elimination with partial pivoting)."""
    a = m.copy()
    x = b.copy()
    for col in range(3):
        pivot = col
        for row in range(col + 1, 3):
            if abs(a[row, col]) > abs(a[pivot, col]):
                pivot = row
        if pivot != col:
            for j in range(3):
                a[col, j], a[pivot, j] = a[pivot, j], a[col, j]
            x[col], x[pivot] = x[pivot], x[col]
        for row in range(col + 1, 3):
            factor = a[row, col] / a[col, col]
            for j in range(col, 3):
                a[row, j] -= factor * a[col, j]
            x[row] -= factor * x[col]
    for row in range(2, -1, -1):
        t = x[row]
        for j in range(row + 1, 3):
            t -= a[row, j] * out[j]
        out[row] = t / a[row, row]


def observer_constants(dt, mass, inertia, gravity, gains) -> np.ndarray:
    """:func:`observer_bank_step`'s constants in one array, in the order it reads them: ``dt``,
    ``mass``, ``inertia`` (3), ``gravity`` and the ``gains`` c_force, c_torque, force decay, velocity
    filter gain, rate filter gain."""
    return np.array((dt, mass, *inertia, gravity, *gains), dtype=float)


@njit
def observer_bank_step(
    positions_state,
    eulers,
    velocities_state,
    euler_rates,
    psi_force,
    psi_torque,
    forces,
    torques_generalised,
    thrusts,
    body_torques,
    positions,
    quaternions,
    velocities,
    body_rates,
    constants,
):
    """One step of every observer, in place, with the constants of :func:`observer_constants`;
    ``velocities`` and ``body_rates`` are (N, 3) where measured, else (0, 3). Returns False,
    touching nothing, when an input is not finite."""
    dt, mass, inertia, gravity = constants[0], constants[1], constants[2:5], constants[5]
    c_force, c_torque, decay, velocity_alpha, rate_alpha = (
        constants[6],
        constants[7],
        constants[8],
        constants[9],
        constants[10],
    )
    count = positions.shape[0]
    with_velocity, with_rates = velocities.shape[0] > 0, body_rates.shape[0] > 0
    if not inputs_finite(thrusts, body_torques, positions, quaternions, velocities, body_rates):
        return False
    kin = np.empty((3, 3))
    kin_dot = np.empty((3, 3))
    j_gen = np.empty((3, 3))
    r = np.empty((3, 3))
    rhs = np.empty(3)
    rate = np.empty(3)
    for n in range(count):
        # -- measurements: velocity and Euler-angle rates, measured or low-passed finite differences --
        roll, pitch, yaw = euler_from_quaternion(
            quaternions[n, 0], quaternions[n, 1], quaternions[n, 2], quaternions[n, 3]
        )
        for i in range(3):
            if with_velocity:
                velocities_state[n, i] = velocities[n, i]
            else:
                raw = (positions[n, i] - positions_state[n, i]) / dt
                velocities_state[n, i] += velocity_alpha * (raw - velocities_state[n, i])
        if with_rates:
            _kinematics(roll, pitch, kin)
            for i in range(3):
                rhs[i] = body_rates[n, i]
            _solve3(kin, rhs, rate)
            for i in range(3):
                euler_rates[n, i] = rate[i]
        else:
            for i, angle in enumerate((roll, pitch, yaw)):
                raw = wrap(angle - eulers[n, i]) / dt
                euler_rates[n, i] += rate_alpha * (raw - euler_rates[n, i])
        for i in range(3):
            positions_state[n, i] = positions[n, i]
        eulers[n, 0], eulers[n, 1], eulers[n, 2] = roll, pitch, yaw
        # -- force block (eq. 13, L = c/m, exact) --
        euler_matrix(roll, pitch, yaw, r)
        for i in range(3):
            drive = -thrusts[n] * r[i, 2] - c_force * velocities_state[n, i]
            if i == 2:
                drive += mass * gravity
            psi_force[n, i] = decay * psi_force[n, i] + (1.0 - decay) * drive
            forces[n, i] = psi_force[n, i] + c_force * velocities_state[n, i]
        # -- torque block (eq. 13, L = c 𝕁⁻¹, backward Euler) --
        _kinematics(roll, pitch, kin)
        sr, cr = math.sin(roll), math.cos(roll)
        sp, cp = math.sin(pitch), math.cos(pitch)
        er0, er1, er2 = euler_rates[n, 0], euler_rates[n, 1], euler_rates[n, 2]
        kin_dot[0, 0], kin_dot[0, 1], kin_dot[0, 2] = 0.0, 0.0, -cp * er1
        kin_dot[1, 0], kin_dot[1, 1], kin_dot[1, 2] = 0.0, -sr * er0, cr * cp * er0 - sr * sp * er1
        kin_dot[2, 0], kin_dot[2, 1], kin_dot[2, 2] = 0.0, -cr * er0, -sr * cp * er0 - cr * sp * er1
        for i in range(3):
            for j in range(3):
                t = 0.0
                for m in range(3):
                    t += kin[m, i] * (inertia[m] * kin[m, j])
                j_gen[i, j] = t
        om = np.empty(3)
        inner = np.empty(3)
        for i in range(3):
            om[i] = kin[i, 0] * er0 + kin[i, 1] * er1 + kin[i, 2] * er2
        for i in range(3):
            inner[i] = inertia[i] * (kin_dot[i, 0] * er0 + kin_dot[i, 1] * er1 + kin_dot[i, 2] * er2)
        j0, j1, j2 = inertia[0] * om[0], inertia[1] * om[1], inertia[2] * om[2]
        inner[0] += om[1] * j2 - om[2] * j1
        inner[1] += om[2] * j0 - om[0] * j2
        inner[2] += om[0] * j1 - om[1] * j0
        gain = c_torque * dt
        for i in range(3):
            coriolis = kin[0, i] * inner[0] + kin[1, i] * inner[1] + kin[2, i] * inner[2]
            applied = (
                kin[0, i] * body_torques[n, 0]
                + kin[1, i] * body_torques[n, 1]
                + kin[2, i] * body_torques[n, 2]
            )
            drive = coriolis - applied - c_torque * euler_rates[n, i]
            rhs[i] = (
                j_gen[i, 0] * psi_torque[n, 0]
                + j_gen[i, 1] * psi_torque[n, 1]
                + j_gen[i, 2] * psi_torque[n, 2]
            ) + gain * drive
        for i in range(3):
            j_gen[i, i] += gain
        _solve3(j_gen, rhs, rate)
        for i in range(3):
            psi_torque[n, i] = rate[i]
            torques_generalised[n, i] = rate[i] + c_torque * euler_rates[n, i]
    return True


@njit
def observer_states(positions, eulers, velocities, euler_rates, out):
    """``ObserverBank.states`` into ``out`` (N, 13): position, velocity, the quaternion of the
    measured ZYX Euler angles, body rates ``T η̇``."""
    kin = np.empty((3, 3))
    for n in range(positions.shape[0]):
        _kinematics(eulers[n, 0], eulers[n, 1], kin)
        for i in range(3):
            out[n, i], out[n, 3 + i] = positions[n, i], velocities[n, i]
            out[n, 10 + i] = (
                kin[i, 0] * euler_rates[n, 0] + kin[i, 1] * euler_rates[n, 1] + kin[i, 2] * euler_rates[n, 2]
            )
        out[n, 6], out[n, 7], out[n, 8], out[n, 9] = quaternion_from_euler(
            eulers[n, 0], eulers[n, 1], eulers[n, 2]
        )


@njit
def observer_wrenches(eulers, forces, torques_generalised, out):
    """``ObserverBank.wrenches`` into ``out`` (N, 6): the force and the body torque ``T⁻ᵀ τ̂_gen``
    turned into the world frame."""
    kin, kin_t, r, body = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty(3)
    for n in range(eulers.shape[0]):
        _kinematics(eulers[n, 0], eulers[n, 1], kin)
        for i in range(3):
            for j in range(3):
                kin_t[i, j] = kin[j, i]
        _solve3(kin_t, torques_generalised[n], body)
        euler_matrix(eulers[n, 0], eulers[n, 1], eulers[n, 2], r)
        for i in range(3):
            out[n, i] = forces[n, i]
            out[n, 3 + i] = r[i, 0] * body[0] + r[i, 1] * body[1] + r[i, 2] * body[2]


@njit
def observer_estimates(
    positions, eulers, velocities, euler_rates, forces, torques_generalised, states, wrenches
):
    """:func:`observer_states` and :func:`observer_wrenches` in one call (``ObserverBank.estimates``)."""
    observer_states(positions, eulers, velocities, euler_rates, states)
    observer_wrenches(eulers, forces, torques_generalised, wrenches)

"""The step of a bank of learned wrench estimators: the features of one physics step's sensor readings
and the gated recurrent unit over them (:class:`quad_wrench_env.estimators.learned.LearnedBank`), their
only implementation, vehicle by vehicle.

Features of a step (:data:`FEATURES`; velocity and body rates only where an onboard state estimator
measures them), from the estimator interface's inputs and the pose measured one step before:

    0-2    (p - p_prev) / T                 the finite-difference velocity (m/s, world)
    3-5    R e_z c_t / m                     the thrust's acceleration (m/s², world)
    6-14   R, row by row                     the measured attitude (body -> world)
    15-17  log(q_prev⁻¹ ⊗ q) / T             the finite-difference body rates (rad/s)
    18-20  τ_m                               the motor torque (N·m, body)
    21-23  v_meas                            the measured velocity (m/s, world)
    24-26  ω_meas                            the measured body rates (rad/s)

The unit steps once per frame of :data:`FRAME_STEPS` physics steps (one policy step of the envs), on
the frame's features side by side, oldest first, standardised: fewer, longer steps than one per
physics step, which a recurrent unit learns more easily; the estimate is updated at each frame's
last step and held between. The recurrent unit is PyTorch's ``GRU`` (Cho et al. 2014): with ``x``
the standardised frame,
``r = σ(W_ir x + b_ir + W_hr h + b_hr)``, ``z = σ(W_iz x + b_iz + W_hz h + b_hz)``,
``n = tanh(W_in x + b_in + r (W_hn h + b_hn))``, ``h' = (1 - z) n + z h``; a linear head reads ``h'``
(:data:`OUTPUTS`). The weights are stored transposed, so that each product runs over its outputs on
SIMD lanes while every sum keeps its order: a vehicle gets the same bits in a bank of any size.
"""

from __future__ import annotations

import math

import numpy as np

from quad_wrench_env.numerics import njit
from quad_wrench_env.numerics.linalg import inputs_finite
from quad_wrench_env.numerics.quaternions import qmul, rotation_entries

FEATURES, MEASURED_FEATURES = 21, 6
"""Features per physics step from the pose and the motor speeds, and those the onboard state estimator
adds."""
FRAME_STEPS = 4
"""Physics steps per step of the recurrent unit (module docstring)."""
OUTPUTS = 18
"""The head's outputs, standardised: force (world, 0-2), external torque in the body frame (3-5), the
log-variances of those six (6-11), velocity (world, 12-14) and body rates (15-17)."""


@njit
def step_features(previous, thrust, body_torque, position, quaternion, velocity, body_rate, dt, mass, out):
    """The features of one vehicle's step (module docstring) into ``out``; ``previous`` holds the
    pose ``[p, q]`` measured one step before; ``velocity`` and ``body_rate`` are empty when not
    measured."""
    w, x, y, z = quaternion[0], quaternion[1], quaternion[2], quaternion[3]
    r = np.empty(9)
    r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8] = rotation_entries(w, x, y, z)
    for i in range(3):
        out[i] = (position[i] - previous[i]) / dt
        out[3 + i] = r[3 * i + 2] * thrust / mass
        out[18 + i] = body_torque[i]
    for i in range(9):
        out[6 + i] = r[i]
    # q_prev⁻¹ ⊗ q (numba 0.6x cannot type a unary minus on an array element here: x (-1) instead)
    dw, dx, dy, dz = qmul(previous[3], previous[4] * -1.0, previous[5] * -1.0, previous[6] * -1.0, w, x, y, z)
    norm = math.sqrt(dx * dx + dy * dy + dz * dz)
    shorter = 1.0 if dw >= 0.0 else -1.0  # the shorter way round
    gain = 2.0 / dt if norm < 1e-12 else 2.0 * shorter * math.atan2(norm, shorter * dw) / (norm * dt)
    out[15], out[16], out[17] = gain * dx, gain * dy, gain * dz
    if velocity.shape[0] > 0:
        for i in range(3):
            out[FEATURES + i] = velocity[i]
            out[FEATURES + 3 + i] = body_rate[i]


@njit
def advance(
    previous, thrusts, body_torques, positions, quaternions, velocities, body_rates, k, dt, mass, out
):
    """The features of row ``k`` of the inputs into ``out`` (:func:`step_features`), then that row's
    pose into ``previous``; ``velocities`` and ``body_rates`` are (0, 3) when not measured."""
    measured = velocities.shape[0] > 0
    empty = np.empty(0)
    step_features(
        previous,
        thrusts[k],
        body_torques[k],
        positions[k],
        quaternions[k],
        velocities[k] if measured else empty,
        body_rates[k] if measured else empty,
        dt,
        mass,
        out,
    )
    previous[:3] = positions[k]
    previous[3:] = quaternions[k]


@njit
def stream_features(thrusts, body_torques, positions, quaternions, velocities, body_rates, start, dt, mass):
    """(T, F) features of one vehicle's recorded stream of T steps (the estimator interface's inputs,
    ``velocities``/``body_rates`` (T, 3) or (0, 3)), its pose at the reset ``start`` = ``[p, q]``."""
    measured = velocities.shape[0] > 0
    out = np.zeros((thrusts.shape[0], FEATURES + (MEASURED_FEATURES if measured else 0)))
    previous = start.copy()
    for k in range(thrusts.shape[0]):
        advance(
            previous,
            thrusts,
            body_torques,
            positions,
            quaternions,
            velocities,
            body_rates,
            k,
            dt,
            mass,
            out[k],
        )
    return out


@njit(inline=True)
def _sigmoid(value):
    return 1.0 / (1.0 + math.exp(-value))


@njit
def gru_step(features, hidden, outputs, weights_in, weights_hidden, bias_in, bias_hidden, head, head_bias):
    """One step of the unit and its head for one vehicle (module docstring): ``features`` (F,)
    standardised, ``hidden`` (H,) updated in place, ``outputs`` (18,) written; the weights transposed,
    ``weights_in`` (F, 3H), ``weights_hidden`` (H, 3H), ``head`` (H, 18)."""
    size = hidden.shape[0]
    gates_in = bias_in.copy()
    for j in range(features.shape[0]):
        xj = features[j]
        for k in range(3 * size):
            gates_in[k] += weights_in[j, k] * xj
    gates_hidden = bias_hidden.copy()
    for j in range(size):
        hj = hidden[j]
        for k in range(3 * size):
            gates_hidden[k] += weights_hidden[j, k] * hj
    for k in range(size):
        reset = _sigmoid(gates_in[k] + gates_hidden[k])
        update = _sigmoid(gates_in[size + k] + gates_hidden[size + k])
        candidate = math.tanh(gates_in[2 * size + k] + reset * gates_hidden[2 * size + k])
        hidden[k] = (1.0 - update) * candidate + update * hidden[k]
    outputs[:] = head_bias
    for j in range(size):
        hj = hidden[j]
        for k in range(outputs.shape[0]):
            outputs[k] += head[j, k] * hj


@njit
def learned_bank_step(
    previous,
    frames,
    filled,
    hidden,
    outputs,
    thrusts,
    body_torques,
    positions,
    quaternions,
    velocities,
    body_rates,
    weights_in,
    weights_hidden,
    bias_in,
    bias_hidden,
    head,
    head_bias,
    feature_mean,
    feature_scale,
    constants,
):
    """One physics step of every estimator, in place: ``previous`` (N, 7) the last measured poses,
    ``frames`` (N, FRAME_STEPS·F) the frame being filled and ``filled`` (N,) its steps so far, ``hidden``
    (N, H), ``outputs`` (N, 18) (updated when a frame is full); ``constants`` = ``[dt, mass]``. Returns
    False, touching nothing, when an input is not finite."""
    if not inputs_finite(thrusts, body_torques, positions, quaternions, velocities, body_rates):
        return False
    dt, mass = constants[0], constants[1]
    width = feature_mean.shape[0] // FRAME_STEPS
    standardised = np.empty(feature_mean.shape[0])
    for n in range(thrusts.shape[0]):
        start = filled[n] * width
        frame = frames[n, start : start + width]
        advance(
            previous[n],
            thrusts,
            body_torques,
            positions,
            quaternions,
            velocities,
            body_rates,
            n,
            dt,
            mass,
            frame,
        )
        filled[n] += 1
        if filled[n] == FRAME_STEPS:
            filled[n] = 0
            for j in range(standardised.shape[0]):
                standardised[j] = (frames[n, j] - feature_mean[j]) / feature_scale[j]
            gru_step(
                standardised,
                hidden[n],
                outputs[n],
                weights_in,
                weights_hidden,
                bias_in,
                bias_hidden,
                head,
                head_bias,
            )
    return True


def stream_frames(features: np.ndarray) -> np.ndarray:
    """(T // FRAME_STEPS, FRAME_STEPS·F) frames of a stream's (T, F) features (as the bank fills them from
    a reset; a last partial frame is dropped)."""
    count = features.shape[0] // FRAME_STEPS
    return features[: count * FRAME_STEPS].reshape(count, FRAME_STEPS * features.shape[1])


@njit
def learned_estimates(previous, outputs, target_scale, states, wrenches):
    """(N, 13) states and (N, 6) world-frame wrenches from the head's standardised ``outputs``: the
    measured pose, the estimated velocity and body rates, the force, and the body-frame torque turned
    into the world frame by the measured attitude."""
    for n in range(previous.shape[0]):
        q = previous[n, 3:]
        r = np.empty(9)
        r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8] = rotation_entries(q[0], q[1], q[2], q[3])
        states[n, :3] = previous[n, :3]
        states[n, 6:10] = q
        for i in range(3):
            states[n, 3 + i] = outputs[n, 12 + i] * target_scale[6 + i]
            states[n, 10 + i] = outputs[n, 15 + i] * target_scale[9 + i]
            wrenches[n, i] = outputs[n, i] * target_scale[i]
        torque = outputs[n, 3:6] * target_scale[3:6]
        for i in range(3):
            wrenches[n, 3 + i] = r[3 * i] * torque[0] + r[3 * i + 1] * torque[1] + r[3 * i + 2] * torque[2]


@njit
def learned_covariances(previous, outputs, target_scale, variance_scale, out):
    """(N, 6, 6) covariance of the world-frame ``[f, τ]``: the head's variances, the force's diagonal in
    the world frame, the torque's turned from the body frame (``R Σ Rᵀ``), each block times its
    ``variance_scale`` (the held-out calibration); no cross terms."""
    out[:] = 0.0
    for n in range(previous.shape[0]):
        q = previous[n, 3:]
        r = np.empty(9)
        r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8] = rotation_entries(q[0], q[1], q[2], q[3])
        for i in range(3):
            out[n, i, i] = math.exp(outputs[n, 6 + i]) * target_scale[i] ** 2 * variance_scale[0]
        body = np.empty(3)
        for i in range(3):
            body[i] = math.exp(outputs[n, 9 + i]) * target_scale[3 + i] ** 2 * variance_scale[1]
        for i in range(3):
            for j in range(3):
                total = 0.0
                for k in range(3):
                    total += r[3 * i + k] * body[k] * r[3 * j + k]
                out[n, 3 + i, 3 + j] = total

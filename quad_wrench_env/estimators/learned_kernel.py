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

Features of a frame's last step, over the last ``2L`` steps for each window ``L`` of :data:`WINDOWS`,
the force that moved the vehicle beyond its thrust and weight (N, world):

    m (Δ²p / (L T)² - Σ_j w_j a_j / L² + g e_z),   Δ²p = p_t - 2 p_{t-L} + p_{t-2L},

with ``a_j`` the thrust's acceleration of step ``j`` (features 3-5) and ``w`` the tent of weights 1..L..1
over the steps ``t-2L+2 .. t``: under the symplectic Euler step (``v' = v + a T``, ``p' = p + v' T``)
the second difference of the positions is exactly ``T²`` times that tent's sum of the accelerations,
so the feature is the external force averaged over the tent (the physics of paper 000's momentum
balance, m v̇ = R e_z c_t + m g + f, over a baseline long enough that the motion capture's noise,
divided by ``(L T)²``, is small). Before ``2L`` steps since the reset, the reset's position and the
first step's thrust stand in for the steps not seen (exact for a vehicle at rest at its trim).

And the **tracker forces**, ``m b̂`` of one steady-state Kalman filter per process noise of
:data:`TRACKER_WALKS`, per axis, on the same balance (an α-β-γ tracker, Kalata 1984): the state
``(p, v, b)`` with ``b`` the external acceleration, predicted by the symplectic Euler step under the
thrust's acceleration, gravity and ``b`` (a random walk of that size per step), corrected by the
measured position with the gains of the discrete Riccati equation for motion-capture noise
:data:`TRACKER_NOISE` (:func:`tracker_gains`). The windows are finite tents, the trackers the optimal
exponential memories of a random-walk force: between them the network chooses the trade-off of lag
and noise that each disturbance needs. Each starts at the reset's position, at rest, its ``b`` the
first step's trim (as the windows).

The unit steps once per frame of :data:`FRAME_STEPS` physics steps (one policy step of the envs), on
the frame's per-step features side by side, oldest first, then its window and tracker forces,
standardised: fewer, longer steps than one per physics step, which a recurrent unit learns more
easily; the estimate is updated at each frame's last step and held between. The recurrent unit is
PyTorch's ``GRU`` (Cho et al. 2014): with ``x`` the standardised frame,
``r = σ(W_ir x + b_ir + W_hr h + b_hr)``, ``z = σ(W_iz x + b_iz + W_hz h + b_hz)``,
``n = tanh(W_in x + b_in + r (W_hn h + b_hn))``, ``h' = (1 - z) n + z h``; a linear head reads ``h'``
(:data:`OUTPUTS`), and two terms add to the force. A linear map of the frame's standardised window and
tracker forces ``x_f`` (a skip connection, ``S x_f``: they pass straight to the force, which a head on
the bounded ``h'`` reads only coarsely). And a mixture of them chosen by the unit: per axis ``i``,
``Σ_j softmax(ℓ_i)_j F_ji`` with ``F_j`` the ``j``-th window or tracker force (N) and ``ℓ_i`` the head's
:data:`LOGITS` for that axis. A fixed map must settle one trade-off of lag and noise for every
flight; the mixture lets the unit pick, from what it has seen, the long average in hover and the
quick tracker in a gust, as a bank of filters with one model per disturbance does (the interacting
multiple model filter, Blom & Bar-Shalom 1988). The per-step features, whose finite differences are
noisy, reach the outputs only through the unit. The weights are stored transposed, so that each
product runs over its outputs on SIMD lanes while every sum keeps its order: a vehicle gets the same
bits in a bank of any size.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import solve_discrete_are

from quad_wrench_env.numerics import njit
from quad_wrench_env.numerics.linalg import inputs_finite
from quad_wrench_env.numerics.quaternions import qmul, rotation_entries
from quad_wrench_env.vehicle import GRAVITY

FEATURES, MEASURED_FEATURES = 21, 6
"""Features per physics step from the pose and the motor speeds, and those the onboard state estimator
adds."""
FRAME_STEPS = 4
"""Physics steps per step of the recurrent unit (module docstring)."""
WINDOWS = (8, 12, 16, 24, 32, 48, 64, 96, 128)
"""Half-baselines ``L`` (physics steps) of the window forces (module docstring)."""
TRAIL = 2 * max(WINDOWS) + 1
"""Steps of position and thrust acceleration each estimator keeps for its window forces."""
TRACKER_WALKS = (0.0005, 0.002, 0.008, 0.03, 0.1)
"""Random walks (m/s² per step) of the trackers' external accelerations: at 200 Hz, 63 % of a step in
0.42, 0.26, 0.16, 0.10 and 0.065 s."""
TRACKER_NOISE = 5e-4
"""Position noise (m) the trackers' gains assume: the motion capture's default (``sensors``)."""
SOURCES = len(WINDOWS) + len(TRACKER_WALKS)
"""The window and tracker forces: each a force vector at the end of a frame."""
FORCES = 3 * SOURCES
"""Their components, the frame's last features, which the skip connection and the mixture read."""


@njit
def frame_width(measured_motion: bool) -> int:
    """Features of one frame: its steps' (27 each with a state estimator's velocity and body rates, else
    21), the window forces and the tracker forces."""
    return FRAME_STEPS * (FEATURES + (MEASURED_FEATURES if measured_motion else 0)) + FORCES


def tracker_gains(dt: float) -> np.ndarray:
    """(len(TRACKER_WALKS), 3) steady-state Kalman gains of the trackers (module docstring) at step
    ``dt``: for ``x = (p, v, b)``, ``F = [[1, T, T²], [0, 1, T], [0, 0, 1]]``, ``H = (1, 0, 0)``, the
    walk on ``b`` and the noise :data:`TRACKER_NOISE`, ``K = P Hᵀ / (H P Hᵀ + r²)`` with ``P`` the
    prior covariance of the discrete algebraic Riccati equation."""
    f = np.array(((1.0, dt, dt * dt), (0.0, 1.0, dt), (0.0, 0.0, 1.0)))
    h = np.array(((1.0, 0.0, 0.0),))
    r = np.array(((TRACKER_NOISE**2,),))
    gains = []
    for walk in TRACKER_WALKS:
        p = solve_discrete_are(f.T, h.T, np.diag((0.0, 0.0, walk**2)), r)
        gains.append((p @ h.T / (h @ p @ h.T + r))[:, 0])
    return np.array(gains)


@njit
def restart_memory(trail, trackers, position):
    """One estimator's ``trail`` (TRAIL, 6) and ``trackers`` (len(TRACKER_WALKS), 3 axes, 3) at a reset
    at ``position``: every step of the trail there, the trackers there at rest; the thrust's
    acceleration and the trackers' ``b`` are set at the first step (module docstring)."""
    trail[:] = 0.0
    trackers[:] = 0.0
    for j in range(trail.shape[0]):
        trail[j, :3] = position
    for j in range(trackers.shape[0]):
        trackers[j, :, 0] = position


OUTPUTS = 18
"""The estimates, standardised: force (world, 0-2), external torque in the body frame (3-5), the
log-variances of those six (6-11), velocity (world, 12-14) and body rates (15-17)."""
LOGITS = 3 * SOURCES
"""The head's further outputs: per axis of the force, one logit per window and tracker force, the
mixture's weights (module docstring)."""


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
def window_forces(trail, seen, dt, mass, out):
    """The window forces (module docstring) into ``out`` (3·len(WINDOWS),) from one estimator's
    ``trail`` (TRAIL, 6) of ``[p, a]`` per step, a ring whose newest row is step ``seen - 1``."""
    for w in range(len(WINDOWS)):
        size = WINDOWS[w]
        newest = (seen - 1) % TRAIL
        middle = (seen - 1 - size) % TRAIL
        oldest = (seen - 1 - 2 * size) % TRAIL
        for i in range(3):
            tent = 0.0
            for back in range(2 * size - 1):  # steps t .. t-2L+2, weights 1 .. L .. 1
                tent += (size - abs(back - (size - 1))) * trail[(seen - 1 - back) % TRAIL, 3 + i]
            second = trail[newest, i] - 2.0 * trail[middle, i] + trail[oldest, i]
            out[3 * w + i] = mass * (second / (size * dt) ** 2 - tent / size**2)
        out[3 * w + 2] += mass * GRAVITY


@njit
def track(trackers, gains, position, acceleration, first, dt):
    """The trackers (module docstring) one step on, in place: predicted under the thrust's
    ``acceleration`` (m/s², world) and gravity, corrected by the measured ``position``; on the ``first``
    step since the reset their ``b`` takes the trim first (a vehicle at rest)."""
    for j in range(trackers.shape[0]):
        for i in range(3):
            drive = acceleration[i] - (GRAVITY if i == 2 else 0.0)
            state = trackers[j, i]
            if first:
                state[2] = -drive
            total = drive + state[2]
            velocity = state[1] + dt * total
            predicted = state[0] + dt * velocity
            innovation = position[i] - predicted
            state[0] = predicted + gains[j, 0] * innovation
            state[1] = velocity + gains[j, 1] * innovation
            state[2] += gains[j, 2] * innovation


@njit
def take_step(
    previous,
    trail,
    trackers,
    gains,
    seen,
    n,
    frame,
    thrusts,
    body_torques,
    positions,
    quaternions,
    velocities,
    body_rates,
    k,
    dt,
    mass,
):
    """Row ``k`` of the inputs into estimator ``n``'s ``frame`` and memory (``previous`` pose, ``trail``,
    ``trackers``, ``seen[n]`` steps since its reset; the trail starts filled with the reset's position,
    the trackers as :func:`restart_memory` leaves them); True when it completed the frame, whose window
    and tracker forces are then written."""
    width = (frame.shape[0] - FORCES) // FRAME_STEPS
    start = (seen[n] % FRAME_STEPS) * width
    step = frame[start : start + width]
    advance(
        previous, thrusts, body_torques, positions, quaternions, velocities, body_rates, k, dt, mass, step
    )
    row = seen[n] % TRAIL
    trail[row, :3] = positions[k]
    if seen[n] == 0:
        for j in range(TRAIL):
            trail[j, 3:] = step[3:6]
    trail[row, 3:] = step[3:6]
    track(trackers, gains, positions[k], step[3:6], seen[n] == 0, dt)
    seen[n] += 1
    if seen[n] % FRAME_STEPS != 0:
        return False
    forces = frame[FRAME_STEPS * width :]
    window_forces(trail, seen[n], dt, mass, forces)
    first = 3 * len(WINDOWS)
    for j in range(trackers.shape[0]):
        for i in range(3):
            forces[first + 3 * j + i] = mass * trackers[j, i, 2]
    return True


@njit
def stream_frames(
    thrusts, body_torques, positions, quaternions, velocities, body_rates, start, dt, mass, gains
):
    """(T // FRAME_STEPS, frame width) frames of one vehicle's recorded stream of T steps (the estimator
    interface's inputs, ``velocities``/``body_rates`` (T, 3) or (0, 3)) as its estimator fills them
    from its reset at the pose ``start`` = ``[p, q]`` (a last partial frame is dropped); ``gains``
    :func:`tracker_gains`."""
    out = np.zeros((thrusts.shape[0] // FRAME_STEPS, frame_width(velocities.shape[0] > 0)))
    previous = start.copy()
    trail = np.empty((TRAIL, 6))
    trackers = np.empty((gains.shape[0], 3, 3))
    restart_memory(trail, trackers, start[:3])
    seen = np.zeros(1, dtype=np.int64)
    frame = np.zeros(out.shape[1])
    for k in range(out.shape[0] * FRAME_STEPS):
        if take_step(
            previous,
            trail,
            trackers,
            gains,
            seen,
            0,
            frame,
            thrusts,
            body_torques,
            positions,
            quaternions,
            velocities,
            body_rates,
            k,
            dt,
            mass,
        ):
            out[k // FRAME_STEPS] = frame
    return out


@njit(inline=True)
def _sigmoid(value):
    return 1.0 / (1.0 + math.exp(-value))


@njit
def gru_step(
    features,
    forces,
    force_scale,
    hidden,
    outputs,
    weights_in,
    weights_hidden,
    bias_in,
    bias_hidden,
    head,
    head_bias,
    skip,
):
    """One step of the unit, its head, the skip connection and the mixture for one vehicle (module
    docstring): ``features`` (F,) standardised, ``forces`` (FORCES,) the frame's window and tracker
    forces in newtons, ``force_scale`` the targets' standardisation (its first three, the force's),
    ``hidden`` (H,) updated in place, ``outputs`` (18,) written; the weights transposed, ``weights_in``
    (F, 3H), ``weights_hidden`` (H, 3H), ``head`` (H, 18 + LOGITS), ``skip`` (S, 3) from the last S
    features to the force."""
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
    read = head_bias.copy()
    for j in range(size):
        hj = hidden[j]
        for k in range(read.shape[0]):
            read[k] += head[j, k] * hj
    outputs[:] = read[:OUTPUTS]
    first = features.shape[0] - skip.shape[0]
    for j in range(skip.shape[0]):
        xj = features[first + j]
        for k in range(skip.shape[1]):
            outputs[k] += skip[j, k] * xj
    for i in range(3):
        logits = read[OUTPUTS + i * SOURCES : OUTPUTS + (i + 1) * SOURCES]
        top = logits.max()
        total, mixed = 0.0, 0.0
        for j in range(SOURCES):
            weight = math.exp(logits[j] - top)
            total += weight
            mixed += weight * forces[3 * j + i]
        outputs[i] += mixed / total / force_scale[i]


@njit
def learned_bank_step(
    previous,
    trail,
    trackers,
    gains,
    seen,
    frames,
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
    skip,
    feature_mean,
    feature_scale,
    target_scale,
    constants,
):
    """One physics step of every estimator, in place: ``previous`` (N, 7) the last measured poses,
    ``trail`` (N, TRAIL, 6), ``trackers`` (N, len(TRACKER_WALKS), 3, 3) and ``seen`` (N,) as
    :func:`take_step` keeps them, ``gains`` :func:`tracker_gains`, ``frames`` (N, frame
    width) the frame being filled, ``hidden`` (N, H), ``outputs`` (N, 18) (updated when a frame is
    full); ``target_scale`` the targets' standardisation (the mixture's force in the outputs' units);
    ``constants`` = ``[dt, mass]``. Returns False, touching nothing, when an input is not finite."""
    if not inputs_finite(thrusts, body_torques, positions, quaternions, velocities, body_rates):
        return False
    dt, mass = constants[0], constants[1]
    standardised = np.empty(feature_mean.shape[0])
    for n in range(thrusts.shape[0]):
        if take_step(
            previous[n],
            trail[n],
            trackers[n],
            gains,
            seen,
            n,
            frames[n],
            thrusts,
            body_torques,
            positions,
            quaternions,
            velocities,
            body_rates,
            n,
            dt,
            mass,
        ):
            for j in range(standardised.shape[0]):
                standardised[j] = (frames[n, j] - feature_mean[j]) / feature_scale[j]
            gru_step(
                standardised,
                frames[n, frames.shape[1] - FORCES :],
                target_scale,
                hidden[n],
                outputs[n],
                weights_in,
                weights_hidden,
                bias_in,
                bias_hidden,
                head,
                head_bias,
                skip,
            )
    return True


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

"""The engine's own arithmetic for N vehicles, compiled: the autopilot (gains and state in
:mod:`quad_wrench_env.autopilot`), the motors (:mod:`quad_wrench_env.rotors`), the body's drag
(:mod:`quad_wrench_env.disturbances.drag`) and the sensors (:mod:`quad_wrench_env.sensors`), vehicle by
vehicle, with no component (wind field, point load,
rotor modifier, task) in it: :mod:`.compose` writes the physics step that calls these kernels and the
components' own between them.

Per-vehicle arrays are views of one flat step buffer whose fields :data:`STEP_FIELDS` declares by name
(the components' states follow them); the parameters are packed in one float array whose parts
:data:`CONSTANT_FIELDS` declares by name (the drag points and the components' numbers follow them).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.lib.stride_tricks import as_strided

from quad_wrench_env.numerics import njit
from quad_wrench_env.numerics.linalg import rows_view
from quad_wrench_env.numerics.quaternions import exp, matrix, qmul
from quad_wrench_env.sensors import quantized_speed

VELOCITY, ATTITUDE, WRENCH, MOTORS = 0, 1, 2, 3


def offsets(fields: tuple[tuple[str, int], ...]) -> dict[str, int]:
    """Start of each named field of a layout of consecutive fields ``(name, width)``."""
    starts, start = {}, 0
    for name, width in fields:
        starts[name] = start
        start += width
    return starts


STEP_FIELDS: tuple[tuple[str, int], ...] = (
    ("time", 1),
    ("position", 3),
    ("quaternion", 4),
    ("velocity", 3),
    ("angular_velocity", 3),
    ("rotation", 9),
    ("body_rates", 3),
    ("forces", 3),
    ("torques", 3),
    ("loads", 6),
    ("thrusts", 1),
    ("body_torques", 3),
    ("measured_position", 3),
    ("measured_quaternion", 4),
    ("motion", 6),
    ("truth", 13),
    ("yaw_setpoint", 1),
    ("velocity_integral", 3),
    ("rate_integral", 3),
    ("speeds", 4),
    ("allocations", 16),
    ("sensed_allocations", 16),
    ("rotor_wrench", 4),
    ("wind_velocity", 3),
)
"""The engine's per-vehicle arrays (widths per vehicle), in the order :func:`step_views` cuts them out
of one flat buffer of ``n`` vehicles (field ``k`` from ``n·start_k``): one array argument instead of
twenty-four, as numba's cost per call grows with the number of array arguments.
The autopilot's and the rotors' state (yaw set-point to allocations) are views the fleet gives them;
the components' own states follow at :data:`STEP_WIDTH`."""

STEP_WIDTH = sum(width for _, width in STEP_FIELDS)
_S = offsets(STEP_FIELDS)
(
    _TIME,
    _POSITION,
    _QUATERNION,
    _VELOCITY,
    _ANGULAR_VELOCITY,
    _ROTATION,
    _BODY_RATES,
    _FORCES,
    _TORQUES,
    _LOADS,
    _THRUSTS,
    _BODY_TORQUES,
    _MEASURED_POSITION,
    _MEASURED_QUATERNION,
    _MOTION,
    _TRUTH,
    _YAW_SETPOINT,
    _VELOCITY_INTEGRAL,
    _RATE_INTEGRAL,
    _SPEEDS,
    _ALLOCATIONS,
    _SENSED_ALLOCATIONS,
    _ROTOR_WRENCH,
    _WIND_VELOCITY,
) = (_S[name] for name, _ in STEP_FIELDS)

CONSTANT_FIELDS: tuple[tuple[str, int], ...] = (
    ("action_type", 1),
    ("scales", 10),
    ("autopilot", 23),
    ("inverse", 16),
    ("motors", 6),
    ("sensing", 7),
    ("dt", 1),
    ("noise_column", 1),
    ("delay_line", 2),
    ("drag_point_count", 1),
)
"""The engine's parameters in the flat constants array, in order (widths): the action type (an index
into the action types) and its scales, the autopilot's gains (``Autopilot.kernel_parameters``), its
mixer's inverse, the motors (lag up and down, speed limits, rotor drag, body drag coefficient), the
sensors (speed levels, speed step, position, attitude, velocity and body-rate noise, whether
velocity and body rates are measured), the physics step, the first column of
the sensors' normal draws, the motion capture's delay line (its latency L in physics steps and where
its ``1 + 7 L`` floats per vehicle start in the step buffer, :func:`delay_line_rows`) and the number P of
drag points; then the drag points (P, 3) and the components' numbers (:func:`component_parameters`)."""

CONSTANT_WIDTH = sum(width for _, width in CONSTANT_FIELDS)
_C = offsets(CONSTANT_FIELDS)
_SCALES, _AUTOPILOT, _INVERSE, _MOTORS, _SENSING, _DT, _NOISE_COLUMN, _DELAY, _POINT_COUNT = (
    _C["scales"],
    _C["autopilot"],
    _C["inverse"],
    _C["motors"],
    _C["sensing"],
    _C["dt"],
    _C["noise_column"],
    _C["delay_line"],
    _C["drag_point_count"],
)


@njit(inline=True)
def rows(buffer, start, n, width):
    """Field ``start`` (a :data:`STEP_FIELDS` offset) of ``n`` vehicles, (n, width) rows."""
    return rows_view(buffer, start * n, n, width)


@njit(inline=True)
def matrices(buffer, start, n, size):
    """Field ``start`` of ``n`` vehicles as (n, size, size) row-major matrices."""
    return as_strided(
        buffer[start * n : (start + size * size) * n],
        shape=(n, size, size),
        strides=(8 * size * size, 8 * size, 8),
    )


@njit(inline=True)
def point_rows(buffer, start, n, count):
    """(n, count, 3) points per vehicle from float ``start`` (per vehicle) of the buffer on."""
    return as_strided(
        buffer[start * n : (start + 3 * count) * n], shape=(n, count, 3), strides=(24 * count, 24, 8)
    )


_MATRICES = {"rotation": (3, 3), "allocations": (4, 4), "sensed_allocations": (4, 4)}
"""The fields that are square matrices per vehicle (the others are rows, or scalars when 1 wide)."""


def step_views(buffer: np.ndarray, n: int) -> tuple[np.ndarray, ...]:
    """The :data:`STEP_FIELDS` of ``n`` vehicles as views of the flat ``buffer``, in their order, cut
    by the declaration alone: time (n,), position (n, 3), quaternion (n, 4), velocity, angular
    velocity (n, 3), rotation (n, 3, 3), body rates (n, 3); the world-frame forces and torques PyBullet
    applies and the external loads (n, 6); the measured thrusts (n,) and body torques (n, 3), the
    motion-capture position (n, 3) and quaternion (n, 4), velocity and body rates (n, 6) and the truth
    (n, 13); the autopilot's yaw setpoints (n,) and velocity and rate integrals (n, 3), the true rotor
    speeds (n, 4) and allocation matrices (n, 4, 4), the allocations the estimators' thrust and torque
    come from (n, 4, 4: the nominal mixer, or a calibrated vehicle's), the rotors' ``[c_t, τ]`` (n, 4)
    and the air velocity at the centre of mass (n, 3). The kernels cut the fields they use with
    :func:`rows` and :func:`matrices` at the same offsets."""
    if buffer.shape[0] < n * STEP_WIDTH:
        raise ValueError("the step buffer must hold at least n * STEP_WIDTH floats")
    views = []
    for name, width in STEP_FIELDS:
        part = buffer[_S[name] * n : (_S[name] + width) * n]
        views.append(part if width == 1 else part.reshape(n, *_MATRICES.get(name, (width,))))
    return tuple(views)


def physics_constants(parts: dict[str, np.ndarray | float], drag_points: np.ndarray) -> np.ndarray:
    """The engine's constants (:data:`CONSTANT_FIELDS`, each part by name) and the (P, 3) drag points,
    packed in one float array."""
    missing = sorted({name for name, _ in CONSTANT_FIELDS} - {"drag_point_count"} - set(parts))
    if missing:
        raise ValueError(f"physics constants {missing} are missing")
    packed = []
    for name, size in CONSTANT_FIELDS:
        part = np.ravel(len(drag_points) if name == "drag_point_count" else parts[name]).astype(float)
        if part.size != size:
            raise ValueError(f"{name} has {part.size} numbers; the kernels read {size}")
        packed.append(part)
    return np.concatenate((*packed, np.ravel(drag_points).astype(float)))


def component_parameters(constants: np.ndarray, parameters: list[np.ndarray]) -> np.ndarray:
    """``constants`` followed by a header of the components' start offsets (one per component and the
    end) and each component's numbers: :func:`component_slice` cuts component ``k``'s out."""
    header = len(constants) + len(parameters) + 1
    starts = header + np.concatenate(([0], np.cumsum([len(p) for p in parameters])))
    return np.concatenate((constants, starts.astype(float), *[np.ravel(p).astype(float) for p in parameters]))


@njit(inline=True)
def component_slice(constants, k):
    """Component ``k``'s numbers in constants packed by :func:`component_parameters`."""
    header = CONSTANT_WIDTH + 3 * int(constants[_POINT_COUNT])
    return constants[int(constants[header + k]) : int(constants[header + k + 1])]


@njit(inline=True)
def time_step(constants):
    """The physics step (s)."""
    return constants[_DT]


@njit(inline=True)
def drag_points(constants):
    """(P, 3) body-frame drag points (rotor hubs first)."""
    return rows_view(constants, CONSTANT_WIDTH, int(constants[_POINT_COUNT]), 3)


@njit
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit
def _mix(thrust, t0, t1, t2, inverse, w2_min, w2_max, out, without):
    """Rotor speeds into ``out`` for ``[c_t, τ]``, yaw given up first (``Autopilot._mix``); returns
    whether the mixer saturated (``without``: 4 floats of scratch space)."""
    scale = 1.0
    for i in range(4):
        without[i] = inverse[i, 0] * thrust + inverse[i, 1] * t0 + inverse[i, 2] * t1
        d = inverse[i, 3] * t2
        total = without[i] + d
        if d > 0.0 and total > w2_max:
            scale = min(scale, max(0.0, (w2_max - without[i]) / d))
        elif d < 0.0 and total < w2_min:
            scale = min(scale, max(0.0, (w2_min - without[i]) / d))
    saturated = scale < 1.0
    for i in range(4):
        squared = without[i] + scale * (inverse[i, 3] * t2)
        clipped = min(max(squared, w2_min), w2_max)
        saturated = saturated or clipped != squared
        out[i] = math.sqrt(clipped)
    return saturated


@njit
def controls(actions, buffer, saturated, constants):
    """The autopilot (every action type) and the motors of every vehicle from (N, 4) ``actions``:
    steps the autopilot's and the rotors' state in ``buffer`` (:func:`step_views`) and fills its
    ``rotor_wrench`` (the true rotors' ``[c_t, τ]``, body frame); ``saturated`` (N,) are the mixer's
    flags."""
    c = actions.shape[0]
    velocity, angular_velocity = rows(buffer, _VELOCITY, c, 3), rows(buffer, _ANGULAR_VELOCITY, c, 3)
    rotation, yaw_setpoint = (
        matrices(buffer, _ROTATION, c, 3),
        buffer[_YAW_SETPOINT * c : (_YAW_SETPOINT + 1) * c],
    )
    velocity_integral, rate_integral = (
        rows(buffer, _VELOCITY_INTEGRAL, c, 3),
        rows(buffer, _RATE_INTEGRAL, c, 3),
    )
    speeds, allocations = rows(buffer, _SPEEDS, c, 4), matrices(buffer, _ALLOCATIONS, c, 4)
    rotor_wrench = rows(buffer, _ROTOR_WRENCH, c, 4)
    action_type, scales, autopilot = (
        int(constants[0]),
        constants[_SCALES : _SCALES + 10],
        constants[_AUTOPILOT:],
    )
    inverse, motors = rows_view(constants, _INVERSE, 4, 4), constants[_MOTORS : _MOTORS + 6]
    vp, vi = autopilot[0:3], autopilot[3:6]
    setpoint_weight, tan_max_tilt = autopilot[6], autopilot[7]
    att_p, max_rate, max_yaw_error = autopilot[8:11], autopilot[11], autopilot[12]
    rate_p, rate_i, mass, gravity, dt = (
        autopilot[13],
        autopilot[14],
        autopilot[15],
        autopilot[16],
        autopilot[17],
    )
    w2_min, w2_max, inertia = autopilot[18], autopilot[19], autopilot[20:23]
    alpha_up, alpha_down, min_speed, max_speed = motors[0], motors[1], motors[2], motors[3]
    work = np.empty(30)  # one allocation, cut into views (each allocation costs as much as a view)
    command, scratch, tv, rates = work[0:4], work[4:8], work[8:11], work[11:14]
    om, torque, desired = work[14:17], work[17:20], rows_view(work, 20, 3, 3)
    for n in range(actions.shape[0]):
        r = rotation[n]
        a = actions[n]
        # -- autopilot: the velocity, attitude, wrench or motors action through the cascade --
        if action_type == MOTORS:
            for i in range(4):
                command[i] = 0.5 * (a[i] + 1.0) * scales[9]
        elif action_type == WRENCH:
            saturated[n] = _mix(
                (1.0 + a[0]) * scales[5],
                a[1] * scales[6],
                a[2] * scales[7],
                a[3] * scales[8],
                inverse,
                w2_min,
                w2_max,
                command,
                scratch,
            )
        else:
            if action_type == VELOCITY:
                for i in range(3):
                    v_cmd = a[i] * scales[i]
                    error = v_cmd - velocity[n, i]
                    proportional = setpoint_weight * v_cmd - velocity[n, i]
                    accel = vp[i] * proportional + vi[i] * velocity_integral[n, i]
                    tv[i] = mass * (accel + (gravity if i == 2 else 0.0))
                    command[i] = error  # the velocity error, until the integrator has used it
                yaw_rate = a[3] * scales[3]
                vertical = max(tv[2], 0.1 * mass * gravity)
                max_horizontal = vertical * tan_max_tilt
                norm = math.hypot(tv[0], tv[1])
                limited = norm > max_horizontal or vertical != tv[2]
                if norm > max_horizontal:
                    tv[0] *= max_horizontal / norm
                    tv[1] *= max_horizontal / norm
                tv[2] = vertical
                if not (limited or saturated[n]):
                    for i in range(3):
                        velocity_integral[n, i] += command[i] * dt
            else:
                yaw_rate = a[2] * scales[3]
            yaw = math.atan2(r[1, 0], r[0, 0])
            ahead = (yaw_setpoint[n] + yaw_rate * dt - yaw + math.pi) % (2.0 * math.pi) - math.pi
            yaw_setpoint[n] = yaw + min(max_yaw_error, max(-max_yaw_error, ahead))
            if action_type == VELOCITY:
                norm = math.sqrt(tv[0] * tv[0] + tv[1] * tv[1] + tv[2] * tv[2])
                z0, z1, z2 = tv[0] / norm, tv[1] / norm, tv[2] / norm
                y0, y1, y2 = _cross(z0, z1, z2, math.cos(yaw_setpoint[n]), math.sin(yaw_setpoint[n]), 0.0)
                norm = math.sqrt(y0 * y0 + y1 * y1 + y2 * y2)
                y0, y1, y2 = y0 / norm, y1 / norm, y2 / norm
                x0, x1, x2 = _cross(y0, y1, y2, z0, z1, z2)
                desired[0, 0], desired[1, 0], desired[2, 0] = x0, x1, x2
                desired[0, 1], desired[1, 1], desired[2, 1] = y0, y1, y2
                desired[0, 2], desired[1, 2], desired[2, 2] = z0, z1, z2
                thrust = tv[0] * r[0, 2] + tv[1] * r[1, 2] + tv[2] * r[2, 2]
            else:
                roll, pitch, yaw_d = a[0] * scales[4], a[1] * scales[4], yaw_setpoint[n]
                cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
                cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
                cy, sy = math.cos(0.5 * yaw_d), math.sin(0.5 * yaw_d)
                matrix(
                    cr * cp * cy + sr * sp * sy,
                    sr * cp * cy - cr * sp * sy,
                    cr * sp * cy + sr * cp * sy,
                    cr * cp * sy - sr * sp * cy,
                    desired,
                )
                thrust = (1.0 + a[3]) * scales[5]
            # attitude loop: e = R_dᵀR - RᵀR_d
            for k, (i, j) in enumerate(((2, 1), (0, 2), (1, 0))):
                dtr, rtd = 0.0, 0.0
                for m in range(3):
                    dtr += desired[m, i] * r[m, j]
                    rtd += r[m, i] * desired[m, j]
                rates[k] = min(max_rate, max(-max_rate, -att_p[k] * (0.5 * (dtr - rtd))))
            # rate loop
            for i in range(3):
                om[i] = (
                    r[0, i] * angular_velocity[n, 0]
                    + r[1, i] * angular_velocity[n, 1]
                    + r[2, i] * angular_velocity[n, 2]
                )
            for i in range(3):
                error = rates[i] - om[i]
                if not saturated[n]:
                    rate_integral[n, i] += error * dt
                torque[i] = inertia[i] * (rate_p * error + rate_i * rate_integral[n, i])
            c0, c1, c2 = _cross(
                om[0], om[1], om[2], inertia[0] * om[0], inertia[1] * om[1], inertia[2] * om[2]
            )
            saturated[n] = _mix(
                thrust,
                torque[0] + c0,
                torque[1] + c1,
                torque[2] + c2,
                inverse,
                w2_min,
                w2_max,
                command,
                scratch,
            )
        # -- motors: the lag towards the command, then the true rotors' [c_t, tau] --
        for i in range(4):
            target = min(max(command[i], min_speed), max_speed)
            error = target - speeds[n, i]
            speeds[n, i] += (alpha_up if error >= 0.0 else alpha_down) * error
        for k in range(4):
            rotor_wrench[n, k] = 0.0
            for i in range(4):
                rotor_wrench[n, k] += allocations[n, k, i] * (speeds[n, i] * speeds[n, i])


@njit
def point_offsets(buffer, constants, n, offsets, points):
    """World offsets (n, P, 3) of the drag points from the centres of mass, and the points (n, P, 3),
    into ``offsets`` and ``points``."""
    position, rotation = rows(buffer, _POSITION, n, 3), matrices(buffer, _ROTATION, n, 3)
    body = drag_points(constants)
    for m in range(n):
        r = rotation[m]
        for p in range(body.shape[0]):
            for i in range(3):
                offsets[m, p, i] = r[i, 0] * body[p, 0] + r[i, 1] * body[p, 1] + r[i, 2] * body[p, 2]
                points[m, p, i] = position[m, i] + offsets[m, p, i]


@njit
def drag_loads(buffer, constants, offsets, air):
    """The ``loads`` of ``buffer`` from quadratic body drag at every drag point and linear rotor drag at
    the hubs (the first four points; ``QuadraticDrag``, ``Rotors.drag_forces``) in the air velocities
    ``air`` (N, P, 3) at the world ``offsets`` (N, P, 3)."""
    n = offsets.shape[0]
    velocity, angular_velocity = rows(buffer, _VELOCITY, n, 3), rows(buffer, _ANGULAR_VELOCITY, n, 3)
    rotation, loads, speeds = (
        matrices(buffer, _ROTATION, n, 3),
        rows(buffer, _LOADS, n, 6),
        rows(buffer, _SPEEDS, n, 4),
    )
    body_drag, rotor_drag = constants[_MOTORS + 5], constants[_MOTORS + 4]
    for m in range(n):
        r = rotation[m]
        f0 = f1 = f2 = t0 = t1 = t2 = 0.0
        for p in range(offsets.shape[1]):
            o0, o1, o2 = offsets[m, p, 0], offsets[m, p, 1], offsets[m, p, 2]
            w0, w1, w2 = _cross(
                angular_velocity[m, 0], angular_velocity[m, 1], angular_velocity[m, 2], o0, o1, o2
            )
            rel0 = air[m, p, 0] - (velocity[m, 0] + w0)
            rel1 = air[m, p, 1] - (velocity[m, 1] + w1)
            rel2 = air[m, p, 2] - (velocity[m, 2] + w2)
            magnitude = math.sqrt(rel0 * rel0 + rel1 * rel1 + rel2 * rel2)
            g0, g1, g2 = (
                body_drag * magnitude * rel0,
                body_drag * magnitude * rel1,
                body_drag * magnitude * rel2,
            )
            if p < 4:  # rotor drag at the hubs (Rotors.drag_forces), airspeed = -relative air
                along = -(rel0 * r[0, 2] + rel1 * r[1, 2] + rel2 * r[2, 2])
                k_d = rotor_drag * speeds[m, p]
                g0 -= k_d * (-rel0 - along * r[0, 2])
                g1 -= k_d * (-rel1 - along * r[1, 2])
                g2 -= k_d * (-rel2 - along * r[2, 2])
            c0, c1, c2 = _cross(o0, o1, o2, g0, g1, g2)
            f0, f1, f2, t0, t1, t2 = f0 + g0, f1 + g1, f2 + g2, t0 + c0, t1 + c1, t2 + c2
        loads[m, 0], loads[m, 1], loads[m, 2], loads[m, 3], loads[m, 4], loads[m, 5] = f0, f1, f2, t0, t1, t2


@njit
def rotor_thrusts(buffer, n, out):
    """(n, 4) true thrust ``k_i·Ω_i²`` of each rotor into ``out``."""
    speeds, allocations = rows(buffer, _SPEEDS, n, 4), matrices(buffer, _ALLOCATIONS, n, 4)
    for m in range(n):
        for i in range(4):
            out[m, i] = allocations[m, 0, i] * (speeds[m, i] * speeds[m, i])


@njit
def added_thrust_loads(buffer, offsets, added):
    """Thrust ``added`` (N, 4) by the rotor modifiers, along body z at the hubs (the first four of the
    world ``offsets``), into the ``loads`` of ``buffer``."""
    n = added.shape[0]
    rotation, loads = matrices(buffer, _ROTATION, n, 3), rows(buffer, _LOADS, n, 6)
    for m in range(n):
        r = rotation[m]
        for i in range(4):
            g0, g1, g2 = added[m, i] * r[0, 2], added[m, i] * r[1, 2], added[m, i] * r[2, 2]
            c0, c1, c2 = _cross(offsets[m, i, 0], offsets[m, i, 1], offsets[m, i, 2], g0, g1, g2)
            loads[m, 0] += g0
            loads[m, 1] += g1
            loads[m, 2] += g2
            loads[m, 3] += c0
            loads[m, 4] += c1
            loads[m, 5] += c2


@njit
def apply_loads(buffer, n):
    """The world-frame ``forces`` and ``torques`` PyBullet applies: the rotors' thrust along body z and
    torque, plus the external ``loads``."""
    rotation, loads, rotor_wrench = (
        matrices(buffer, _ROTATION, n, 3),
        rows(buffer, _LOADS, n, 6),
        rows(buffer, _ROTOR_WRENCH, n, 4),
    )
    forces, torques = rows(buffer, _FORCES, n, 3), rows(buffer, _TORQUES, n, 3)
    for m in range(n):
        r = rotation[m]
        for i in range(3):
            forces[m, i] = r[i, 2] * rotor_wrench[m, 0] + loads[m, i]
            torques[m, i] = (
                r[i, 0] * rotor_wrench[m, 1] + r[i, 1] * rotor_wrench[m, 2] + r[i, 2] * rotor_wrench[m, 3]
            ) + loads[m, 3 + i]


@njit
def read_state(flat, buffer, constants):
    """After PyBullet's step, into ``buffer``: the true states from its (N, 13) rows one after another in
    ``flat`` (``World.read_flat``), time on by one step (``RigidBodyState.from_pybullet``)."""
    n = flat.shape[0] // 13
    time, position, quaternion = (
        buffer[_TIME * n : (_TIME + 1) * n],
        rows(buffer, _POSITION, n, 3),
        rows(buffer, _QUATERNION, n, 4),
    )
    velocity, angular_velocity = rows(buffer, _VELOCITY, n, 3), rows(buffer, _ANGULAR_VELOCITY, n, 3)
    rotation, body_rates = matrices(buffer, _ROTATION, n, 3), rows(buffer, _BODY_RATES, n, 3)
    raw = rows_view(flat, 0, n, 13)
    dt = constants[_DT]
    for m in range(n):
        qw, qx, qy, qz = raw[m, 6], raw[m, 3], raw[m, 4], raw[m, 5]
        quaternion[m, 0], quaternion[m, 1], quaternion[m, 2], quaternion[m, 3] = qw, qx, qy, qz
        r = rotation[m]
        matrix(qw, qx, qy, qz, r)
        for i in range(3):
            position[m, i] = raw[m, i]
            velocity[m, i] = raw[m, 7 + i]
            angular_velocity[m, i] = raw[m, 10 + i]
        for i in range(3):
            body_rates[m, i] = r[0, i] * raw[m, 10] + r[1, i] * raw[m, 11] + r[2, i] * raw[m, 12]
        time[m] += dt


@njit
def take_normals(noise_buffer, noise_cursor, out):
    """(N, width) standard normal draws of this physics step into ``out``, each vehicle's next row of
    its block (``NoiseBlocks``); the cursors move on by one."""
    for m in range(noise_buffer.shape[0]):
        out[m] = noise_buffer[m, noise_cursor[m]]
        noise_cursor[m] += 1


def delay_line_width(latency: int) -> int:
    """Floats per vehicle of the motion capture's delay line: the slot written next, then ``latency``
    poses ``[position (3), quaternion (4)]`` (:func:`sense` reads and overwrites the oldest)."""
    return 1 + 7 * latency if latency else 0


@njit(inline=True)
def delay_line_rows(buffer, constants, n):
    """The (n, 1 + 7 L) delay lines (L = latency, at least one column wide where L = 0 and unused)."""
    latency = int(constants[_DELAY])
    return rows(buffer, int(constants[_DELAY + 1]), n, 1 + 7 * latency), latency


@njit
def sense(buffer, normals, constants):
    """What the estimators see, into ``buffer``: the quantized motor speeds (:func:`quantized_speed`)
    through each vehicle's ``sensed_allocations`` (the nominal mixer, or a calibrated vehicle's) into
    ``thrusts`` and ``body_torques``; the noisy pose (``MotionCapture``)
    into ``measured_position`` and ``measured_quaternion`` and, with an onboard state estimator, noisy
    velocity and body rates into ``motion``; the true position, velocity, quaternion and body rates
    into ``truth``. The sensors' draws are the columns of ``normals`` from ``noise_column`` on. With a
    latency of L physics steps the pose measured is the one L steps old: each vehicle's delay line
    hands out its oldest pose and keeps the current one in its place (McKinnon & Schoellig 2016,
    Sec. II-B, motion capture; ``docs/physics.md``, "Sensors")."""
    n = normals.shape[0]
    position, quaternion, velocity = (
        rows(buffer, _POSITION, n, 3),
        rows(buffer, _QUATERNION, n, 4),
        rows(buffer, _VELOCITY, n, 3),
    )
    body_rates, speeds, truth = (
        rows(buffer, _BODY_RATES, n, 3),
        rows(buffer, _SPEEDS, n, 4),
        rows(buffer, _TRUTH, n, 13),
    )
    thrusts, body_torques = buffer[_THRUSTS * n : (_THRUSTS + 1) * n], rows(buffer, _BODY_TORQUES, n, 3)
    measured_position, measured_quaternion = (
        rows(buffer, _MEASURED_POSITION, n, 3),
        rows(buffer, _MEASURED_QUATERNION, n, 4),
    )
    motion = rows(buffer, _MOTION, n, 6)
    sensing = constants[_SENSING : _SENSING + 7]
    sensed_allocations = matrices(buffer, _SENSED_ALLOCATIONS, n, 4)
    levels, step, position_noise, attitude_noise = sensing[0], sensing[1], sensing[2], sensing[3]
    column = int(constants[_NOISE_COLUMN])
    delay, latency = delay_line_rows(buffer, constants, n)
    body, pose = np.empty(4), np.empty(7)
    for m in range(n):
        draws = normals[m, column:]
        body[:] = 0.0
        for i in range(4):
            quantized = quantized_speed(speeds[m, i], levels, step)
            for k in range(4):
                body[k] += sensed_allocations[m, k, i] * (quantized * quantized)
        thrusts[m] = body[0]
        body_torques[m, 0], body_torques[m, 1], body_torques[m, 2] = body[1], body[2], body[3]
        for i in range(3):
            pose[i] = position[m, i]
        for i in range(4):
            pose[3 + i] = quaternion[m, i]
        if latency:
            line = delay[m]
            slot = 1 + 7 * int(line[0])
            for i in range(7):
                pose[i], line[slot + i] = line[slot + i], pose[i]
            line[0] = (line[0] + 1.0) % latency
        for i in range(3):
            measured_position[m, i] = pose[i] + position_noise * draws[i]
        ew, ex, ey, ez = exp(attitude_noise * draws[3], attitude_noise * draws[4], attitude_noise * draws[5])
        qw, qx, qy, qz = pose[3], pose[4], pose[5], pose[6]
        mw, mx, my, mz = qmul(qw, qx, qy, qz, ew, ex, ey, ez)
        norm = math.sqrt(mw * mw + mx * mx + my * my + mz * mz)
        q = measured_quaternion[m]
        q[0], q[1], q[2], q[3] = mw / norm, mx / norm, my / norm, mz / norm
        if sensing[6] > 0.0:
            for i in range(3):
                motion[m, i] = velocity[m, i] + sensing[4] * draws[6 + i]
                motion[m, 3 + i] = body_rates[m, i] + sensing[5] * draws[9 + i]
        for i in range(3):
            truth[m, i] = position[m, i]
            truth[m, 3 + i] = velocity[m, i]
            truth[m, 10 + i] = body_rates[m, i]
        for i in range(4):
            truth[m, 6 + i] = quaternion[m, i]


@njit
def termination_codes(position, rotation, limits, out):
    """``Fleet.terminations`` into ``out``, but for contacts: 1 crash (below ``limits[0]``), 2 flip
    (``R[2, 2]`` below ``limits[1]``), 3 out of the arena ``limits[2:6]`` (x_min, x_max, y half width,
    z_max), else 0. Returns whether any vehicle is below ``limits[6]`` (``World.clear_height``), low
    enough to touch a surface that ends its episode: only then need its contacts be asked for."""
    near = False
    for n in range(position.shape[0]):
        x, y, z = position[n, 0], position[n, 1], position[n, 2]
        near = near or z < limits[6]
        if z < limits[0]:
            out[n] = 1
        elif rotation[n, 2, 2] < limits[1]:
            out[n] = 2
        elif x < limits[2] or x > limits[3] or abs(y) > limits[4] or z > limits[5]:
            out[n] = 3
        else:
            out[n] = 0
    return near


SENSOR_READING_WIDTH = 13
"""Numbers of one physics step's sensor reading in the observation's ``sensors`` block: the four motor
speeds, the position, the attitude's six; :data:`MOTION_READING_WIDTH` more with an onboard state
estimator."""
MOTION_READING_WIDTH = 6


@njit
def record_sensor_readings(buffer, constants, frames):
    """Each vehicle's last ``K`` sensor readings ``frames`` (N, K, width), newest first, moved one physics
    step on: the readings of the step just sensed (:func:`sense`, what the estimators are handed) go
    first. A reading: the motor speeds as reported (:func:`quantized_speed`) over the top reported speed,
    the measured position, the measured attitude as the first two columns of its rotation matrix (the
    ``attitude`` block's form) and, with an onboard state estimator (``width`` 19), the measured velocity
    and body rates."""
    n, depth = frames.shape[0], frames.shape[1]
    speeds, motion = rows(buffer, _SPEEDS, n, 4), rows(buffer, _MOTION, n, 6)
    position, quaternion = rows(buffer, _MEASURED_POSITION, n, 3), rows(buffer, _MEASURED_QUATERNION, n, 4)
    levels, step = constants[_SENSING], constants[_SENSING + 1]
    top = levels * step
    r = np.empty((3, 3))
    for m in range(n):
        for k in range(depth - 1, 0, -1):
            frames[m, k, :] = frames[m, k - 1, :]
        row = frames[m, 0]
        for i in range(4):
            row[i] = quantized_speed(speeds[m, i], levels, step) / top
        q = quaternion[m]
        matrix(q[0], q[1], q[2], q[3], r)
        for i in range(3):
            row[4 + i] = position[m, i]
            row[7 + i] = r[i, 0]
            row[10 + i] = r[i, 1]
        for i in range(frames.shape[2] - SENSOR_READING_WIDTH):
            row[SENSOR_READING_WIDTH + i] = motion[m, i]


@njit
def assemble_observations(states, wrenches, last_actions, observe_wrench, starts, out):
    """The engine's observation blocks into ``out`` (N, width, float32), each from its column in
    ``starts`` (``ObservationLayout.kernel_starts``: position, velocity, attitude, body rates, force,
    torque, last action): from the states (N, 13) the position, velocity, the first two columns of the
    rotation matrix of the (normalised) quaternion and the body rates; the wrenches (N, 6) times
    ``observe_wrench`` (1 or 0) and the last actions (N, 4)."""
    r = np.empty((3, 3))
    p, v, a, w, f, t, u = starts[0], starts[1], starts[2], starts[3], starts[4], starts[5], starts[6]
    for n in range(states.shape[0]):
        s = states[n]
        norm = math.sqrt(s[6] * s[6] + s[7] * s[7] + s[8] * s[8] + s[9] * s[9])
        matrix(s[6] / norm, s[7] / norm, s[8] / norm, s[9] / norm, r)
        for i in range(3):
            out[n, p + i] = s[i]
            out[n, v + i] = s[3 + i]
            out[n, a + i] = r[i, 0]
            out[n, a + 3 + i] = r[i, 1]
            out[n, w + i] = s[10 + i]
            out[n, f + i] = wrenches[n, i] * observe_wrench
            out[n, t + i] = wrenches[n, 3 + i] * observe_wrench
        for i in range(4):
            out[n, u + i] = last_actions[n, i]

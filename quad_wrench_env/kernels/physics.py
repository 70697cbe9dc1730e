"""One physics step of N vehicles, compiled: the arithmetic of the numpy reference in
:mod:`quad_wrench_env.autopilot`, :mod:`quad_wrench_env.rotors`, :mod:`quad_wrench_env.disturbances`
and :mod:`quad_wrench_env.sensors`, vehicle by vehicle.

``before_world_step`` runs the autopilot (every action type), the motors and the external loads
(fan jet at every drag point, quadratic and rotor drag, payload, scheduled wrench) and returns what
the world applies; ``after_world_step`` advances the turbulence and measures what the estimators see.
Parameters come packed in float arrays whose layouts :class:`quad_wrench_env.envs.compiled_step.
CompiledStep` builds; they are documented there.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.lib.stride_tricks import as_strided

from quad_wrench_env.kernels import njit
from quad_wrench_env.kernels.linalg import rows_view
from quad_wrench_env.kernels.quaternions import exp, matrix, qmul

VELOCITY, ATTITUDE, WRENCH, MOTORS = 0, 1, 2, 3

STEP_FIELDS: tuple[tuple[str, int], ...] = (
    ("time", 1), ("position", 3), ("quaternion", 4), ("velocity", 3), ("angular_velocity", 3),
    ("rotation", 9), ("body_rates", 3), ("forces", 3), ("torques", 3), ("loads", 6), ("thrusts", 1),
    ("body_torques", 3), ("measured_position", 3), ("measured_quaternion", 4), ("motion", 6), ("truth", 13),
    ("yaw_setpoint", 1), ("velocity_integral", 3), ("rate_integral", 3), ("speeds", 4), ("allocations", 16),
    ("fan_noise", 3),
)  # fmt: skip
"""The per-vehicle arrays the kernels read and write, in the order :func:`step_views` cuts them out of
one flat buffer (widths per vehicle): one array argument instead of twenty-two, as numba's cost per
call grows with the number of array arguments (about 35 ns each). The last six are the components'
state (autopilot, rotors, fan turbulence), which the compiled step makes views of this buffer."""

STEP_WIDTH = sum(width for _, width in STEP_FIELDS)


@njit(inline=True)
def step_views(buffer, n):
    """The :data:`STEP_FIELDS` of ``n`` vehicles as views of the flat ``buffer`` (``n * STEP_WIDTH``
    floats): time (n,), position (n, 3), quaternion (n, 4), velocity, angular velocity (n, 3),
    rotation (n, 3, 3), body rates (n, 3); the world-frame forces and torques PyBullet applies and
    the external loads (n, 6); the measured thrusts (n,) and body torques (n, 3), the motion-capture
    position (n, 3) and quaternion (n, 4), velocity and body rates (n, 6) and the truth (n, 13); the
    autopilot's yaw setpoints (n,) and velocity and rate integrals (n, 3), the true rotor speeds
    (n, 4) and allocation matrices (n, 4, 4) and the fan's turbulence state (n, 3)."""
    if buffer.shape[0] != n * STEP_WIDTH:
        raise ValueError("the step buffer must hold n * STEP_WIDTH floats")
    time, position, quaternion = buffer[0:n], rows_view(buffer, n, n, 3), rows_view(buffer, 4 * n, n, 4)
    velocity, angular_velocity = rows_view(buffer, 8 * n, n, 3), rows_view(buffer, 11 * n, n, 3)
    rotation = as_strided(buffer[14 * n : 23 * n], shape=(n, 3, 3), strides=(72, 24, 8))
    body_rates, forces = rows_view(buffer, 23 * n, n, 3), rows_view(buffer, 26 * n, n, 3)
    torques, loads = rows_view(buffer, 29 * n, n, 3), rows_view(buffer, 32 * n, n, 6)
    thrusts, body_torques = buffer[38 * n : 39 * n], rows_view(buffer, 39 * n, n, 3)
    measured_position, measured_quaternion = rows_view(buffer, 42 * n, n, 3), rows_view(buffer, 45 * n, n, 4)
    motion, truth = rows_view(buffer, 49 * n, n, 6), rows_view(buffer, 55 * n, n, 13)
    yaw_setpoint, velocity_integral = buffer[68 * n : 69 * n], rows_view(buffer, 69 * n, n, 3)
    rate_integral, speeds = rows_view(buffer, 72 * n, n, 3), rows_view(buffer, 75 * n, n, 4)
    allocations = as_strided(buffer[79 * n : 95 * n], shape=(n, 4, 4), strides=(128, 32, 8))
    fan_noise = rows_view(buffer, 95 * n, n, 3)
    return (
        time, position, quaternion, velocity, angular_velocity, rotation, body_rates, forces, torques,
        loads, thrusts, body_torques, measured_position, measured_quaternion, motion, truth, yaw_setpoint,
        velocity_integral, rate_integral, speeds, allocations, fan_noise,
    )  # fmt: skip


def physics_constants(
    action_type: int, scales: np.ndarray, autopilot: np.ndarray, inverse: np.ndarray, motors: np.ndarray,
    fan: np.ndarray, payload: np.ndarray, sensing: np.ndarray, nominal_allocation: np.ndarray, dt: float,
    drag_points: np.ndarray, segments: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """The kernels' constants packed in one float array (:func:`unpack_constants` cuts it up): the
    action type (an index into the action types) and its scales (10), the autopilot's gains (23,
    ``Autopilot.kernel_parameters``), its mixer's inverse (4, 4), the motors (6: lag up and down,
    speed limits, rotor drag, body drag coefficient), the fan jet (7), the payload (7), the sensors (7:
    speed levels, speed step, position, attitude, velocity and body-rate noise, whether velocity and
    body rates are measured), the nominal allocation (4, 4), the physics step, the drag points (P, 3)
    and the scheduled wrench segments (K, 8), each of these two after its count."""
    for name, part, size in (
        ("scales", scales, 10), ("autopilot", autopilot, 23), ("inverse", inverse, 16), ("motors", motors, 6),
        ("fan", fan, 7), ("payload", payload, 7), ("sensing", sensing, 7),
        ("nominal_allocation", nominal_allocation, 16),
    ):  # fmt: skip
        if np.size(part) != size:
            raise ValueError(f"{name} has {np.size(part)} numbers; the kernels read {size}")
    parts = (
        (action_type,), scales, autopilot, inverse.ravel(), motors, fan, payload, sensing,
        nominal_allocation.ravel(), (dt, len(drag_points)), drag_points.ravel(), (len(segments),),
        segments.ravel(),
    )  # fmt: skip
    return np.concatenate([np.asarray(part, dtype=float).ravel() for part in parts])


@njit(inline=True)
def unpack_constants(c):
    """The parts of :func:`physics_constants`, in its order, as views of ``c``."""
    scales, autopilot, inverse = c[1:11], c[11:34], rows_view(c, 34, 4, 4)
    motors, fan, payload, sensing = c[50:56], c[56:63], c[63:70], c[70:77]
    nominal_allocation, dt, n_points = rows_view(c, 77, 4, 4), c[93], int(c[94])
    o = 95 + 3 * n_points
    drag_points, n_segments = rows_view(c, 95, n_points, 3), int(c[o])
    segments = rows_view(c, o + 1, n_segments, 8)
    return (
        int(c[0]), scales, autopilot, inverse, motors, fan, payload, sensing, nominal_allocation, dt,
        drag_points, segments,
    )  # fmt: skip


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
def _motion_y(table, t):
    """Fan y at time ``t`` from a motion table (``FanMotion.table``)."""
    t = max(t, 0.0)
    y = table[0] + table[1] * math.sin(2.0 * math.pi * table[2] * t)
    count = int(table[3])
    if count > 0:
        k = 0
        for i in range(count):
            if table[4 + i] <= t:
                k = i
        y += table[4 + count + k] + table[4 + 2 * count + k] * (t - table[4 + k])
    return y


_SQRT2 = math.sqrt(2.0)
_CORE_INTEGRAL = _SQRT2 + math.asinh(1.0)
"""``F(x_c)·2c/R²`` (``FanJet.transit_time``): at ``x_c = R/c``, ``b = √2·R`` and ``c·x_c/R = 1``."""


@njit
def jet_speed(fan, x):
    """``FanJet.centreline_speed`` and ``FanJet.half_width`` at distance ``x`` for the jet ``fan``
    (``FanJet.kernel_parameters``: the outlet radius R in ``fan[3]``)."""
    radius = fan[3]
    b = math.sqrt(radius * radius + (fan[4] * x) ** 2)
    return fan[1] * min(1.0, _SQRT2 * radius / b), b


@njit
def transit_time(fan, x, b):
    """``FanJet.transit_time`` of one distance ``x`` where the half-width is ``b``."""
    x = max(x, 0.0)
    u0, core, radius, c = fan[1], fan[2], fan[3], fan[4]
    if x <= core:
        return x / u0
    scale = radius * radius / (2.0 * c)
    integral = 0.5 * x * b + scale * (math.asinh(c * x / radius) - _CORE_INTEGRAL)
    return core / u0 + integral / (_SQRT2 * u0 * radius)


@njit
def jet_axis_y(x, t, motion_tables, fan):
    """(N,) ``FanJet.axis_y``: each vehicle's jet axis at distance ``x[n]`` and time ``t[n]``."""
    out = np.empty(x.shape[0])
    for n in range(x.shape[0]):
        _, b = jet_speed(fan, max(x[n], 0.0))
        out[n] = _motion_y(motion_tables[n], t[n] - transit_time(fan, x[n], b))
    return out


FAN_TRACKING_NUMBERS = 10
"""Columns of :func:`fan_tracking_terms`' output."""


@njit
def fan_tracking_terms(position, time, actions, ended, motion_tables, fan, weights, out):
    """FanTracking's per-vehicle numbers into ``out`` (N, 10): the reward terms ``tracking``,
    ``standoff``, ``effort`` and ``crash``; the signed ``axis_error`` y - jet axis, the jet axis y at
    the vehicle, the fan's position ``(0, y, height)`` and the signed stand-off error ``x - x_ref``
    (``FanTracking.reward_terms`` and ``FanTracking.info``). ``fan``: the jet
    (``FanJet.kernel_parameters``); ``weights``: the stand-off ``x_ref``, the reward's axis scale,
    stand-off weight, effort weight and crash penalty."""
    height = fan[5]
    x_ref, axis_scale, standoff_weight, effort_weight, crash_penalty = (
        weights[0], weights[1], weights[2], weights[3], weights[4],
    )  # fmt: skip
    for n in range(position.shape[0]):
        _, b = jet_speed(fan, max(position[n, 0], 0.0))
        axis = _motion_y(motion_tables[n], time[n] - transit_time(fan, position[n, 0], b))
        dy, dz = position[n, 1] - axis, position[n, 2] - height
        standoff = position[n, 0] - x_ref
        out[n, 0] = math.exp(-math.sqrt(dy * dy + dz * dz) / axis_scale)
        out[n, 1] = -standoff_weight * abs(standoff)
        effort = 0.0
        for i in range(actions.shape[1]):
            effort += actions[n, i] * actions[n, i]
        out[n, 2] = (-effort_weight / actions.shape[1]) * effort
        out[n, 3] = -crash_penalty * ended[n]
        out[n, 4] = dy
        out[n, 5] = axis
        out[n, 6], out[n, 7], out[n, 8] = 0.0, _motion_y(motion_tables[n], time[n]), height
        out[n, 9] = standoff


@njit
def before_world_step(actions, buffer, saturated, motion_tables, constants):
    """Motor commands, motor lag and external loads of every vehicle from (N, 4) ``actions``; fills
    the ``forces`` and ``torques`` of ``buffer`` (:func:`step_views`; world frame, what PyBullet
    applies) and its ``loads`` (the external ``[F, τ]``), and steps the autopilot's and the rotors'
    state there; ``saturated`` (N,) are the mixer's flags. ``constants``: :func:`physics_constants`."""
    (
        time, position, _, velocity, angular_velocity, rotation, _, forces, torques, loads, _, _, _, _, _, _,
        yaw_setpoint, velocity_integral, rate_integral, speeds, allocations, fan_noise,
    ) = step_views(buffer, actions.shape[0])  # fmt: skip
    action_type, scales, autopilot, inverse, motors, fan, payload, _, _, _, drag_points, segments = (
        unpack_constants(constants)
    )
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
    alpha_up, alpha_down, min_speed, max_speed, rotor_drag = (
        motors[0],
        motors[1],
        motors[2],
        motors[3],
        motors[4],
    )
    work = np.empty(39)  # one allocation, cut into views (each allocation costs as much as a view)
    command, scratch, body, tv, rates = work[0:4], work[4:8], work[8:12], work[12:15], work[15:18]
    om, torque, w, desired = work[18:21], work[21:24], work[24:30], rows_view(work, 30, 3, 3)
    n_points = drag_points.shape[0]
    for n in range(actions.shape[0]):
        r = rotation[n]
        a = actions[n]
        # -- autopilot (Autopilot.velocity_command / attitude_command / wrench_command) --
        if action_type == MOTORS:
            for i in range(4):
                command[i] = 0.5 * (a[i] + 1.0) * scales[9]
        elif action_type == WRENCH:
            saturated[n] = _mix(
                (1.0 + a[0]) * scales[5], a[1] * scales[6], a[2] * scales[7], a[3] * scales[8],
                inverse, w2_min, w2_max, command, scratch,
            )  # fmt: skip
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
                    cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                    cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy, desired,
                )  # fmt: skip
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
                thrust, torque[0] + c0, torque[1] + c1, torque[2] + c2, inverse, w2_min, w2_max,
                command, scratch,
            )  # fmt: skip
        # -- motors (Rotors.step, thrust_and_torque) --
        for i in range(4):
            target = min(max(command[i], min_speed), max_speed)
            error = target - speeds[n, i]
            speeds[n, i] += (alpha_up if error >= 0.0 else alpha_down) * error
        body[:] = 0.0
        for k in range(4):
            for i in range(4):
                body[k] += allocations[n, k, i] * (speeds[n, i] * speeds[n, i])
        # -- external loads (Fleet.external_loads) --
        f0 = f1 = f2 = t0 = t1 = t2 = 0.0
        for p in range(n_points):
            o0 = r[0, 0] * drag_points[p, 0] + r[0, 1] * drag_points[p, 1] + r[0, 2] * drag_points[p, 2]
            o1 = r[1, 0] * drag_points[p, 0] + r[1, 1] * drag_points[p, 1] + r[1, 2] * drag_points[p, 2]
            o2 = r[2, 0] * drag_points[p, 0] + r[2, 1] * drag_points[p, 1] + r[2, 2] * drag_points[p, 2]
            w0, w1, w2 = _cross(
                angular_velocity[n, 0], angular_velocity[n, 1], angular_velocity[n, 2], o0, o1, o2
            )
            rel0, rel1, rel2 = -(velocity[n, 0] + w0), -(velocity[n, 1] + w1), -(velocity[n, 2] + w2)
            if fan[0] > 0.0:  # FanJet.velocity_at
                x = position[n, 0] + o0
                u_c, b = jet_speed(fan, x)
                dy = position[n, 1] + o1 - _motion_y(motion_tables[n], time[n] - transit_time(fan, x, b))
                dz = position[n, 2] + o2 - fan[5]
                speed = u_c * math.exp(-(dy * dy + dz * dz) / (b * b)) if x > 0.0 else 0.0
                rel0 += speed * (1.0 + fan[6] * fan_noise[n, 0])
                rel1 += speed * (fan[6] * fan_noise[n, 1])
                rel2 += speed * (fan[6] * fan_noise[n, 2])
            magnitude = math.sqrt(rel0 * rel0 + rel1 * rel1 + rel2 * rel2)
            g0, g1, g2 = (
                motors[5] * magnitude * rel0,
                motors[5] * magnitude * rel1,
                motors[5] * magnitude * rel2,
            )
            if p < 4:  # rotor drag at the hubs (Rotors.drag_forces), airspeed = -relative air
                along = -(rel0 * r[0, 2] + rel1 * r[1, 2] + rel2 * r[2, 2])
                k_d = rotor_drag * speeds[n, p]
                g0 -= k_d * (-rel0 - along * r[0, 2])
                g1 -= k_d * (-rel1 - along * r[1, 2])
                g2 -= k_d * (-rel2 - along * r[2, 2])
            c0, c1, c2 = _cross(o0, o1, o2, g0, g1, g2)
            f0, f1, f2, t0, t1, t2 = f0 + g0, f1 + g1, f2 + g2, t0 + c0, t1 + c1, t2 + c2
        if payload[0] > 0.0 and payload[5] <= time[n] < payload[6]:  # Payload.point_load
            o0 = r[0, 0] * payload[1] + r[0, 1] * payload[2] + r[0, 2] * payload[3]
            o1 = r[1, 0] * payload[1] + r[1, 1] * payload[2] + r[1, 2] * payload[3]
            o2 = r[2, 0] * payload[1] + r[2, 1] * payload[2] + r[2, 2] * payload[3]
            c0, c1, c2 = _cross(o0, o1, o2, 0.0, 0.0, payload[4])
            f2 += payload[4]
            t0, t1, t2 = t0 + c0, t1 + c1, t2 + c2
        if segments.shape[0] > 0:  # WrenchProfile.point_load
            w[:] = 0.0
            for k in range(segments.shape[0]):
                if segments[k, 0] <= time[n] < segments[k, 1]:
                    for i in range(6):
                        w[i] += segments[k, 2 + i]
            f0, f1, f2 = f0 + w[0], f1 + w[1], f2 + w[2]
            t0, t1, t2 = t0 + w[3], t1 + w[4], t2 + w[5]
        loads[n, 0], loads[n, 1], loads[n, 2], loads[n, 3], loads[n, 4], loads[n, 5] = f0, f1, f2, t0, t1, t2
        for i in range(3):
            forces[n, i] = r[i, 2] * body[0] + loads[n, i]
            torques[n, i] = (r[i, 0] * body[1] + r[i, 1] * body[2] + r[i, 2] * body[3]) + loads[n, 3 + i]


@njit
def after_world_step(flat, buffer, noise_buffer, noise_cursor, constants):
    """After PyBullet's step, into ``buffer`` (:func:`step_views`): the true states from its (N, 13)
    rows one after another in ``flat`` (``World.read_flat``), time on by one step; turbulence one
    step on (``FanJet.advance``) with this step's standard normal draws from each vehicle's block
    (``NoiseBlocks``); the quantized motor speeds through the nominal mixer (``MotorSpeedSensor``)
    into ``thrusts`` and ``body_torques``; the noisy pose (``MotionCapture``) into ``measured_position`` and
    ``measured_quaternion`` and, with an onboard state estimator, noisy velocity and body rates into
    ``motion``; the true position, velocity, quaternion and body rates into ``truth``."""
    (
        time, position, quaternion, velocity, angular_velocity, rotation, body_rates, _, _, _, thrusts,
        body_torques, measured_position, measured_quaternion, motion, truth, _, _, _, speeds, _, fan_noise,
    ) = step_views(buffer, flat.shape[0] // 13)  # fmt: skip
    raw = rows_view(flat, 0, time.shape[0], 13)
    _, _, _, _, _, fan, _, sensing, nominal_allocation, dt, _, _ = unpack_constants(constants)
    levels, step, position_noise, attitude_noise = sensing[0], sensing[1], sensing[2], sensing[3]
    body = np.empty(4)
    for n in range(raw.shape[0]):
        # -- true state (RigidBodyState.from_pybullet) --
        qw, qx, qy, qz = raw[n, 6], raw[n, 3], raw[n, 4], raw[n, 5]
        quaternion[n, 0], quaternion[n, 1], quaternion[n, 2], quaternion[n, 3] = qw, qx, qy, qz
        r = rotation[n]
        matrix(qw, qx, qy, qz, r)
        for i in range(3):
            position[n, i] = raw[n, i]
            velocity[n, i] = raw[n, 7 + i]
            angular_velocity[n, i] = raw[n, 10 + i]
        for i in range(3):
            body_rates[n, i] = r[0, i] * raw[n, 10] + r[1, i] * raw[n, 11] + r[2, i] * raw[n, 12]
        time[n] += dt
        # -- this step's draws --
        normals = noise_buffer[n, noise_cursor[n]]
        noise_cursor[n] += 1
        # -- turbulence --
        if fan[0] > 0.0 and fan[6] != 0.0:
            u_c, b = jet_speed(fan, max(position[n, 0], 1e-3))
            decay = math.exp(-dt * u_c / b)
            for i in range(3):
                fan_noise[n, i] = decay * fan_noise[n, i] + math.sqrt(1.0 - decay * decay) * normals[i]
        # -- motor speeds through the nominal mixer --
        body[:] = 0.0
        for i in range(4):
            quantized = min(max(np.rint(speeds[n, i] / step), 0.0), levels) * step
            for k in range(4):
                body[k] += nominal_allocation[k, i] * (quantized * quantized)
        thrusts[n] = body[0]
        body_torques[n, 0], body_torques[n, 1], body_torques[n, 2] = body[1], body[2], body[3]
        # -- motion capture --
        for i in range(3):
            measured_position[n, i] = position[n, i] + position_noise * normals[3 + i]
        ew, ex, ey, ez = exp(
            attitude_noise * normals[6], attitude_noise * normals[7], attitude_noise * normals[8]
        )
        mw, mx, my, mz = qmul(qw, qx, qy, qz, ew, ex, ey, ez)
        norm = math.sqrt(mw * mw + mx * mx + my * my + mz * mz)
        q = measured_quaternion[n]
        q[0], q[1], q[2], q[3] = mw / norm, mx / norm, my / norm, mz / norm
        if sensing[6] > 0.0:
            for i in range(3):
                motion[n, i] = velocity[n, i] + sensing[4] * normals[9 + i]
                motion[n, 3 + i] = body_rates[n, i] + sensing[5] * normals[12 + i]
        for i in range(3):
            truth[n, i] = position[n, i]
            truth[n, 3 + i] = velocity[n, i]
            truth[n, 10 + i] = body_rates[n, i]
        for i in range(4):
            truth[n, 6 + i] = quaternion[n, i]


@njit
def before_world_step_one(actions, buffer, saturated, motion_tables, constants):
    """:func:`before_world_step` for a fleet of one vehicle, returning what ``World.step_one``
    applies as tuples of floats: the force, the torque and the centre of mass."""
    before_world_step(actions, buffer, saturated, motion_tables, constants)
    _, position, _, _, _, _, _, forces, torques, _, _, _, _, _, _, _, _, _, _, _, _, _ = step_views(buffer, 1)
    return (
        (forces[0, 0], forces[0, 1], forces[0, 2]),
        (torques[0, 0], torques[0, 1], torques[0, 2]),
        (position[0, 0], position[0, 1], position[0, 2]),
    )


@njit
def after_world_step_one(readings, buffer, noise_buffer, noise_cursor, constants):
    """:func:`after_world_step` for a fleet of one vehicle, from PyBullet's ``(pose, twist)`` tuples
    as ``World.read_first`` returns them."""
    (position, orientation), (linear, angular) = readings
    row = np.empty(13)
    for i in range(3):
        row[i], row[7 + i], row[10 + i] = position[i], linear[i], angular[i]
    for i in range(4):
        row[3 + i] = orientation[i]
    after_world_step(row, buffer, noise_buffer, noise_cursor, constants)


@njit
def termination_codes(position, rotation, limits, out):
    """``Fleet.terminations`` into ``out``, but for ground contact: 1 crash (below ``limits[0]``), 2
    flip (``R[2, 2]`` below ``limits[1]``), 3 out of the arena ``limits[2:6]`` (x_min, x_max, y half
    width, z_max), else 0. Returns whether any vehicle is below ``limits[6]`` (``World.clear_height``),
    low enough to touch the ground: only then need its contacts be asked for (crash, code 1)."""
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


@njit
def assemble_observations(states, wrenches, last_actions, observe_wrench, out):
    """``Fleet.observations`` into ``out`` (N, 25, float32): from the states (N, 13) the position,
    velocity, the first two columns of the rotation matrix of the (normalised) quaternion and the
    body rates; the wrenches (N, 6) times ``observe_wrench`` (1 or 0) and the last actions (N, 4)."""
    r = np.empty((3, 3))
    for n in range(states.shape[0]):
        s = states[n]
        norm = math.sqrt(s[6] * s[6] + s[7] * s[7] + s[8] * s[8] + s[9] * s[9])
        matrix(s[6] / norm, s[7] / norm, s[8] / norm, s[9] / norm, r)
        for i in range(6):
            out[n, i] = s[i]
        for i in range(3):
            out[n, 6 + i] = r[i, 0]
            out[n, 9 + i] = r[i, 1]
            out[n, 12 + i] = s[10 + i]
        for i in range(6):
            out[n, 15 + i] = wrenches[n, i] * observe_wrench
        for i in range(4):
            out[n, 21 + i] = last_actions[n, i]

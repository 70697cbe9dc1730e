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

from quad_wrench_env.kernels import njit
from quad_wrench_env.kernels.quaternions import exp, matrix, qmul

VELOCITY, ATTITUDE, WRENCH, MOTORS = 0, 1, 2, 3


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


@njit
def _transit_time(x, u0, core):
    """``FanJet.transit_time`` of one distance."""
    x = max(x, 0.0)
    return x / u0 if x <= core else core / u0 + (x * x - core * core) / (2.0 * u0 * core)


@njit
def jet_axis_y(x, t, motion_tables, u0, core):
    """(N,) ``FanJet.axis_y``: each vehicle's jet axis at distance ``x[n]`` and time ``t[n]``."""
    out = np.empty(x.shape[0])
    for n in range(x.shape[0]):
        out[n] = _motion_y(motion_tables[n], t[n] - _transit_time(x[n], u0, core))
    return out


@njit
def fan_tracking_terms(position, time, actions, ended, motion_tables, u0, core, height, weights, out):
    """FanTracking's per-vehicle numbers into ``out`` (N, 6): the reward terms ``tracking``,
    ``effort`` and ``crash`` (``weights`` = axis scale, effort weight, crash penalty), the signed
    ``axis_error`` y - jet axis, the jet axis y at the vehicle and the fan's y
    (``FanTracking.reward_terms`` and ``FanTracking.info``)."""
    for n in range(position.shape[0]):
        axis = _motion_y(motion_tables[n], time[n] - _transit_time(position[n, 0], u0, core))
        dy, dz = position[n, 1] - axis, position[n, 2] - height
        out[n, 0] = math.exp(-(dy * dy + dz * dz) / weights[0] ** 2)
        effort = 0.0
        for i in range(actions.shape[1]):
            effort += actions[n, i] * actions[n, i]
        out[n, 1] = (-weights[1] / actions.shape[1]) * effort
        out[n, 2] = -weights[2] * ended[n]
        out[n, 3] = dy
        out[n, 4] = position[n, 1] - dy
        out[n, 5] = _motion_y(motion_tables[n], time[n])


@njit
def before_world_step(
    action_type, actions, position, velocity, angular_velocity, rotation, time,
    yaw_setpoint, velocity_integral, rate_integral, saturated, speeds, allocations,
    autopilot, scales, inverse, motors, drag_points, fan, fan_noise, motion_tables,
    payload, segments, forces, torques, loads,
):  # fmt: skip
    """Motor commands, motor lag and external loads of every vehicle; fills ``forces`` and
    ``torques`` (world frame, what PyBullet applies) and ``loads`` (the external ``[F, τ]``)."""
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
    command, scratch, body = np.empty(4), np.empty(4), np.empty(4)
    desired = np.empty((3, 3))
    tv, rates, om, torque, w = np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(6)
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
                u_c = fan[1] * min(1.0, fan[2] / max(x, 1e-9))
                b = math.sqrt(fan[3] + (fan[4] * x) ** 2)
                dy = (
                    position[n, 1]
                    + o1
                    - _motion_y(motion_tables[n], time[n] - _transit_time(x, fan[1], fan[2]))
                )
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
def after_world_step(
    raw, position, quaternion, velocity, angular_velocity, rotation, body_rates, time, dt,
    noise_buffer, noise_cursor, normals, fan, fan_noise, speeds, sensing, nominal_allocation,
    thrusts, body_torques, measured_position, measured_quaternion, motion, truth,
):  # fmt: skip
    """After PyBullet's step: the true states from its (N, 13) ``raw`` rows (``World.read``) into the
    state arrays, time on by ``dt``; this step's standard normal draws from each vehicle's block
    (``NoiseBlocks``); turbulence one step on (``FanJet.advance``); the quantized motor speeds
    through the nominal mixer (``MotorSpeedSensor``) into ``thrusts`` and ``body_torques``; the noisy
    pose (``MotionCapture``) into ``measured_position`` and ``measured_quaternion`` and, with an onboard
    state estimator, noisy velocity and body rates into ``motion`` (N, 6); the true position,
    velocity, quaternion and body rates into ``truth`` (N, 13)."""
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
        row = noise_cursor[n]
        for i in range(normals.shape[1]):
            normals[n, i] = noise_buffer[n, row, i]
        noise_cursor[n] = row + 1
        # -- turbulence --
        if fan[0] > 0.0 and fan[6] != 0.0:
            x = max(position[n, 0], 1e-3)
            u_c = fan[1] * min(1.0, fan[2] / max(x, 1e-9))
            b = math.sqrt(fan[3] + (fan[4] * x) ** 2)
            decay = math.exp(-dt * u_c / b)
            for i in range(3):
                fan_noise[n, i] = decay * fan_noise[n, i] + math.sqrt(1.0 - decay * decay) * normals[n, i]
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
            measured_position[n, i] = position[n, i] + position_noise * normals[n, 3 + i]
        ew, ex, ey, ez = exp(
            attitude_noise * normals[n, 6], attitude_noise * normals[n, 7], attitude_noise * normals[n, 8]
        )
        mw, mx, my, mz = qmul(qw, qx, qy, qz, ew, ex, ey, ez)
        norm = math.sqrt(mw * mw + mx * mx + my * my + mz * mz)
        q = measured_quaternion[n]
        q[0], q[1], q[2], q[3] = mw / norm, mx / norm, my / norm, mz / norm
        if motion.shape[0] > 0:
            for i in range(3):
                motion[n, i] = velocity[n, i] + sensing[4] * normals[n, 9 + i]
                motion[n, 3 + i] = body_rates[n, i] + sensing[5] * normals[n, 12 + i]
        for i in range(3):
            truth[n, i] = position[n, i]
            truth[n, 3 + i] = velocity[n, i]
            truth[n, 10 + i] = body_rates[n, i]
        for i in range(4):
            truth[n, 6 + i] = quaternion[n, i]


@njit
def termination_codes(position, rotation, touching, limits, out):
    """``Fleet.terminations`` into ``out``: 1 crash (below ``limits[0]`` or ``touching`` the ground),
    2 flip (``R[2, 2]`` below ``limits[1]``), 3 out of the arena ``limits[2:6]`` (x_min, x_max, y half
    width, z_max), else 0."""
    for n in range(position.shape[0]):
        x, y, z = position[n, 0], position[n, 1], position[n, 2]
        if z < limits[0] or touching[n]:
            out[n] = 1
        elif rotation[n, 2, 2] < limits[1]:
            out[n] = 2
        elif x < limits[2] or x > limits[3] or abs(y) > limits[4] or z > limits[5]:
            out[n] = 3
        else:
            out[n] = 0


@njit
def assemble_observations(states, wrenches, last_actions, out):
    """``Fleet.observations`` into ``out`` (N, 23, float32): states (N, 13) with ``w >= 0``, wrenches
    (N, 6) and the last actions (N, 4)."""
    for n in range(states.shape[0]):
        sign = -1.0 if states[n, 6] < 0.0 else 1.0
        for i in range(13):
            out[n, i] = states[n, i] * sign if 6 <= i < 10 else states[n, i]
        for i in range(6):
            out[n, 13 + i] = wrenches[n, i]
        for i in range(4):
            out[n, 19 + i] = last_actions[n, i]

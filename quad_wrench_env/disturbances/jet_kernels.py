"""Compiled forms of the round turbulent jet (:mod:`.fan`, :mod:`.jet`), point by point: what every physics
step runs (the fields' ``velocity_at`` gives the same air at an episode's start). A jet's numbers start
``[on, U0, x_c, R, c]`` (on > 0, outlet speed, core length ``D/(2c)``, outlet radius ``D/2``, spread);
:func:`jet_speed` and :func:`transit_time` read those. Both jets' turbulence steps with
:func:`turbulence_step`."""

from __future__ import annotations

import math

import numpy as np

from quad_wrench_env.numerics import njit

_SQRT2 = math.sqrt(2.0)
_CORE_INTEGRAL = _SQRT2 + math.asinh(1.0)
"""``F(x_c)·2c/R²`` (``FanJet.transit_time``): at ``x_c = R/c``, ``b = √2·R`` and ``c·x_c/R = 1``."""


@njit
def jet_speed(jet, x):
    """``FanJet.centreline_speed`` and ``FanJet.half_width`` at distance ``x`` along the jet."""
    radius = jet[3]
    b = math.sqrt(radius * radius + (jet[4] * x) ** 2)
    return jet[1] * min(1.0, _SQRT2 * radius / b), b


@njit
def transit_time(jet, x, b):
    """``FanJet.transit_time`` of one distance ``x`` where the half-width is ``b``."""
    x = max(x, 0.0)
    u0, core, radius, c = jet[1], jet[2], jet[3], jet[4]
    if x <= core:
        return x / u0
    scale = radius * radius / (2.0 * c)
    integral = 0.5 * x * b + scale * (math.asinh(c * x / radius) - _CORE_INTEGRAL)
    return core / u0 + integral / (_SQRT2 * u0 * radius)


@njit
def motion_y(table, t):
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
def jet_axis_y(x, t, motion_tables, fan):
    """(N,) ``FanJet.axis_y``: each vehicle's jet axis at distance ``x[n]`` and time ``t[n]``."""
    out = np.empty(x.shape[0])
    for n in range(x.shape[0]):
        _, b = jet_speed(fan, max(x[n], 0.0))
        out[n] = motion_y(motion_tables[n], t[n] - transit_time(fan, x[n], b))
    return out


@njit
def fan_velocity(fan, motion_tables, noise, points, time, out):
    """``FanJet.velocity_at`` added to ``out``: the moving fan's jet (numbers ``[on, U0, x_c, R, c,
    height, I]``) at the world ``points`` (N, P, 3), each vehicle's fan moving by its motion table,
    its turbulence ``noise`` (N, 3) multiplying the local speed."""
    if fan[0] <= 0.0:
        return
    for n in range(points.shape[0]):
        table = motion_tables[n]
        for p in range(points.shape[1]):
            x = points[n, p, 0]
            u_c, b = jet_speed(fan, x)
            dy = points[n, p, 1] - motion_y(table, time[n] - transit_time(fan, x, b))
            dz = points[n, p, 2] - fan[5]
            speed = u_c * math.exp(-(dy * dy + dz * dz) / (b * b)) if x > 0.0 else 0.0
            out[n, p, 0] += speed * (1.0 + fan[6] * noise[n, 0])
            out[n, p, 1] += speed * (fan[6] * noise[n, 1])
            out[n, p, 2] += speed * (fan[6] * noise[n, 2])


@njit
def turbulence_step(noise, n, dt, speed, length, normals):
    """A jet's turbulence of vehicle ``n`` one step ``dt`` on, in place: a unit-variance
    Ornstein-Uhlenbeck process ``noise[n]`` (3,) of time scale ``length/speed`` (eddies of size
    ``length`` carried past at ``speed``), stepped exactly, ``n' = a·n + sqrt(1 - a²)·η`` with
    ``a = exp(-dt·speed/length)`` on its standard normal draws ``η = normals[n]``: its variance stays 1
    and its autocorrelation is ``exp(-τ·speed/length)`` at lag τ, at any ``dt``."""
    decay = math.exp(-dt * speed / length)
    for i in range(3):
        noise[n, i] = decay * noise[n, i] + math.sqrt(1.0 - decay * decay) * normals[n, i]


@njit
def fan_advance(fan, motion_tables, noise, position, velocity, dt, normals):
    """The fan's ``advance``: each vehicle's turbulence one step on, an Ornstein-Uhlenbeck process of time
    scale ``b/u_c`` at its distance from the fan."""
    if fan[0] <= 0.0 or fan[6] == 0.0:
        return
    for n in range(position.shape[0]):
        u_c, b = jet_speed(fan, max(position[n, 0], 1e-3))
        turbulence_step(noise, n, dt, u_c, b, normals)


@njit
def fixed_jet_velocity(jet, speed_scale, turbulence, points, time, out):
    """``Jet.velocity_at`` added to ``out``: a fixed jet (numbers ``[on, U0, x_c, R, c, origin (3),
    direction (3), I, L]``) at the world ``points`` (N, P, 3), each vehicle's times its ``speed_scale``;
    with an intensity ``I`` > 0 its ``turbulence`` (N, 3) adds ``I·n`` to the direction."""
    if jet[0] <= 0.0:
        return
    o0, o1, o2, d0, d1, d2 = jet[5], jet[6], jet[7], jet[8], jet[9], jet[10]
    intensity = jet[11]
    for n in range(points.shape[0]):
        for p in range(points.shape[1]):
            r0, r1, r2 = points[n, p, 0] - o0, points[n, p, 1] - o1, points[n, p, 2] - o2
            x = r0 * d0 + r1 * d1 + r2 * d2
            if x <= 0.0:
                continue
            e0, e1, e2 = r0 - x * d0, r1 - x * d1, r2 - x * d2
            u_c, b = jet_speed(jet, x)
            speed = speed_scale[n, 0] * u_c * math.exp(-(e0 * e0 + e1 * e1 + e2 * e2) / (b * b))
            if intensity > 0.0:
                out[n, p, 0] += speed * (d0 + intensity * turbulence[n, 0])
                out[n, p, 1] += speed * (d1 + intensity * turbulence[n, 1])
                out[n, p, 2] += speed * (d2 + intensity * turbulence[n, 2])
            else:
                out[n, p, 0] += speed * d0
                out[n, p, 1] += speed * d1
                out[n, p, 2] += speed * d2


@njit
def fixed_jet_advance(jet, speed_scale, turbulence, position, velocity, dt, normals):
    """The jet's ``advance``: each vehicle's turbulence one step on, time scale ``L/u_c`` at its distance
    along the jet (``L`` the half-width ``b`` there when the config gives none), ``u_c`` times the
    vehicle's ``speed_scale`` (a jet switched off, scale 0, keeps its turbulence still)."""
    o0, o1, o2, d0, d1, d2 = jet[5], jet[6], jet[7], jet[8], jet[9], jet[10]
    for n in range(position.shape[0]):
        x = (position[n, 0] - o0) * d0 + (position[n, 1] - o1) * d1 + (position[n, 2] - o2) * d2
        u_c, b = jet_speed(jet, max(x, 1e-3))
        length = jet[12] if jet[12] > 0.0 else b
        turbulence_step(turbulence, n, dt, speed_scale[n, 0] * u_c, length, normals)

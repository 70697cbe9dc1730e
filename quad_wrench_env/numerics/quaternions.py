"""Scalar quaternion helpers for the kernels (Hamilton ``[w, x, y, z]``, as in
:mod:`quad_wrench_env.rotations`)."""

from __future__ import annotations

import math

from quad_wrench_env.numerics import njit


@njit
def qmul(aw, ax, ay, az, bw, bx, by, bz):
    """``a ⊗ b``."""
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


@njit
def from_mrp(r0, r1, r2):
    """Quaternion of MRPs (``rotations.quat_from_mrp``)."""
    n2 = r0 * r0 + r1 * r1 + r2 * r2
    w = (1.0 - n2) / (1.0 + n2)
    return w, r0 * (1.0 + w), r1 * (1.0 + w), r2 * (1.0 + w)


@njit
def to_mrp(w, x, y, z):
    """MRPs of a unit quaternion, ``w >= 0`` first (``rotations.mrp_from_quat``)."""
    scale = math.copysign(1.0, w) / (1.0 + abs(w))
    return x * scale, y * scale, z * scale


@njit(inline=True)
def half_angle_squared(v0, v1, v2):
    """``(θ/2)²`` of the rotation vector ``v``: :func:`exp` takes :func:`exp_small` below 1e-4."""
    return 0.25 * (v0 * v0 + v1 * v1 + v2 * v2)


@njit(inline=True)
def exp_small(h2, v0, v1, v2):
    """:func:`exp` for a half angle below 0.01 rad (``h2``: its square): cos and sin/x from their
    Taylor series, whose first omitted terms (x⁸/8!, x⁸/9!) are below 1e-20, so the same numbers to
    rounding without the transcendental calls (one filter step takes 37 of these). Plain arithmetic:
    it runs on SIMD lanes too (:mod:`~quad_wrench_env.estimators.ukf_lanes_kernel`)."""
    cosine = 1.0 - h2 / 2.0 * (1.0 - h2 / 12.0 * (1.0 - h2 / 30.0))
    scale = 0.5 * (1.0 - h2 / 6.0 * (1.0 - h2 / 20.0 * (1.0 - h2 / 42.0)))
    return cosine, v0 * scale, v1 * scale, v2 * scale


@njit
def exp(v0, v1, v2):
    """Quaternion of the rotation vector ``v`` (``rotations.quat_exp``)."""
    h2 = half_angle_squared(v0, v1, v2)
    if h2 < 1e-4:
        return exp_small(h2, v0, v1, v2)
    half = math.sqrt(h2)
    return (
        math.cos(half),
        v0 * (0.5 * math.sin(half) / half),
        v1 * (0.5 * math.sin(half) / half),
        v2 * (0.5 * math.sin(half) / half),
    )


@njit(inline=True)
def rotation_entries(w, x, y, z):
    """The nine entries of the body -> world rotation matrix, row by row (``rotations.rotation_matrix``).
    Plain arithmetic: it runs on SIMD lanes too (:mod:`~quad_wrench_env.estimators.ukf_lanes_kernel`)."""
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    return (
        1.0 - 2.0 * (yy + zz),
        2.0 * (xy - wz),
        2.0 * (xz + wy),
        2.0 * (xy + wz),
        1.0 - 2.0 * (xx + zz),
        2.0 * (yz - wx),
        2.0 * (xz - wy),
        2.0 * (yz + wx),
        1.0 - 2.0 * (xx + yy),
    )


@njit
def matrix(w, x, y, z, out):
    """Body -> world rotation matrix into ``out`` (3, 3) (:func:`rotation_entries`)."""
    (out[0, 0], out[0, 1], out[0, 2], out[1, 0], out[1, 1], out[1, 2], out[2, 0], out[2, 1], out[2, 2]) = (
        rotation_entries(w, x, y, z)
    )

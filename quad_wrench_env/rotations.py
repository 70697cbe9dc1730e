"""Quaternions, rotation matrices and attitude helpers.

Conventions (``docs/architecture.md``, "Conventions"):

* quaternions are Hamilton, scalar first ``[w, x, y, z]`` and rotate body -> world;
* this is the ONE module that converts to and from PyBullet's ``[x, y, z, w]`` order;
* ``R = rotation_matrix(q)`` maps body vectors to world vectors, i.e. it is the matrix that
  McKinnon & Schoellig 2016 eq. (7) calls ``R^T``.

The functions are written for single vectors on the hot path of the simulation (plain numpy, no
per-call object construction); the tests check them against ``scipy.spatial.transform.Rotation``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = [
    "cross",
    "euler_zyx_from_quat",
    "from_pybullet",
    "mrp_from_quat",
    "quat_conjugate",
    "quat_exp",
    "quat_from_axis_angle",
    "quat_from_euler_zyx",
    "quat_from_matrix",
    "quat_from_mrp",
    "quat_multiply",
    "quat_normalize",
    "rotation_matrices",
    "rotation_matrix",
    "rows_times",
    "skew",
    "tilt_angle",
    "to_pybullet",
    "wrap_angle",
    "yaw_of",
]


def to_pybullet(q_wxyz: np.ndarray) -> np.ndarray:
    """Project ``[w, x, y, z]`` -> PyBullet ``[x, y, z, w]``; row-wise on (..., 4) arrays."""
    return np.asarray(q_wxyz, dtype=float)[..., [1, 2, 3, 0]]


def from_pybullet(q_xyzw) -> np.ndarray:
    """PyBullet ``[x, y, z, w]`` -> project ``[w, x, y, z]``; row-wise on (..., 4) arrays."""
    return np.asarray(q_xyzw, dtype=float)[..., [3, 0, 1, 2]]


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a ⊗ b`` (rotate by ``b`` first, then by ``a``)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array(
        (
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        )
    )


_CONJUGATE = np.array((1.0, -1.0, -1.0, -1.0))


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """Inverse of a unit quaternion; row-wise on (..., 4) arrays."""
    return q * _CONJUGATE


def quat_normalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternion with a non-negative scalar part (one of the two signs, chosen canonically)."""
    q = np.asarray(q, dtype=float)
    n = math.sqrt(float(q @ q))
    if not n > 0.0:
        raise ValueError(f"cannot normalise quaternion {q!r}: its norm is {n}")
    return q / n if q[0] >= 0.0 else -q / n


def quat_from_axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation by ``angle`` (rad) about the unit vector ``axis``."""
    half = 0.5 * angle
    s = math.sin(half)
    return np.array((math.cos(half), axis[0] * s, axis[1] * s, axis[2] * s))


def euler_cos_sin(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float, float, float]:
    """``(cos φ, sin φ, cos θ, sin θ, cos ψ, sin ψ)`` of ZYX Euler angles (rad), the factors of
    ``R = Rz(ψ)·Ry(θ)·Rx(φ)``."""
    return math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw)


def quat_from_euler_zyx(roll, pitch, yaw) -> np.ndarray:
    """Quaternion(s) of ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (intrinsic z-y'-x'', aerospace order);
    scalar angles give (4,), arrays of angles (..., 4)."""
    cr, sr = np.cos(0.5 * np.asarray(roll)), np.sin(0.5 * np.asarray(roll))
    cp, sp = np.cos(0.5 * np.asarray(pitch)), np.sin(0.5 * np.asarray(pitch))
    cy, sy = np.cos(0.5 * np.asarray(yaw)), np.sin(0.5 * np.asarray(yaw))
    return np.stack(
        (
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ),
        axis=-1,
    )


def rotation_matrix(q: np.ndarray) -> np.ndarray:
    """Body -> world rotation matrix of the unit quaternion ``q`` (McKinnon & Schoellig 2016,
    eq. 7, its ``R^T``)."""
    w, x, y, z = q
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    return np.array(
        (
            (1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)),
            (2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)),
            (2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)),
        )
    )


def quat_from_matrix(matrix: np.ndarray) -> np.ndarray:
    """Unit quaternion ``[w, x, y, z]`` (w >= 0) of a body -> world rotation matrix."""
    x, y, z, w = Rotation.from_matrix(matrix).as_quat()
    return quat_normalize(np.array((w, x, y, z)))


def quat_from_mrp(rho: np.ndarray) -> np.ndarray:
    """Error quaternion of Modified Rodrigues Parameters ``ρ = tan(θ/4)·e`` (McKinnon &
    Schoellig 2016, eq. 17).

    Works row-wise on (N, 3) arrays too.
    """
    n2 = (rho * rho).sum(axis=-1, keepdims=True)
    w = (1.0 - n2) / (1.0 + n2)
    return np.concatenate((w, rho * (1.0 + w)), axis=-1)


def mrp_from_quat(q: np.ndarray) -> np.ndarray:
    """MRPs ``ρ = q_v/(1 + q_0)`` of a unit quaternion (McKinnon & Schoellig 2016 eq. 16), taking the sign
    with ``q_0 >= 0`` first so that ``|ρ| <= 1`` (the rotation of at most π). Row-wise on (N, 4)."""
    w = q[..., :1]
    return q[..., 1:] * (np.copysign(1.0, w) / (1.0 + np.abs(w)))


def quat_exp(rotation_vector: np.ndarray) -> np.ndarray:
    """Quaternion of the rotation ``θ·e`` given as the vector ``θ e`` (rad); row-wise on (N, 3)."""
    angle = np.sqrt((rotation_vector * rotation_vector).sum(axis=-1, keepdims=True))
    half = 0.5 * angle
    scale = 0.5 * np.sinc(half / np.pi)  # sin(θ/2)/θ, finite at θ = 0
    return np.concatenate((np.cos(half), rotation_vector * scale), axis=-1)


def _bilinear_tensor(function, size_a: int, size_b: int) -> np.ndarray:
    """``T`` with ``function(a, b) == (a ⊗ b).reshape(-1) @ T`` for a function bilinear in (a, b),
    read off the function on the basis vectors."""
    basis_a, basis_b = np.eye(size_a), np.eye(size_b)
    return np.array([np.ravel(function(ea, eb)) for ea in basis_a for eb in basis_b])


def _homogeneous_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Symmetric bilinear form whose value at (q, q) is the rotation matrix of q (|q| = 1)."""
    va, vb = a[1:], b[1:]
    return (
        (a[0] * b[0] - va @ vb) * np.eye(3)
        + np.outer(va, vb)
        + np.outer(vb, va)
        + a[0] * skew(vb)
        + b[0] * skew(va)
    )


def rows_times(rows: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """``rows @ matrix`` for (..., k) ``rows`` and a (k, m) ``matrix``, summed over ``k`` in order by
    elementwise operations, so that each row's result has the same bits whatever the other rows are.
    ``@`` on an (N, k) array is one BLAS product whose kernel (and so the grouping of its sums) the
    library picks by N and by the CPU: a vehicle of a fleet of 3 then differs in the last bits from
    the same vehicle alone (seen with OpenBLAS's AVX-512 kernels)."""
    out = np.zeros((*rows.shape[:-1], matrix.shape[1]))
    for k in range(matrix.shape[0]):
        out += rows[..., k, None] * matrix[k]
    return out


def rotation_matrices(q: np.ndarray) -> np.ndarray:
    """(..., 3, 3) body -> world matrices of (..., 4) unit quaternions (one product with the bilinear
    tensor, :func:`rows_times`)."""
    outer = q[..., :, None] * q[..., None, :]
    return rows_times(outer.reshape(*q.shape[:-1], 16), _ROTATION).reshape(*q.shape[:-1], 3, 3)


def euler_zyx_from_quat(q: np.ndarray) -> np.ndarray:
    """``(roll, pitch, yaw)`` of ``R = Rz(yaw) Ry(pitch) Rx(roll)``; the inverse of
    :func:`quat_from_euler_zyx` for pitch in (-π/2, π/2). Row-wise on (..., 4) arrays."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return np.stack((roll, pitch, yaw), axis=-1)


def wrap_angle(angle):
    """Angle(s) wrapped to [-π, π)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def yaw_of(q: np.ndarray) -> float:
    """Heading (rad) of the body x axis projected on the world x-y plane."""
    w, x, y, z = q
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def tilt_angle(q: np.ndarray) -> float:
    """Angle (rad) between the body z axis and the world z axis."""
    x, y = q[1], q[2]
    cos_tilt = 1.0 - 2.0 * (x * x + y * y)
    return math.acos(max(-1.0, min(1.0, cos_tilt)))


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` for 3-vectors or row-wise for (N, 3) arrays (``np.cross`` without its overhead)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0), axis=-1)


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix: ``skew(a) @ b == np.cross(a, b)``."""
    return np.array(((0.0, -v[2], v[1]), (v[2], 0.0, -v[0]), (-v[1], v[0], 0.0)))


# The bilinear tensor of the row-wise rotation matrices, read off the single-quaternion form above.
_ROTATION = _bilinear_tensor(_homogeneous_rotation, 4, 4)

"""Small dense linear algebra and input checks shared by the compiled estimator kernels."""

from __future__ import annotations

import math

from numpy.lib.stride_tricks import as_strided

from quad_wrench_env.numerics import njit


@njit(inline=True)
def rows_view(array, start, n, width):
    """(n, width) view, rows in order, of the flat float ``array`` from ``start``: free where numba's
    ``reshape`` costs a call (as much as a small kernel's arithmetic)."""
    return as_strided(array[start : start + n * width], shape=(n, width), strides=(8 * width, 8))


@njit
def cholesky(a, out):
    """Lower Cholesky factor of ``a`` into ``out``; False when ``a`` is not positive definite."""
    n = a.shape[0]
    for j in range(n):
        s = a[j, j]
        for k in range(j):
            s -= out[j, k] * out[j, k]
        if not s > 0.0:
            return False
        d = math.sqrt(s)
        out[j, j] = d
        for i in range(j + 1, n):
            t = a[i, j]
            for k in range(j):
                t -= out[i, k] * out[j, k]
            out[i, j] = t / d
        for i in range(j):
            out[i, j] = 0.0
    return True


@njit
def weighted_gram(weighted, columns, out):
    """``out = weighted columnsᵀ`` for (k, m) ``weighted`` and ``columns`` whose product is symmetric
    (``weighted`` is ``columns`` with each column scaled): the lower triangle as dot products along the
    contiguous rows, four of a row's at once (independent sums the CPU overlaps), mirrored. Each sum runs
    over the columns in order, as the UKF's SIMD lanes sum
    (:mod:`~quad_wrench_env.estimators.ukf_lanes_kernel`), and none is regrouped: a filter gives the same
    bits in a bank of any size, on any CPU's vector width."""
    m = columns.shape[1]
    for a in range(out.shape[0]):
        c = 0
        while c + 3 <= a:  # four sums at once, each over the columns in order
            t0 = t1 = t2 = t3 = 0.0
            for j in range(m):
                w = weighted[a, j]
                t0 += w * columns[c, j]
                t1 += w * columns[c + 1, j]
                t2 += w * columns[c + 2, j]
                t3 += w * columns[c + 3, j]
            out[a, c], out[a, c + 1], out[a, c + 2], out[a, c + 3] = t0, t1, t2, t3
            c += 4
        while c <= a:
            total = 0.0
            for j in range(m):
                total += weighted[a, j] * columns[c, j]
            out[a, c] = total
            c += 1
    for a in range(out.shape[0]):
        for c in range(a):
            out[c, a] = out[a, c]


@njit(inline=True)
def forward_solve_rows(root, rows, out):
    """``out[r] = L⁻¹ rows[r]`` for every row of ``rows`` (m, k), ``root`` the lower factor ``L``
    (k, k) of ``S = L Lᵀ``: with ``rows = P Hᵀ``, ``out`` is ``M = P Hᵀ L⁻ᵀ``, and ``K S Kᵀ = M Mᵀ``.
    ``out`` may be ``rows`` (each entry is read before it is written)."""
    k = root.shape[0]
    for r in range(rows.shape[0]):
        for c in range(k):
            t = rows[r, c]
            for m in range(c):
                t -= root[c, m] * out[r, m]
            out[r, c] = t / root[c, c]


@njit(inline=True)
def cholesky_solve_rows(root, rows, out):
    """``out[r] = (L Lᵀ)⁻¹ rows[r]`` for every row of ``rows`` (m, k), with the lower factor ``root``
    (k, k) of a symmetric matrix: the Kalman gain ``K = P Hᵀ S⁻¹`` row by row from ``rows = P Hᵀ``."""
    k = root.shape[0]
    forward_solve_rows(root, rows, out)
    for r in range(rows.shape[0]):
        for c in range(k - 1, -1, -1):
            t = out[r, c]
            for m in range(c + 1, k):
                t -= root[m, c] * out[r, m]
            out[r, c] = t / root[c, c]


@njit(inline=True)
def all_finite(values):
    """Whether every entry of the 1-d array ``values`` is finite (``np.isfinite(values).all()``): one
    independent test per entry, where a running sum would chain the additions one after another
    (and turn an overflow into a false alarm)."""
    finite = True
    for i in range(values.shape[0]):
        finite &= math.isfinite(values[i])
    return finite


@njit
def inputs_finite(thrusts, body_torques, positions, quaternions, velocities, body_rates):
    """Whether every estimator input is finite (one sum per vehicle: NaN and inf propagate);
    ``velocities`` and ``body_rates`` are (0, 3) when not measured."""
    with_velocity, with_rates = velocities.shape[0] > 0, body_rates.shape[0] > 0
    for n in range(thrusts.shape[0]):
        total = thrusts[n]
        for i in range(3):
            total += body_torques[n, i] + positions[n, i]
            if with_velocity:
                total += velocities[n, i]
            if with_rates:
                total += body_rates[n, i]
        for i in range(4):
            total += quaternions[n, i]
        if not math.isfinite(total):
            return False
    return True

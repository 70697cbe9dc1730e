"""Hentzen et al.'s (2019) eq. (4) as the sparse QP, written apart from the controller's condensed one:
the states ``x_1..x_N`` and the inputs ``u_0..u_{N-1}`` (with the slack ``ε_k`` where on) all decision
variables (the slack on the height ``ζ_k`` too, with a ``height_limit``), the model
``x_{k+1} = A_d·x_k + B_d·u_k + c_d`` as equality constraints, solved by OSQP to
``1e-10`` with polishing (the active set's exact solution). It reads from the controller only the model
it linearised (``A_d``, ``B_d``, ``c_d``) and the references it solved for, both checked elsewhere
(tests/test_mpc.py: the model against the nonlinear equations, the input reference against the thrust
vector)."""

from __future__ import annotations

import numpy as np
import osqp
from scipy import sparse

from quad_wrench_env.control.mpc_controller import NU, NX, PositionMPC


def sparse_solution(
    mpc: PositionMPC, hard: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(states (N+1, 8), inputs (N, 3), cross-track slacks (N), height slacks (N)) of the QP ``mpc``
    solved last (its model, references, weights and bounds); ``hard``: no slack variables at all, the
    bands imposed outright."""
    g, n = mpc.gains, mpc.horizon
    soft = g.slack and not hard
    height = g.slack and g.height_limit is not None
    slacks = int(soft) * (1 + int(height))  # per step: ε_k, then ζ_k
    nu = NU + slacks
    size = n * NX + n * nu
    x = lambda k: (k - 1) * NX  # noqa: E731  column of x_k, k = 1..N
    u = lambda k: n * NX + k * nu  # noqa: E731  column of u_k, k = 0..N-1

    q = np.array((*g.position_weight, *g.velocity_weight, g.attitude_weight, g.attitude_weight))
    state_weights = [q * (g.terminal_weight if k == n else 1.0) for k in range(1, n + 1)]
    r = np.array((g.input_weight[0] / mpc.mass**2, g.input_weight[1], g.input_weight[2]))
    linear, quadratic = mpc.slack_weights
    p_diag = np.zeros(size)
    q_lin = np.zeros(size)
    for k in range(1, n + 1):
        p_diag[x(k) : x(k) + NX] = 2.0 * state_weights[k - 1]
        q_lin[x(k) : x(k) + NX] = -2.0 * state_weights[k - 1] * mpc.state_reference[k]
    for k in range(n):
        p_diag[u(k) : u(k) + NU] = 2.0 * r
        q_lin[u(k) : u(k) + NU] = -2.0 * r * mpc.input_reference[k]
        for which, factor in enumerate((1.0, g.height_priority)[:slacks]):
            p_diag[u(k) + NU + which] = 2.0 * quadratic * factor
            q_lin[u(k) + NU + which] = linear * factor

    rows, lower, upper = [], [], []

    def row(entries: dict[int, float], low: float, high: float) -> None:
        line = np.zeros(size)
        for column, value in entries.items():
            line[column] += value
        rows.append(line)
        lower.append(low)
        upper.append(high)

    x0 = mpc.predicted_states[0]
    for k in range(n):  # x_{k+1} - A x_k - B u_k = c (x_0 is data)
        for i in range(NX):
            entries = {x(k + 1) + i: 1.0}
            for j in range(NU):
                entries[u(k) + j] = entries.get(u(k) + j, 0.0) - mpc.B_d[i, j]
            rhs = mpc.c_d[i]
            if k == 0:
                rhs += mpc.A_d[i] @ x0
            else:
                for j in range(NX):
                    entries[x(k) + j] = entries.get(x(k) + j, 0.0) - mpc.A_d[i, j]
            row(entries, rhs, rhs)
    for k in range(n):
        for j in range(NU):
            row({u(k) + j: 1.0}, mpc.input_lower[j], mpc.input_upper[j])
        for which in range(slacks):
            row({u(k) + NU + which: 1.0}, 0.0, np.inf)
    if g.slack:
        bands = [(0, g.cross_track_limit, 0), (1, g.cross_track_limit, 0)]
        if height:
            bands.append((2, g.height_limit, 1))
        for k in range(1, n + 1):
            for axis, e, which in bands:
                p_ref = mpc.state_reference[k, axis]
                if soft:
                    row({x(k) + axis: 1.0, u(k - 1) + NU + which: -1.0}, -np.inf, p_ref + e)
                    row({x(k) + axis: 1.0, u(k - 1) + NU + which: 1.0}, p_ref - e, np.inf)
                else:
                    row({x(k) + axis: 1.0}, p_ref - e, p_ref + e)

    solver = osqp.OSQP()
    solver.setup(
        sparse.diags(p_diag, format="csc"),
        q_lin,
        sparse.csc_matrix(np.array(rows)),
        np.array(lower),
        np.array(upper),
        eps_abs=1e-10,
        eps_rel=1e-10,
        max_iter=200_000,
        polishing=True,
        verbose=False,
    )
    result = solver.solve(raise_error=False)
    assert result.info.status == "solved", result.info.status
    z = result.x
    inputs = z[n * NX :].reshape(n, nu)
    states = np.vstack((x0, z[: n * NX].reshape(n, NX)))
    zeros = np.zeros(n)
    return (
        states,
        inputs[:, :NU],
        inputs[:, NU] if slacks else zeros,
        inputs[:, NU + 1] if slacks == 2 else zeros,
    )

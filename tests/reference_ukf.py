"""A plain unscented wrench filter, written here from McKinnon & Schoellig (2016, Sec. II) as the module
docstring of :mod:`quad_wrench_env.estimators.ukf` states its equations, to hold the compiled filter to
(``tests/test_ukf.py``). It uses none of the package's filter code and none of its shortcuts:

* prediction: all ``2L + 1 = 61`` sigma points of the extended state, the 18 error-state components
  and the 12 process-noise terms ``η = (η_τm, η_τe, η_ct, η_fe)`` (L = 30), from the Cholesky factor
  of ``diag(P, Q)`` (eqs. 18-22), each through the nonlinear model with its noise (eqs. 2-5, 11-14),
  recombined with attitude errors as MRPs about the propagated central point (eqs. 25-27);
* correction: the unscented form (eqs. 29-36): ``2·24 + 1`` sigma points of ``diag(P̌, G)`` mapped
  through the measurement, the motion-capture position and the attitude as MRPs about the prediction
  (eq. 35) plus their noise, the weighted covariances ``Σ_yy`` and ``Σ_xy``, the gain
  ``K = Σ_xy Σ_yy⁻¹``, and the update of eq. 37.

Weights ``κ/(L+κ)`` and ``1/(2(L+κ))`` (eq. 28 with the second corrected so that they sum to one,
as in the package). Plain numpy, one filter, one sigma point at a time as the paper writes them:
slow and unoptimised on purpose. The quaternion helpers are written here too (Hamilton,
``[w, x, y, z]``, body -> world).
"""

from __future__ import annotations

import math

import numpy as np

from quad_wrench_env.estimators.noise import FilterNoise


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` of two 3-vectors."""
    return np.array((a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]))


def qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a ⊗ b``."""
    aw, av, bw, bv = a[0], a[1:], b[0], b[1:]
    return np.concatenate(((aw * bw - av @ bv,), aw * bv + bw * av + cross(av, bv)))


def qinv(q: np.ndarray) -> np.ndarray:
    """Inverse of a unit quaternion."""
    return np.concatenate((q[:1], -q[1:]))


def q_from_mrp(rho: np.ndarray) -> np.ndarray:
    """Unit quaternion of MRPs ``ρ = q_v/(1 + q_0)`` (eq. 17)."""
    n2 = rho @ rho
    return np.concatenate((((1.0 - n2) / (1.0 + n2),), 2.0 * rho / (1.0 + n2)))


def mrp_from_q(q: np.ndarray) -> np.ndarray:
    """MRPs ``q_v/(1 + q_0)`` of a unit quaternion taken with ``q_0 >= 0`` (eq. 16)."""
    q = q if q[0] >= 0.0 else -q
    return q[1:] / (1.0 + q[0])


def q_exp(rotation_vector: np.ndarray) -> np.ndarray:
    """Quaternion of the rotation by the vector ``θ e``: ``(cos θ/2, sin(θ/2) e)``."""
    angle = math.sqrt(rotation_vector @ rotation_vector)
    if angle == 0.0:
        return np.array((1.0, 0.0, 0.0, 0.0))
    return np.concatenate(((math.cos(angle / 2.0),), math.sin(angle / 2.0) * rotation_vector / angle))


def rotation(q: np.ndarray) -> np.ndarray:
    """Body -> world rotation matrix of a unit quaternion."""
    w, x, y, z = q
    return np.array(
        (
            (1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
            (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
            (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)),
        )
    )


def sigma_points(covariance: np.ndarray, kappa: float) -> tuple[np.ndarray, np.ndarray]:
    """The ``2L + 1`` points ``0, ±sqrt(L+κ)·col_j chol(covariance)`` (eqs. 19-22) and their weights."""
    size = len(covariance)
    lam = size + kappa
    offsets = math.sqrt(lam) * np.linalg.cholesky(covariance).T  # row j: column j of the factor
    points = np.vstack((np.zeros(size), offsets, -offsets))
    weights = np.full(2 * size + 1, 1.0 / (2.0 * lam))
    weights[0] = kappa / lam
    return points, weights


class ReferenceUKF:
    """One unscented wrench filter of McKinnon & Schoellig (2016): mean quaternion ``q``, ``rest`` =
    (ω, x, ẋ, τ_e, f_e) and the (18, 18) error-state covariance ``P``."""

    def __init__(self, mass: float, inertia: np.ndarray, dt: float, gravity: float, noise: FilterNoise):
        self.mass, self.inertia, self.dt, self.gravity, self.kappa = mass, inertia, dt, gravity, noise.kappa
        n = noise
        self.Q = np.diag(np.repeat((n.motor_torque, n.torque_walk, n.thrust, n.force_walk), 3) ** 2)
        self.G = np.diag(np.repeat((n.position, math.tan(n.attitude / 4.0)), 3) ** 2)  # ρ = tan(θ/4)
        initial = (math.tan(n.initial_attitude / 4.0), n.initial_rates, n.initial_position)
        initial += (n.initial_velocity, n.initial_torque, n.initial_force)
        self.P = np.diag(np.repeat(initial, 3) ** 2)
        self.q = np.array((1.0, 0.0, 0.0, 0.0))
        self.rest = np.zeros(15)
        self.Q0 = self.Q.copy()
        self.adaptive, self.forgetting, self.floor = n.adaptive_walks, n.walk_forgetting, n.walk_floor
        self.ceiling = n.walk_ceiling
        self.M: dict[int, np.ndarray] = {}
        self.reset_walks()

    def reset_walks(self) -> None:
        """The walks where a filter starts: ``Q``'s own, the floor added where they are matched."""
        self.Q = self.Q0.copy()
        self.M = {first: self.Q0[first : first + 3, first : first + 3].copy() for first in (3, 9)}
        if self.adaptive:
            for first in self.M:
                self._walk_into_q(first)

    def _walk_into_q(self, first: int) -> None:
        block = np.s_[first : first + 3]
        self.Q[block, block] = self.M[first] + self.floor**2 * self.Q0[block, block]

    def reset(self, position: np.ndarray, quaternion: np.ndarray) -> None:
        """At the pose, at rest, no external wrench, the walks where they start."""
        self.q = np.array(quaternion, dtype=float)
        self.rest = np.zeros(15)
        self.rest[3:6] = position
        self.reset_walks()

    def model(self, q: np.ndarray, rest: np.ndarray, noise: np.ndarray, thrust: float, torque: np.ndarray):
        """One step of the motion model (eqs. 2-5, 11-14) of the state ``(q, rest)`` with the process
        noise ``(η_τm, η_τe, η_ct, η_fe)``: the next quaternion and rest."""
        T, m, J = self.dt, self.mass, self.inertia
        omega, x, v, tau_e, f_e = (rest[i : i + 3] for i in range(0, 15, 3))
        eta_tm, eta_te, eta_ct, eta_fe = (noise[i : i + 3] for i in range(0, 12, 3))
        R = rotation(q)
        accel = R @ (np.array((0.0, 0.0, thrust)) + eta_ct) / m - np.array((0.0, 0.0, self.gravity)) + f_e / m
        omega_next = omega + T * (R.T @ tau_e + torque + eta_tm - cross(omega, J * omega)) / J
        rest_next = np.concatenate(
            (omega_next, x + T * v + 0.5 * T * T * accel, v + T * accel, tau_e + eta_te, f_e + eta_fe)
        )
        return qmul(q, q_exp(omega * T)), rest_next

    def predict(self, thrust: float, torque: np.ndarray) -> None:
        """The 61 sigma points of ``diag(P, Q)`` through :meth:`model`, recombined (eqs. 18-28)."""
        extended = np.zeros((30, 30))
        extended[:18, :18], extended[18:, 18:] = self.P, self.Q
        points, weights = sigma_points(extended, self.kappa)
        propagated = [
            self.model(qmul(self.q, q_from_mrp(p[0:3])), self.rest + p[3:18], p[18:], thrust, torque)
            for p in points
        ]
        centre = propagated[0][0]
        errors = np.array([np.concatenate((mrp_from_q(qmul(qinv(centre), q)), r)) for q, r in propagated])
        mean = weights @ errors
        deviations = errors - mean
        self.P = (weights[:, None] * deviations).T @ deviations
        self.q = qmul(centre, q_from_mrp(mean[0:3]))
        self.rest = mean[3:]

    def correct(self, position: np.ndarray, quaternion: np.ndarray) -> None:
        """The unscented correction with the measured pose (eqs. 29-37)."""
        extended = np.zeros((24, 24))
        extended[:18, :18], extended[18:, 18:] = self.P, self.G
        points, weights = sigma_points(extended, self.kappa)
        measured = []
        for p in points:  # the measurement of each point: its position and its attitude about q̌
            q_point = qmul(self.q, q_from_mrp(p[0:3]))
            attitude = mrp_from_q(qmul(qinv(self.q), q_point))
            measured.append(np.concatenate((self.rest[3:6] + p[6:9] + p[18:21], attitude + p[21:24])))
        measured = np.array(measured)
        y_mean = weights @ measured
        dy = measured - y_mean
        dx = points[:, :18] - weights @ points[:, :18]
        s = (weights[:, None] * dy).T @ dy  # Σ_yy (eq. 33)
        c = (weights[:, None] * dx).T @ dy  # Σ_xy (eq. 34)
        gain = c @ np.linalg.inv(s)  # (29)
        innovation = np.concatenate((position, mrp_from_q(qmul(qinv(self.q), quaternion)))) - y_mean  # (35)
        delta = gain @ innovation  # (31), (36)
        self.P = self.P - gain @ s @ gain.T  # (30)
        q = qmul(self.q, q_from_mrp(delta[0:3]))  # (37)
        self.q = q / np.linalg.norm(q)
        self.rest = self.rest + delta[3:]

    def step(self, thrust: float, torque: np.ndarray, position: np.ndarray, quaternion: np.ndarray) -> None:
        """Predict, correct, then (``adaptive_walks``) each walk block ``M`` of ``Q`` (torque: entries
        3-5, force: 9-11) moves towards the outer product of the change the step made to its wrench
        estimate, by exponential forgetting (Akhlaghi, Zhou & Huang 2017), ``M <- α M + (1 - α) d dᵀ``,
        shrunk to a trace of ``ceiling²`` times the start's where above; ``Q`` holds ``M`` plus the floor,
        ``floor²`` times the walk's variance at the start, on its diagonal."""
        before = self.rest[9:15].copy()  # τ_e, f_e
        self.predict(thrust, torque)
        self.correct(position, quaternion)
        if self.adaptive:
            change = self.rest[9:15] - before
            for first, d in ((3, change[:3]), (9, change[3:])):
                self.M[first] = self.forgetting * self.M[first] + (1.0 - self.forgetting) * np.outer(d, d)
                limit = self.ceiling**2 * np.trace(self.Q0[first : first + 3, first : first + 3])
                self.M[first] *= min(1.0, limit / np.trace(self.M[first]))
                self._walk_into_q(first)

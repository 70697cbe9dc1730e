"""The unscented external force and torque estimator of McKinnon & Schoellig (paper 000, Sec. II).

State ``s = (q, ω, x, ẋ, τ_e, f_e)`` (eq. list of Sec. II-C): attitude quaternion (Hamilton, body ->
world), body rates, position, velocity, and the external torque and force in the world frame. The
attitude mean is a unit quaternion; its uncertainty is a 3-vector of MRPs ``δρ = δq_v/(1 + δq_0)``
(eqs. 15-17, USQUE), so the error state has 18 components:

    index  0-2 δρ | 3-5 ω | 6-8 x | 9-11 ẋ | 12-14 τ_e | 15-17 f_e

Process noise (eq. 18) stacks ``η = (η_τm, η_τe, η_ct, η_fe)``, 12 terms, for an extended state of
``L = 30``. Sigma points come from the Cholesky factor of the block-diagonal extended covariance
(eqs. 19-22) with weights ``κ/(L+κ)`` and ``1/(2(L+κ))`` (eq. 28 as corrected in
``shared/papers/README.md``: they sum to one).

Prediction (eqs. 2-5, 11-14), for each sigma point, with thrust ``c_t`` and motor torque ``τ_m``
from the nominal mixer and the quantized motor speeds:

    ẍ = R (c_t e_z + η_ct)/m - g e_z + f_e/m             (4)
    x' = x + T ẋ + ½ T² ẍ,   ẋ' = ẋ + T ẍ                 (2), (3)
    q' = q ⊗ exp(ω T / 2)                                 (11), (13)  [Hamilton: q_i = q ⊗ δq_i]
    ω' = ω + T J⁻¹ (Rᵀ τ_e + τ_m + η_τm - ω × J ω)         (12)
    τ_e' = τ_e + η_τe,   f_e' = f_e + η_fe                (14), (5)

The paper writes the attitude in the Shuster (JPL) convention with ``q_i = δq_i ⊗ q`` (eq. 24); in
the Hamilton body -> world convention used here the same filter reads ``q_i = q ⊗ δq_i`` and
``δq_i = q_0⁻¹ ⊗ q_i`` (eq. 25), and the measured attitude is compared through
``δq = q̌⁻¹ ⊗ q_meas`` (eq. 35) and applied as ``q̂ = q̌ ⊗ δq`` (eq. 37).

Two exact shortcuts make the step cheap, both checked against the plain form by the tests:

* The 24 noise-only sigma points have the mean state, and the noise enters the model linearly
  (``B``, below), so they add exactly ``B Q Bᵀ`` to the covariance and nothing to the mean: only the
  37 state sigma points go through the nonlinear model.
* The observation (position, attitude MRP) is linear in the error state, so the unscented
  correction (eqs. 29-36, sigma points of ``(P̌, G)``) equals the Kalman update with
  ``H = [I_δρ, I_x]``; it is done in that form.

If the covariance loses positive definiteness (Cholesky fails), the filter keeps its mean and resets
the covariance to the initial one; if its state ever became non-finite it restarts from the measured
pose at rest. Either way it reports ``status = "reinitialised"`` from then on (the env puts it in
``info["estimator_status"]``). A non-finite input raises ``ValueError``: nothing non-finite enters.
"""

from __future__ import annotations

import math

import numpy as np

from quad_wrench_env.estimators.base import StateEstimate, WrenchEstimate, check_finite_inputs
from quad_wrench_env.estimators.noise import FilterNoise, mrp_std
from quad_wrench_env.rotations import (
    cross,
    mrp_from_quat,
    quat_conjugate,
    quat_exp,
    quat_from_mrp,
    quat_multiply,
    quat_multiply_rows,
    rotation_matrices,
)
from quad_wrench_env.vehicle import GRAVITY, VehicleParams

STATE_DIM = 18
NOISE_DIM = 12
ATT, RATE, POS, VEL, TORQUE, FORCE = (slice(i, i + 3) for i in range(0, 18, 3))
_MEASURED = np.r_[6:9, 0:3]
"""Error-state indices of the measurement ``(x, δρ)`` (``H`` selects them)."""
_WRENCH_BLOCK = np.ix_(np.r_[15:18, 12:15], np.r_[15:18, 12:15])
"""Error-state block of ``[f_e, τ_e]`` (the order of :class:`WrenchEstimate`'s covariance)."""


class UnscentedWrenchEstimator:
    """USQUE-based external wrench estimator (paper 000); see the module docstring."""

    name = "ukf"

    def __init__(self, vehicle: VehicleParams, dt: float, noise: FilterNoise | None = None) -> None:
        self.vehicle = vehicle
        self.dt = dt
        self.noise = noise or FilterNoise()
        n = self.noise
        self.mass = vehicle.mass
        self.inertia = np.array(vehicle.inertia)
        self.L = STATE_DIM + NOISE_DIM
        lam = self.L + n.kappa
        self.spread = math.sqrt(lam)
        self.weight_centre = n.kappa / lam
        self.weight_other = 1.0 / (2.0 * lam)
        self.num_noise_points = 2 * NOISE_DIM
        # The noise-only points have the mean state: their weight adds to the centre's (module doc).
        self._mean_weights = np.full(2 * STATE_DIM + 1, self.weight_other)
        self._mean_weights[0] = self.weight_centre + self.num_noise_points * self.weight_other
        self.Q = np.diag(np.repeat((n.motor_torque, n.torque_walk, n.thrust, n.force_walk), 3) ** 2)
        self.G = np.diag(np.repeat((n.position, mrp_std(n.attitude)), 3) ** 2)
        self.P0 = np.diag(
            np.repeat(
                (
                    mrp_std(n.initial_attitude),
                    n.initial_rates,
                    n.initial_position,
                    n.initial_velocity,
                    n.initial_torque,
                    n.initial_force,
                ),
                3,
            )
            ** 2
        )
        self._prior_rotation = np.eye(3)
        self._B = np.zeros((STATE_DIM, NOISE_DIM))
        self._B[RATE, 0:3] = np.diag(dt / self.inertia)
        self._B[TORQUE, 3:6] = np.eye(3)
        self._B[FORCE, 9:12] = np.eye(3)
        self._q_diagonal = np.diag(self.Q).copy()
        self.quaternion = np.array((1.0, 0.0, 0.0, 0.0))
        self.rest = np.zeros(STATE_DIM - 3)
        """(ω, x, ẋ, τ_e, f_e): the error-state components other than the attitude, at their mean."""
        self.P = self.P0.copy()
        self.status = "ok"
        self.reinitialisations = 0

    # -- interface -------------------------------------------------------------------------------
    def reset(self, position: np.ndarray, quaternion_wxyz: np.ndarray) -> None:
        self.quaternion = np.array(quaternion_wxyz, dtype=float)
        self.rest = np.zeros(STATE_DIM - 3)
        self.rest[POS.start - 3 : POS.stop - 3] = position
        self.P = self.P0.copy()
        self.status = "ok"
        self.reinitialisations = 0

    def step(
        self,
        thrust: float,
        body_torque: np.ndarray,
        position: np.ndarray,
        quaternion_wxyz: np.ndarray,
        velocity: np.ndarray | None = None,
        body_rates: np.ndarray | None = None,
    ) -> WrenchEstimate:
        """Predict and correct with the measured pose; paper 000's filter measures nothing else, so
        ``velocity`` and ``body_rates`` are not used."""
        check_finite_inputs(
            self.name, thrust=thrust, body_torque=body_torque, position=position, quaternion=quaternion_wxyz
        )
        position = np.asarray(position, dtype=float)
        quaternion = np.asarray(quaternion_wxyz, dtype=float)
        self.predict(float(thrust), np.asarray(body_torque, dtype=float))
        self.correct(position, quaternion)
        if not (np.all(np.isfinite(self.rest)) and np.all(np.isfinite(self.P))):
            self.reset(position, quaternion)
            self.status = "reinitialised"
            self.reinitialisations += 1
        return self.estimate

    @property
    def estimate(self) -> WrenchEstimate:
        r = self.rest
        return WrenchEstimate(r[12:15].copy(), r[9:12].copy(), self.P[_WRENCH_BLOCK])

    @property
    def state(self) -> StateEstimate:
        r = self.rest
        return StateEstimate(r[3:6].copy(), r[6:9].copy(), self.quaternion.copy(), r[0:3].copy())

    # -- prediction (eqs. 18-28) -------------------------------------------------------------------
    def state_sigma_points(self) -> np.ndarray:
        """(37, 18) error-state sigma points ``0, ±sqrt(L+κ)·col_j chol(P)`` (eqs. 19-22)."""
        try:
            root = np.linalg.cholesky(self.P)
        except np.linalg.LinAlgError:
            self.P = self.P0.copy()
            self.status = "reinitialised"
            self.reinitialisations += 1
            root = np.linalg.cholesky(self.P)
        offsets = self.spread * root.T
        return np.vstack((np.zeros(STATE_DIM), offsets, -offsets))

    def propagate(
        self, errors: np.ndarray, thrust: float, body_torque: np.ndarray, noise: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Motion model (eqs. 2-5, 11-14) for error-state points (N, 18) around the current mean,
        optionally with process noise (N, 12); returns propagated quaternions (N, 4) and the other
        components (N, 15)."""
        T, m = self.dt, self.mass
        q = quat_multiply_rows(self.quaternion, quat_from_mrp(errors[:, ATT]))
        rest = self.rest + errors[:, 3:]
        omega, v, tau_e, f_e = rest[:, 0:3], rest[:, 6:9], rest[:, 9:12], rest[:, 12:15]
        R = rotation_matrices(q)
        self._prior_rotation = R[0]
        if noise is None:
            accel = (thrust / m) * R[:, :, 2] + f_e / m
            motor_torque = body_torque
        else:
            body_force = noise[:, 6:9].copy()
            body_force[:, 2] += thrust
            accel = np.einsum("nij,nj->ni", R, body_force) / m + f_e / m
            motor_torque = body_torque + noise[:, 0:3]
        accel[:, 2] -= GRAVITY
        torque = np.einsum("nji,nj->ni", R, tau_e) + motor_torque - cross(omega, omega * self.inertia)
        out = rest.copy()  # ω, x, ẋ, τ_e, f_e
        out[:, 0:3] += (T / self.inertia) * torque
        out[:, 3:6] += T * v + (0.5 * T * T) * accel
        out[:, 6:9] += T * accel
        if noise is not None:
            out[:, 9:12] += noise[:, 3:6]
            out[:, 12:15] += noise[:, 9:12]
        return quat_multiply_rows(q, quat_exp(omega * T)), out

    def noise_jacobian(self, R: np.ndarray) -> np.ndarray:
        """``B`` (18, 12): how the process noise enters the error state over one step, for the mean
        attitude ``R`` before the step."""
        T, m = self.dt, self.mass
        B = self._B
        B[POS, 6:9] = (0.5 * T * T / m) * R
        B[VEL, 6:9] = (T / m) * R
        return B

    def recombine(self, q_points: np.ndarray, rest_points: np.ndarray, weights: np.ndarray):
        """Predicted mean quaternion, other components and covariance of propagated sigma points
        (eqs. 25-27): attitude errors are MRPs relative to the propagated central point."""
        q0 = q_points[0]
        errors = np.hstack((mrp_from_quat(quat_multiply_rows(quat_conjugate(q0), q_points)), rest_points))
        mean = weights @ errors
        deviations = errors - mean
        covariance = (deviations * weights[:, None]).T @ deviations
        return quat_multiply(q0, quat_from_mrp(mean[ATT])), mean[3:], covariance

    def predict(self, thrust: float, body_torque: np.ndarray) -> None:
        q_points, rest_points = self.propagate(self.state_sigma_points(), thrust, body_torque)
        B = self.noise_jacobian(self._prior_rotation)  # the central point is the prior mean
        self.quaternion, self.rest, P = self.recombine(q_points, rest_points, self._mean_weights)
        self.P = P + (B * self._q_diagonal) @ B.T  # B Q Bᵀ, Q diagonal

    # -- correction (eqs. 29-37) -------------------------------------------------------------------
    def innovation(self, position: np.ndarray, quaternion: np.ndarray) -> np.ndarray:
        """Measured minus predicted ``(x, δρ)``; the attitude part is ``δq = q̌⁻¹ ⊗ q_meas`` (eq. 35)."""
        attitude = mrp_from_quat(quat_multiply(quat_conjugate(self.quaternion), quaternion))
        return np.concatenate((position - self.rest[3:6], attitude))

    def correct(self, position: np.ndarray, quaternion: np.ndarray) -> None:
        P = self.P
        PHt = P[:, _MEASURED]  # Σ_xy = P Hᵀ: H only picks the position and attitude components
        S = PHt[_MEASURED] + self.G  # Σ_yy
        K = np.linalg.solve(S, PHt.T).T  # (29)
        delta = K @ self.innovation(position, quaternion)  # (31), (36)
        P = P - K @ PHt.T  # (30)
        self.P = 0.5 * (P + P.T)
        q = quat_multiply(self.quaternion, quat_from_mrp(delta[ATT]))  # (37)
        self.quaternion = q / math.sqrt(float(q @ q))
        self.rest = self.rest + delta[3:]

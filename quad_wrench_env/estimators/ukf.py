"""The unscented external force and torque estimator of McKinnon & Schoellig (2016, Sec. II).

State ``s = (q, ω, x, ẋ, τ_e, f_e)`` (eq. list of Sec. II-C): attitude quaternion (Hamilton, body ->
world), body rates, position, velocity, and the external torque and force in the world frame. The
attitude mean is a unit quaternion; its uncertainty is a 3-vector of MRPs ``δρ = δq_v/(1 + δq_0)``
(eqs. 15-17, USQUE), so the error state has 18 components:

    index  0-2 δρ | 3-5 ω | 6-8 x | 9-11 ẋ | 12-14 τ_e | 15-17 f_e

Process noise (eq. 18) stacks ``η = (η_τm, η_τe, η_ct, η_fe)``, 12 terms, for an extended state of
``L = 30``. Sigma points come from the Cholesky factor of the block-diagonal extended covariance
(eqs. 19-22) with weights ``κ/(L+κ)`` and ``1/(2(L+κ))`` (eq. 28 as printed gives
``½·κ/(L+κ)`` for the second, corrected here so that they sum to one; ``docs/physics.md``, "The unscented
filter").

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

:class:`UnscentedFilterBank` runs N such filters as one batched computation (every array carries
a leading filter axis); :class:`UnscentedWrenchEstimator`, the single-vehicle estimator, is a bank
of one, so there is one implementation of the algebra. Compiled (numba), a bank runs filter by
filter (:mod:`quad_wrench_env.kernels.ukf`) or, from
:data:`~quad_wrench_env.kernels.ukf_lanes.LANES_FROM` filters on, eight filters at a time on SIMD
lanes (:mod:`quad_wrench_env.kernels.ukf_lanes`).
"""

from __future__ import annotations

import math

import numpy as np

from quad_wrench_env.estimators.bank import BankOfOne, FilterBank
from quad_wrench_env.estimators.noise import FilterNoise, mrp_std, rotor_spread_body, rotor_spread_covariance
from quad_wrench_env.kernels import resolve_backend
from quad_wrench_env.kernels.ukf import ukf_bank_step, ukf_constants, ukf_estimates
from quad_wrench_env.rotations import (
    cross,
    mrp_from_quat,
    quat_conjugate,
    quat_exp,
    quat_from_mrp,
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


class UnscentedFilterBank(FilterBank):
    """N unscented wrench filters of one vehicle model, stepped together (McKinnon & Schoellig 2016, Sec. II).

    State arrays: ``quaternions`` (N, 4), ``rests`` (N, 15) = (ω, x, ẋ, τ_e, f_e) at their mean, and
    ``covariances`` (N, 18, 18) of the error state.
    """

    def __init__(
        self, vehicle: VehicleParams, dt: float, noise: FilterNoise | None, count: int, backend: str = "numpy"
    ) -> None:
        if count < 1:
            raise ValueError(f"count={count!r} must be at least 1 filter")
        self.backend = resolve_backend(backend)
        self.vehicle = vehicle
        self.dt = dt
        self.noise = noise or FilterNoise()
        self._rotor_spread = rotor_spread_body(vehicle, self.noise.rotor_spread)
        n = self.noise
        self.count = count
        self.mass = vehicle.mass
        self.inertia = np.array(vehicle.inertia)
        self.L = STATE_DIM + NOISE_DIM
        lam = self.L + n.kappa
        self.spread = math.sqrt(lam)
        self.weight_centre = n.kappa / lam
        self.weight_other = 1.0 / (2.0 * lam)
        # The noise-only points have the mean state: their weight adds to the centre's (module doc).
        self.mean_weights = np.full(2 * STATE_DIM + 1, self.weight_other)
        self.mean_weights[0] = self.weight_centre + 2 * NOISE_DIM * self.weight_other
        self.Q = np.diag(np.repeat((n.motor_torque, n.torque_walk, n.thrust, n.force_walk), 3) ** 2)
        self.G = np.diag(np.repeat((n.position, mrp_std(n.attitude)), 3) ** 2)
        initial = (n.initial_attitude, n.initial_rates, n.initial_position, n.initial_velocity)
        self.P0 = np.diag(
            np.repeat((mrp_std(initial[0]), *initial[1:], n.initial_torque, n.initial_force), 3) ** 2
        )
        self._B = np.zeros((STATE_DIM, NOISE_DIM))
        self._B[RATE, 0:3] = np.diag(dt / self.inertia)
        self._B[TORQUE, 3:6] = np.eye(3)
        self._B[FORCE, 9:12] = np.eye(3)
        self._q_diagonal = np.diag(self.Q).copy()
        self.kernel_constants = ukf_constants(
            dt, self.mass, self.inertia, GRAVITY, self.spread, self.mean_weights[0], self.weight_other,
            self._q_diagonal, np.diag(self.G), self.P0,
        )  # fmt: skip
        """The compiled step's constants (:func:`~quad_wrench_env.kernels.ukf.ukf_constants`)."""
        self.quaternions = np.tile((1.0, 0.0, 0.0, 0.0), (count, 1))
        self.rests = np.zeros((count, STATE_DIM - 3))
        self.covariances = np.tile(self.P0, (count, 1, 1))
        self.reinitialisations = np.zeros(count, dtype=int)
        self._step_kernel = ukf_bank_step
        """The compiled step: filter by filter, or on lanes for a bank large enough (module docstring)."""
        if self.backend == "numba":
            from quad_wrench_env.kernels.ukf_lanes import LANES_FROM, ukf_lanes_step  # needs numba

            if count >= LANES_FROM:
                self._step_kernel = ukf_lanes_step

    name = "ukf"

    def reset(self, index: int | slice | np.ndarray, positions: np.ndarray, quaternions: np.ndarray) -> None:
        """Start the filters ``index`` afresh at the given poses, at rest, with no external wrench."""
        self._restart(index, positions, quaternions)
        self.reinitialisations[index] = 0

    def _restart(
        self, index: int | slice | np.ndarray, positions: np.ndarray, quaternions: np.ndarray
    ) -> None:
        self.quaternions[index] = quaternions
        self.rests[index] = 0.0
        self.rests[index, 3:6] = positions
        self.covariances[index] = self.P0

    def _kernel(self, thrusts, body_torques, positions, quaternions, velocities, body_rates):
        """The filter of McKinnon & Schoellig 2016 measures the pose only: ``velocities`` and
        ``body_rates`` are unused."""
        return self._step_kernel, (
            self.quaternions, self.rests, self.covariances, self.reinitialisations,
            thrusts, body_torques, positions, quaternions, self.kernel_constants,
        )  # fmt: skip

    def _numpy_step(self, thrusts, body_torques, positions, quaternions, velocities, body_rates) -> None:
        """Predict with (N,) thrusts and (N, 3) body torques, correct with (N, 3) positions and (N, 4)
        quaternions; restart any filter whose state became non-finite."""
        self.predict(thrusts, body_torques)
        self.correct(positions, quaternions)
        broken = ~(np.isfinite(self.rests).all(axis=1) & np.isfinite(self.covariances).all(axis=(1, 2)))
        if np.any(broken):
            self._restart(broken, positions[broken], quaternions[broken])
            self.reinitialisations[broken] += 1

    def wrenches(self) -> np.ndarray:
        """(N, 6) estimated ``[f_e, τ_e]``, world frame."""
        return np.concatenate((self.rests[:, 12:15], self.rests[:, 9:12]), axis=1)

    def states(self) -> np.ndarray:
        """(N, 13) estimated position, velocity, quaternion and body rates."""
        r = self.rests
        return np.concatenate((r[:, 3:9], self.quaternions, r[:, 0:3]), axis=1)

    def _estimates_kernel(self):
        return ukf_estimates, (self.quaternions, self.rests)

    def wrench_covariances(self) -> np.ndarray:
        """(N, 6, 6) covariance of ``[f_e, τ_e]`` about the external wrench: the filter's own, plus the
        rotors' thrust-coefficient spread it cannot tell from an external wrench
        (:func:`~quad_wrench_env.estimators.noise.rotor_spread_covariance`)."""
        spread = rotor_spread_covariance(self._rotor_spread, self.quaternions)
        return self.covariances[:, _WRENCH_BLOCK[0], _WRENCH_BLOCK[1]] + spread

    def statuses(self) -> list[str]:
        return ["ok" if k == 0 else "reinitialised" for k in self.reinitialisations.tolist()]

    # -- prediction (eqs. 18-28) -------------------------------------------------------------------
    def state_sigma_points(self) -> np.ndarray:
        """(N, 37, 18) error-state sigma points ``0, ±sqrt(L+κ)·col_j chol(P)`` (eqs. 19-22)."""
        try:
            roots = np.linalg.cholesky(self.covariances)
        except np.linalg.LinAlgError:
            for k in range(self.count):
                try:
                    np.linalg.cholesky(self.covariances[k])
                except np.linalg.LinAlgError:
                    self.covariances[k] = self.P0
                    self.reinitialisations[k] += 1
            roots = np.linalg.cholesky(self.covariances)
        offsets = self.spread * roots.transpose(0, 2, 1)
        return np.concatenate((np.zeros((self.count, 1, STATE_DIM)), offsets, -offsets), axis=1)

    def propagate(
        self,
        errors: np.ndarray,
        thrusts: np.ndarray,
        body_torques: np.ndarray,
        noise: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Motion model (eqs. 2-5, 11-14) for error-state points (N, P, 18) around the means,
        optionally with process noise (N, P, 12). Returns the propagated quaternions (N, P, 4), the
        other components (N, P, 15) and the attitude matrices of the points before the step."""
        T, m = self.dt, self.mass
        q = quat_multiply_rows(self.quaternions[:, None, :], quat_from_mrp(errors[..., ATT]))
        rest = self.rests[:, None, :] + errors[..., 3:]
        omega, v, tau_e, f_e = rest[..., 0:3], rest[..., 6:9], rest[..., 9:12], rest[..., 12:15]
        R = rotation_matrices(q)
        thrusts = np.asarray(thrusts, dtype=float)[:, None, None]
        motor_torque = np.asarray(body_torques, dtype=float)[:, None, :]
        if noise is None:
            accel = (thrusts / m) * R[..., 2] + f_e / m
        else:
            body_force = noise[..., 6:9].copy()
            body_force[..., 2:3] += thrusts[..., 0]
            accel = np.einsum("...ij,...j->...i", R, body_force) / m + f_e / m
            motor_torque = motor_torque + noise[..., 0:3]
        accel[..., 2] -= GRAVITY
        torque = np.einsum("...ji,...j->...i", R, tau_e) + motor_torque - cross(omega, omega * self.inertia)
        out = rest.copy()  # ω, x, ẋ, τ_e, f_e
        out[..., 0:3] += (T / self.inertia) * torque
        out[..., 3:6] += T * v + (0.5 * T * T) * accel
        out[..., 6:9] += T * accel
        if noise is not None:
            out[..., 9:12] += noise[..., 3:6]
            out[..., 12:15] += noise[..., 9:12]
        return quat_multiply_rows(q, quat_exp(omega * T)), out, R

    def noise_jacobians(self, R: np.ndarray) -> np.ndarray:
        """``B`` (N, 18, 12): how the process noise enters the error state over one step, for the
        mean attitudes ``R`` (N, 3, 3) before the step."""
        T, m = self.dt, self.mass
        B = np.broadcast_to(self._B, (len(R), STATE_DIM, NOISE_DIM)).copy()
        B[:, POS, 6:9] = (0.5 * T * T / m) * R
        B[:, VEL, 6:9] = (T / m) * R
        return B

    @staticmethod
    def recombine(
        q_points: np.ndarray, rest_points: np.ndarray, weights: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Predicted mean quaternions (N, 4), other components (N, 15) and covariances (N, 18, 18) of
        propagated sigma points (N, P, ...) (eqs. 25-27): attitude errors are MRPs relative to the
        propagated central point."""
        q0 = q_points[:, 0]
        relative = quat_multiply_rows(quat_conjugate(q0)[:, None, :], q_points)
        errors = np.concatenate((mrp_from_quat(relative), rest_points), axis=-1)
        mean = np.einsum("p,npk->nk", weights, errors)
        deviations = errors - mean[:, None, :]
        covariance = (deviations * weights[None, :, None]).transpose(0, 2, 1) @ deviations
        return quat_multiply_rows(q0, quat_from_mrp(mean[:, ATT])), mean[:, 3:], covariance

    def predict(self, thrusts: np.ndarray, body_torques: np.ndarray) -> None:
        q_points, rest_points, R = self.propagate(self.state_sigma_points(), thrusts, body_torques)
        B = self.noise_jacobians(R[:, 0])  # the central point is the prior mean
        self.quaternions, self.rests, P = self.recombine(q_points, rest_points, self.mean_weights)
        self.covariances = P + (B * self._q_diagonal) @ B.transpose(0, 2, 1)  # B Q Bᵀ, Q diagonal

    # -- correction (eqs. 29-37) -------------------------------------------------------------------
    def innovations(self, positions: np.ndarray, quaternions: np.ndarray) -> np.ndarray:
        """Measured minus predicted ``(x, δρ)`` (N, 6); the attitude part is ``δq = q̌⁻¹ ⊗ q_meas``
        (eq. 35)."""
        attitude = mrp_from_quat(quat_multiply_rows(quat_conjugate(self.quaternions), quaternions))
        return np.concatenate((positions - self.rests[:, 3:6], attitude), axis=-1)

    def correct(self, positions: np.ndarray, quaternions: np.ndarray) -> None:
        P = self.covariances
        PHt = P[:, :, _MEASURED]  # Σ_xy = P Hᵀ: H only picks the position and attitude components
        S = PHt[:, _MEASURED, :] + self.G  # Σ_yy
        K = np.linalg.solve(S, PHt.transpose(0, 2, 1)).transpose(0, 2, 1)  # (29)
        delta = (K @ self.innovations(positions, quaternions)[..., None])[..., 0]  # (31), (36)
        P = P - K @ PHt.transpose(0, 2, 1)  # (30)
        self.covariances = 0.5 * (P + P.transpose(0, 2, 1))
        q = quat_multiply_rows(self.quaternions, quat_from_mrp(delta[:, ATT]))  # (37)
        self.quaternions = q / np.linalg.norm(q, axis=1, keepdims=True)
        self.rests = self.rests + delta[:, 3:]


class UnscentedWrenchEstimator(BankOfOne):
    """USQUE-based external wrench estimator of one vehicle (McKinnon & Schoellig 2016): a bank of one filter.
    Their filter measures the pose only: ``step`` ignores ``velocity`` and ``body_rates``."""

    name = "ukf"

    def __init__(
        self, vehicle: VehicleParams, dt: float, noise: FilterNoise | None = None, backend: str = "numpy"
    ) -> None:
        self.bank = UnscentedFilterBank(vehicle, dt, noise, count=1, backend=backend)
        b = self.bank
        self.noise, self.mass, self.L, self.spread = b.noise, b.mass, b.L, b.spread
        self.weight_centre, self.weight_other, self.Q, self.G = b.weight_centre, b.weight_other, b.Q, b.G

    # the single filter's state, as views into the bank
    @property
    def quaternion(self) -> np.ndarray:
        return self.bank.quaternions[0]

    @property
    def rest(self) -> np.ndarray:
        """(ω, x, ẋ, τ_e, f_e) at their mean."""
        return self.bank.rests[0]

    @property
    def covariance(self) -> np.ndarray:
        """(18, 18) covariance of the error state."""
        return self.bank.covariances[0]

    @property
    def reinitialisations(self) -> int:
        return int(self.bank.reinitialisations[0])

    # -- single-filter views of the bank's steps (used by the tests of the algebra) ---------------
    def state_sigma_points(self) -> np.ndarray:
        return self.bank.state_sigma_points()[0]

    def propagate(
        self, errors: np.ndarray, thrust: float, body_torque: np.ndarray, noise: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        q, rest, _ = self.bank.propagate(
            errors[None],
            np.array((thrust,)),
            np.asarray(body_torque)[None],
            None if noise is None else noise[None],
        )
        return q[0], rest[0]

    def recombine(self, q_points: np.ndarray, rest_points: np.ndarray, weights: np.ndarray):
        q, rest, P = self.bank.recombine(q_points[None], rest_points[None], weights)
        return q[0], rest[0], P[0]

    def predict(self, thrust: float, body_torque: np.ndarray) -> None:
        self.bank.predict(np.array((thrust,)), np.asarray(body_torque)[None])

    def correct(self, position: np.ndarray, quaternion: np.ndarray) -> None:
        self.bank.correct(np.asarray(position)[None], np.asarray(quaternion)[None])

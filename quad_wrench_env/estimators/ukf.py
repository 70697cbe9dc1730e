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

Two exact shortcuts make the step cheap, both checked by ``tests/test_ukf.py`` against a plain
unscented filter written from the equations above (``tests/reference_ukf.py``: all 61 sigma points
through the model, the unscented correction with measurement sigma points):

* The 24 noise-only sigma points have the mean state, and the noise enters the model linearly
  (through ``B``: ``T/J`` into ω, ``[T²/2m; T/m]·R`` into x and ẋ, identity into τ_e and f_e), so
  they add exactly ``B Q Bᵀ`` to the covariance and nothing to the mean: only the 37 state sigma
  points go through the nonlinear model.
* The observation (position, attitude MRP) is linear in the error state, so the unscented
  correction (eqs. 29-36, sigma points of ``(P̌, G)``) equals the Kalman update with
  ``H = [I_δρ, I_x]``; it is done in that form.

If the covariance loses positive definiteness (Cholesky fails), the filter keeps its mean and resets
the covariance to the initial one; if its state ever became non-finite it restarts from the measured
pose at rest. Either way it reports ``status = "reinitialised"`` from then on (the env puts it in
``info["estimator_status"]``). A non-finite input raises ``ValueError``: nothing non-finite enters.

:class:`UnscentedFilterBank` runs N such filters as one batched computation (every array carries
a leading filter axis) by its kernel, the one implementation of the algebra: filter by filter
(:mod:`quad_wrench_env.estimators.ukf_kernel`) or, compiled and from
:data:`~quad_wrench_env.estimators.ukf_lanes_kernel.LANES_FROM` filters on, eight filters at a time on SIMD
lanes (:mod:`quad_wrench_env.estimators.ukf_lanes_kernel`, the same bits). :class:`UnscentedWrenchEstimator`,
the single-vehicle estimator, is a bank of one.
"""

from __future__ import annotations

import math

import numpy as np

from quad_wrench_env.estimators.bank import BankOfOne, EstimatorInputs, FilterBank
from quad_wrench_env.estimators.noise import (
    FilterNoise,
    mrp_std,
    rotor_spread_body,
    walk_matrices,
)
from quad_wrench_env.estimators.ukf_kernel import (
    ukf_bank_step,
    ukf_constants,
    ukf_estimates,
    ukf_wrench_covariances,
)
from quad_wrench_env.numerics import COMPILED
from quad_wrench_env.vehicle import GRAVITY, VehicleParams

STATE_DIM = 18
NOISE_DIM = 12


class UnscentedFilterBank(FilterBank):
    """N unscented wrench filters of one vehicle model, stepped together (McKinnon & Schoellig 2016, Sec. II).

    State arrays: ``quaternions`` (N, 4), ``rests`` (N, 15) = (ω, x, ẋ, τ_e, f_e) at their mean,
    ``covariances`` (N, 18, 18) of the error state and ``walks`` (N, 2, 3, 3), the force's and the
    torque's random walks (:mod:`~quad_wrench_env.estimators.walks`).
    """

    def __init__(self, vehicle: VehicleParams, dt: float, noise: FilterNoise | None, count: int) -> None:
        if count < 1:
            raise ValueError(f"count={count!r} must be at least 1 filter")
        self.vehicle = vehicle
        self.dt = dt
        self.noise = (noise or FilterNoise()).for_vehicle(vehicle)
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
        initial = (n.initial_attitude, n.initial_rates, n.initial_position, n.initial_velocity)
        self.P0 = np.diag(
            np.repeat((mrp_std(initial[0]), *initial[1:], n.initial_torque, n.initial_force), 3) ** 2
        )
        q_diagonal = np.repeat((n.motor_torque, n.torque_walk, n.thrust, n.force_walk), 3) ** 2  # η (eq. 18)
        g_diagonal = np.repeat((n.position, mrp_std(n.attitude)), 3) ** 2  # measurement (x, δρ)
        # The noise-only points have the mean state: their weight adds to the centre's (module doc).
        centre = self.weight_centre + 2 * NOISE_DIM * self.weight_other
        self.kernel_constants = ukf_constants(
            dt,
            self.mass,
            self.inertia,
            GRAVITY,
            self.spread,
            centre,
            self.weight_other,
            q_diagonal,
            g_diagonal,
            self.P0,
            n.walk_adaptation(),
        )
        """The step kernel's constants (:func:`~quad_wrench_env.estimators.ukf_kernel.ukf_constants`)."""
        self.quaternions = np.tile((1.0, 0.0, 0.0, 0.0), (count, 1))
        self.rests = np.zeros((count, STATE_DIM - 3))
        self.covariances = np.tile(self.P0, (count, 1, 1))
        self.walk_defaults = walk_matrices(np.repeat((n.force_walk, n.torque_walk), 3) ** 2)
        """The walks (2, 3, 3) each filter starts from: force, torque (per step)."""
        self.walks = np.tile(self.walk_defaults, (count, 1, 1, 1))
        """(N, 2, 3, 3) each filter's walks now (the defaults unless ``adaptive_walks`` matches them to
        its corrections)."""
        self.reinitialisations = np.zeros(count, dtype=int)
        self._step_kernel = ukf_bank_step
        """The step kernel: filter by filter, or on lanes for a bank large enough (module docstring)."""
        if COMPILED:  # the lanes are SIMD values of compiled code: they have no plain-Python form
            from quad_wrench_env.estimators.ukf_lanes_kernel import LANES_FROM, ukf_lanes_step

            if count >= LANES_FROM:
                self._step_kernel = ukf_lanes_step

    name = "ukf"

    def reset(self, index: int | slice | np.ndarray, positions: np.ndarray, quaternions: np.ndarray) -> None:
        """Start the filters ``index`` afresh at the given poses, at rest, with no external wrench."""
        self.quaternions[index] = quaternions
        self.rests[index] = 0.0
        self.rests[index, 3:6] = positions
        self.covariances[index] = self.P0
        self.walks[index] = self.walk_defaults
        self.reinitialisations[index] = 0

    def _kernel(self, inputs: EstimatorInputs) -> tuple:
        """The filter of McKinnon & Schoellig 2016 measures the pose only: ``velocities`` and
        ``body_rates`` are unused."""
        return self._step_kernel, (
            self.quaternions,
            self.rests,
            self.covariances,
            self.walks,
            self.reinitialisations,
            *inputs[:4],
            self.kernel_constants,
        )

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
        out = np.empty((self.count, 6, 6))
        ukf_wrench_covariances(self.covariances, self.quaternions, self._rotor_spread, out)
        return out

    def statuses(self) -> list[str]:
        return ["ok" if k == 0 else "reinitialised" for k in self.reinitialisations.tolist()]


class UnscentedWrenchEstimator(BankOfOne):
    """USQUE-based external wrench estimator of one vehicle (McKinnon & Schoellig 2016): a bank of one filter.
    Their filter measures the pose only: ``step`` ignores ``velocity`` and ``body_rates``."""

    name = "ukf"

    def __init__(self, vehicle: VehicleParams, dt: float, noise: FilterNoise | None = None) -> None:
        self.bank = UnscentedFilterBank(vehicle, dt, noise, count=1)
        b = self.bank
        self.noise, self.mass, self.L, self.spread = b.noise, b.mass, b.L, b.spread
        self.weight_centre, self.weight_other = b.weight_centre, b.weight_other

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

"""The wrench estimators against references built outside them (issue 21): a manoeuvring rigid body
integrated here, a step in external force, and what the env actually feeds them."""

from __future__ import annotations

import functools
import inspect
import math
import textwrap

import gymnasium as gym
import numba
import numpy as np
import pytest

import quad_wrench_env  # noqa: F401  (registers the env ids)
import quad_wrench_env.estimators.ekf as ekf_module
import quad_wrench_env.estimators.observer as observer_module
import quad_wrench_env.estimators.ukf as ukf_module
from quad_wrench_env.estimators import EKFNoise, FilterNoise, make_estimator, make_estimator_bank
from quad_wrench_env.estimators.bank import EstimatorInputs
from quad_wrench_env.estimators.ekf_kernel import ekf_bank_step, ekf_transition
from quad_wrench_env.estimators.observer_kernel import observer_bank_step
from quad_wrench_env.estimators.ukf_kernel import ukf_bank_step
from quad_wrench_env.rotations import cross, quat_exp, quat_multiply, rotation_matrix
from quad_wrench_env.vehicle import GRAVITY, Mixer, make_vehicle
from tests.conftest import EstimatorSpy

DT = 0.005
VEHICLE = make_vehicle("ardrone2")
MASS, INERTIA = VEHICLE.mass, np.array(VEHICLE.inertia)
NOISE = FilterNoise().for_vehicle(VEHICLE)
POSITION_NOISE, ATTITUDE_NOISE = NOISE.position, NOISE.attitude
"""The motion-capture noise the filters' defaults assume (0.5 mm, 2 mrad), and what they are fed here."""
MOTION_NOISE = EKFNoise().velocity, EKFNoise().body_rate
"""An onboard state estimator's velocity (m/s) and body-rate (rad/s) noise, as the EKF assumes."""

# -- 1. a manoeuvring rigid body -------------------------------------------------------------------
F_EXT = np.array((0.3, -0.2, 0.15))
TAU_EXT = np.array((0.01, -0.008, 0.005))
"""The constant external force (N) and torque (N·m), world frame, acting on the reference flight."""
RATE_AMPLITUDE = np.array((1.5, 1.5, 2.5))
RATE_FREQUENCY = 2.0 * np.pi * np.array((1.0, 1.2, 0.5))
RATE_PHASE = np.array((0.0, 1.0, 2.0))
"""Body rates ω_i = a_i sin(2π f_i t + φ_i): 1.5-2.5 rad/s about every axis, tilts within ~0.5 rad."""
FLIGHT_SECONDS, SUBSTEPS = 5.0, 5
SETTLED = 500
"""Steps (2.5 s) left out as convergence before the estimates are compared."""


def _rates(t: float) -> tuple[np.ndarray, np.ndarray]:
    angle = RATE_FREQUENCY * t + RATE_PHASE
    return RATE_AMPLITUDE * np.sin(angle), RATE_AMPLITUDE * RATE_FREQUENCY * np.cos(angle)


def _inputs(t: float, q: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """Attitude matrix, thrust and body torque of the nominal rotors at time ``t`` in attitude ``q``:
    the thrust holds a vertical acceleration of 0.5 sin(2π 0.7 t) m/s² against gravity and the
    external force's share; the torque is Newton-Euler's J ω̇ + ω × J ω - Rᵀ τ_ext."""
    R = rotation_matrix(q)
    omega, omega_dot = _rates(t)
    thrust = MASS * (GRAVITY + 0.5 * math.sin(2.0 * math.pi * 0.7 * t)) / R[2, 2]
    torque = INERTIA * omega_dot + cross(omega, INERTIA * omega) - R.T @ TAU_EXT
    return R, thrust, torque


def _derivative(t: float, s: np.ndarray) -> np.ndarray:
    """(q̇, ẋ, v̇) of the state (q, x, v): m a = R e_z T + F_ext - m g e_z."""
    q = s[:4] / np.linalg.norm(s[:4])
    R, thrust, _ = _inputs(t, q)
    acceleration = (R[:, 2] * thrust + F_EXT) / MASS
    acceleration[2] -= GRAVITY
    return np.concatenate(
        (0.5 * quat_multiply(q, np.concatenate(((0.0,), _rates(t)[0]))), s[7:10], acceleration)
    )


@functools.cache
def reference_flight() -> tuple[np.ndarray, np.ndarray]:
    """The truth: states (n + 1, 10) = (q, x, v) every DT, and (n, 4) thrust and body torque averaged
    over each step (what rotors holding their speed over a motion-capture period give). RK4 with
    SUBSTEPS substeps per DT: its error (~h⁴) is far below the noise."""
    h, t = DT / SUBSTEPS, 0.0
    s = np.concatenate(((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 1.0), np.zeros(3)))
    states, inputs = [s.copy()], []
    for _ in range(round(FLIGHT_SECONDS / DT)):
        mean = np.zeros(4)
        for _ in range(SUBSTEPS):
            _, thrust, torque = _inputs(t, s[:4])
            mean += np.r_[thrust, torque] / (2 * SUBSTEPS)
            k1 = _derivative(t, s)
            k2 = _derivative(t + h / 2, s + h / 2 * k1)
            k3 = _derivative(t + h / 2, s + h / 2 * k2)
            k4 = _derivative(t + h, s + h * k3)
            s = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            s[:4] /= np.linalg.norm(s[:4])
            t += h
            _, thrust, torque = _inputs(t, s[:4])
            mean += np.r_[thrust, torque] / (2 * SUBSTEPS)
        states.append(s.copy())
        inputs.append(mean)
    return np.array(states), np.array(inputs)


def fly_reference(name: str, seed: int, motion: bool = False, **settings) -> tuple[np.ndarray, np.ndarray]:
    """Estimated ``[f, τ]`` (n, 6) and the standard deviations its covariance reports (n, 6) of
    estimator ``name`` fed the reference flight's exact inputs and its poses with the motion-capture
    noise (and with ``motion`` an onboard estimator's velocity and body rates)."""
    states, inputs = reference_flight()
    rng = np.random.default_rng(seed)
    if name in ("ukf", "ekf"):  # the reference's rotors are exact: no spread in the reported covariance
        settings = {"rotor_spread": 0.0, **settings}
    est = make_estimator(name, VEHICLE, DT, **settings)
    est.reset(states[0, 4:7], states[0, :4])
    wrenches, sigmas = [], []
    for k, (s, u) in enumerate(zip(states[1:], inputs, strict=True)):
        position = s[4:7] + POSITION_NOISE * rng.standard_normal(3)
        attitude = quat_multiply(s[:4], quat_exp(ATTITUDE_NOISE * rng.standard_normal(3)))
        velocity = rates = None
        if motion:
            velocity = s[7:10] + MOTION_NOISE[0] * rng.standard_normal(3)
            rates = _rates((k + 1) * DT)[0] + MOTION_NOISE[1] * rng.standard_normal(3)
        out = est.step(u[0], u[1:], position, attitude, velocity, rates)
        wrenches.append(np.concatenate((out.force, out.torque)))
        sigmas.append(np.sqrt(np.diag(out.covariance)))
    assert est.status == "ok"
    return np.array(wrenches), np.array(sigmas)


def _errors(wrenches: np.ndarray, window: int = 1) -> np.ndarray:
    """|estimate - truth| after convergence, as running means over ``window`` steps."""
    error = wrenches[SETTLED:] - np.concatenate((F_EXT, TAU_EXT))
    if window > 1:
        error = np.cumsum(error, axis=0)
        error = (error[window:] - error[:-window]) / window
    return np.abs(error)


def _max_gyroscopic() -> float:
    omegas = [_rates(k * DT)[0] for k in range(round(FLIGHT_SECONDS / DT))]
    return max(float(np.abs(cross(w, INERTIA * w)).max()) for w in omegas)


def mutated(kernel, *edits: tuple[str, str], **helpers):
    """``kernel`` (one of the estimators' kernels) compiled anew from its source with each text of
    ``edits`` replaced (each must occur exactly once) and the kernels it calls replaced by ``helpers``
    (by name): a deliberate bug, to check that a test catches it. Seconds of compiling (not cached)."""
    function = getattr(kernel, "py_func", kernel)
    source = textwrap.dedent(inspect.getsource(function))
    for text, replacement in edits:
        assert source.count(text) == 1, text
        source = source.replace(text, replacement)
    namespace = {**function.__globals__, **helpers, "njit": lambda f=None, **_: f or (lambda g: g)}
    exec(compile(source, f"<mutated {function.__name__}>", "exec"), namespace)
    return numba.njit(error_model="numpy")(namespace[function.__name__])


MUTATIONS = {
    "ukf: gyroscopic sign flipped": lambda: {
        (ukf_module, "ukf_bank_step"): mutated(
            ukf_bank_step, *((f"torque[{i}] -= ", f"torque[{i}] += ") for i in range(3))
        )
    },
    "ekf: gyroscopic sign flipped": lambda: {
        (ekf_module, "ekf_bank_step"): mutated(
            ekf_bank_step,
            ekf_transition=mutated(ekf_transition, *((f" - c{i}) / ", f" + c{i}) / ") for i in range(3))),
        )
    },
    "observer: ω × Jω dropped": lambda: {
        (observer_module, "observer_bank_step"): mutated(
            observer_bank_step, *((f"inner[{i}] += ", f"inner[{i}] += 0.0 * ") for i in range(3))
        )
    },
    "observer: Coriolis dropped": lambda: {
        (observer_module, "observer_bank_step"): mutated(
            observer_bank_step,
            *((f"inner[{i}] += ", f"inner[{i}] += 0.0 * ") for i in range(3)),
            ("inner[i] = inertia[i] * (", "inner[i] = 0.0 * ("),
        )
    },
}
"""Deliberate bugs in the estimators' kernels, by name: what to put where (the bank modules' names
of the kernels, which the banks read when they step)."""


def _mutate(monkeypatch: pytest.MonkeyPatch, mutation: str | None) -> None:
    if mutation:
        for (module, name), kernel in MUTATIONS[mutation]().items():
            monkeypatch.setattr(module, name, kernel)


@pytest.mark.parametrize(
    "mutation", [None, pytest.param("ukf: gyroscopic sign flipped", marks=pytest.mark.slow)]
)
def test_ukf_tracks_a_constant_wrench_in_manoeuvring_flight(monkeypatch, mutation):
    """Catches a wrong motion model away from hover (the gyroscopic term ω × Jω, the attitude
    kinematics, the rotation of τ_e into the body): every estimate after 2.5 s lies within 4 σ of
    the truth, σ from the filter's own covariance (seen: at most 1.8 σ over two seeds; 4 σ leaves
    room for the ~0.03 N the force model's start-of-step thrust direction misses, T|ω|dt/2).
    With the gyroscopic term's sign flipped (max |ω × Jω| ≈ 0.009 N·m, an error of twice that
    against σ ≈ 0.001 N·m) it must fail; the mutated run (its kernel compiled anew: slow) is checked
    to fail here too."""
    _mutate(monkeypatch, mutation)
    wrenches, sigmas = fly_reference("ukf", seed=0)
    within = _errors(wrenches) < 4.0 * sigmas[SETTLED:]
    assert within.all() != bool(mutation), np.abs(wrenches[SETTLED:] - np.r_[F_EXT, TAU_EXT]).max(axis=0)


@pytest.mark.parametrize(
    "mutation", [None, pytest.param("ekf: gyroscopic sign flipped", marks=pytest.mark.slow)]
)
def test_ekf_tracks_a_constant_wrench_in_manoeuvring_flight(monkeypatch, mutation):
    """Catches a wrong motion model of Hentzen et al.'s (2019) EKF away from hover. Its covariance is
    overconfident in this flight (torque errors up to 5.7 of its σ: forward-Euler Euler-angle
    kinematics), so the bounds are on 0.1 s running means: torque within 0.008 N·m, less than the
    2 max|ω × Jω| ≈ 0.018 N·m a flipped gyroscopic sign costs (seen: 0.0054 correct, 0.016 flipped);
    force within 0.1 N (~3 σ of 0.022 N plus the ~0.03 N start-of-step thrust direction error;
    seen 0.066 N). With the fixed walks these bounds are sized from (the matched ones follow the
    covariance's own overconfidence here with larger walks: force 0.117 N)."""
    _mutate(monkeypatch, mutation)
    assert 2.0 * _max_gyroscopic() > 0.008
    errors = _errors(fly_reference("ekf", seed=1, motion=True, adaptive_walks=False)[0], window=20).max(
        axis=0
    )
    assert (errors[3:].max() < 0.008) != bool(mutation), errors
    assert errors[:3].max() < 0.1, errors


@pytest.mark.parametrize(
    "mutation",
    [
        None,
        *(
            pytest.param(f"observer: {m}", marks=pytest.mark.slow)
            for m in ("ω × Jω dropped", "Coriolis dropped")
        ),
    ],
)
def test_observer_tracks_a_constant_wrench_in_manoeuvring_flight(monkeypatch, mutation):
    """Catches a wrong Coriolis term C(η, η̇) η̇ of Yüksel et al.'s (2014) observer away from hover. Fed the
    onboard estimator's velocity and body rates (0.01 noise; the observer's finite differences of
    noisy poses are far noisier), its 0.1 s running-mean torque error stays within 0.005 N·m: the
    rate noise passes as c_τ σ_ω |T⁻ᵀ| ≈ 0.005 N·m per step, 0.0011 over 20 steps, times 4
    (seen: 0.0017). Dropping ω × Jω (up to 0.009 N·m) or the whole Coriolis term must exceed it
    (seen: 0.010, 0.017). Force within 0.15 N: its discretisation lags by c dt |a|/2 ≈ 0.1 N at the
    flight's 7.8 m/s² (see the report of issue 21) plus c σ_v ≈ 0.05 N of noise (seen: 0.11 N)."""
    _mutate(monkeypatch, mutation)
    # Yüksel et al.'s (2014) printed gains (unscaled: on this light vehicle a fast observer, whose lag hides
    # nothing)
    wrenches = fly_reference("observer", seed=0, motion=True, c_force=5.0, c_torque=0.5)[0]
    errors = _errors(wrenches, window=20).max(axis=0)
    assert (errors[3:].max() < 0.005) != bool(mutation), errors
    assert errors[:3].max() < 0.15, errors


# -- 2. a step in external force -------------------------------------------------------------------
STEP_FORCE, STEP_AT = 0.5, 2.0


def predicted_rise_time(noise: FilterNoise) -> float:
    """10-90 % rise time of the steady-state linear Kalman filter of one horizontal axis with the
    filter's noise settings: state (x, ẋ, f), thrust noise η_ct entering as acceleration, force
    random walk η_fe, position noise; its deterministic response to the force step. Built here,
    independently of the estimators' code: what their noise settings predict."""
    A = np.array(((1.0, DT, 0.5 * DT * DT / MASS), (0.0, 1.0, DT / MASS), (0.0, 0.0, 1.0)))
    B = np.array((0.5 * DT * DT / MASS, DT / MASS, 0.0))
    Q = np.outer(B, B) * noise.thrust**2 + np.diag((0.0, 0.0, noise.force_walk**2))
    H, R = np.array((1.0, 0.0, 0.0)), noise.position**2
    P = np.diag((1.0, 1.0, 1.0))
    for _ in range(20000):
        P = A @ P @ A.T + Q
        gain = P @ H / (H @ P @ H + R)
        P = P - np.outer(gain, H @ P)
    x, truth, t, crossings = np.zeros(3), np.array((0.0, 0.0, STEP_FORCE)), 0.0, {}
    while 0.9 not in crossings:
        truth = A @ truth
        x = A @ x
        x = x + gain * (truth[0] - x[0])
        t += DT
        for level in (0.1, 0.9):
            if level not in crossings and x[2] >= level * STEP_FORCE:
                crossings[level] = t
    return crossings[0.9] - crossings[0.1]


def measured_rise_time(name: str, seconds: float, motion: bool = False, **settings) -> float:
    """10-90 % rise time of the mean x-force estimate of 6 estimators ``name`` (independent noise)
    fed a vehicle hovering at (0, 0, 1) with exact hover inputs, on which STEP_FORCE N along x acts
    from STEP_AT s (it drifts: x = F t²/2m); inf if 90 % is not reached within ``seconds``."""
    count, rng = 6, np.random.default_rng(7)
    bank = make_estimator_bank(name, VEHICLE, DT, count, **settings)
    start, level = np.array((0.0, 0.0, 1.0)), np.array((1.0, 0.0, 0.0, 0.0))
    for i in range(count):
        bank.reset(i, start, level)
    crossings = {}
    for k in range(1, round(seconds / DT) + 1):
        after = max(k * DT - STEP_AT, 0.0)
        position = start + np.array((0.5 * STEP_FORCE / MASS * after**2, 0.0, 0.0))
        velocity = np.array((STEP_FORCE / MASS * after, 0.0, 0.0))
        noisy = position + POSITION_NOISE * rng.standard_normal((count, 3))
        errors = quat_exp(ATTITUDE_NOISE * rng.standard_normal((count, 3)))
        attitude = np.array([quat_multiply(level, error) for error in errors])
        moving = rates = None
        if motion:
            moving = velocity + MOTION_NOISE[0] * rng.standard_normal((count, 3))
            rates = MOTION_NOISE[1] * rng.standard_normal((count, 3))
        bank.step(
            EstimatorInputs(
                np.full(count, MASS * GRAVITY), np.zeros((count, 3)), noisy, attitude, moving, rates
            )
        )
        force = bank.wrenches()[:, 0].mean()
        for fraction in (0.1, 0.9):
            if k * DT > STEP_AT and fraction not in crossings and force >= fraction * STEP_FORCE:
                crossings[fraction] = k * DT
    return crossings.get(0.9, math.inf) - crossings.get(0.1, STEP_AT)


RISE_BAND = (0.5, 2.0)
"""Measured rise time over predicted: the mean of 6 noisy filters crosses 10 % and 90 % up to a
few steps early or late (the running noise, σ ≈ 0.008 N on the mean, is 2 % of the step), and
the UKF and EKF linearise about hover; a factor two either way is well within, and a force random
walk 100x smaller (rise time ~ 8x longer) is well outside."""


@pytest.mark.parametrize("name", ["ukf", "ekf"])
def test_kalman_filters_rise_as_their_noise_settings_predict(name):
    """Catches a force random walk, thrust noise or position noise not entering the filter as its
    settings say (a Q or G scaled, squared twice, per second instead of per step): the rise time of
    the force estimate after a 0.5 N step lies within RISE_BAND of the linear steady-state filter's
    with the same settings, fixed (``adaptive_walks: false``: the linear filter's walk is the setting).
    Note: the defaults predict ~0.17 s, faster than McKinnon & Schoellig's (2016) ~1 s (a force walk of
    ~4e-4 N per step gives ~1.4 s)."""
    predicted = predicted_rise_time(NOISE)
    measured = measured_rise_time(name, STEP_AT + 1.0, adaptive_walks=False)
    assert RISE_BAND[0] * predicted < measured < RISE_BAND[1] * predicted, (measured, predicted)


def test_a_ukf_with_a_100x_smaller_force_walk_rises_outside_the_band():
    """The mutation issue 21 names: force_walk / 100 (through the noise settings, as
    ``estimator_params`` gives them) must move the rise time of the fixed walks out of the default's
    band; matched to its corrections (``adaptive_walks``), the same walk is raised by the step itself and the
    filter rises inside the band's upper edge again."""
    predicted = predicted_rise_time(NOISE)
    seconds, small = STEP_AT + RISE_BAND[1] * predicted + 0.5, NOISE.force_walk / 100
    slow = measured_rise_time("ukf", seconds, force_walk=small, adaptive_walks=False)
    assert slow > RISE_BAND[1] * predicted, (slow, predicted)
    assert (
        measured_rise_time("ukf", seconds, force_walk=small, adaptive_walks=True) < RISE_BAND[1] * predicted
    )
    slow_noise = FilterNoise(force_walk=NOISE.force_walk / 100).for_vehicle(VEHICLE)
    assert predicted_rise_time(slow_noise) > RISE_BAND[1] * predicted


def test_observer_rises_as_exp_minus_c_t_over_m():
    """Catches a wrong force gain or discretisation of Yüksel et al.'s (2014) observer: its force error decays
    as exp(-c t/m) (eq. 8), a 10-90 % rise of ln 9 m/c = 0.44 s with the default c (Yüksel et al.'s (2014)
    5 N·s/m per kg); the band RISE_BAND around it. Fed the onboard velocity (a finite-difference low-pass
    would add its 0.05 s lag)."""
    predicted = math.log(9.0) * MASS / (5.0 * MASS / 1.0)  # Yüksel et al.'s (2014) c = 5 N·s/m per kg
    measured = measured_rise_time("observer", STEP_AT + 1.0, motion=True)
    assert RISE_BAND[0] * predicted < measured < RISE_BAND[1] * predicted, (measured, predicted)


# -- 3. what the env feeds the estimators ----------------------------------------------------------
def _spied_flight(estimator: str, **kwargs):
    """The fleet and the spy's calls of 5 control steps of zero actions (20 physics steps)."""
    env = gym.make("QuadWrench/FanTracking-v1", estimator=estimator, **kwargs)
    try:
        env.reset(seed=3, options={"offset_y": 0.4})
        fleet = env.unwrapped.fleet
        fleet.estimator = spy = EstimatorSpy(fleet.estimator, fleet)
        for _ in range(5):
            env.step(np.zeros(4, dtype=np.float32))
    finally:
        env.close()
    return fleet, spy.calls


def test_the_estimators_get_the_nominal_mixer_of_the_quantized_speeds():
    """Catches the env feeding the estimators the true rotor speeds or the true per-rotor kf: the
    thrust and body torque each step are the nominal Mixer applied to the speeds rounded to the
    nearest of 2^8 - 1 levels over [0, max_rotor_speed] (computed here), and differ from the truth."""
    fleet, calls = _spied_flight("ukf", kf_spread=0.05)
    mixer, step = Mixer(VEHICLE), VEHICLE.max_rotor_speed / 255.0
    true_allocation = fleet.rotors.allocations[0]
    assert len(calls) >= 5
    for (thrusts, torques, *_), speeds, _ in calls:
        quantized = np.clip(np.round(speeds[0] / step), 0, 255) * step
        expected = mixer.wrench(quantized)
        np.testing.assert_allclose(thrusts[0], expected[0], rtol=1e-12)
        np.testing.assert_allclose(torques[0], expected[1:], atol=1e-12)
        assert not np.allclose(quantized, speeds[0], rtol=1e-9)  # the quantization is visible
        assert not np.allclose(true_allocation @ (speeds[0] * speeds[0]), expected, rtol=1e-6)


@pytest.mark.parametrize("calibration", [0.0, 0.004])
def test_a_calibrated_vehicles_estimators_get_its_rotors_to_the_residual(calibration):
    """``rotor_calibration`` σ: the thrust and body torque handed to the estimators are the quantized
    speeds through ``k·(1 + ε_i + δ_i)`` (δ_i ~ N(0, σ²), so the true coefficients at σ = 0), computed
    here from the true allocation with the spread taken out and the residual put in by hand: with
    σ = 0 exactly the true rotors' wrench; with σ > 0 per-rotor relative errors of about σ, far below
    the 5 % spread; the motion capture's noise is the uncalibrated vehicle's, draw for draw (the
    residual has a generator of its own). Catches the nominal mixer kept (errors of the spread's size),
    the truth handed over (no residual) or a residual drawn from the episode's generator."""
    fleet, calls = _spied_flight("ukf", kf_spread=0.05, rotor_calibration=calibration)
    step = VEHICLE.max_rotor_speed / 255.0
    true_kf = fleet.rotors.allocations[0, 0] / VEHICLE.kf  # (1 + ε_i), the true rotors' row of thrusts
    sensed_kf = fleet.rotors.sensed_allocations[0, 0] / VEHICLE.kf
    residual = sensed_kf - true_kf  # δ_i
    assert np.abs(true_kf - 1.0).max() > 0.01  # the 5 % spread shows
    if calibration == 0.0:
        np.testing.assert_array_equal(residual, 0.0)
    else:
        assert 1e-4 < np.abs(residual).max() < 5 * calibration
    for (thrusts, torques, *_), speeds, _ in calls:
        squared = (np.clip(np.round(speeds[0] / step), 0, 255) * step) ** 2
        expected = Mixer(VEHICLE, VEHICLE.kf * sensed_kf).wrench(np.sqrt(squared))
        np.testing.assert_allclose(thrusts[0], expected[0], rtol=1e-12)
        np.testing.assert_allclose(torques[0], expected[1:], atol=1e-12)
        nominal = Mixer(VEHICLE).wrench(np.sqrt(squared))
        assert abs(thrusts[0] - nominal[0]) > 1e-4 * nominal[0]  # not the nominal mixer
    _, uncalibrated = _spied_flight("ukf", kf_spread=0.05)
    for ((_, _, position, quaternion, *_), *_), ((_, _, position_0, quaternion_0, *_), *_) in zip(
        calls, uncalibrated, strict=True
    ):
        np.testing.assert_array_equal(position, position_0)
        np.testing.assert_array_equal(quaternion, quaternion_0)


@pytest.mark.parametrize("name", ["ekf", "observer"])
def test_a_state_estimator_feeds_velocity_and_rates_near_the_truth(name):
    """Catches the env dropping (None) or garbling the onboard state estimator's measurements: with
    sensors.state_estimator the EKF and the observer get velocity and body rates within 5 σ (0.05)
    of the true ones every step."""
    _, calls = _spied_flight(name, sensors={"state_estimator": True})
    assert len(calls) == 20  # four physics steps per control step
    for (_, _, _, _, velocities, rates), _, truth in calls:
        assert velocities is not None and rates is not None
        np.testing.assert_allclose(velocities, truth.velocity, atol=5 * MOTION_NOISE[0])
        np.testing.assert_allclose(rates, truth.body_rates, atol=5 * MOTION_NOISE[1])


@pytest.mark.parametrize("offset", [(0.1, 0.0), (0.0, 0.1)], ids=["velocity", "body_rates"])
def test_the_ekf_uses_velocity_and_rates(offset):
    """Catches an EKF that ignores the velocity or the body-rate measurements: the same poses and
    inputs with velocities offset by 0.1 m/s (or rates by 0.1 rad/s) change its estimate."""
    out = []
    for velocity, rates in ((0.0, 0.0), offset):
        est = make_estimator("ekf", VEHICLE, DT)
        est.reset(np.array((0.0, 0.0, 1.0)), np.array((1.0, 0.0, 0.0, 0.0)))
        for _ in range(50):
            w = est.step(
                MASS * GRAVITY,
                np.zeros(3),
                np.array((0.0, 0.0, 1.0)),
                np.array((1.0, 0.0, 0.0, 0.0)),
                np.full(3, velocity),
                np.full(3, rates),
            )
        out.append(np.concatenate((w.force, w.torque)))
    assert np.abs(out[1] - out[0]).max() > 1e-3


def test_the_motion_capture_noise_is_independent_of_the_fans_turbulence():
    """Each component draws its own normals: the mocap's position error (what the estimator is
    handed minus the truth, over σ_p) and the fan turbulence's innovations η_k = (n_k - a·n_(k-1)) /
    sqrt(1 - a²) (a = exp(-dt·u_c/b) at the vehicle) are independent standard normals. Over 2000
    physics steps per axis the sample correlation of independent ones has sd 1/sqrt(2000) = 0.022:
    |r| < 0.11 (5 sd); sensors reading the fan's columns give r = 1."""
    env = gym.make("QuadWrench/FanTracking-v1", estimator="oracle")
    try:
        env.reset(seed=5, options={"fan_motion": "static", "offset_y": 0.3})
        base = env.unwrapped
        fleet, fan = base.fleet, base.task.fan
        errors, turbulence, positions = [], [fan.noise[0].copy()], []

        class Spy(EstimatorSpy):
            def step(self, inputs):
                errors.append(
                    (inputs.positions[0] - fleet.state.position[0]) / fleet.cfg.sensors.position_noise
                )
                turbulence.append(fan.noise[0].copy())
                positions.append(fleet.state.position[0].copy())
                return self._inner.step(inputs)

        fleet.estimator = Spy(fleet.estimator, fleet)
        for _ in range(500):
            env.step(np.zeros(4, dtype=np.float32))
        assert len(errors) == 2000
    finally:
        env.close()
    noise, x = np.array(turbulence), np.maximum(np.array(positions)[:, 0], 1e-3)
    decay = np.exp(-fleet.dt * fan.centreline_speed(x) / fan.half_width(x))[:, None]
    innovations = (noise[1:] - decay * noise[:-1]) / np.sqrt(1.0 - decay * decay)
    errors = np.array(errors)
    for axis in range(3):
        assert abs(np.std(innovations[:, axis]) - 1.0) < 0.1  # the recovery is right: unit variance
        assert abs(np.corrcoef(errors[:, axis], innovations[:, axis])[0, 1]) < 0.11

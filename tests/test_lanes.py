"""SIMD lanes (kernels.lanes) and the UKF bank on them (kernels.ukf_lanes): each lane is exactly the
float arithmetic, and the lane kernel is the filter-by-filter kernel to the bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

import quad_wrench_env.estimators.ukf as ukf_module
from quad_wrench_env.estimators.bank import EstimatorInputs
from quad_wrench_env.estimators.noise import FilterNoise
from quad_wrench_env.estimators.ukf import UnscentedFilterBank
from quad_wrench_env.estimators.ukf_kernel import ukf_bank_step
from quad_wrench_env.numerics import COMPILED
from quad_wrench_env.numerics.quaternions import qmul, to_mrp
from quad_wrench_env.vehicle import GRAVITY, make_vehicle

pytestmark = pytest.mark.skipif(not COMPILED, reason="lanes are compiled code (numba, no NUMBA_DISABLE_JIT)")

if COMPILED:
    import numba

    from quad_wrench_env.estimators.ukf_lanes_kernel import LANES_FROM, ukf_lanes_step
    from quad_wrench_env.numerics import lanes

    @numba.njit
    def _lane_arithmetic(a, b, out):
        x, y = lanes.load(a, 0), lanes.load(b, 0)
        results = (
            x + y,
            x - y,
            x * y,
            x / y,
            -x,
            2.0 * x,
            x / 3.0,
            1.0 - x,
            lanes.sqrt(abs(x)),
            abs(x),
            math.copysign(1.0, x),
            math.copysign(x, y),
            lanes.splat(0.5),
        )
        for k in range(len(results)):
            lanes.store(out, k * lanes.WIDTH, results[k])
        w, qx, qy, qz = qmul(x, y, x * y, x - y, y, x, 0.5, y / x)  # a float function, compiled for lanes
        m0, m1, m2 = to_mrp(w, qx, qy, qz)
        for k, value in enumerate((w, qx, qy, qz, m0, m1, m2)):
            lanes.store(out, (len(results) + k) * lanes.WIDTH, value)

    @numba.njit
    def _float_arithmetic(a, b, out):
        for i in range(a.shape[0]):
            x, y = a[i], b[i]
            results = (
                x + y,
                x - y,
                x * y,
                x / y,
                -x,
                2.0 * x,
                x / 3.0,
                1.0 - x,
                math.sqrt(abs(x)),
                abs(x),
                math.copysign(1.0, x),
                math.copysign(x, y),
                0.5,
            )
            w, qx, qy, qz = qmul(x, y, x * y, x - y, y, x, 0.5, y / x)
            for k, value in enumerate((*results, w, qx, qy, qz, *to_mrp(w, qx, qy, qz))):
                out[k * a.shape[0] + i] = value

    @numba.njit
    def _masks(a, bound):
        x = lanes.load(a, 0)
        replaced = lanes.with_lane(x, 3, -7.0)
        return (
            lanes.greater_mask(x, lanes.splat(bound)),
            lanes.finite_mask(x),
            lanes.all_less(x, bound),
            lanes.lane(x, 2),
            lanes.lane(replaced, 3),
            lanes.lane(replaced, 4),
        )

    @numba.njit
    def _load_at(array, offset):
        return lanes.lane(lanes.load(array, offset), 0)

    @numba.njit
    def _store_at(array, offset):
        lanes.store(array, offset, lanes.splat(1.0))


def test_each_lane_is_the_float_arithmetic_bit_for_bit():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=lanes.WIDTH), rng.normal(size=lanes.WIDTH)
    a[0], b[1] = -1.25, -3.0  # signs that copysign must keep
    on_lanes, floats = np.zeros(20 * lanes.WIDTH), np.zeros(20 * lanes.WIDTH)
    _lane_arithmetic(a, b, on_lanes)
    _float_arithmetic(a, b, floats)
    np.testing.assert_array_equal(on_lanes, floats)


def test_masks_and_single_lanes():
    a = np.array([1.0, -2.0, np.nan, 3.0, np.inf, -np.inf, 0.5, 0.0])
    greater, finite, below, third, replaced, kept = _masks(a, 0.25)
    assert greater == sum(1 << i for i, x in enumerate(a) if x > 0.25)  # NaN is not greater
    assert finite == sum(1 << i for i, x in enumerate(a) if np.isfinite(x))
    assert not below and np.isnan(third) and replaced == -7.0 and kept == np.inf
    assert _masks(np.full(lanes.WIDTH, 1e-5), 1e-4)[2]
    assert not _masks(np.r_[np.full(lanes.WIDTH - 1, 1e-5), np.nan], 1e-4)[2]  # NaN is not below


def test_lanes_outside_the_array_and_other_arrays_are_refused():
    array = np.zeros(2 * lanes.WIDTH)
    assert _load_at(array, lanes.WIDTH) == 0.0
    for offset in (-1, lanes.WIDTH + 1, 2 * lanes.WIDTH):
        with pytest.raises(IndexError, match="lanes outside the array"):
            _load_at(array, offset)
        with pytest.raises(IndexError, match="lanes outside the array"):
            _store_at(array, offset)
    np.testing.assert_array_equal(array, 0.0)
    with pytest.raises(TypeError, match="1-d C-contiguous float64"):
        _load_at(np.zeros((2, lanes.WIDTH)), 0)


def _fly_banks(count: int, steps: int = 300, **settings):
    """Two identical UKF banks stepped by the filter-by-filter kernel and the lane kernel on the same
    inputs: tilted, moving vehicles with noisy poses; at step 150 filter 0's covariance is made
    indefinite (the Cholesky fails) and at step 250 filter 1's thrust overflows the state."""
    vehicle = make_vehicle("ardrone2")
    banks = [UnscentedFilterBank(vehicle, 0.005, FilterNoise(**settings), count) for _ in range(2)]
    rng = np.random.default_rng(count)
    positions = rng.normal(size=(count, 3))
    quaternions = rng.normal(size=(count, 4))
    quaternions /= np.linalg.norm(quaternions, axis=1, keepdims=True)
    for bank in banks:
        bank.reset(slice(None), positions, quaternions)
    for k in range(steps):
        thrusts = vehicle.mass * GRAVITY * (1.0 + 0.2 * rng.standard_normal(count))
        torques = 0.01 * rng.standard_normal((count, 3))
        measured_p = positions + 0.01 * rng.standard_normal((count, 3)) + 0.001 * k
        measured_q = quaternions + 0.02 * rng.normal(size=(count, 4))
        measured_q /= np.linalg.norm(measured_q, axis=1, keepdims=True)
        if k == 150:
            for bank in banks:
                bank.covariances[0] *= -1.0
        if k == 250:
            thrusts[1] = 1e308
        for kernel, bank in zip((ukf_bank_step, ukf_lanes_step), banks, strict=True):
            state = (bank.quaternions, bank.rests, bank.covariances, bank.walks, bank.reinitialisations)
            assert kernel(*state, thrusts, torques, measured_p, measured_q, bank.kernel_constants)
    return banks


@pytest.mark.parametrize("settings", [{}, {"adaptive_walks": True}], ids=["fixed walks", "matched walks"])
@pytest.mark.parametrize("count", [3, 8, 19])  # the smallest bank on lanes, one block, three
def test_lane_kernel_equals_the_filter_by_filter_kernel(count, settings):
    """300 steps of full blocks and a short last one (spare lanes): the same filters to the bit (each
    lane does the filter-by-filter kernel's operations in its order, on any CPU), the same restarts,
    with fixed walks and with matched ones (the walks too)."""
    by_filter, on_lanes = _fly_banks(count, **settings)
    np.testing.assert_array_equal(on_lanes.reinitialisations, by_filter.reinitialisations)
    assert by_filter.reinitialisations[0] >= 1 and by_filter.reinitialisations[1] >= 1
    for name in ("quaternions", "rests", "covariances", "walks"):
        np.testing.assert_array_equal(getattr(on_lanes, name), getattr(by_filter, name), err_msg=name)
    np.testing.assert_array_equal(on_lanes.covariances, on_lanes.covariances.transpose(0, 2, 1))


def test_lane_kernel_refuses_non_finite_input_and_touches_nothing():
    vehicle, count = make_vehicle("ardrone2"), 9
    bank = UnscentedFilterBank(vehicle, 0.005, None, count)
    assert bank._step_kernel is ukf_lanes_step
    before = (bank.quaternions.copy(), bank.rests.copy(), bank.covariances.copy())
    thrusts, torques = np.full(count, vehicle.mass * GRAVITY), np.zeros((count, 3))
    positions, quaternions = np.zeros((count, 3)), np.tile((1.0, 0.0, 0.0, 0.0), (count, 1))
    positions[8, 2] = np.nan
    with pytest.raises(ValueError, match="non-finite input"):
        bank.step(EstimatorInputs(thrusts, torques, positions, quaternions))
    for array, saved in zip((bank.quaternions, bank.rests, bank.covariances), before, strict=True):
        np.testing.assert_array_equal(array, saved)


def test_banks_below_the_threshold_run_filter_by_filter(monkeypatch):
    """And every bank where the kernels are not compiled (``NUMBA_DISABLE_JIT=1``): lanes have no
    plain-Python form."""
    vehicle = make_vehicle("ardrone2")
    assert UnscentedFilterBank(vehicle, 0.005, None, LANES_FROM - 1)._step_kernel is ukf_bank_step
    assert UnscentedFilterBank(vehicle, 0.005, None, LANES_FROM)._step_kernel is ukf_lanes_step
    monkeypatch.setattr(ukf_module, "COMPILED", False)
    assert UnscentedFilterBank(vehicle, 0.005, None, LANES_FROM)._step_kernel is ukf_bank_step


def test_a_filter_on_lanes_depends_on_its_own_inputs_only():
    """The same filters in reverse order (other lanes, other neighbours, the spare lanes elsewhere)
    give the same bits, filter for filter."""
    vehicle, count = make_vehicle("ardrone2"), 11
    banks = [UnscentedFilterBank(vehicle, 0.005, None, count) for _ in range(2)]
    rng = np.random.default_rng(4)
    positions = rng.normal(size=(count, 3))
    quaternions = rng.normal(size=(count, 4))
    quaternions /= np.linalg.norm(quaternions, axis=1, keepdims=True)
    reverse = np.arange(count)[::-1]  # a copy in reverse order (C-contiguous, as the envs pass them)
    banks[0].reset(slice(None), positions, quaternions)
    banks[1].reset(slice(None), positions[reverse], quaternions[reverse])
    for _ in range(100):
        thrusts = vehicle.mass * GRAVITY * (1.0 + 0.2 * rng.standard_normal(count))
        torques = 0.01 * rng.standard_normal((count, 3))
        measured_p = positions + 0.01 * rng.standard_normal((count, 3))
        banks[0].step(EstimatorInputs(thrusts, torques, measured_p, quaternions))
        banks[1].step(
            EstimatorInputs(thrusts[reverse], torques[reverse], measured_p[reverse], quaternions[reverse])
        )
    for name in ("quaternions", "rests", "covariances", "walks"):
        np.testing.assert_array_equal(getattr(banks[1], name)[reverse], getattr(banks[0], name), err_msg=name)

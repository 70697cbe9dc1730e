"""The moving jet and the loads it causes on the body (``docs/physics.md``, "Fan"; McKinnon & Schoellig
2016, Fig. 6)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from quad_wrench_env.disturbances import jet_kernels
from quad_wrench_env.disturbances.fan import FanConfig, FanJet, make_motion
from quad_wrench_env.engine.world import RigidBodyState
from quad_wrench_env.rotations import quat_from_euler_zyx


def _still_jet(**config) -> FanJet:
    jet = FanJet(FanConfig(turbulence_intensity=0.0, motion="static", **config))
    jet.reset(0, np.random.default_rng(0))
    return jet


def _field(jet: FanJet, points: np.ndarray, t: float = 0.0) -> np.ndarray:
    """Air velocity at (P, 3) points as vehicle 0 meets it at time ``t``."""
    return jet.velocity_at(points[None], np.array((t,)), np.array((0,)))[0]


def test_field_is_symmetric_about_the_axis_and_blows_along_x():
    jet = _still_jet()
    d = np.linspace(0.0, 1.5, 7)
    left = _field(jet, np.column_stack((np.full(7, 2.3), d, np.full(7, 1.0))))
    right = _field(jet, np.column_stack((np.full(7, 2.3), -d, np.full(7, 1.0))))
    up = _field(jet, np.column_stack((np.full(7, 2.3), np.zeros(7), 1.0 + d)))
    np.testing.assert_allclose(left, right)
    np.testing.assert_allclose(left, up)
    assert np.all(np.diff(left[:, 0]) < 0)
    np.testing.assert_array_equal(left[:, 1:], 0.0)
    assert _field(jet, np.array([[-0.5, 0.0, 1.0]]))[0, 0] == 0.0


U0, D, C = 10.0, 0.75, 0.42
"""FanConfig's defaults: outlet speed and diameter, spread (``docs/physics.md``, "Fan")."""


def _half_width(x):
    return np.sqrt((D / 2) ** 2 + (C * x) ** 2)


@pytest.mark.parametrize("x", [1.0, 2.3, 4.0, 6.0, 10.0])
def test_jet_carries_the_outlets_momentum_flux_beyond_the_core(x):
    """A free jet's axial momentum flux is conserved: ∫ρu²dA at x equals the outlet's ρU0²πD²/4.
    The integral runs over the sampled field (radially symmetric, tested above) on a radial grid to
    5 half-widths (the Gaussian's u² tail beyond holds e^-50 of it): trapezoid error << 1 %."""
    jet = _still_jet()
    assert x > D / (2 * C)  # beyond the core, x_c = D/(2c) = 0.89 m
    r = np.linspace(0.0, 5.0 * _half_width(x), 4001)
    u = _field(jet, np.column_stack((np.full_like(r, x), r, np.ones_like(r))))[:, 0]
    flux = np.trapezoid(2.0 * np.pi * r * u * u, r)
    assert flux == pytest.approx(U0**2 * np.pi * D**2 / 4.0, rel=0.01)


def test_centreline_speed_at_the_vehicle_is_paper_scale():
    """``docs/physics.md``, "Fan": u_c ≈ 5.1 m/s and b ≈ 1.04 m at 2.3 m; U0 on the axis inside the core."""
    jet = _still_jet()
    u = _field(jet, np.array([[0.5, 0.0, 1.0], [2.3, 0.0, 1.0]]))[:, 0]
    assert u[0] == pytest.approx(U0)
    assert u[1] == pytest.approx(5.1, abs=0.05)
    width = _field(jet, np.array([[2.3, 1.04, 1.0]]))[0, 0] / u[1]  # exp(-(r/b)²) at r = 1.04 m
    assert width == pytest.approx(math.exp(-1.0), abs=0.01)


@pytest.mark.parametrize("x", [0.5, 2.3, 5.0])
def test_axis_follows_the_fan_with_the_transit_delay(x):
    """The delay is ∫dξ/u_c(ξ) over the sampled centre-line speed (numerical quadrature, apart from
    the closed form under test), inside the core (0.5 m) and beyond it."""
    jet = FanJet(FanConfig(motion="constant_speed", turbulence_intensity=0.0))
    xi = np.linspace(1e-9, x, 20001)  # the field is zero at the outlet plane itself (x > 0 only)
    speed = jet.velocity_at(
        np.column_stack((xi, np.zeros_like(xi), np.ones_like(xi)))[None],
        np.zeros(1),
        np.array((0,)),
        mean=True,
    )[0, :, 0]
    delay = np.trapezoid(1.0 / speed, xi)
    assert float(jet.transit_time(np.asarray(x))) == pytest.approx(delay, rel=1e-5)
    assert float(jet.axis_y(np.array((x,)), np.array((10.0,)))[0]) == pytest.approx(0.1 * (10.0 - delay))
    assert float(jet.fan_y(np.array((10.0,)))[0]) == pytest.approx(1.0)


def test_motions():
    np.testing.assert_allclose(make_motion("static", y0=0.3).y(np.array([0.0, 5.0])), 0.3)
    sine = make_motion("sine", amplitude=0.5, frequency=0.25)
    assert float(sine.y(np.asarray(1.0))) == pytest.approx(0.5)
    piecewise = make_motion("piecewise", segments=[[2.0, 0.5], [1.0, -1.0]])
    y = piecewise.y(np.array([-1.0, 1.0, 2.0, 2.5, 3.0, 10.0]))
    np.testing.assert_allclose(y, (0.0, 0.5, 1.0, 0.5, 0.0, 0.0))
    with pytest.raises(ValueError, match="'zigzag'.*allowed"):
        make_motion("zigzag")
    with pytest.raises(ValueError, match="'speeed'"):
        make_motion("constant_speed", speeed=1.0)


def test_turbulence_is_a_unit_variance_process_scaled_by_intensity():
    jet = FanJet(FanConfig(turbulence_intensity=0.15, motion="static"))
    rng = np.random.default_rng(1)
    jet.reset(0, rng)
    point = np.array([[2.3, 0.0, 1.0]])
    samples = []
    params, still = jet.kernel_parameters(), np.zeros((1, 3))
    for _ in range(40000):  # the fan's compiled ``advance``
        normals = rng.standard_normal((1, 3))
        jet_kernels.fan_advance(params, jet.motion_tables, jet.noise, point, still, 0.005, normals)
        samples.append(_field(jet, point)[0])
    samples = np.array(samples)
    # time scale b/u_c ≈ 0.2 s: 200 s hold ~500 independent samples, so the sd is good to ~6 %
    u_c = U0 * D / (math.sqrt(2.0) * _half_width(2.3))  # momentum-conserving centre-line speed
    assert np.std(samples[:, 1]) == pytest.approx(0.15 * u_c, rel=0.2)
    assert np.mean(samples[:, 0]) == pytest.approx(u_c, rel=0.05)


def _loads(env, x: float, y: float) -> tuple[np.ndarray, np.ndarray]:
    q = quat_from_euler_zyx(0.0, 0.0, math.pi)
    rest = RigidBodyState.at_rest(np.array(((x, y, 1.0),)), q[None])
    loads = env.fleet.external_loads(rest, np.array((0,)), mean=True)[0]
    return loads[:3], loads[3:]


@pytest.mark.parametrize("spread", [0.2, 0.42])
def test_fan_loads_have_the_shape_of_paper_000_fig_6(make_env, spread):
    env = make_env(fan={"motion": "static", "spread": spread}, kf_spread=0.0).unwrapped
    env.reset(seed=0, options={"offset_y": 0.0})
    offsets = np.linspace(-1.5, 1.5, 61)
    loads = [_loads(env, 2.3, y) for y in offsets]
    fx = np.array([f[0] for f, _ in loads])
    tau_z = np.array([t[2] for _, t in loads])
    assert offsets[np.argmax(fx)] == pytest.approx(0.0)
    assert fx.max() > 0.2 * env.vehicle.mass * 9.81  # "a strong force along +x"
    np.testing.assert_allclose(tau_z, -tau_z[::-1], atol=1e-12)  # anti-symmetric in the offset
    assert np.all(tau_z[offsets > 0.05] > 0)  # +y side: the -y side of the body sits in faster air
    peak = abs(offsets[np.argmax(np.abs(tau_z))])
    assert 0.3 <= peak <= 0.8


def test_fan_loads_decay_with_distance(make_env):
    env = make_env(fan={"motion": "static"}).unwrapped
    env.reset(seed=0, options={"offset_y": 0.0})
    fx = [_loads(env, x, 0.0)[0][0] for x in (3.0, 4.0, 5.0)]
    assert fx[0] > fx[1] > fx[2] > 0

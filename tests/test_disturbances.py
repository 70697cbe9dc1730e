"""The disturbances beyond the fan: Dryden turbulence, the 1-cosine gust, a fixed jet, the ground
effect over the ground and tables (``docs/physics.md``), each against its formula, its compiled kernels and,
through the env, the numbers ``info`` reports."""

from __future__ import annotations

import math

import numpy as np
import pytest

from quad_wrench_env.disturbances.dryden import DrydenConfig, DrydenGust, dryden_advance, dryden_velocity
from quad_wrench_env.disturbances.ground_effect import GroundEffect, ground_effect_thrust
from quad_wrench_env.disturbances.jet import Jet, JetConfig
from quad_wrench_env.disturbances.jet_kernels import fixed_jet_velocity
from quad_wrench_env.disturbances.one_cosine import OneCosineConfig, OneCosineGust, one_cosine_velocity
from quad_wrench_env.scene import Ceiling, Table, Wall, surface_tops
from quad_wrench_env.vehicle import GRAVITY

NO_TABLE = np.zeros((1, 0))
"""The empty ``table`` (and stateless ``state``) argument of a component's kernels."""
STEADY = {"offset_y": 0.0, "fan_motion": "static"}
"""Reset options: the vehicle starts at (2.3, 0, fan height)."""


# -- Dryden ----------------------------------------------------------------------------------------
def test_dryden_scales_follow_mil_f_8785c_low_altitude():
    """σ and L of each axis against the low-altitude formulas written out here with h in ft: catches
    a unit slip (h used in m, L returned in ft), swapped exponents (1.2 / 0.4) or axes, a wrong W20
    factor."""
    altitude, w20 = 2.0, 5.0
    h = altitude / 0.3048
    sigma_w = 0.1 * w20
    sigma_u = sigma_w / (0.177 + 0.000823 * h) ** 0.4
    length_u = h / (0.177 + 0.000823 * h) ** 1.2 * 0.3048  # ft -> m
    sigma, length = DrydenConfig(w20=w20, altitude=altitude).scales()
    np.testing.assert_allclose(sigma, (sigma_u, sigma_u, sigma_w), rtol=1e-12)
    np.testing.assert_allclose(length, (length_u, length_u, altitude), rtol=1e-12)
    assert length_u == pytest.approx(15.41, abs=0.01)  # 50.6 ft: the horizontal scale is ~8 h here
    # DrydenConfig's own example: light turbulence (W20 = 7.7 m/s) gives σ_u ≈ 1.5 m/s at 2 m
    assert DrydenConfig(w20=7.7, altitude=2.0).scales()[0][0] == pytest.approx(1.5, abs=0.05)


def _stats(samples: np.ndarray, lags: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-axis standard deviation and autocorrelation at per-axis lags (in samples) of (T, S, 3)
    samples: T times of S independent streams, each axis's lag pooled over the streams."""
    g = samples - samples.reshape(-1, 3).mean(axis=0)
    std = g.reshape(-1, 3).std(axis=0)
    rho = np.array([np.sum(g[:-k, :, i] * g[k:, :, i]) / np.sum(g[:, :, i] ** 2) for i, k in enumerate(lags)])
    return std, rho


MEAN_WIND = 3.0
"""m/s along x: a vehicle at rest in it has V = 3 m/s, so the correlation times L/V are 2.6 s
(horizontal, L = 7.8 m at 1 m) and 0.33 s (vertical, L = 1 m)."""


@pytest.mark.parametrize("physics_hz", [200, 400])
def test_dryden_filter_has_sigma_and_correlation_length_at_any_step(physics_hz):
    """One simulated hour of the component (60 vehicles at rest for 60 s each, one stream per vehicle,
    started from the stationary distribution by ``reset``): each axis's std within 10 % of σ and its
    autocorrelation at lag L/V within 0.1 of e^-1, at dt = 1/200 and 1/400 alike (what the exact
    discrete filter buys). The same normals through the filter without the ``sqrt(1 - a²)`` factor
    (``u = a·u + σ·η``) give a std of σ/sqrt(1 - a²), 6 to 23 σ here and growing as dt shrinks: the
    test catches that, a wrong decay (dt, V or L), and gusts that ignore the normals they are given.

    Tolerances: an exponentially correlated process of correlation time τ = L/V over a total time T has
    N = T/τ independent samples (1380 horizontally, 10800 vertically); the sample std's relative sd is
    1/sqrt(2N) (1.9 %, so 10 % is 5 sd) and Bartlett's formula gives the autocorrelation at lag τ an sd
    of sqrt(0.59/N) (0.021, so 0.1 is 4.8 sd)."""
    config = DrydenConfig(w20=2.0, altitude=1.0, mean=(MEAN_WIND, 0.0, 0.0))
    sigma, length = config.scales()
    streams, seconds, dt = 60, 60.0, 1.0 / physics_hz
    steps = round(seconds / dt)
    gust = DrydenGust(config, streams)
    rng = np.random.default_rng(7)
    for index in range(streams):
        gust.reset(index, rng)
    rest = np.zeros((streams, 3))
    points = np.zeros((streams, 1, 3))
    times = np.zeros(streams)
    decay = np.exp(-MEAN_WIND * dt / length)
    unscaled = gust.gust.copy()
    wind = np.empty((steps, streams, 3))
    peer = np.empty((steps, streams, 3))
    for k in range(steps):
        normals = rng.standard_normal((streams, 3))
        dryden_advance(gust.kernel_parameters(), gust.weather, gust.gust, rest, rest, dt, normals)
        wind[k] = gust.velocity_at(points, times, slice(None))[:, 0]
        unscaled = decay * unscaled + sigma * normals
        peer[k] = unscaled
    lags = np.rint(length / (MEAN_WIND * dt)).astype(int)
    std, rho = _stats(wind, lags)
    np.testing.assert_allclose(std / sigma, 1.0, atol=0.1)
    np.testing.assert_allclose(rho, math.exp(-1.0), atol=0.1)
    # the sample mean's sd is σ·sqrt(2/N) (0.04 σ horizontally): 0.15 σ is 4 sd
    np.testing.assert_allclose((wind.reshape(-1, 3).mean(axis=0) - config.mean) / sigma, 0.0, atol=0.15)
    peer_std, _ = _stats(peer, lags)
    assert np.all(peer_std > 4.0 * sigma)
    np.testing.assert_allclose(peer_std / sigma, 1.0 / np.sqrt(1.0 - decay**2), rtol=0.15)


# -- 1-cosine gust --------------------------------------------------------------------------------
PEAK = np.array((1.5, -0.5, 0.25))
START, DURATION = 1.0, 2.0


def _one_cosine(t: float, hold: bool) -> np.ndarray:
    """V(t) written out: the rise over [t0, t0 + t_g], then the peak, or the mirror image of the rise
    over [t0 + t_g, t0 + 2 t_g] and zero after."""
    s = t - START
    if s <= 0.0:
        return np.zeros(3)
    if s <= DURATION:
        return PEAK / 2.0 * (1.0 - math.cos(math.pi * s / DURATION))
    if hold:
        return PEAK
    return _one_cosine(2.0 * (START + DURATION) - t, hold) if s <= 2.0 * DURATION else np.zeros(3)


TIMES = np.array((0.0, 0.5, 1.0, 1.3, 2.0, 2.7, 3.0, 3.5, 4.0, 4.6, 5.0, 6.0, 30.0))


@pytest.mark.parametrize("hold", [True, False])
def test_one_cosine_gust_follows_its_formula(hold):
    """Each of 13 vehicles at its own time (before, during and after the rise and the fall), at 5 points
    of its own: the field equals the formula, is the same at every point, half the peak half way up
    (and half way down in a bump), the peak at the top. Catches the wrong phase (t_g vs 2 t_g), a
    bump that holds or a hold that falls, the vehicles' times mixed up, and the kernel (to 1e-12,
    added to what ``out`` held) departing from the reference."""
    gust = OneCosineGust(
        OneCosineConfig(peak=tuple(PEAK), start=START, duration=DURATION, hold=hold), len(TIMES)
    )
    points = np.random.default_rng(3).uniform(-5.0, 5.0, (len(TIMES), 5, 3))
    field = gust.velocity_at(points, TIMES, slice(None))
    expected = np.array([_one_cosine(t, hold) for t in TIMES])
    np.testing.assert_allclose(field, np.broadcast_to(expected[:, None, :], points.shape), atol=1e-12)
    np.testing.assert_allclose(field[TIMES == START + DURATION / 2, 0], [PEAK / 2], atol=1e-12)
    np.testing.assert_allclose(field[TIMES == START + DURATION, 0], [PEAK], atol=1e-12)
    after = field[TIMES == START + 1.5 * DURATION, 0]
    np.testing.assert_allclose(after, [PEAK if hold else PEAK / 2], atol=1e-12)
    np.testing.assert_allclose(field[-1, 0], PEAK if hold else 0.0, atol=1e-12)
    out = np.random.default_rng(4).standard_normal(points.shape)
    before = out.copy()
    one_cosine_velocity(gust.kernel_parameters(), gust.shape, NO_TABLE, points, TIMES, out)
    np.testing.assert_allclose(out - before, field, atol=1e-12)


# -- fixed jet ------------------------------------------------------------------------------------
JET = JetConfig(position=(1.0, -2.0, 0.8), direction=(1.0, 2.0, 0.5), speed=12.0, diameter=0.5, spread=0.42)


def _jet_frame() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The outlet, the unit direction and two unit vectors across it."""
    d = np.array(JET.direction) / np.linalg.norm(JET.direction)
    e1 = np.cross(d, (0.0, 0.0, 1.0))
    e1 /= np.linalg.norm(e1)
    return np.array(JET.position), d, e1, np.cross(d, e1)


def _jet_field(points: np.ndarray) -> np.ndarray:
    jet = Jet(JET)
    return jet.velocity_at(points[None], np.zeros(1), np.zeros(1, dtype=int))[0]


def _jet_scales(x: float) -> tuple[float, float]:
    """Half-width b and centre-line speed u_c at distance x: written out from ``docs/physics.md``, "Fan"."""
    b = math.sqrt((JET.diameter / 2) ** 2 + (JET.spread * x) ** 2)
    return b, JET.speed * min(1.0, JET.diameter / (math.sqrt(2.0) * b))


@pytest.mark.parametrize("x", [0.3, 1.0, 2.5, 6.0])
def test_jet_profile_blows_along_its_direction(x):
    """On the axis at distance x the speed is u_c(x) (U0 in the core, x < D/(2c) = 0.6 m), e^-1 of it
    at r = b in any direction across, and the air moves along the (normalised) direction, also off the
    axis; behind the outlet plane, and on it, still air. Catches an unnormalised direction, the origin
    or the axis misplaced, a wrong half-width, and a field blowing backwards."""
    origin, d, e1, e2 = _jet_frame()
    b, u_c = _jet_scales(x)
    points = np.array(
        [
            origin + x * d,
            origin + x * d + b * e1,
            origin + x * d - b * e2,
            origin + x * d + 0.3 * b * (e1 + e2),
        ]
    )
    field = _jet_field(points)
    speed = field @ d
    assert speed[0] == pytest.approx(u_c, rel=1e-12)
    np.testing.assert_allclose(speed[1:3], u_c * math.exp(-1.0), rtol=1e-12)
    np.testing.assert_allclose(field, speed[:, None] * d, atol=1e-12)  # no radial component
    assert speed[3] == pytest.approx(u_c * math.exp(-0.18), rel=1e-12)  # r² = 2·(0.3 b)²
    behind = _jet_field(
        np.array([origin - x * d, origin - x * d + 0.1 * e1, origin, origin - 1e-6 * d + 0.1 * e2])
    )
    np.testing.assert_array_equal(behind, 0.0)


@pytest.mark.parametrize("x", [1.0, 3.0, 6.0])
def test_jet_carries_the_outlets_momentum_flux(x):
    """The jet's axial momentum flux ∫ρu²dA over a plane across it equals the outlet's ρU0²πD²/4 beyond
    the core (ρ cancels): catches a centre-line speed that does not fall as 1/b. The integral runs over
    the sampled field along one radius (the profile is radially symmetric, checked above) to 5
    half-widths (the Gaussian's u² tail beyond holds e^-50 of it): trapezoid error << 1 %."""
    assert x > JET.diameter / (2 * JET.spread)  # beyond the core, 0.6 m
    origin, d, e1, _ = _jet_frame()
    b, u_c = _jet_scales(x)
    r = np.linspace(0.0, 5.0 * b, 4001)
    u = _jet_field(origin + x * d + r[:, None] * e1) @ d
    flux = np.trapezoid(2.0 * np.pi * r * u * u, r)
    outlet = JET.speed**2 * np.pi * JET.diameter**2 / 4.0
    assert flux == pytest.approx(outlet, rel=0.01)
    assert u_c**2 * np.pi * b**2 / 2.0 == pytest.approx(outlet, rel=1e-12)  # the closed form


# -- ground effect --------------------------------------------------------------------------------
R = 0.1
"""ardrone2's rotor radius (m)."""
CAP_HEIGHT = R / (4.0 * math.sqrt(1.0 - 1.0 / 1.4))
"""Height (0.0468 m) below which 1/(1 - (R/4z)²) exceeds the cap 1.4."""


def _cheeseman_bennett(z: np.ndarray) -> np.ndarray:
    """T_IGE/T_OGE at rotor heights z above the surface below, capped."""
    return np.where(z < CAP_HEIGHT, 1.4, 1.0 / (1.0 - (R / (4.0 * np.asarray(z))) ** 2))


TABLE = Table(center=(2.0, 0.0), size=(1.0, 0.6), height=0.75)
"""x in [1.5, 2.5], y in [-0.3, 0.3], top at 0.75 m."""


def test_scene_gives_the_tops_of_its_tables_alone():
    """Walls and ceilings have no top the ground effect sees; a table's footprint and height in the
    order [x_min, x_max, y_min, y_max, z]: catches swapped or half/full size mix-ups."""
    tops = surface_tops([Wall(), TABLE, Ceiling()])
    np.testing.assert_allclose(tops, [[1.5, 2.5, -0.3, 0.3, 0.75]])
    assert surface_tops([Wall()]).shape == (0, 5)


def test_ground_effect_against_cheeseman_bennett_over_ground_and_table():
    """Each rotor's added thrust (ratio - 1)·T for hubs at heights z above the ground (no scene) and
    above the table's top (hub at 0.75 + z), through the cap at z < R/(4·sqrt(1 - 1/1.4)): catches a
    wrong formula (R/2z, R/4z not squared), a missing or misplaced cap, heights measured from the
    ground when over a table, and thrusts not scaling the gain."""
    heights = np.array((0.02, 0.04, 0.045, 0.05, 0.08, 0.1, 0.2, 0.5, 1.0, 3.0))
    assert heights[2] < CAP_HEIGHT < heights[3]
    thrusts = np.linspace(0.8, 1.4, 4)[None].repeat(len(heights), axis=0)
    expected = (_cheeseman_bennett(heights)[:, None] - 1.0) * thrusts
    rotation = np.broadcast_to(np.eye(3), (len(heights), 3, 3))
    hubs = np.zeros((len(heights), 4, 3))
    hubs[..., :2] = (2.0, 0.1) + 0.129 * np.array(((1, 1), (-1, 1), (-1, -1), (1, -1)))  # over the table
    ground = GroundEffect(R, np.zeros((0, 5)))
    table = GroundEffect(R, surface_tops([TABLE]))
    hubs[..., 2] = heights[:, None]
    np.testing.assert_allclose(ground.added_thrust(hubs, rotation, thrusts), expected, rtol=1e-12)
    hubs[..., 2] += TABLE.height  # z = (0.75 + h) - 0.75 rounds: (ratio - 1) ~ 1e-4 at 3 m, so 1e-9
    np.testing.assert_allclose(table.added_thrust(hubs, rotation, thrusts), expected, rtol=1e-9)
    assert _cheeseman_bennett(0.08) == pytest.approx(1.0 / (1.0 - (0.1 / 0.32) ** 2))  # ≈ 1.108


def test_a_higher_cap_leaves_the_formula_alone_below_it():
    """With a cap of 3 the ratio follows 1/(1 - (R/4z)²) up to 3 on both paths: at (R/4z)² = 0.6 it is
    2.5 (a clamp meant only for the capped branch once gave 2 there)."""
    height = 0.1 / (4.0 * math.sqrt(0.6))
    effect = GroundEffect(0.1, np.zeros((0, 5)), cap=3.0)
    hubs = np.tile((0.0, 0.0, height), (1, 4, 1))
    thrusts = np.ones((1, 4))
    np.testing.assert_allclose(effect.added_thrust(hubs, np.eye(3)[None], thrusts), 1.5)
    out = np.zeros((1, 4))
    ground_effect_thrust(
        effect.kernel_parameters(), np.zeros((1, 0)), np.zeros((1, 0)), hubs, np.eye(3)[None], thrusts, out
    )
    np.testing.assert_allclose(out, 1.5)


def test_a_table_counts_only_under_a_rotor_above_its_top():
    """The surface under a hub is the highest top whose footprint holds it and that is not above it:
    a hub below the top (beside the table's leg, say) or outside the footprint measures from the
    ground; of two stacked tops the higher one under the hub counts. Catches a top counted from
    outside its footprint (x and y mixed up, half sizes as full), a top above the hub (which would
    give a negative height and a huge or capped gain) and the lowest instead of the highest top."""
    shelf = Table(center=(2.0, 0.0), size=(0.2, 0.2), height=0.9)  # on the table, above 0.75
    effect = GroundEffect(R, surface_tops([TABLE, shelf]))
    hubs = np.array(
        [
            [2.0, 0.2, 0.83],  # over the table: 0.08 above its top
            [2.0, 0.2, 0.70],  # within its footprint but below the top: 0.70 above the ground
            [2.0, 0.4, 0.83],  # beyond its y edge (0.3) though within its x range: over the ground
            [2.6, 0.0, 0.83],  # beyond its x edge (2.5) though within its y range: over the ground
            [2.0, 0.0, 0.98],  # over the shelf: 0.08 above its top
            [2.0, 0.0, 0.83],  # under the shelf's top, over the table's: 0.08
            [2.05, 0.15, 0.95],  # over the table beside the shelf: 0.20
        ]
    )[None]
    heights = np.array((0.08, 0.70, 0.83, 0.83, 0.08, 0.08, 0.20))
    added = effect.added_thrust(hubs, np.eye(3)[None], np.ones((1, len(heights))))[0]  # any number of hubs
    np.testing.assert_allclose(added, _cheeseman_bennett(heights) - 1.0, rtol=1e-9)


def _hover(make_env, table: dict):
    """A FanTracking env, fan off, oracle estimator, hovering 8 cm above the top of ``table``
    (the hubs are at body z = 0, so the rotors are 8 cm above it), after 2 s of zero actions."""
    height = table["height"] + 0.08
    env = make_env(
        fan={"enabled": False, "height": height},
        estimator="oracle",
        ground_effect=True,
        scene=[table],
    )
    env.reset(seed=0, options=STEADY)
    for _ in range(100):
        _, _, terminated, truncated, info = env.step(np.zeros(4))
        assert not (terminated or truncated)
    assert info["position"][2] == pytest.approx(height, abs=2e-3)  # still 8 cm above the top
    return env.unwrapped, info


def test_hover_over_a_table_gains_the_cheeseman_bennett_thrust(make_env):
    """Acceptance: 8 cm above a table, all four rotors over it, the external force the world applies
    (``wrench_true``) is the ground effect's, (1 - 1/ratio)·weight, within 3 %.

    Derivation: each rotor over the table gains (ratio - 1)·T_i, so the gain is A = (ratio - 1)·T with
    T = ΣT_i the rotors' own thrust; in a trimmed hover in still air T + A = W (no drag at rest), so
    A = (ratio - 1)·(W - A), i.e. A = W·(ratio - 1)/ratio = W·(1 - 1/ratio) = 0.0977·W = 0.402 N with
    ratio = 1/(1 - (0.1/0.32)²) = 1.108; (ratio - 1)·W, the gain on the weight, would be 11 % more, and
    the test tells them apart. Catches the gain missing from the load or from wrench_true, and heights
    from the ground instead of the top."""
    env, info = _hover(make_env, {"kind": "table", "center": [2.3, 0.0], "size": [1.0, 1.0], "height": 0.75})
    weight = env.vehicle.mass * GRAVITY
    ratio = float(_cheeseman_bennett(0.08))
    expected = weight * (1.0 - 1.0 / ratio)
    assert info["wrench_true"][2] == pytest.approx(expected, rel=0.03)
    thrust = env.fleet.rotors.thrusts().sum()
    assert info["wrench_true"][2] == pytest.approx((ratio - 1.0) * thrust, rel=0.03)
    np.testing.assert_allclose(info["wrench_true"][[0, 1, 3, 4, 5]], 0.0, atol=1e-3 * expected)


EDGES = {
    "table at -x": ([1.8, 0.0], 1, +1.0),  # x_max = 2.3: rotors at world x < 2.3 over it
    "table at +x": ([2.8, 0.0], 1, -1.0),  # x_min = 2.3
    "table at -y": ([2.3, -0.5], 0, -1.0),  # y_max = 0: rotors at world y < 0 over it
    "table at +y": ([2.3, 0.5], 0, +1.0),
}


@pytest.mark.parametrize("edge", list(EDGES), ids=list(EDGES))
def test_half_over_the_edge_pitches_towards_the_sign_the_geometry_gives(make_env, edge):
    """Two rotors over the table, two 0.83 m above the ground beyond its edge under the centre of
    mass: the torque about the centre of mass in ``wrench_true`` is Σ r_i × (A_i ẑ) over the hubs
    (world frame, from the hub positions after the yaw of π at reset), which is (r_y·A, -r_x·A, 0):
    rotors over a table on the -x side (r_x < 0) give +τ_y, on the -y side (r_y < 0) give -τ_x. The
    expected sign comes from the geometry alone, the value (to 3 %) from the formula on the rotors'
    own thrusts. Catches a torque of the wrong sign (r × F reversed, hubs in body instead of world
    coordinates, the yaw forgotten), the gain applied at the centre of mass (no torque) and the
    footprint test mixing x and y."""
    center, axis, sign = EDGES[edge]
    table = {"kind": "table", "center": center, "size": [1.0, 1.0], "height": 0.75}
    env, info = _hover(make_env, table)
    state = env.fleet.state
    offsets = env.vehicle.rotor_positions @ state.rotation[0].T  # hub offsets, world frame
    lo, hi = np.array(center) - 0.5, np.array(center) + 0.5
    hubs = state.position[0] + offsets
    over = np.all((hubs[:, :2] >= lo) & (hubs[:, :2] <= hi), axis=1)
    assert over.sum() == 2
    heights = np.where(over, hubs[:, 2] - 0.75, hubs[:, 2])
    added = (_cheeseman_bennett(heights) - 1.0) * env.fleet.rotors.thrusts()[0]
    torque = np.cross(offsets, added[:, None] * state.rotation[0][:, 2]).sum(axis=0)
    # τ = Σ r × (A ẑ) = (r_y·A, -r_x·A, 0): the rotors over the table (A ≈ 0.1 N) outweigh those
    # 0.83 m above the ground (A ≈ 0.001 N)
    r_over = offsets[over].mean(axis=0)
    assert (np.sign(r_over[1]) if axis == 0 else -np.sign(r_over[0])) == sign
    assert np.sign(info["wrench_true"][3 + axis]) == sign
    assert info["wrench_true"][3 + axis] == pytest.approx(torque[axis], rel=0.03)
    assert abs(info["wrench_true"][3 + axis]) > 0.02  # 2 rotors x 0.1 N x 0.129 m
    # the other axis: only the rotors' small thrust differences (kf_spread) over the table
    assert abs(info["wrench_true"][4 - axis]) < 0.02 * abs(info["wrench_true"][3 + axis])
    # the component alone, on the same hubs: the same torque
    direct = GroundEffect(R, surface_tops([Table(center=center, size=(1.0, 1.0), height=0.75)])).added_thrust(
        hubs[None], state.rotation, env.fleet.rotors.thrusts()
    )[0]
    np.testing.assert_allclose(direct, added, rtol=1e-12)


# -- the env: info reports the air the vehicle is in ----------------------------------------------
def test_info_wind_velocity_is_the_gust_plus_the_jet_at_the_centre_of_mass(make_env):
    """With a bump gust and a jet blowing across the vehicle, ``info["wind_velocity"]`` after each step
    is the 1-cosine formula at ``info["time"]`` plus the jet at ``info["position"]``, to rounding:
    catches fields sampled at the time or position before the step, a field left out of the sum
    or counted twice."""
    jet = {"model": "jet", "position": [2.3, -3.0, 1.0], "direction": [0.0, 1.0, 0.0], "speed": 3.0}
    gust = {"model": "one_cosine", "peak": PEAK.tolist(), "start": START, "duration": DURATION, "hold": False}
    env = make_env(wind=[gust, jet], fan={"enabled": False}, estimator="oracle")
    env.reset(seed=0, options=STEADY)
    field = Jet(JetConfig(**{k: v for k, v in jet.items() if k != "model"}))
    seen = []
    for _ in range(int((START + 2.5 * DURATION) * 50)):
        _, _, terminated, truncated, info = env.step(np.zeros(4))
        assert not (terminated or truncated)
        at_jet = field.velocity_at(info["position"][None, None], np.zeros(1), np.zeros(1, dtype=int))[0, 0]
        expected = _one_cosine(info["time"], hold=False) + at_jet
        np.testing.assert_allclose(info["wind_velocity"], expected, atol=1e-12)
        seen.append(info["wind_velocity"][0])
    assert max(seen) == pytest.approx(PEAK[0], abs=0.05)  # the jet adds nothing along x
    assert at_jet[1] == pytest.approx(0.83, abs=0.05)  # u_c at 3 m: 3·0.5/(√2·1.28)


# -- compiled kernels against the reset-time forms and the filter's formula ---------------------------
@pytest.mark.parametrize("mean", [(1.2, -0.7, 0.1), (0.3, 0.0, 0.2)], ids=["mean-above-1", "mean-below-1"])
def test_dryden_kernels_match_the_reference(mean):
    """``dryden_velocity`` against ``DrydenGust.velocity_at`` and ``dryden_advance`` (argument order of
    base.py's table) against the exact first-order filter written here, ``g' = a·g + σ·sqrt(1 - a²)·η``
    with ``a = exp(-V·dt/L)``, on random gusts, points, airspeeds and normals, to 1e-9; airspeeds from
    0 to several m/s about mean winds above and below 1 m/s take every branch of
    V = max(airspeed, |mean|, 1 m/s). Catches a kernel reading params in another order, a different V,
    or writing another vehicle's row."""
    rng = np.random.default_rng(11)
    gust = DrydenGust(DrydenConfig(w20=3.0, altitude=1.5, mean=mean), 8)
    gust.gust[:] = rng.standard_normal((8, 3))
    gust.weather[4:] = np.column_stack((rng.normal(0.0, 1.5, (4, 3)), rng.uniform(0.0, 2.0, 4)))
    params = gust.kernel_parameters()
    points = rng.uniform(-3.0, 3.0, (8, 5, 3))
    out = rng.standard_normal(points.shape)
    before = out.copy()
    dryden_velocity(params, gust.weather, gust.gust, points, rng.uniform(0, 9, 8), out)
    np.testing.assert_allclose(out - before, gust.velocity_at(points, np.zeros(8), slice(None)), atol=1e-9)
    spread = np.array((0.1, 0.5, 1.0, 3.0, 0.0, 0.2, 5.0, 2.0))[:, None]
    velocity = gust.weather[:, :3] + spread * rng.standard_normal((8, 3))
    position = rng.uniform(-3.0, 3.0, (8, 3))
    for dt in (1.0 / 200, 1.0 / 400, 0.3):
        normals = rng.standard_normal((8, 3))
        mean = gust.weather[:, :3]
        airspeed = np.linalg.norm(velocity - mean, axis=1)
        speed = np.maximum(np.maximum(airspeed, np.linalg.norm(mean, axis=1)), 1.0)
        decay = np.exp(-speed[:, None] * dt / gust.length)
        expected = decay * gust.gust + gust.sigma * np.sqrt(1.0 - decay * decay) * normals
        dryden_advance(params, gust.weather, gust.gust, position, velocity, dt, normals)
        np.testing.assert_allclose(gust.gust, expected, atol=1e-9)


@pytest.mark.parametrize("hold", [True, False])
def test_one_cosine_kernel_matches_the_reference(hold):
    """``one_cosine_velocity`` at random times (before, during, after) to 1e-9."""
    rng = np.random.default_rng(12)
    gust = OneCosineGust(OneCosineConfig(peak=(0.3, 2.0, -1.0), start=0.7, duration=1.3, hold=hold), 50)
    gust.shape[::2] = np.column_stack(
        (rng.normal(0.0, 2.0, (25, 3)), rng.uniform(0, 2, 25), rng.uniform(0.2, 2, 25))
    )
    points, times = rng.uniform(-2.0, 2.0, (50, 3, 3)), rng.uniform(-1.0, 5.0, 50)
    out = np.zeros(points.shape)
    one_cosine_velocity(gust.kernel_parameters(), gust.shape, NO_TABLE, points, times, out)
    np.testing.assert_allclose(out, gust.velocity_at(points, times, slice(None)), atol=1e-9)


def test_fixed_jet_kernel_matches_the_reference():
    """``fixed_jet_velocity`` at random points in front of, beside and behind the outlet, in and beyond
    the core, to 1e-9: catches the kernel's packed origin, direction or core length out of step with
    ``Jet.kernel_parameters``."""
    rng = np.random.default_rng(13)
    jet = Jet(JET, 40)
    jet.speed_scale[::2, 0] = rng.uniform(0.0, 3.0, 20)  # each vehicle's own strength
    points = np.array(JET.position) + rng.uniform(-6.0, 6.0, (40, 6, 3))
    out = rng.standard_normal(points.shape)
    before = out.copy()
    fixed_jet_velocity(jet.kernel_parameters(), jet.speed_scale, NO_TABLE, points, np.zeros(40), out)
    reference = jet.velocity_at(points, np.zeros(40), slice(None))
    assert np.count_nonzero(reference[..., 0]) > 50  # the sample reaches into the jet
    np.testing.assert_allclose(out - before, reference, atol=1e-9)


def test_ground_effect_kernel_matches_the_reference():
    """``ground_effect_thrust`` on random hubs over, beside and under two tables, down to the cap, to
    1e-9: catches the kernel unpacking the tops in another order or skipping the cap."""
    rng = np.random.default_rng(14)
    tops = surface_tops([TABLE, Table(center=(2.2, 0.2), size=(0.4, 0.4), height=0.9)])
    effect = GroundEffect(R, tops)
    hubs = np.column_stack(
        (rng.uniform(1.3, 2.7, 400), rng.uniform(-0.5, 0.5, 400), rng.uniform(0.01, 1.2, 400))
    ).reshape(100, 4, 3)
    rotation = np.broadcast_to(np.eye(3), (100, 3, 3)).copy()
    thrusts = rng.uniform(0.5, 1.5, (100, 4))
    out = rng.standard_normal((100, 4))
    before = out.copy()
    ground_effect_thrust(effect.kernel_parameters(), NO_TABLE, NO_TABLE, hubs, rotation, thrusts, out)
    reference = effect.added_thrust(hubs, rotation, thrusts)
    assert np.isclose(reference, 0.4 * thrusts).any()  # the cap is reached
    np.testing.assert_allclose(out - before, reference, atol=1e-9)


# -- acceptance: an hour of Dryden gusts through the env ----------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("physics_hz", [200, 400])
def test_an_hour_of_dryden_gusts_at_the_vehicle_has_the_specified_statistics(make_env, physics_hz):
    """Acceptance: an hour of hover (zero velocity actions) in a 3 m/s mean wind along x with light
    turbulence (W20 = 1 m/s at 1 m: σ = 0.20, 0.20, 0.10 m/s; L = 7.8, 7.8, 1.0 m): each axis of
    ``info["wind_velocity"]``, sampled at 50 Hz, has its std within 10 % of σ and its autocorrelation at
    lag L/V within 0.1 of e^-1, at physics_hz 200 and 400 alike. Tolerances as in the component test
    (N = T·V/L = 1380 independent samples horizontally: the std's sd is 1.9 %, the autocorrelation's
    0.021); V varies by a few % with the vehicle's own motion (airspeed 2.9 to 3.1 m/s measured), and
    the lag rounds to whole policy steps (shifting e^-1 by < 0.01). Catches a gust that the engine's
    compiled step advances with the wrong dt or draws, samples at the wrong time or scales wrongly.
    About 40 s (200 Hz) and 65 s (400 Hz) with numba, after the compile."""
    spec = {"model": "dryden", "w20": 1.0, "altitude": 1.0, "mean": [MEAN_WIND, 0.0, 0.0]}
    env = make_env(
        wind=[spec],
        fan={"enabled": False},
        estimator="oracle",
        physics_hz=physics_hz,
        policy_hz=50,
        episode_seconds=3600.0,
    )
    env.reset(seed=1, options=STEADY)
    steps = 3600 * 50
    wind = np.empty((steps, 3))
    position = np.empty((steps, 3))
    action = np.zeros(4)
    for k in range(steps):
        _, _, terminated, truncated, info = env.step(action)
        wind[k], position[k] = info["wind_velocity"], info["position"]
        assert not terminated and (not truncated or k == steps - 1)
    sigma, length = DrydenConfig(w20=1.0, altitude=1.0).scales()
    std, rho = _stats(wind[:, None, :], np.rint(length / MEAN_WIND * 50).astype(int))
    np.testing.assert_allclose(std / sigma, 1.0, atol=0.1)
    np.testing.assert_allclose(rho, math.exp(-1.0), atol=0.1)
    assert np.all(np.abs(position - (2.3, 0.0, 1.0)).max(axis=0) < (0.5, 0.5, 0.1))  # held in place


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ({"kind": "table", "height": -1.0}, r"scene table: height=-1.0 must be > 0"),
        (
            {"kind": "table", "center": [1.0, 2.0, 3.0]},
            r"scene table: center=\[1.0, 2.0, 3.0\] must be finite",
        ),
        ({"kind": "wall", "width": 0.0}, r"scene wall: width=0.0 must be > 0"),
        ({"kind": "ceiling", "size": [1.0, math.nan]}, r"scene ceiling: size=\[1.0, nan\] must be finite"),
        ({"kind": "sofa"}, r"scene\[0\]: unknown kind 'sofa'; allowed: \['ceiling', 'table', 'wall'\]"),
        ({"kind": "table", "legs": 4}, r"legs"),
    ],
)
def test_bad_scene_entries_are_refused_by_name(entry, message):
    from quad_wrench_env.scene import make_scene_part

    with pytest.raises(ValueError, match=message):
        make_scene_part(entry)


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ({"model": "hurricane"}, r"wind\[0\]: unknown model 'hurricane'"),
        ({"model": "dryden", "w20": "2"}, r"wind\[0\]\.w20='2' must be a number"),
        ({"model": "jet", "direction": [0.0, 0.0, 0.0]}, r"direction=\[0, 0, 0\] has no direction"),
        ({"model": "one_cosine", "duration": 0.0}, r"duration"),
        ({"speed": 3.0}, r"must be a mapping with a 'model'"),
    ],
)
def test_bad_wind_entries_are_refused_by_name(entry, message):
    from quad_wrench_env.disturbances.base import wind_config

    with pytest.raises(ValueError, match=message):
        wind_config(entry)

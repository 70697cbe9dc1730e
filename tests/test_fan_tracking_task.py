"""FanTracking-v1 as a task: a continuous attitude block, a default episode distribution that only
the wrench reveals, the stand-off term, the reward's values and the wrench ablation switch."""

from __future__ import annotations

import math

import numpy as np
import pytest

from quad_wrench_env.config import build
from quad_wrench_env.disturbances.fan import ConstantSpeed, FanConfig, PiecewiseVelocity, Sine, Static
from quad_wrench_env.engine.world import RigidBodyState
from quad_wrench_env.estimators.noise import FilterNoise
from quad_wrench_env.rotations import rotation_matrix
from quad_wrench_env.tasks.fan_tracking import FanEpisodes, FanTrackingConfig
from quad_wrench_env.vehicle import make_vehicle


def test_attitude_block_is_the_rotation_matrix_and_moves_no_faster_than_the_body_rates(make_env):
    """The vehicle faces the fan (yaw = π, where a quaternion kept to w >= 0 flips sign): between two
    observations 20 ms apart the block can change by at most what the body rates turn it, |ω|·dt per
    column (plus the estimator's noise, a few mrad), never a jump of order 1."""
    env = make_env(estimator="oracle")
    obs, _ = env.reset(seed=3, options={"offset_y": 0.8, "fan_motion": "static"})
    layout = env.unwrapped.obs_layout
    assert layout["attitude"] == slice(6, 12)
    rng = np.random.default_rng(0)
    dt = 1.0 / env.unwrapped.cfg.policy_hz
    for _ in range(300):
        action = rng.uniform(-1, 1, 4).astype(np.float32)  # yaw rate too: cross w = 0 many times
        new, _, terminated, _, _ = env.step(action)
        if terminated:
            break
        before, after = obs[layout["attitude"]], new[layout["attitude"]]
        rates = max(np.linalg.norm(obs[layout["body_rates"]]), np.linalg.norm(new[layout["body_rates"]]))
        for column in (slice(0, 3), slice(3, 6)):
            assert np.linalg.norm(after[column] - before[column]) <= 1.5 * rates * dt + 1e-3
        obs = new
    quaternion = env.unwrapped.world.state().quaternion[0]
    np.testing.assert_allclose(
        obs[layout["attitude"]], rotation_matrix(quaternion)[:, :2].T.ravel(), atol=1e-6
    )


def test_default_episodes_draw_every_motion_family_across_the_y0_range(make_env):
    env = make_env()
    episodes = env.unwrapped.cfg.episodes
    kinds, y0s = set(), []
    for seed in range(60):
        env.reset(seed=seed)
        motion = env.unwrapped.task.fan.motion(0)
        kinds.add(type(motion))
        y0s.append(float(motion.y(np.asarray(0.0))))
        path = motion.y(np.linspace(0.0, env.unwrapped.cfg.episode_seconds, 301))
        assert np.all(np.abs(path) <= episodes.y_range + 1e-9)  # the fan stays in the documented range
    assert kinds == {Static, ConstantSpeed, Sine, PiecewiseVelocity}
    # uniform y0 over about ±2 m: 60 draws cover most of it, both sides
    assert min(y0s) < -1.0 and max(y0s) > 1.0
    assert np.std(y0s) > 0.5


def test_same_seed_same_episode_and_the_paper_cases_stay_named(make_env):
    env = make_env()
    env.reset(seed=7)
    first = env.unwrapped.task.fan.motion(0)
    env.reset(seed=7)
    assert env.unwrapped.task.fan.motion(0) == first
    env.reset(seed=7, options={"fan_motion": "sine"})
    assert env.unwrapped.task.fan.motion(0) == Sine(amplitude=0.5, frequency=1.0 / 30.0, y0=0.0)
    env.reset(seed=7, options={"fan_motion": {"name": "static", "y0": 1.2}, "offset_y": 0.8})
    assert env.unwrapped.task.fan.motion(0) == Static(1.2)
    assert env.unwrapped.fleet.state.position[0, 1] == pytest.approx(2.0)


@pytest.mark.parametrize(
    "episodes",
    [
        FanEpisodes(motions=("constant_speed",), max_speed=1.0, y_range=1.0),
        FanEpisodes(max_speed=0.5, max_amplitude=3.0),
    ],
)
def test_episode_draw_fits_a_fast_motion_into_the_range(episodes):
    rng = np.random.default_rng(8)
    for _ in range(50):
        path = episodes.draw(rng, 30.0).y(np.linspace(0.0, 30.0, 301))
        assert np.all(np.abs(path) <= episodes.y_range + 1e-9)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"episodes": {"max_segment_seconds": float("nan")}}, "max_segment_seconds=nan"),
        ({"episodes": {"segments": True}}, "segments=True"),
        ({"max_initial_offset": -1.0}, "max_initial_offset=-1.0"),
        ({"standoff_distance": "2.3"}, "standoff_distance='2.3'"),
        ({"episodes": {"y_range": 3.5}}, "y_range=3.5"),
    ],
)
def test_bad_task_config_names_the_value(make_env, kwargs, match):
    with pytest.raises(ValueError, match=match):
        make_env(**kwargs)


def test_bad_offset_option_names_it(make_env):
    env = make_env()
    with pytest.raises(ValueError, match="offset_y='abc'"):
        env.reset(seed=0, options={"offset_y": "abc"})


def test_reward_terms_by_hand(make_env):
    """A still fan at y0 = 0: after one step the terms follow from the true position alone."""
    env = make_env(estimator="oracle", fan={"turbulence_intensity": 0.0})
    env.reset(seed=0, options={"fan_motion": "static", "offset_y": 0.4})
    action = np.array((0.5, 0.0, 0.0, -0.5), dtype=np.float32)
    _, reward, _, _, info = env.step(action)
    x, y, z = info["position"]
    d = math.hypot(y - 0.0, z - 1.0)  # the axis of a still fan at y = 0 is y = 0 at every x
    terms = info["reward_terms"]
    assert terms["tracking"] == pytest.approx(math.exp(-d / 0.5), rel=1e-9)
    assert terms["standoff"] == pytest.approx(-abs(x - 2.3), rel=1e-9)
    assert terms["effort"] == pytest.approx(-0.01 * (0.25 + 0.25) / 4, rel=1e-6)
    assert terms["crash"] == 0.0
    assert info["axis_error"] == pytest.approx(y, abs=1e-12)
    assert info["standoff_error"] == pytest.approx(x - 2.3, abs=1e-12)
    assert reward == pytest.approx(sum(terms.values()))
    assert math.exp(-0.8 / 0.5) > 0.15  # signal at the 0.8 m start, unlike exp(-(0.8/0.3)²) = 8e-4


def test_observe_wrench_false_zeroes_the_wrench_blocks_only(make_env):
    seen = make_env()
    hidden = make_env(observe_wrench=False)
    a, info_a = seen.reset(seed=1)
    b, info_b = hidden.reset(seed=1)
    layout = seen.unwrapped.obs_layout
    for _ in range(20):
        a, *_, info_a = seen.step(np.full(4, 0.1, dtype=np.float32))
        b, *_, info_b = hidden.step(np.full(4, 0.1, dtype=np.float32))
    assert np.any(a[layout["wrench"]] != 0)
    np.testing.assert_array_equal(b[layout["wrench"]], 0.0)
    keep = np.ones(a.shape, dtype=bool)
    keep[layout["wrench"]] = False
    np.testing.assert_array_equal(a[keep], b[keep])
    np.testing.assert_array_equal(info_a["wrench_est"], info_b["wrench_est"])


@pytest.mark.parametrize(
    "settings",
    [
        {"vehicle": "ardrone2"},
        {"vehicle": "yuksel1kg", "estimator": "ekf"},
        {
            "vehicle": "hummingbird",
            "physics_hz": 400,
            "standoff_distance": 1.5,
            "fan": {"turbulence_intensity": 0.3},
        },
    ],
)
def test_fan_walks_are_the_turbulences_largest_change_per_step_added_to_the_defaults(make_env, settings):
    """``fan_walks``: the filter's force and torque walks are the vehicle's defaults and, in quadrature,
    the largest over lateral offsets of the per-step change of the wrench the turbulence puts on the
    vehicle, measured here on the env's own loads: the fan's turbulence state ``n`` nudged along each
    axis, ``Fleet.external_loads`` differenced (every drag point, the rotors' drag at their trimmed
    speeds), times the OU step ``sqrt(1 - a²)``, ``a = exp(-dt·u_c/b)`` worked from the jet's definition
    (``docs/physics.md``, "Fan": at the stand-off x, b = sqrt((D/2)² + (c x)²), u_c = U0·D/(√2·b) beyond
    the core, dt the physics step); the intensity is in the loads. A given walk is kept; the default
    (false) leaves the vehicle's defaults; other estimators and named settings are refused."""
    standoff, physics_hz = settings.get("standoff_distance", 2.3), settings.get("physics_hz", 200)
    fan = FanConfig(**settings.get("fan", {}))
    b = math.hypot(fan.outlet_diameter / 2, fan.spread * standoff)
    u_c = fan.outlet_speed * fan.outlet_diameter / (math.sqrt(2.0) * b)
    assert fan.outlet_diameter / (math.sqrt(2.0) * b) < 1.0  # beyond the core
    step = math.sqrt(1.0 - math.exp(-2.0 * u_c / (b * physics_hz)))
    env = make_env(**{**settings, "fan": {**settings.get("fan", {}), "motion": "static"}}).unwrapped
    env.reset(seed=0, options={"offset_y": 0.0})
    jet = next(field for field in env.fleet.components.winds if field.name == "fan")
    level = np.array(((1.0, 0.0, 0.0, 0.0),))
    largest = np.zeros(2)
    for offset in np.linspace(0.0, b, 41):
        rest = RigidBodyState.at_rest(np.array(((standoff, offset, fan.height),)), level)
        columns = []
        for axis in range(3):
            jet.noise[0] = 0.0
            jet.noise[0, axis] = 1e-4
            nudged = env.fleet.external_loads(rest, np.array((0,)))[0]
            jet.noise[0, axis] = -1e-4
            columns.append((nudged - env.fleet.external_loads(rest, np.array((0,)))[0]) / 2e-4)
        jacobian = np.array(columns).T  # (6, 3): d wrench / d n
        per_axis = np.sqrt(np.sum(jacobian**2, axis=1)) * step  # sd of each component's change per step
        largest = np.maximum(largest, np.sqrt(np.mean(per_axis.reshape(2, 3) ** 2, axis=1)))
    defaults = FilterNoise().for_vehicle(make_vehicle(settings["vehicle"]))
    walks = build(FanTrackingConfig, {**settings, "fan_walks": True}).resolved_estimator_params()
    assert walks["force_walk"] == pytest.approx(math.hypot(defaults.force_walk, largest[0]), rel=0.015)
    assert walks["torque_walk"] == pytest.approx(math.hypot(defaults.torque_walk, largest[1]), rel=0.015)
    assert walks["force_walk"] > 3 * defaults.force_walk  # the turbulence outruns the still-air walk
    flown = make_env(**settings, fan_walks=True).unwrapped.fleet.estimator.noise
    assert (flown.force_walk, flown.torque_walk) == (walks["force_walk"], walks["torque_walk"])
    given = build(
        FanTrackingConfig, {**settings, "fan_walks": True, "estimator_params": {"force_walk": 0.01}}
    )
    assert given.resolved_estimator_params() == {"force_walk": 0.01, "torque_walk": walks["torque_walk"]}
    assert given.estimator_params == {"force_walk": 0.01}  # the config keeps what it was given
    assert build(FanTrackingConfig, settings).resolved_estimator_params() == {}  # the default: off


def test_fan_walks_refuses_what_it_cannot_size():
    """``fan_walks`` sizes the UKF's and the EKF's walks: other estimators and named settings are refused
    by name, and it must be a bool."""
    with pytest.raises(ValueError, match="estimator='observer' has none"):
        build(FanTrackingConfig, {"fan_walks": True, "estimator": "observer"})
    with pytest.raises(ValueError, match="estimator='oracle' has none"):
        build(FanTrackingConfig, {"fan_walks": True, "estimator": "oracle"})
    with pytest.raises(ValueError, match="estimator_params='paper'"):
        build(FanTrackingConfig, {"fan_walks": True, "estimator_params": "paper"})
    with pytest.raises(ValueError, match="fan_walks=1 must be true or false"):
        build(FanTrackingConfig, {"fan_walks": 1})

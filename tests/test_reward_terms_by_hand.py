"""ForceExertion's and DisturbanceRejection's reward terms against hand computations (issue 33), as
``tests/test_reference_task.py`` does for FanTracking: every expected number is written here from the
reward tables of ``docs/tasks.md`` (the tasks' docstrings) and the physics, from the ``info`` of real
env steps (and the vehicle's pose), never by calling the task's own reward code. ForceExertion flies
on both surfaces and DisturbanceRejection in every scenario, through an
episode's early end (the crash term) and, for DisturbanceRejection, its truncation (no crash term)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from quad_wrench_env.agents import make_agent

FORCE_EXERTION = "QuadWrench/ForceExertion-v0"
DISTURBANCE_REJECTION = "QuadWrench/DisturbanceRejection-v0"
EFFORT_WEIGHT, CRASH_PENALTY = 0.01, 10.0  # both tasks' reward tables
TRACKING_CAP, CONTACT_CAP = 5.0, 2.0  # the caps of the tracking and contact (N) terms, and the alive term
TRACKING_SCALE = 0.5  # m: the length of the tracking kernel c·exp(-e/s) (docs/tasks.md)
APPROACH_WEIGHT, DISCOUNT = 10.0, 0.99  # ForceExertion's shaping: Φ = -10·gap, γ = 0.99
WALL_X, CEILING_HEIGHT, TIP_RADIUS, START_GAP = 4.5, 2.2, 0.015, 0.05  # ForceExertion's room (m)
NORMALS = {"wall": np.array((1.0, 0.0, 0.0)), "ceiling": np.array((0.0, 0.0, 1.0))}
"""The normal into each surface: ``f*`` points along it, ``+x`` on the wall, ``+z`` on the ceiling."""
TARGET = 0.8  # |f*| (N)
EXACT = {"rel": 1e-9, "abs": 1e-12}  # the same formulas on the same float64 numbers: rounding only


def _effort(action: np.ndarray) -> float:
    """``-effort_weight·mean(a²)`` of the action as clipped to [-1, 1]."""
    a = np.clip(np.asarray(action, dtype=float), -1.0, 1.0)
    return -EFFORT_WEIGHT * float(np.mean(a * a))


def _check(info: dict, reward: float, expected: dict[str, float]) -> None:
    assert info["reward_terms"].keys() == expected.keys()
    for name, value in expected.items():
        assert info["reward_terms"][name] == pytest.approx(value, **EXACT), name
    assert reward == pytest.approx(sum(expected.values()), rel=1e-9, abs=1e-12)


# -- ForceExertion ------------------------------------------------------------------------------------
def _gap(env, surface: str) -> float:
    """The tip's distance (m) to the surface's face, from the vehicle's pose: the tip's centre is
    ``(arm + rotor_radius + 0.1, 0, hull_height/2 + 0.1)`` in the body frame (0.1 m beyond the hull,
    ahead and above), its sphere ``TIP_RADIUS``; 0 when touching (a distance is never negative)."""
    base = env.unwrapped
    v = base.vehicle
    offset = np.array((v.arm + v.rotor_radius + 0.1, 0.0, 0.5 * v.hull_height + 0.1))
    state = base.fleet.state
    tip = state.position[0] + state.rotation[0] @ offset
    face = WALL_X if surface == "wall" else CEILING_HEIGHT
    return max(face - float(tip @ NORMALS[surface]) - TIP_RADIUS, 0.0)


def _force_exertion_terms(
    info: dict, action: np.ndarray, potential_before: float, potential: float, terminated: bool
) -> dict[str, float]:
    """The reward table: the tip exerts on the surface minus the surface's force on the tip
    (Newton's third law), compared with ``f*``; Φ = -approach_weight·gap, shaping γ·Φ(s') - Φ(s)."""
    exerted = -np.asarray(info["contact_force"], dtype=float)
    return {
        "contact": -min(float(np.linalg.norm(exerted - np.asarray(info["target_force"]))), CONTACT_CAP),
        "alive": 0.0 if terminated else CONTACT_CAP,
        "effort": _effort(action),
        "crash": -CRASH_PENALTY if terminated else 0.0,
        "approach": DISCOUNT * potential - potential_before,
    }


@pytest.mark.parametrize("surface", ["wall", "ceiling"])
def test_force_exertion_reward_terms_by_hand(make_env, surface):
    """The tip flown into the surface by the autopilot's velocity cascade (0.5 m/s at the wall, 0.3
    m/s up at the ceiling) and pressing on it (at the ceiling until the pivoting hull touches it: a
    crash), then a descent at full speed (an action beyond [-1, 1], clipped) below a crash height set
    just under the start, so that the episode ends early: at every step the four terms
    and the reward equal the table's, with the force the tip exerts *on* the surface the opposite of
    ``info["contact_force"]`` (the surface's force on the tip, which points out of the surface while
    touching: checked here) and ``f*`` = 0.8 N along the normal into the surface. Catches the exerted
    force's sign flipped (the contact term then adds the two forces), a contact term against another
    target, the shaping without the discount or with the potentials swapped, an effort on the
    unclipped action or summed, a crash penalty outside an early end."""
    crash_height = 1.0 if surface == "wall" else 1.7  # the wall's start is at 1.2 m, the ceiling's ~1.9 m
    env = make_env(
        FORCE_EXERTION,
        estimator="oracle",
        kf_spread=0.0,
        action_type="velocity",
        crash_height=crash_height,
    )
    _, info = env.reset(seed=0, options={"surface": surface, "target_force": TARGET})
    normal = NORMALS[surface]
    np.testing.assert_array_equal(info["target_force"], TARGET * normal)
    gap = _gap(env, surface)
    assert gap == pytest.approx(START_GAP, abs=1e-9)
    potential = -APPROACH_WEIGHT * gap
    press = np.array((0.5, 0.0, 0.0, 0.0)) if surface == "wall" else np.array((0.0, 0.0, 0.6, 0.0))
    descend = np.array((0.0, 0.1, -1.7, 0.0))  # down at max_speed_z: clipped to -1
    touching, approach_seen, terminated = 0, 0, False
    for step in range(200):
        action = press if step < 60 else descend
        _, reward, terminated, truncated, info = env.step(action)
        assert not truncated
        before, potential = potential, -APPROACH_WEIGHT * _gap(env, surface)
        _check(info, reward, _force_exertion_terms(info, action, before, potential, terminated))
        contact = np.asarray(info["contact_force"])
        if np.linalg.norm(contact) > 0.05:
            touching += 1
            assert contact @ normal < 0.0  # the surface pushes the tip back out: f_exerted along +n
            assert abs(info["reward_terms"]["contact"]) > 0.05  # the contact term is not trivial
        approach_seen += abs(info["reward_terms"]["approach"]) > 1e-3
        if terminated:
            break
    assert terminated and info["termination_reason"] == "crash", info.get("termination_reason")
    assert info["reward_terms"]["crash"] == -CRASH_PENALTY
    assert touching >= 5, touching  # pressed for a while (the case is not the approach alone)
    assert approach_seen >= 5, approach_seen


@pytest.mark.parametrize(("surface", "push"), [("wall", 3.0), ("wall", -3.0), ("ceiling", -3.0)])
def test_the_first_steps_shaping_starts_from_the_tilted_start(make_env, surface, push):
    """Under a push the vehicle starts trimmed against it, tilted, so its tip is not ``start_gap``
    from the surface: the first step's shaping is γ·Φ(s₁) - Φ(s₀) with Φ(s₀) from the start's own
    pose (the reward table), not from ``start_gap``. A 3 N push on the 1 kg vehicle tilts it about
    17°, which moves the tip by centimetres."""
    env = make_env(FORCE_EXERTION, estimator="oracle", action_type="velocity")
    env.reset(seed=0, options={"surface": surface, "target_force": TARGET, "push": push})
    start = -APPROACH_WEIGHT * _gap(env, surface)
    assert start < 0.0  # a gap to close
    assert abs(start + APPROACH_WEIGHT * START_GAP) > 0.05 * APPROACH_WEIGHT * START_GAP  # tilted
    _, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
    after = -APPROACH_WEIGHT * _gap(env, surface)
    assert info["reward_terms"]["approach"] == pytest.approx(DISCOUNT * after - start, rel=1e-9, abs=1e-12)


# -- DisturbanceRejection ------------------------------------------------------------------------------
EASE = 1.0
"""s: each straight move's speed eases up as (1 - cos(π t/EASE))/2 (the task's ``_glide`` docstring)."""
OPTIONS = {
    "jet_crossing": {"scenario": "jet_crossing", "jet_speed": 10.0},
    "table_pass": {"scenario": "table_pass"},
    "gusts": {"scenario": "gusts"},
    "figure8": {"scenario": "figure8", "wind_speed": 8.5},
}


def _eased(t: float, speed: float) -> float:
    """Distance along a straight move started at rest ``t`` s ago, during its ease-in (t <= EASE)."""
    assert t <= EASE  # the flights here end before the cruise
    t = max(t, 0.0)
    return speed * (0.5 * t - EASE / (2.0 * math.pi) * math.sin(math.pi * t / EASE))


def _reference(scenario: str, t: float, hull_height: float) -> np.ndarray:
    """Each scenario's path from the task's table (docs/tasks.md), at time ``t`` (s)."""
    if scenario == "jet_crossing":  # hover at (2, 0, 2.2) for 1 s, then down at 0.5 m/s
        return np.array((2.0, 0.0, 2.2 - _eased(t - 1.0, 0.5)))
    if scenario == "table_pass":  # hover at x = 2.5 over y = 2, the hull's bottom 8 cm over the top
        return np.array((2.5 + _eased(t - 1.0, 0.3), 2.0, 0.7 + 0.08 + 0.5 * hull_height))
    if scenario == "gusts":
        return np.array((2.5, 0.0, 1.5))
    # figure8: φ̇ = (1 - cos(π t/2))/2 rad/s over the first 2 s
    assert t <= 2.0
    phase = 0.5 * (t - 2.0 / math.pi * math.sin(math.pi * t / 2.0))
    return np.array((2.5 + 1.25 * math.sin(phase), 0.0, 1.5 + 0.75 * math.sin(2.0 * phase)))


def _tracking(offset: np.ndarray, vertical_scale: float | None) -> float:
    """The table's tracking term: one kernel on the 3-D error, or with ``vertical_scale`` half the
    cap on the horizontal error (length ``tracking_scale``) and half on the vertical one."""
    if vertical_scale is None:
        return -TRACKING_CAP * (1.0 - math.exp(-float(np.linalg.norm(offset)) / TRACKING_SCALE))
    horizontal = math.hypot(offset[0], offset[1])
    return -0.5 * TRACKING_CAP * (1.0 - math.exp(-horizontal / TRACKING_SCALE)) - 0.5 * TRACKING_CAP * (
        1.0 - math.exp(-abs(offset[2]) / vertical_scale)
    )


def _disturbance_rejection_terms(
    info: dict, action: np.ndarray, reference: np.ndarray, terminated: bool, vertical_scale: float | None
) -> dict[str, float]:
    return {
        "tracking": _tracking(np.asarray(info["position"]) - reference, vertical_scale),
        "alive": 0.0 if terminated else TRACKING_CAP,
        "effort": _effort(action),
        "crash": -CRASH_PENALTY if terminated else 0.0,
    }


@pytest.mark.parametrize(
    ("scenario", "vertical_scale"),
    [(scenario, None) for scenario in OPTIONS] + [("figure8", 0.02), ("jet_crossing", 0.02)],
)
def test_disturbance_rejection_reward_terms_by_hand(make_env, scenario, vertical_scale):
    """Two episodes of 1.5 s: the PID flying the path (every fourth step with its yaw rate beyond
    [-1, 1], clipped) to the truncation, then the thrust cut to a crash. At every step the path is the
    table's (worked out here from its numbers, time from ``info``), the three terms and the reward
    equal the table's with ``p`` the true position, the crash penalty on the early end and not on the
    truncation. Catches a tracking term on the horizontal error alone or against another reference, a
    linear kernel or another length, a sign error, an effort on the unclipped action or summed, a
    crash penalty on a truncation or missing on an early end; with ``reward.vertical_scale`` the
    horizontal and vertical kernels (a 3-D kernel, or the lengths swapped, fail)."""
    env = make_env(
        DISTURBANCE_REJECTION,
        estimator="oracle",
        kf_spread=0.0,
        episode_seconds=1.5,
        reward={"vertical_scale": vertical_scale},
    )
    hull = env.unwrapped.vehicle.hull_height
    policy = make_agent("pid")
    obs, info = env.reset(seed=4, options=OPTIONS[scenario])
    policy.reset(env)
    start = _reference(scenario, 0.0, hull)
    np.testing.assert_allclose(info["reference_position"], start, rtol=0, atol=1e-12)
    np.testing.assert_allclose(info["position"], start, rtol=0, atol=1e-12)  # starts on the path
    largest = 0.0
    for step in range(100):
        action = policy.act(obs).astype(float)
        if step % 4 == 1:
            action[2] = 1.6 if step % 8 == 1 else -1.6
        obs, reward, terminated, truncated, info = env.step(action)
        reference = _reference(scenario, info["time"], hull)
        np.testing.assert_allclose(info["reference_position"], reference, rtol=0, atol=1e-12)
        _check(
            info, reward, _disturbance_rejection_terms(info, action, reference, terminated, vertical_scale)
        )
        largest = max(largest, -info["reward_terms"]["tracking"])
        if terminated or truncated:
            break
    assert truncated and not terminated, info.get("termination_reason")
    assert step + 1 == 75 and info["reward_terms"]["crash"] == 0.0
    assert largest > 1e-3  # off the path by more than rounding

    env.reset(seed=4, options=OPTIONS[scenario])
    cut = np.array((0.0, 0.0, 0.0, -1.4))  # collective thrust (1 + a3)·m·g, clipped to 0
    for _ in range(60):
        _, reward, terminated, truncated, info = env.step(cut)
        reference = _reference(scenario, info["time"], hull)
        _check(info, reward, _disturbance_rejection_terms(info, cut, reference, terminated, vertical_scale))
        if terminated or truncated:
            break
    assert terminated and info["termination_reason"] == "crash"
    assert info["reward_terms"]["crash"] == -CRASH_PENALTY


def test_the_peak_term_sums_to_the_episodes_largest_horizontal_deviation(make_env):
    """``reward.peak_weight`` w: each step's ``peak`` term is ``-w·`` how far the step's horizontal
    distance from the reference (true position, from ``info``) rises above the largest one of the
    episode so far, that largest starting at the reset's distance; so an episode's terms sum to ``-w·``
    (its largest horizontal deviation, the harness's score, minus the start's). Two episodes of one env:
    the figure-8 in 12.1 m/s wind without compensation (decimetres off), then a hover in gusts
    (centimetres), so that a
    largest carried from the first episode into the second leaves the second's terms all zero and fails;
    also fails on the 3-D error, a term on the distance itself, or the default (no term) changed."""
    weight = 300.0
    env = make_env(
        DISTURBANCE_REJECTION, estimator="oracle", episode_seconds=1.5, reward={"peak_weight": weight}
    )
    policy = make_agent("pid", compensation=False)
    sums = []
    for options in ({"scenario": "figure8", "wind_speed": 12.1}, {"scenario": "gusts"}):
        obs, info = env.reset(seed=5, options=options)
        policy.reset(env)
        offset = np.asarray(info["position"]) - np.asarray(info["reference_position"])
        largest = start = math.hypot(offset[0], offset[1])
        total, terminated, truncated = 0.0, False, False
        while not (terminated or truncated):
            obs, _, terminated, truncated, info = env.step(policy.act(obs))
            offset = np.asarray(info["position"]) - np.asarray(info["reference_position"])
            distance = math.hypot(offset[0], offset[1])
            expected = -weight * (max(largest, distance) - largest)
            assert info["reward_terms"]["peak"] == pytest.approx(expected, **EXACT)
            largest = max(largest, distance)
            total += info["reward_terms"]["peak"]
        assert total == pytest.approx(-weight * (largest - start), rel=1e-9, abs=1e-12)
        sums.append(total)
    assert sums[0] < 4.0 * sums[1] < -weight * 1e-3, sums  # decimetres, then centimetres off

    plain = make_env(DISTURBANCE_REJECTION, estimator="oracle", episode_seconds=1.5)
    plain.reset(seed=5)
    _, _, _, _, info = plain.step(np.zeros(4))
    assert "peak" not in info["reward_terms"]


def test_peak_scenario_factors_weigh_each_scenarios_peak_term(make_env):
    """``reward.peak_scenario_factors``: in an episode of a named scenario the ``peak`` term is ``-w·f·``
    the rise of the largest horizontal deviation, in one of a scenario not named ``-w·``; the same env
    flies the named scenario, then the other, so a factor kept from the episode before, or applied to
    every scenario, fails. A scenario not in the task, or a factor <= 0, is refused naming it."""
    weight, factor = 300.0, 4.0
    reward = {"peak_weight": weight, "peak_scenario_factors": {"gusts": factor}}
    env = make_env(DISTURBANCE_REJECTION, estimator="oracle", episode_seconds=0.5, reward=reward)
    policy = make_agent("pid", compensation=False)
    for scenario, scale in (("gusts", factor), ("table_pass", 1.0)):
        obs, info = env.reset(seed=2, options={"scenario": scenario})
        policy.reset(env)
        offset = np.asarray(info["position"]) - np.asarray(info["reference_position"])
        largest = math.hypot(offset[0], offset[1])
        rises = 0
        for _ in range(25):
            obs, _, _, _, info = env.step(policy.act(obs))
            offset = np.asarray(info["position"]) - np.asarray(info["reference_position"])
            distance = math.hypot(offset[0], offset[1])
            expected = -weight * scale * (max(largest, distance) - largest)
            assert info["reward_terms"]["peak"] == pytest.approx(expected, **EXACT), scenario
            rises += distance > largest
            largest = max(largest, distance)
        assert rises > 0, scenario  # the term was not zero throughout
    for factors, named in (({"tornado": 2.0}, "tornado"), ({"gusts": 0.0}, "gusts=0.0")):
        with pytest.raises(ValueError, match=named):
            make_env(DISTURBANCE_REJECTION, reward={"peak_weight": weight, "peak_scenario_factors": factors})


def test_the_action_rate_term_prices_the_change_of_the_action_from_the_step_before(make_env):
    """``reward.action_rate_weight`` w: each step's ``action_rate`` term is ``-w·mean((a - a_prev)²)`` of
    the actions as clipped to [-1, 1], ``a_prev`` the step before's and zero on an episode's first step.
    Two episodes of one env, the second's first action the first's last: a previous action carried
    across the reset gives that step a term of zero and fails; so do the unclipped action, the action
    itself in place of its change, or the default (no term) changed."""
    weight = 7.0
    env = make_env(DISTURBANCE_REJECTION, estimator="oracle", reward={"action_rate_weight": weight})
    rng = np.random.default_rng(3)
    actions = rng.uniform(-0.2, 0.2, size=(8, 4))
    actions[3, 1] = 1.6  # clipped to 1 before the task sees it
    for options in ({"scenario": "gusts"}, {"scenario": "table_pass"}):
        env.reset(seed=11, options=options)
        previous = np.zeros(4)
        for action in actions:
            _, _, terminated, truncated, info = env.step(action)
            clipped = np.clip(action, -1.0, 1.0)
            expected = -weight * float(np.mean((clipped - previous) ** 2))
            assert info["reward_terms"]["action_rate"] == pytest.approx(expected, **EXACT)
            previous = clipped
            assert not (terminated or truncated)
        actions = np.roll(actions, 1, axis=0)  # the next episode starts with this one's last action

    plain = make_env(DISTURBANCE_REJECTION, estimator="oracle")
    plain.reset(seed=11)
    _, _, _, _, info = plain.step(np.zeros(4))
    assert "action_rate" not in info["reward_terms"]

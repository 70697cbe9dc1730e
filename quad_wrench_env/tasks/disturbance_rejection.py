"""``QuadWrench/DisturbanceRejection-v0``: follow a reference path while a disturbance acts.

The experiments of Hentzen et al. 2019 (Sec. V-E and V-F) and the wind-tunnel figure-8 of
Neural-Fly (O'Connell et al., Science Robotics 2022), in one room (world frame, z up, m):

- a gust fan at ``(2.0, -1.0, 1.4)`` blowing along +y across the vertical line ``x = 2, y = 0``;
- a table (1 m x 1 m, top at 0.7 m) centred at ``(3.5, 2.0)``;
- ground effect (Cheeseman-Bennett, per rotor) over the ground and the table top.

Each episode flies one scenario (config ``scenario``, or ``reset(options={"scenario": ...})``; by
default ``"random"`` draws one of ``scenarios`` per episode):

============  ================================================================================
scenario      what happens (parameters in :class:`JetCrossing`, :class:`TablePass`, :class:`Gusts`,
              :class:`Figure8`)
============  ================================================================================
jet_crossing  hover at ``(2, 0, 2.2)`` for 1 s, descend at 0.5 m/s to 0.6 m through the fan's
              horizontal stream (centre speed ``jet_speed`` where it crosses the path: Hentzen et al. 2019
              flew 3, 10 and 12 m/s; drawn from ``jet_speeds`` unless given), then hover. The
              descent speed, the heights and the jet's size (0.6 m outlet 1 m from the path) are
              not in the paper: chosen here. The outlet stands on the path's -y side (both sides, one
              drawn per episode, with ``jet_crossing.jet_sides``). The jet is steady unless
              ``jet_turbulence_intensity`` is set (the fan's turbulence model)
table_pass    hover at ``x = 2.5`` over ``y = 2``, fly along +x at 0.3 m/s with the hull's bottom 8 cm
              above the table top across both edges, hover at ``x = 4.5`` (Hentzen et al. 2019 Fig. 10-11)
gusts         hover at ``(2.5, 0, 1.5)`` in Dryden turbulence (``w20`` 4 m/s) and one horizontal
              1-cosine bump of random direction, peak in [2, 6] m/s, start in [3, 10] s, rise in
              [0.5, 2] s
figure8       ``x = 2.5 + 1.25 sin φ``, ``z = 1.5 + 0.75 sin 2φ`` at ``y = 0`` (``φ`` eases from rest
              to 1 rad/s over 2 s) in a steady wind ``wind_speed`` along +y (0, 8.5 or 12.1 m/s,
              drawn unless given; its heading drawn per episode with ``figure8.wind_heading_spread``)
              with light turbulence (``w20`` 1 m/s)
============  ================================================================================

Default vehicle ``hummingbird`` (Hentzen et al.'s (2019) 700 g class); every preset flies it. Default action
``attitude`` (collective thrust, roll, pitch, yaw rate: what Hentzen et al.'s (2019) controllers output).

Observation (float32, 31; ``env.unwrapped.obs_layout`` names the slices): the 25 of FanTracking
(estimated position, velocity, attitude, body rates, estimated force and torque, last action), then

=====  ==================  ======================================================
index  name                meaning
=====  ==================  ======================================================
25-27  reference_position  where the vehicle should be now (m, world frame)
28-30  reference_velocity  the reference's velocity now (m/s, world frame)
=====  ==================  ======================================================

With ``preview_seconds`` T > 0 the observation adds ``reference_velocity_ahead`` (31-33):
``v_ref(t + T) - v_ref(t)``, the reference's velocity change over the next T seconds (m/s, world frame;
about T times its acceleration), the feed-forward PID and MPC take from the reference.

With ``observe_reference_acceleration=True`` the observation adds ``reference_acceleration`` (3, after
the blocks above): the reference's acceleration now (m/s², world frame); with ``observe_reference_jerk=True``
``reference_jerk`` (3, after that): its jerk now (m/s³, world frame), which steps where a glide's or the
figure-8's easing ends. With ``path_ahead_seconds``
``(τ_1, ..., τ_K)`` it adds ``path_ahead`` (3K, last): ``p_ref(t + τ_k) - p̂`` for each k, the path ahead
relative to the vehicle's estimated position (m, world frame).

With ``observe_tracking_error=True`` the same columns hold the tracking error as the vehicle sees it
instead (what PID and MPC, which read the reference, refuse):

=====  ==================  ======================================================
index  name                meaning
=====  ==================  ======================================================
25-27  position_error      ``p_ref - p̂``: reference minus estimated position (m)
28-30  velocity_error      ``v_ref - v̂``: reference minus estimated velocity (m/s)
=====  ==================  ======================================================

Reward per step (terms in ``info["reward_terms"]``): ``tracking = -c·(1 - exp(-|p - p_ref|/s))`` (or, with
``reward.vertical_scale``, a kernel each for the horizontal and the vertical error), ``alive = +c`` on
every step that does not end the episode early (``c = tracking_cap``, 5; ``s = tracking_scale``, 0.5 m),
``effort = -effort_weight·mean(a²)``, ``crash = -crash_penalty`` on an early end; with
``reward.peak_weight`` w > 0, ``peak = -w·`` the rise of the episode's largest horizontal deviation (the
terms sum to ``-w·`` the episode's Table I score; ``reward.peak_scenario_factors`` weighs it per
scenario); with ``reward.action_rate_weight`` w > 0, ``action_rate = -w·mean((a - a_prev)²)``,
``a_prev`` the action of the step before (zero on an episode's first step).
``tracking + alive = c·exp(-|p - p_ref|/s)`` lies in (0, c]: a step flown is never worth less than
nothing, so ending an episode early never pays (with ``tracking = -|p - p_ref|`` alone a policy that
crashed escaped the tracking cost, and PPO learned to end its episodes), and the kernel is steepest at
the reference (with the linear ``-min(|p - p_ref|, c)`` PPO hovered 0.3 m off it). Episode end as
FanTracking (crash, flip, out of the arena); truncated after ``episode_seconds`` (15 s).

Reset options: ``scenario``, ``jet_speed`` (m/s; implies ``jet_crossing``), ``wind_speed`` (m/s;
implies ``figure8``). ``info`` adds ``reference_position`` (3,), ``reference_velocity`` (3,) and
``tracking_error`` (m). The harness reports ``max_horizontal_deviation`` (Hentzen et al. 2019 Table I),
``mean_tracking_error`` and ``max_vertical_error`` (m).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any, ClassVar

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.disturbances.dryden import DrydenConfig, DrydenGust
from quad_wrench_env.disturbances.fan import centreline_speed
from quad_wrench_env.disturbances.jet import Jet, JetConfig
from quad_wrench_env.disturbances.one_cosine import OneCosineConfig, OneCosineGust
from quad_wrench_env.engine.components import Components
from quad_wrench_env.engine.env_config import EnvConfig
from quad_wrench_env.engine.fleet_view import FleetView
from quad_wrench_env.registry import register
from quad_wrench_env.rotations import quat_from_axis_angle, rotation_matrix
from quad_wrench_env.scene import Table
from quad_wrench_env.tasks import terms
from quad_wrench_env.tasks.base import TaskDefaults, TaskRecord
from quad_wrench_env.vehicle import VehicleParams

SCENARIOS = ("jet_crossing", "table_pass", "gusts", "figure8")
PATH_SAMPLES = 301
"""Points of the reference path a frame draws (:meth:`DisturbanceRejection.render_marks`)."""
RANDOM = "random"
JET_SIDES = {"-y": 1.0, "+y": -1.0}
"""``jet_crossing.jet_sides``: the outlet's side of the path and the sign of the jet's direction along y."""
REFERENCE_BLOCKS = (("reference_position", 3, 20.0), ("reference_velocity", 3, 20.0))
"""The task's observation blocks ``(name, width, bound)`` by default."""
ERROR_BLOCKS = (("position_error", 3, 20.0), ("velocity_error", 3, 20.0))
"""Its blocks with ``observe_tracking_error``."""
PREVIEW_BLOCK = ("reference_velocity_ahead", 3, 20.0)
"""The block ``preview_seconds`` > 0 adds after them."""
ACCELERATION_BLOCK = ("reference_acceleration", 3, 50.0)
"""The block ``observe_reference_acceleration`` adds after those."""
JERK_BLOCK = ("reference_jerk", 3, 200.0)
"""The block ``observe_reference_jerk`` adds after that."""
ACCELERATION_STEP = 1.0e-3
"""s: the half-width of the central differences of the reference's velocity that give its acceleration
(exact to ~1e-6 m/s² on these paths, whose velocity is smooth but where a straight move's easing
starts and ends) and its jerk (the second difference; within this of an easing's end it averages the
jerk's step)."""
PATH_AHEAD_MAX = 10
"""The most times ``path_ahead_seconds`` may name."""
EASE = 1.0
"""Seconds over which the reference's speed eases up and down at each end of a straight move."""


def _check_speeds(owner: str, speeds: tuple[float, ...]) -> tuple[float, ...]:
    speeds = tuple(speeds)
    if not speeds or not all(
        isinstance(s, (int, float)) and not isinstance(s, bool) and math.isfinite(s) and s >= 0
        for s in speeds
    ):
        raise ValueError(f"{owner}={list(speeds)!r} must be one or more finite speeds >= 0 (m/s)")
    return speeds


@dataclass
class JetCrossing:
    """Hentzen et al. 2019 Sec. V-F: a vertical descent through a strong horizontal jet."""

    jet_speeds: tuple[float, ...] = (3.0, 10.0, 12.0)
    """Centre speeds (m/s) where the jet crosses the path; one is drawn when ``jet_speed`` is not given."""
    path: tuple[float, float] = (2.0, 0.0)
    """x, y (m) of the vertical path."""
    start_height: float = 2.2
    end_height: float = 0.6
    descent_speed: float = 0.5
    hover_seconds: float = 1.0
    """Hover at the start before the descent (s)."""
    jet_height: float = 1.4
    jet_distance: float = 1.0
    """From the outlet to the path (m)."""
    jet_sides: tuple[str, ...] = ("-y",)
    """Where the outlet stands: ``"-y"`` (blowing along +y, the default), ``"+y"`` (blowing along -y);
    with both, one is drawn per episode. A policy trained on one side learns where the jet pushes
    instead of reading the wrench (docs/results.md, "DisturbanceRejection without the shortcut")."""
    jet_diameter: float = 0.6
    jet_spread: float = 0.42
    jet_turbulence_intensity: float = 0.0
    """The jet's turbulence intensity ``I`` (1): each component's sd over the local mean speed, the fan's
    model (:mod:`~quad_wrench_env.disturbances.jet`); 0, the default, is none (Hentzen et al.
    2019 give none)."""
    jet_turbulence_length: float | None = None
    """Its length scale ``L`` (m), the time scale being ``L/u_c``; None: the jet's half-width where it
    crosses the path (0.52 m), as the fan's turbulence."""

    def __post_init__(self) -> None:
        self.jet_speeds = _check_speeds("jet_crossing.jet_speeds", self.jet_speeds)
        self.path = tuple(self.path)
        self.jet_sides = tuple(self.jet_sides)
        sides = self.jet_sides
        if not sides or len(set(sides)) != len(sides) or not set(sides) <= set(JET_SIDES):
            raise ValueError(
                f"jet_crossing.jet_sides={list(sides)!r} must name one or both of {list(JET_SIDES)}, "
                "each once"
            )
        check_numbers("jet_crossing", self, ("start_height", "end_height", "descent_speed", "jet_height"))
        check_numbers("jet_crossing", self, ("jet_distance", "jet_diameter", "jet_spread"))
        check_numbers("jet_crossing", self, ("hover_seconds",), positive=False)
        if not (0.0 <= self.jet_turbulence_intensity < 1.0):
            raise ValueError(
                f"jet_crossing.jet_turbulence_intensity={self.jet_turbulence_intensity!r} must be in [0, 1)"
            )
        if self.jet_turbulence_length is not None:
            check_numbers("jet_crossing", self, ("jet_turbulence_length",))
        if self.end_height >= self.start_height:
            raise ValueError(
                f"jet_crossing: end_height={self.end_height} must be below start_height={self.start_height}"
            )

    def outlet_speed(self, centre_speed: float) -> float:
        """Outlet speed ``U0`` whose jet has ``centre_speed`` on its axis at the path
        (``docs/physics.md``, "Fan": ``u_c(x) = U0·min(1, D/(√2·b(x)))``)."""
        radius2 = (0.5 * self.jet_diameter) ** 2
        return centre_speed / float(centreline_speed(self.jet_distance, 1.0, radius2, self.jet_spread))


@dataclass
class TablePass:
    """Hentzen et al. 2019 Sec. V-E: horizontal flight over a table's two edges at 0.3 m/s."""

    table_center: tuple[float, float] = (3.5, 2.0)
    table_size: tuple[float, float] = (1.0, 1.0)
    table_height: float = 0.7
    clearance: float = 0.08
    """Gap (m) between the hull's bottom and the table top (Hentzen et al. 2019: 8 cm)."""
    speed: float = 0.3
    start_x: float = 2.5
    end_x: float = 4.5
    hover_seconds: float = 1.0

    def __post_init__(self) -> None:
        self.table_center, self.table_size = tuple(self.table_center), tuple(self.table_size)
        check_numbers("table_pass", self, ("table_height", "clearance", "speed"))
        check_numbers("table_pass", self, ("hover_seconds",), positive=False)
        low, high = (
            self.table_center[0] - 0.5 * self.table_size[0],
            self.table_center[0] + 0.5 * self.table_size[0],
        )
        if not (self.start_x < low and high < self.end_x):
            raise ValueError(
                f"table_pass: start_x={self.start_x} and end_x={self.end_x} must lie beyond the table's "
                f"edges ({low:.3g}, {high:.3g}) so that the pass crosses both"
            )


@dataclass
class Gusts:
    """Hover in Dryden turbulence with one 1-cosine bump (the wind gusts of Hentzen et al. 2019;
    ``docs/physics.md``, "Dryden turbulence" and "1-cosine gust")."""

    position: tuple[float, float, float] = (2.5, 0.0, 1.5)
    w20: float = 4.0
    """Dryden's wind speed at 20 ft (m/s; σ_u ≈ 0.8 m/s at 1.5 m)."""
    peak: tuple[float, float] = (2.0, 6.0)
    """Range of the bump's horizontal peak speed (m/s); its direction is uniform."""
    start: tuple[float, float] = (3.0, 10.0)
    duration: tuple[float, float] = (0.5, 2.0)
    """Range of its rise time ``t_g`` (s); it falls back over as long."""

    def __post_init__(self) -> None:
        self.position = tuple(self.position)
        check_numbers("gusts", self, ("w20",), positive=False)
        for key in ("peak", "start", "duration"):
            low, high = getattr(self, key)
            if not (0.0 <= low <= high and math.isfinite(high)):
                raise ValueError(
                    f"gusts.{key}={[low, high]!r} must be a range [low, high] with 0 <= low <= high"
                )
        if self.duration[0] <= 0.0:
            raise ValueError(f"gusts.duration={list(self.duration)!r} must be above 0 s")


@dataclass
class Figure8:
    """Neural-Fly's wind-tunnel benchmark: a figure-8 in the x-z plane in a steady wind."""

    wind_speeds: tuple[float, ...] = (0.0, 8.5, 12.1)
    """Steady wind speeds (m/s) along ``wind_direction``; one is drawn when ``wind_speed`` is not given."""
    wind_direction: tuple[float, float, float] = (0.0, 1.0, 0.0)
    wind_heading_spread: float = 0.0
    """Half-width (rad) of a uniform draw, per episode, of the wind's heading about ``wind_direction``
    (turned about the vertical): 0 (the default) blows along ``wind_direction`` always, π from any
    horizontal heading. A policy trained on one direction learns it instead of reading the wrench
    (docs/results.md, "DisturbanceRejection learns")."""
    center: tuple[float, float, float] = (2.5, 0.0, 1.5)
    amplitude: tuple[float, float] = (1.25, 0.75)
    """x = A_x sin φ, z = A_z sin 2φ (m)."""
    rate: float = 1.0
    """dφ/dt after the ease-in (rad/s)."""
    ramp_seconds: float = 2.0
    turbulence_w20: float = 1.0

    def __post_init__(self) -> None:
        self.wind_speeds = _check_speeds("figure8.wind_speeds", self.wind_speeds)
        self.wind_direction, self.center = tuple(self.wind_direction), tuple(self.center)
        self.amplitude = tuple(self.amplitude)
        if math.hypot(*self.wind_direction) == 0.0:
            raise ValueError("figure8.wind_direction=[0, 0, 0] has no direction; give a non-zero vector")
        check_numbers("figure8", self, ("rate", "ramp_seconds"))
        check_numbers("figure8", self, ("turbulence_w20", "wind_heading_spread"), positive=False)
        if self.wind_heading_spread > math.pi:
            raise ValueError(
                f"figure8.wind_heading_spread={self.wind_heading_spread!r} must be in [0, π] rad"
            )

    def phase(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``φ(t)`` and ``φ̇(t)``: ``φ̇ = rate·(1 - cos(π t/T))/2`` for ``t < T``, then ``rate``."""
        T, w = self.ramp_seconds, self.rate
        early = t < T
        rate = np.where(early, 0.5 * w * (1.0 - np.cos(math.pi * np.minimum(t, T) / T)), w)
        phase = np.where(
            early,
            0.5 * w * (t - T / math.pi * np.sin(math.pi * np.minimum(t, T) / T)),
            0.5 * w * T + w * (t - T),
        )
        return phase, rate


@dataclass
class DisturbanceRejectionReward:
    effort_weight: float = 0.01
    crash_penalty: float = 10.0
    tracking_cap: float = 5.0
    """The most a step's tracking costs, and what ``alive`` pays per step flown: the tracking term is
    ``-c·(1 - exp(-|p - p_ref|/s))`` with ``c = tracking_cap`` and ``s = tracking_scale``, so a step
    earns ``c·exp(-|p - p_ref|/s)`` in (0, c] and ending an episode early never pays (module
    docstring)."""
    tracking_scale: float = 0.5
    """m: the length of the tracking kernel. The cost's slope is ``c/s`` (10 per m) at the reference
    and falls off beyond a metre. Its predecessor, the linear ``-min(|p - p_ref|, c)``, had a slope of
    1 per m everywhere: PPO kept its episodes but hovered 0.2-0.3 m below and behind the reference, hit
    the table and deviated 0.67 ± 0.07 m at most (3 training seeds, 2 M steps) against 0.07 m with
    this kernel on the same selection seeds (docs/results.md)."""
    vertical_scale: float | None = None
    """m. None: one kernel on the 3-D error (above). A length: the horizontal and the vertical error
    each through their own kernel with half the cap, ``-c/2·(1 - exp(-|e_xy|/s)) - c/2·(1 -
    exp(-|e_z|/s_z))`` with ``s_z`` this length, so that a height given up (a controller at its tilt
    limit, 0.6 m above the figure-8 in 12.1 m/s wind) does not flatten the horizontal term, which
    carries Hentzen et al.'s (2019) Table I metric; ``tracking + alive`` stays in (0, c]."""
    peak_weight: float = 0.0
    """per m; > 0 adds the term ``peak = -w·(max(P, |e_xy|) - P)``, ``P`` the episode's largest
    horizontal error before this step (from its start), raised to it: the terms sum to ``-w·`` the
    episode's largest horizontal deviation, Hentzen et al.'s (2019) Table I score, which the tracking
    kernel's mean over 750 steps hardly sees (a half-second transient at the start, a few saturated
    seconds). 0: no term."""
    peak_scenario_factors: dict[str, float] = field(default_factory=dict)
    """Scenario (:data:`SCENARIOS`) -> factor (> 0) on ``peak_weight`` in that scenario's episodes; 1 for
    a scenario not named. One weight prices a millimetre alike in every scenario, so the scenarios with
    the largest deviations (a 12 m/s jet's 5-7 cm, a saturated figure-8's 27 cm) carry the term's
    gradient and a table pass's 5 mm hardly counts; a factor weighs a scenario's Table I score (Hentzen
    et al. 2019) by its own scale."""

    action_rate_weight: float = 0.0
    """> 0 adds the term ``action_rate = -w·mean((a - a_prev)²)``, ``a_prev`` the step before's action
    (zero on an episode's first step): the temporal smoothness of CAPS (Mysore et al. 2021, its temporal
    loss) as a reward term: ``effort`` prices an action's size, this its change from one step to the
    next. 0: no term."""

    def __post_init__(self) -> None:
        check_numbers(
            "reward",
            self,
            ("effort_weight", "crash_penalty", "peak_weight", "action_rate_weight"),
            positive=False,
        )
        check_numbers("reward", self, ("tracking_cap", "tracking_scale"))
        if not isinstance(self.peak_scenario_factors, Mapping):
            raise ValueError(
                f"reward.peak_scenario_factors={self.peak_scenario_factors!r} must map scenarios "
                f"{list(SCENARIOS)} to factors > 0"
            )
        unknown = sorted(set(self.peak_scenario_factors) - set(SCENARIOS))
        if unknown:
            raise ValueError(f"reward.peak_scenario_factors names {unknown}; allowed: {list(SCENARIOS)}")
        factors = SimpleNamespace(**self.peak_scenario_factors)
        check_numbers("reward.peak_scenario_factors", factors, tuple(self.peak_scenario_factors))
        if self.vertical_scale is not None:
            check_numbers("reward", self, ("vertical_scale",))


@dataclass
class DisturbanceRejectionConfig(EnvConfig):
    vehicle: str = "hummingbird"
    action_type: str = "attitude"
    episode_seconds: float = 15.0
    ground_effect: bool = True
    scenario: str = RANDOM
    """One of :data:`SCENARIOS`, or ``"random"`` (one of ``scenarios`` per episode)."""
    scenarios: tuple[str, ...] = SCENARIOS
    jet_crossing: JetCrossing = field(default_factory=JetCrossing)
    table_pass: TablePass = field(default_factory=TablePass)
    gusts: Gusts = field(default_factory=Gusts)
    figure8: Figure8 = field(default_factory=Figure8)
    reward: DisturbanceRejectionReward = field(default_factory=DisturbanceRejectionReward)
    observe_tracking_error: bool = False
    """The task's observation blocks: the reference (False) or the tracking error from the vehicle's
    estimate, ``p_ref - p̂`` and ``v_ref - v̂`` (True: the same numbers relative to the vehicle, which
    a learned policy need not learn to subtract)."""
    preview_seconds: float = 0.0
    """s; > 0 adds the block ``reference_velocity_ahead``, ``v_ref(t + T) - v_ref(t)``: how the
    reference's velocity changes over the next ``T`` (about ``T`` times its acceleration), the
    feed-forward that PID and MPC take from the reference they read. 0: no block."""

    observe_reference_acceleration: bool = False
    """True adds the block ``reference_acceleration``: the reference's acceleration now (m/s², world
    frame), what a tracking controller feeds forward."""
    observe_reference_jerk: bool = False
    """True adds the block ``reference_jerk``: the reference's jerk now (m/s³, world frame), the rate at
    which that feed-forward changes (it steps where a glide's or the figure-8's easing ends)."""
    path_ahead_seconds: tuple[float, ...] = ()
    """s, increasing, each > 0 (at most :data:`PATH_AHEAD_MAX`); adds the block ``path_ahead``: for each
    time ``τ`` the reference position ``τ`` ahead relative to the vehicle's estimate, ``p_ref(t + τ) -
    p̂`` (m, world frame), so that a bend of the path can be anticipated. Empty: no block."""

    def __post_init__(self) -> None:
        super().__post_init__()
        for name in ("observe_tracking_error", "observe_reference_acceleration", "observe_reference_jerk"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name}={getattr(self, name)!r} must be true or false")
        ahead = self.path_ahead_seconds
        times = tuple(ahead) if isinstance(ahead, (list, tuple)) else None
        numbers = times is not None and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > 0
            for x in times
        )
        if not (numbers and len(times) <= PATH_AHEAD_MAX and all(np.diff(times) > 0)):
            raise ValueError(
                f"path_ahead_seconds={ahead!r} must list up to {PATH_AHEAD_MAX} increasing times > 0 (s; "
                "[] for no block)"
            )
        self.path_ahead_seconds = tuple(float(x) for x in times)
        preview = self.preview_seconds
        finite = (
            isinstance(preview, (int, float)) and not isinstance(preview, bool) and math.isfinite(preview)
        )
        if not (finite and preview >= 0):
            raise ValueError(f"preview_seconds={preview!r} must be a finite number >= 0 (s; 0: no preview)")
        self.scenarios = tuple(self.scenarios)
        if not self.scenarios or any(s not in SCENARIOS for s in self.scenarios):
            raise ValueError(f"scenarios={list(self.scenarios)!r} must name one or more of {list(SCENARIOS)}")
        if self.scenario not in (RANDOM, *SCENARIOS):
            raise ValueError(f"scenario={self.scenario!r}; allowed: {[RANDOM, *SCENARIOS]}")


def _speed_option(options: Mapping[str, Any], key: str) -> float | None:
    if key not in options:
        return None
    value = options[key]
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if not (ok and math.isfinite(value) and value >= 0):
        raise ValueError(f"{key}={value!r} must be a finite speed >= 0 (m/s)")
    return float(value)


@register("task")
class DisturbanceRejection(TaskDefaults):
    """Follow each scenario's reference path under its disturbance (module docstring), N vehicles."""

    env_id: ClassVar[str] = "QuadWrench/DisturbanceRejection-v0"
    config_class: ClassVar[type[EnvConfig]] = DisturbanceRejectionConfig
    reset_options: ClassVar[tuple[str, ...]] = ("scenario", "jet_speed", "wind_speed")
    metric_columns: ClassVar[tuple[tuple[str, str, str], ...]] = (
        ("max_horizontal_deviation", "max horizontal deviation [m]", "{:.3f}"),
        ("mean_tracking_error", "mean tracking error [m]", "{:.3f}"),
        ("max_vertical_error", "max vertical error [m]", "{:.3f}"),
    )
    observation_blocks: tuple[tuple[str, int, float], ...] = REFERENCE_BLOCKS
    """:data:`REFERENCE_BLOCKS`, or :data:`ERROR_BLOCKS` with ``observe_tracking_error``."""
    trace_keys: ClassVar[tuple[str, ...]] = ("reference_position", "tracking_error")

    def __init__(self, cfg: DisturbanceRejectionConfig, vehicle: VehicleParams, count: int) -> None:
        self.cfg = cfg
        self.vehicle = vehicle
        if cfg.observe_tracking_error:
            self.observation_blocks = ERROR_BLOCKS
        if cfg.preview_seconds > 0.0:
            self.observation_blocks = (*self.observation_blocks, PREVIEW_BLOCK)
        if cfg.observe_reference_acceleration:
            self.observation_blocks = (*self.observation_blocks, ACCELERATION_BLOCK)
        if cfg.observe_reference_jerk:
            self.observation_blocks = (*self.observation_blocks, JERK_BLOCK)
        if cfg.path_ahead_seconds:
            width = 3 * len(cfg.path_ahead_seconds)
            self.observation_blocks = (*self.observation_blocks, ("path_ahead", width, 20.0))
        jc, tp, fig = cfg.jet_crossing, cfg.table_pass, cfg.figure8
        x, y = jc.path
        self.jets = [
            Jet(
                JetConfig(
                    position=(x, y - sign * jc.jet_distance, jc.jet_height),
                    direction=(0.0, sign, 0.0),
                    speed=1.0,
                    diameter=jc.jet_diameter,
                    spread=jc.jet_spread,
                    turbulence_intensity=jc.jet_turbulence_intensity,
                    turbulence_length=jc.jet_turbulence_length,
                ),
                count,
            )
            for sign in (JET_SIDES[side] for side in jc.jet_sides)
        ]
        """One jet per entry of ``jet_crossing.jet_sides``; a vehicle's copy of each is off (speed 0)
        but for the side drawn in a jet crossing."""
        self.turbulence = DrydenGust(DrydenConfig(w20=1.0, altitude=cfg.gusts.position[2]), count)
        self.bump = OneCosineGust(OneCosineConfig(hold=False), count)
        self.table = Table(center=tp.table_center, size=tp.table_size, height=tp.table_height)
        self._wind_direction = np.array(fig.wind_direction) / math.hypot(*fig.wind_direction)
        self.scenario = np.zeros(count, dtype=int)
        """Each vehicle's scenario (index into :data:`SCENARIOS`)."""
        self.jet_side = np.zeros(count, dtype=int)
        """Each vehicle's jet side (index into ``jet_crossing.jet_sides``) in a jet crossing."""
        self.disturbance_speed = np.zeros(count)
        """Each vehicle's ``jet_speed`` (jet_crossing) or ``wind_speed`` (figure8), m/s; else 0."""
        self.peak_deviation = np.zeros(count)
        """m: each vehicle's largest horizontal deviation in its episode so far (kept with
        ``reward.peak_weight`` > 0 only)."""
        factors = cfg.reward.peak_scenario_factors
        self.peak_weights = cfg.reward.peak_weight * np.array([factors.get(s, 1.0) for s in SCENARIOS])
        """per m: ``reward.peak_weight`` times each scenario's factor (index: :data:`SCENARIOS`)."""
        self.previous_action = np.zeros((count, 4))
        """Each vehicle's action of the step before (zero at its episode's start; kept with
        ``reward.action_rate_weight`` > 0 only)."""

    def components(self) -> Components:
        """The gust fan's jets, the turbulence, the 1-cosine bump and the table; each vehicle's copy of
        a wind is switched on by its scenario (the others' tables are zero)."""
        return Components(winds=[*self.jets, self.turbulence, self.bump], scene=[self.table])

    # -- episodes ----------------------------------------------------------------------------------
    def _choose(
        self, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> tuple[str, float | None, float | None]:
        jet_speed, wind_speed = _speed_option(options, "jet_speed"), _speed_option(options, "wind_speed")
        implied = "jet_crossing" if jet_speed is not None else "figure8" if wind_speed is not None else None
        if jet_speed is not None and wind_speed is not None:
            raise ValueError("jet_speed (jet_crossing) and wind_speed (figure8) cannot both be given")
        scenario = options.get("scenario", implied or self.cfg.scenario)
        if scenario == RANDOM:
            scenario = self.cfg.scenarios[int(rng.integers(len(self.cfg.scenarios)))]
        if scenario not in SCENARIOS:
            raise ValueError(f"scenario={scenario!r}; allowed: {[RANDOM, *SCENARIOS]}")
        if implied is not None and scenario != implied:
            key = "jet_speed" if implied == "jet_crossing" else "wind_speed"
            raise ValueError(f"{key} applies to the {implied!r} scenario, not {scenario!r}")
        return scenario, jet_speed, wind_speed

    def reset_vehicle(
        self, index: int, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> tuple[np.ndarray, float]:
        cfg = self.cfg
        scenario, jet_speed, wind_speed = self._choose(rng, options)
        self.scenario[index] = SCENARIOS.index(scenario)
        for jet in self.jets:
            jet.speed_scale[index] = 0.0
        self.turbulence.set_weather(index)  # still air, no turbulence
        self.bump.set_gust(index)  # no gust
        speed = 0.0
        if scenario == "jet_crossing":
            jc = cfg.jet_crossing
            speed = jet_speed if jet_speed is not None else float(rng.choice(jc.jet_speeds))
            # one side draws nothing: the default episodes keep their random numbers bit for bit
            side = int(rng.integers(len(self.jets))) if len(self.jets) > 1 else 0
            self.jets[side].speed_scale[index] = jc.outlet_speed(speed)
            self.jet_side[index] = side
        elif scenario == "gusts":
            g = cfg.gusts
            heading = rng.uniform(0.0, 2.0 * math.pi)
            peak = rng.uniform(*g.peak)
            self.turbulence.set_weather(index, factor=g.w20)
            self.bump.set_gust(
                index,
                (peak * math.cos(heading), peak * math.sin(heading), 0.0),
                rng.uniform(*g.start),
                rng.uniform(*g.duration),
            )
        elif scenario == "figure8":
            fig = cfg.figure8
            speed = wind_speed if wind_speed is not None else float(rng.choice(fig.wind_speeds))
            direction = self._wind_direction
            if fig.wind_heading_spread > 0.0:
                turn = rng.uniform(-fig.wind_heading_spread, fig.wind_heading_spread)
                direction = rotation_matrix(quat_from_axis_angle(np.array((0.0, 0.0, 1.0)), turn)) @ direction
            self.turbulence.set_weather(index, speed * direction, fig.turbulence_w20)
        self.disturbance_speed[index] = speed
        position, _ = self.reference(np.zeros(1), self.scenario[index : index + 1])
        return position[0], 0.0

    # -- the reference path --------------------------------------------------------------------------
    def reference(self, t: np.ndarray, scenario: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n, 3) reference positions and velocities at times ``t`` (n,) of vehicles flying
        ``scenario`` (n,) (indices into :data:`SCENARIOS`); only the scenarios flown are computed."""
        t = np.asarray(t, dtype=float)
        position, velocity = np.zeros((t.size, 3)), np.zeros((t.size, 3))
        paths = (self._jet_crossing_path, self._table_pass_path, self._gusts_path, self._figure8_path)
        for k in np.unique(scenario):
            rows = scenario == k
            position[rows], velocity[rows] = paths[k](t[rows])
        return position, velocity

    def _jet_crossing_path(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """z falls at ``descent_speed`` between the two hovers."""
        jc = self.cfg.jet_crossing
        s, speed = _glide(t - jc.hover_seconds, jc.start_height - jc.end_height, jc.descent_speed, EASE)
        position = np.column_stack(
            (np.full(s.size, jc.path[0]), np.full(s.size, jc.path[1]), jc.start_height - s)
        )
        return position, np.column_stack((np.zeros(s.size), np.zeros(s.size), -speed))

    def _table_pass_path(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x rises at ``speed`` over the table, the hull ``clearance`` above its top."""
        tp = self.cfg.table_pass
        s, speed = _glide(t - tp.hover_seconds, tp.end_x - tp.start_x, tp.speed, EASE)
        height = tp.table_height + tp.clearance + 0.5 * self.vehicle.hull_height
        position = np.column_stack(
            (tp.start_x + s, np.full(s.size, tp.table_center[1]), np.full(s.size, height))
        )
        return position, np.column_stack((speed, np.zeros(s.size), np.zeros(s.size)))

    def _gusts_path(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A hover."""
        return np.tile(self.cfg.gusts.position, (t.size, 1)), np.zeros((t.size, 3))

    def _figure8_path(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``x = c_x + A_x sin φ``, ``z = c_z + A_z sin 2φ``."""
        fig = self.cfg.figure8
        phase, rate = fig.phase(t)
        (ax, az), (cx, cy, cz) = fig.amplitude, fig.center
        position = np.column_stack(
            (cx + ax * np.sin(phase), np.full(phase.size, cy), cz + az * np.sin(2.0 * phase))
        )
        velocity = np.column_stack(
            (ax * np.cos(phase) * rate, np.zeros(phase.size), 2.0 * az * np.cos(2.0 * phase) * rate)
        )
        return position, velocity

    def start(self, view: FleetView, index: np.ndarray) -> TaskRecord:
        record = self._record(view, None, None)
        if self.cfg.reward.peak_weight > 0.0:
            offset = view.state.position[index] - record.info["reference_position"][index]
            self.peak_deviation[index] = _horizontal_distance(offset)
        self.previous_action[index] = 0.0
        return record

    def step(self, view: FleetView, actions: np.ndarray, ended: np.ndarray) -> TaskRecord:
        return self._record(view, actions, ended)

    def _record(self, view: FleetView, actions: np.ndarray | None, ended: np.ndarray | None) -> TaskRecord:
        """The step's terms (none without ``actions``), blocks and ``info`` (module docstring)."""
        position, velocity = self.reference(view.time, self.scenario)
        offset = view.state.position - position
        error = np.linalg.norm(offset, axis=1)
        reward_terms = {}
        if actions is not None:
            r = self.cfg.reward
            if r.vertical_scale is None:
                tracking = terms.saturating_cost(error, r.tracking_cap, r.tracking_scale)
            else:
                horizontal = np.linalg.norm(offset[:, :2], axis=1)
                tracking = terms.saturating_cost(horizontal, 0.5 * r.tracking_cap, r.tracking_scale)
                tracking += terms.saturating_cost(
                    np.abs(offset[:, 2]), 0.5 * r.tracking_cap, r.vertical_scale
                )
            reward_terms = {
                "tracking": tracking,
                "alive": terms.alive(ended, r.tracking_cap),
                "effort": terms.efforts(actions, r.effort_weight),
                "crash": terms.crashes(ended, r.crash_penalty),
            }
            if r.peak_weight > 0.0:
                reward_terms["peak"] = terms.peak_rise(
                    _horizontal_distance(offset), self.peak_deviation, self.peak_weights[self.scenario]
                )
            if r.action_rate_weight > 0.0:
                reward_terms["action_rate"] = terms.action_rate(
                    actions, self.previous_action, r.action_rate_weight
                )
        info = {"reference_position": position, "reference_velocity": velocity, "tracking_error": error}
        return TaskRecord(reward_terms, blocks=self._blocks(view, position, velocity), info=info)

    def _blocks(self, view: FleetView, position: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        """(N, width) the observation blocks of :attr:`observation_blocks`, in order."""
        cfg, estimated = self.cfg, view.estimated_state
        out = np.empty((view.count, sum(width for _, width, _ in self.observation_blocks)))
        if cfg.observe_tracking_error:
            out[:, :3], out[:, 3:6] = position - estimated[:, :3], velocity - estimated[:, 3:6]
        else:
            out[:, :3], out[:, 3:6] = position, velocity
        column = 6
        if cfg.preview_seconds > 0.0:
            _, ahead = self.reference(view.time + cfg.preview_seconds, self.scenario)
            out[:, 6:9] = ahead - velocity
            column = 9
        if cfg.observe_reference_acceleration or cfg.observe_reference_jerk:
            _, later = self.reference(view.time + ACCELERATION_STEP, self.scenario)
            _, earlier = self.reference(view.time - ACCELERATION_STEP, self.scenario)
        if cfg.observe_reference_acceleration:
            out[:, column : column + 3] = (later - earlier) / (2.0 * ACCELERATION_STEP)
            column += 3
        if cfg.observe_reference_jerk:
            out[:, column : column + 3] = (later - 2.0 * velocity + earlier) / ACCELERATION_STEP**2
            column += 3
        for k, ahead_seconds in enumerate(cfg.path_ahead_seconds):
            ahead, _ = self.reference(view.time + ahead_seconds, self.scenario)
            out[:, column + 3 * k : column + 3 * k + 3] = ahead - estimated[:, :3]
        return out

    def render_marks(self, vehicle: int) -> dict[str, Any]:
        """The scenario (with the jet's speed and side, the wind's speed and heading, or the gust) and
        its reference path over the whole episode; the reference point comes from
        ``info["reference_position"]``."""
        index = int(self.scenario[vehicle])
        name, speed = SCENARIOS[index], float(self.disturbance_speed[vehicle])
        gust, start = math.hypot(*self.bump.shape[vehicle, :2]), float(self.bump.shape[vehicle, 3])
        side = self.cfg.jet_crossing.jet_sides[self.jet_side[vehicle]]
        wind = self.turbulence.weather[vehicle, :2] / max(speed, 1e-12)
        detail = {
            "jet_crossing": f"jet {speed:.1f} m/s across the path from {side}",
            "table_pass": "ground effect over the table",
            "gusts": f"turbulence, a gust of {gust:.1f} m/s at t = {start:.1f} s",
            "figure8": f"steady wind {speed:.1f} m/s"
            + (f" along ({wind[0]:+.2f}, {wind[1]:+.2f})" if speed > 0.0 else ""),
        }[name]
        times = np.linspace(0.0, self.cfg.episode_seconds, PATH_SAMPLES)
        path, _ = self.reference(times, np.full(times.size, index))
        return {"label": f"scenario {name}: {detail}", "path": path}

    @staticmethod
    def metrics(trace: Mapping[str, np.ndarray]) -> dict[str, float]:
        """Hentzen et al.'s (2019) Table I score, the largest horizontal distance from the reference (m), with
        the mean distance (m) and the largest vertical error (m), over the whole episode."""
        error = np.asarray(trace["position"]) - np.asarray(trace["reference_position"])
        return {
            "max_horizontal_deviation": float(np.max(_horizontal_distance(error))),
            "mean_tracking_error": float(np.mean(np.linalg.norm(error, axis=1))),
            "max_vertical_error": float(np.max(np.abs(error[:, 2]))),
        }


def _horizontal_distance(offset: np.ndarray) -> np.ndarray:
    """(N,) ``hypot(x, y)`` of (N, 3) offsets from the reference (m): the distance Hentzen et al.'s
    (2019) Table I scores, which the ``peak`` term follows."""
    return np.hypot(offset[:, 0], offset[:, 1])


def _glide(t: np.ndarray, length: float, speed: float, ease: float) -> tuple[np.ndarray, np.ndarray]:
    """Distance (m) and speed (m/s) along a straight move of ``length`` that starts at ``t = 0``: the
    speed eases up to ``speed`` as ``(1 - cos(π t/ease))/2`` over ``ease`` s, cruises, and eases down
    the same way (a reference with continuous velocity: no step for a controller to differentiate)."""
    ease = min(ease, length / speed)
    total = length / speed + ease
    t = np.clip(t, 0.0, total)
    rise = np.minimum(t, ease)
    fall = np.clip(t - (total - ease), 0.0, ease)
    distance = speed * (
        0.5 * rise
        - ease / (2.0 * math.pi) * np.sin(math.pi * rise / ease)
        + np.clip(t - ease, 0.0, total - 2.0 * ease)
        + 0.5 * fall
        + ease / (2.0 * math.pi) * np.sin(math.pi * fall / ease)
    )
    rate = np.where(
        t < ease,
        0.5 * (1.0 - np.cos(math.pi * rise / ease)),
        np.where(t > total - ease, 0.5 * (1.0 + np.cos(math.pi * fall / ease)), 1.0),
    )
    return distance, speed * np.where(t >= total, 0.0, rate)

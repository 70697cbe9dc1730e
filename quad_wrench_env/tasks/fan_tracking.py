"""``QuadWrench/FanTracking-v1``: stay in the centre of a fan's jet while the fan moves along y.

The task of McKinnon & Schoellig 2016 Sec. V (Figs. 6-7). A fan at ``(0, y_f(t), height)`` blows along +x; the
vehicle starts ``standoff_distance`` (2.3 m) in front of it at the fan's height, facing it (yaw = π), up to
``max_initial_offset`` (0.8 m) to one side of the jet axis, and must keep that stand-off while it
follows the jet sideways. The agent never observes the fan: only the estimated external force and
torque tell it where the jet is.

Episodes (``fan.motion``, or the ``fan_motion`` reset option): by default (``"random"``) each episode
draws the fan's motion family, its parameters and its start ``y0`` from the ranges of
:class:`FanEpisodes`, so that no trajectory can be memorised: static; constant speed in
``[-max_speed, max_speed]``; a sine of amplitude in ``[-max_amplitude, max_amplitude]`` and frequency in
``[min_frequency, max_frequency]``; piecewise constant velocities (``segments`` segments of
``[min_segment_seconds, max_segment_seconds]`` at speeds in ``[-max_speed, max_speed]``); then ``y0``
uniform such that the fan stays within ``|y| <= y_range`` for the whole episode. McKinnon & Schoellig's (2016)
cases are named motions with the parameters of ``fan.motions`` (``static``, ``constant_speed`` 0.1 m/s, the
``sine`` of A = 0.5 m and period 30 s, ``piecewise``), each starting at ``y0`` (0 unless given).

Observation (float32, 25; ``env.unwrapped.obs_layout`` names the slices; SI units, world frame unless
noted; everything is the estimator's belief, and with ``estimator="oracle"`` it is the truth):

=====  ==============  ====================================================================
index  name            meaning
=====  ==============  ====================================================================
0-2    position        estimated position (m)
3-5    velocity        estimated velocity (m/s)
6-11   attitude        estimated attitude as the first two columns of the rotation matrix
                       (body x and y axes in the world frame): continuous, unlike a quaternion
12-14  body_rates      estimated angular velocity in the body frame (rad/s)
15-17  force           estimated external force (N); zeros with ``observe_wrench=False``
18-20  torque          estimated external torque (N·m); zeros with ``observe_wrench=False``
21-24  last_action     the previous (clipped) action
=====  ==============  ====================================================================

Action: ``Box(-1, 1, (4,), float32)``, meaning set by ``action_type`` (see
:mod:`quad_wrench_env.engine.actions`); default ``velocity``: ``(v_x, v_y, v_z, yaw rate)``.

Reward per step (terms in ``info["reward_terms"]``), with ``d`` the distance in the y-z plane from
the jet axis at the vehicle's x (the retarded axis, ``docs/physics.md``, "Fan"):

=========  ===========================================  ==========================================
term       value                                        why
=========  ===========================================  ==========================================
tracking   ``exp(-d/axis_scale)`` (0.5 m)               0.2 at the 0.8 m start: signal across the
                                                        jet's ~1 m half-width, sharpest on the axis
standoff   ``-standoff_weight·|x - standoff_distance|`` keeps the stand-off that the harness scores
effort     ``-effort_weight·mean(a²)``                  smooth commands
crash      ``-crash_penalty`` on an early end, else 0
=========  ===========================================  ==========================================

Episode end: terminated on ``crash`` (below ``crash_height``, or the hull touching the ground or any
scene part), ``flip`` (tilt above ``flip_tilt_deg``) or ``out_of_arena``, named in
``info["termination_reason"]``;
truncated after ``episode_seconds`` (30 s at 50 Hz: 1500 steps; physics at 200 Hz).

Reset options: ``offset_y`` (initial offset from the jet axis, m), ``fan_motion`` (``"random"``, a
motion name, or a mapping ``{"name": ..., **parameters}``; every motion takes ``y0``).

``info``: ``time``, ``position``, ``velocity``, ``wrench_true``, ``wrench_est``, ``wrench_cov`` (its
covariance), ``fan_position`` (the fan itself, now), ``jet_axis_y`` (the axis at the vehicle's x),
``axis_error`` (signed ``y - jet_axis_y``), ``standoff_error`` (signed ``x - standoff_distance``),
``reward_terms``, ``termination_reason``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.disturbances.fan import (
    MOTIONS,
    RANDOM,
    FanConfig,
    FanJet,
    FanMotion,
    make_motion,
    turbulence_walks,
)
from quad_wrench_env.disturbances.jet_kernels import jet_speed, motion_y, transit_time
from quad_wrench_env.engine.components import Components
from quad_wrench_env.engine.env_config import EnvConfig
from quad_wrench_env.engine.fleet_view import FleetView
from quad_wrench_env.estimators.noise import FilterNoise
from quad_wrench_env.numerics import njit
from quad_wrench_env.registry import register
from quad_wrench_env.tasks import terms
from quad_wrench_env.tasks.base import TaskDefaults, TaskRecord
from quad_wrench_env.vehicle import VehicleParams, make_vehicle


@dataclass
class FanTrackingReward:
    axis_scale: float = 0.5
    """Length (m) of the tracking term ``exp(-d/axis_scale)``."""
    standoff_weight: float = 1.0
    """Reward lost per metre of ``|x - standoff_distance|`` and step."""
    effort_weight: float = 0.01
    crash_penalty: float = 10.0

    def __post_init__(self) -> None:
        check_numbers("reward", self, ("axis_scale",))
        check_numbers("reward", self, ("standoff_weight", "effort_weight", "crash_penalty"), positive=False)


@dataclass
class FanEpisodes:
    """Ranges of the default episode distribution (``fan.motion = "random"``; module docstring)."""

    motions: tuple[str, ...] = ("static", "constant_speed", "sine", "piecewise")
    y_range: float = 2.0
    """The fan stays within ``|y| <= y_range`` (m) for the whole episode."""
    max_speed: float = 0.1
    max_amplitude: float = 1.0
    min_frequency: float = 1.0 / 60.0
    max_frequency: float = 1.0 / 15.0
    segments: int = 3
    min_segment_seconds: float = 5.0
    max_segment_seconds: float = 12.0

    def __post_init__(self) -> None:
        self.motions = tuple(self.motions)
        if not self.motions or any(m not in MOTIONS for m in self.motions):
            raise ValueError(
                f"episodes.motions={list(self.motions)!r} must name one or more of {sorted(MOTIONS)}"
            )
        check_numbers(
            "episodes",
            self,
            ("y_range", "min_frequency", "max_frequency", "min_segment_seconds", "max_segment_seconds"),
        )
        check_numbers("episodes", self, ("max_speed", "max_amplitude"), positive=False)
        if self.min_frequency > self.max_frequency or self.min_segment_seconds > self.max_segment_seconds:
            raise ValueError(
                f"episodes: min_frequency={self.min_frequency} <= max_frequency={self.max_frequency} and "
                f"min_segment_seconds={self.min_segment_seconds} <= max_segment_seconds="
                f"{self.max_segment_seconds} are required"
            )
        if not (
            isinstance(self.segments, int) and not isinstance(self.segments, bool) and self.segments >= 1
        ):
            raise ValueError(f"episodes.segments={self.segments!r} must be an integer >= 1")

    def draw(self, rng: np.random.Generator, seconds: float) -> FanMotion:
        """A motion drawn from the ranges, placed by ``y0`` so that the fan stays within ``y_range``
        for ``seconds`` (excursions that cannot fit are scaled down to fit)."""
        name = self.motions[int(rng.integers(len(self.motions)))]
        v = self.max_speed
        if name == "static":
            params: dict[str, Any] = {}
        elif name == "constant_speed":
            params = {"speed": float(rng.uniform(-v, v))}
        elif name == "sine":
            params = {
                "amplitude": float(rng.uniform(-self.max_amplitude, self.max_amplitude)),
                "frequency": float(rng.uniform(self.min_frequency, self.max_frequency)),
            }
        else:
            durations = rng.uniform(self.min_segment_seconds, self.max_segment_seconds, self.segments)
            velocities = rng.uniform(-v, v, self.segments)
            params = {"segments": tuple(zip(durations.tolist(), velocities.tolist(), strict=True))}
        excursion = make_motion(name, **params).y(np.linspace(0.0, seconds, 601))
        low, high = float(excursion.min()), float(excursion.max())
        width = high - low
        if width > 2.0 * self.y_range:  # too far for the range: slow the motion down to fit
            shrink = 2.0 * self.y_range / width
            params = _scaled(name, params, shrink)
            low, high = low * shrink, high * shrink
        lowest, highest = -self.y_range - low, self.y_range - high
        y0 = float(rng.uniform(lowest, max(lowest, highest)))  # equal to rounding when scaled to fit
        return make_motion(name, **params, y0=y0)


def _scaled(name: str, params: dict[str, Any], factor: float) -> dict[str, Any]:
    """The parameters of motion ``name`` with every excursion scaled by ``factor``."""
    if name == "constant_speed":
        return {"speed": params["speed"] * factor}
    if name == "sine":
        return {**params, "amplitude": params["amplitude"] * factor}
    return {"segments": tuple((d, v * factor) for d, v in params["segments"])}


@dataclass
class FanTrackingConfig(EnvConfig):
    fan: FanConfig = field(default_factory=FanConfig)
    episodes: FanEpisodes = field(default_factory=FanEpisodes)
    standoff_distance: float = 2.3
    """x (m) in front of the fan where the vehicle starts and must stay (McKinnon & Schoellig 2016 Fig. 7)."""
    max_initial_offset: float = 0.8
    reward: FanTrackingReward = field(default_factory=FanTrackingReward)
    fan_walks: bool = False
    """True: the UKF's and the EKF's force and torque random walks are the vehicle's defaults and, added
    in quadrature, the largest change per physics step of the drag the fan's turbulence puts on the
    vehicle anywhere across the jet at the stand-off (:func:`~quad_wrench_env.disturbances.fan.
    turbulence_walks`; :meth:`resolved_estimator_params`; a walk given in ``estimator_params`` is kept):
    covariances that follow the fan's turbulence (``docs/estimators.md``, "The fan's turbulence as
    process noise"; the estimates get noisier, and a policy trained on them tracks worse). Only for the
    UKF and the EKF with settings by key. False (default): the vehicle's default walks."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_numbers("env", self, ("standoff_distance",))
        check_numbers("env", self, ("max_initial_offset",), positive=False)
        if not isinstance(self.fan_walks, bool):
            raise ValueError(f"fan_walks={self.fan_walks!r} must be true or false")
        if self.fan_walks and self.estimator not in ("ukf", "ekf"):
            raise ValueError(
                f"fan_walks=True sizes the UKF's and the EKF's random walks; estimator={self.estimator!r} "
                "has none (allowed: 'ukf', 'ekf')"
            )
        if self.fan_walks and isinstance(self.estimator_params, str):
            raise ValueError(
                f"fan_walks=True with estimator_params={self.estimator_params!r}: the named settings fix "
                "their own walks; give the settings by key (force_walk, torque_walk to set them yourself)"
            )

    def resolved_estimator_params(self) -> dict[str, Any] | str:
        """``estimator_params``, with ``fan_walks`` the walks it does not give sized from the jet."""
        if not self.fan_walks:
            return self.estimator_params
        vehicle = make_vehicle(self.vehicle, **self.vehicle_params)
        defaults = FilterNoise().for_vehicle(vehicle)
        fan = turbulence_walks(self.fan, vehicle, self.standoff_distance, 1.0 / self.physics_hz)
        walks = {
            "force_walk": math.hypot(defaults.force_walk, fan[0]),
            "torque_walk": math.hypot(defaults.torque_walk, fan[1]),
        }
        return {**walks, **self.estimator_params}


@register("task")
class FanTracking(TaskDefaults):
    """Track the centre of a moving fan's jet from the estimated wrench (see the module docstring),
    for N vehicles, each in front of a fan of its own."""

    env_id: ClassVar[str] = "QuadWrench/FanTracking-v1"
    config_class: ClassVar[type[EnvConfig]] = FanTrackingConfig
    reset_options: ClassVar[tuple[str, ...]] = ("offset_y", "fan_motion")
    trace_keys: ClassVar[tuple[str, ...]] = ("fan_position", "jet_axis_y", "axis_error", "standoff_error")
    metric_columns: ClassVar[tuple[tuple[str, str, str], ...]] = (
        ("mean_abs_error_after_5s", "mean abs(y - y_axis) after 5 s [m]", "{:.3f}"),
        ("fraction_within_0.15m", "time within 0.15 m", "{:.0%}"),
        ("time_to_0.15m", "first within 0.15 m [s]", "{:.2f}"),
        ("mean_abs_standoff_error_after_5s", "mean abs(x - x_ref) after 5 s [m]", "{:.3f}"),
    )

    def __init__(self, cfg: FanTrackingConfig, vehicle: VehicleParams, count: int) -> None:
        arena = cfg.arena
        if not (arena.x_min < cfg.standoff_distance < arena.x_max):
            raise ValueError(
                f"standoff_distance={cfg.standoff_distance} must lie inside the arena "
                f"({arena.x_min}, {arena.x_max})"
            )
        margin = arena.y_half_width - vehicle.hull_radius
        if cfg.episodes.y_range + cfg.max_initial_offset >= margin:
            raise ValueError(
                f"episodes.y_range={cfg.episodes.y_range} + max_initial_offset={cfg.max_initial_offset} must "
                f"stay below the arena's half-width minus the hull radius ({margin:.3g} m)"
            )
        self.cfg = cfg
        self.vehicle = vehicle
        self.fan = FanJet(cfg.fan, count)
        self._jet = self.fan.kernel_parameters()
        r = cfg.reward
        self._weights = np.array((r.axis_scale, r.standoff_weight, r.effort_weight, r.crash_penalty))

    def components(self) -> Components:
        """The fan's jet (switched off with ``fan.enabled=False``, it still takes its draws)."""
        return Components(winds=[self.fan])

    def _motion(self, option: Any, rng: np.random.Generator) -> FanMotion:
        fan = self.cfg.fan
        if option is None:
            option = fan.motion
        if option == RANDOM:
            return self.cfg.episodes.draw(rng, self.cfg.episode_seconds)
        if isinstance(option, Mapping):
            params = dict(option)
            if "name" not in params:
                raise ValueError(f"fan_motion={option!r} needs a 'name' key")
            return fan.make_motion(params.pop("name"), **params)
        if isinstance(option, str):
            return fan.make_motion(option)
        raise ValueError(f"fan_motion={option!r} must be 'random', a motion name or a mapping")

    def reset_vehicle(
        self, index: int, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> tuple[np.ndarray, float]:
        cfg = self.cfg
        motion = self._motion(options.get("fan_motion"), rng)
        fan_y0 = float(motion.y(np.asarray(0.0)))
        if "offset_y" in options:
            value = options["offset_y"]
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
                raise ValueError(f"offset_y={value!r} must be a number (m from the jet axis)")
            offset = float(value)
        else:
            offset = float(rng.uniform(-cfg.max_initial_offset, cfg.max_initial_offset))
        start_y = fan_y0 + offset
        margin = cfg.arena.y_half_width - self.vehicle.hull_radius
        if not (math.isfinite(offset) and abs(start_y) < margin):
            raise ValueError(
                f"offset_y={options.get('offset_y', offset)!r} puts the vehicle at y={start_y:.3g} m; "
                f"allowed: |fan y0 + offset_y| < {margin:.3g} m (arena half-width minus hull radius)"
            )
        self.fan.set_motion(index, motion)
        return np.array((cfg.standoff_distance, start_y, cfg.fan.height)), math.pi

    def start(self, view: FleetView, index: np.ndarray) -> TaskRecord:
        return TaskRecord({}, info=self._info(self._geometry(view)))

    def step(self, view: FleetView, actions: np.ndarray, ended: np.ndarray) -> TaskRecord:
        """The terms of the module docstring (:func:`fan_tracking_step`)."""
        geometry, rewards = np.empty((view.count, FAN_TRACKING_GEOMETRY)), np.empty((4, view.count))
        position, time = view.state.position, view.time
        tables, standoff = self.fan.motion_tables, self.cfg.standoff_distance
        fan_tracking_step(
            position, time, tables, self._jet, standoff, actions, ended, self._weights, geometry, rewards
        )
        return TaskRecord(
            {name: rewards[k] for k, name in enumerate(REWARD_TERMS)}, info=self._info(geometry)
        )

    def _geometry(self, view: FleetView) -> np.ndarray:
        """(N, 7) :func:`fan_tracking_geometry` of the vehicles now."""
        geometry = np.empty((view.count, FAN_TRACKING_GEOMETRY))
        fan_tracking_geometry(
            view.state.position,
            view.time,
            self.fan.motion_tables,
            self._jet,
            self.cfg.standoff_distance,
            geometry,
        )
        return geometry

    @staticmethod
    def _info(geometry: np.ndarray) -> dict[str, np.ndarray]:
        return {
            "fan_position": geometry[:, FAN_POSITION],
            "jet_axis_y": geometry[:, AXIS_Y],
            "axis_error": geometry[:, AXIS_ERROR],
            "standoff_error": geometry[:, STANDOFF_ERROR],
        }

    @staticmethod
    def metrics(
        trace: Mapping[str, np.ndarray], settle_time: float = 5.0, band: float = 0.15
    ) -> dict[str, float]:
        """McKinnon & Schoellig 2016 Fig. 7 scores: mean |y - y_axis| after ``settle_time`` (m), fraction of
        time within ``band`` of the axis, time to first come within ``band`` (s; inf if never), and the mean
        |x - standoff_distance| after ``settle_time`` (m), so that tracking from closer to the fan,
        where the torque is stronger, does not pass for better tracking."""
        t = trace["time"]
        error = np.abs(trace["axis_error"])
        standoff = np.abs(trace["standoff_error"])
        late = t >= settle_time
        inside = error <= band
        first = np.flatnonzero(inside)
        return {
            "mean_abs_error_after_5s": float(np.mean(error[late])) if np.any(late) else math.nan,
            "fraction_within_0.15m": float(np.mean(inside)),
            "time_to_0.15m": float(t[first[0]]) if first.size else math.inf,
            "mean_abs_standoff_error_after_5s": float(np.mean(standoff[late])) if np.any(late) else math.nan,
        }


FAN_TRACKING_GEOMETRY = 7
"""Columns of :func:`fan_tracking_geometry`'s output, named below."""
DISTANCE, AXIS_ERROR, AXIS_Y, FAN_POSITION, STANDOFF_ERROR = 0, 1, 2, slice(3, 6), 6
REWARD_TERMS = ("tracking", "standoff", "effort", "crash")
"""The rows of :func:`fan_tracking_step`'s reward terms."""


@njit
def fan_tracking_step(
    position, time, motion_tables, fan, standoff_distance, actions, ended, weights, geometry, out
):
    """Each vehicle's :func:`fan_tracking_geometry` into ``geometry`` (N, 7) and its reward terms into the
    rows of ``out`` (4, N), :data:`REWARD_TERMS`: ``tracking = exp(-d/axis_scale)`` of the distance ``d``
    from the jet's axis, ``standoff = -standoff_weight·|x - x_ref|``, ``effort`` of its action (N, 4)
    and ``crash`` where ``ended`` (N,); ``weights``: ``(axis_scale, standoff_weight, effort_weight,
    crash_penalty)``."""
    fan_tracking_geometry(position, time, motion_tables, fan, standoff_distance, geometry)
    for n in range(position.shape[0]):
        out[0, n] = terms.closeness(geometry[n, DISTANCE], weights[0])
        out[1, n] = terms.linear_cost(geometry[n, STANDOFF_ERROR], weights[1])
        out[2, n] = terms.effort(actions[n], weights[2])
        out[3, n] = terms.crash(ended[n], weights[3])


@njit
def fan_tracking_geometry(position, time, motion_tables, fan, standoff_distance, out):
    """Each vehicle's place relative to its jet into ``out`` (N, 7): the distance from the jet's axis
    in the y-z plane, the signed ``axis_error`` y - y_axis, the jet axis's y at the vehicle (the fan's
    y when the air now at the vehicle left it, McKinnon & Schoellig 2016 Sec. VI-B), the fan's
    position now ``(0, y, height)`` and the signed stand-off error ``x - standoff_distance``. ``fan``: the jet
    (``FanJet.kernel_parameters``)."""
    height = fan[5]
    for n in range(position.shape[0]):
        _, b = jet_speed(fan, max(position[n, 0], 0.0))
        axis = motion_y(motion_tables[n], time[n] - transit_time(fan, position[n, 0], b))
        dy, dz = position[n, 1] - axis, position[n, 2] - height
        out[n, 0] = math.sqrt(dy * dy + dz * dz)
        out[n, 1] = dy
        out[n, 2] = axis
        out[n, 3], out[n, 4], out[n, 5] = 0.0, motion_y(motion_tables[n], time[n]), height
        out[n, 6] = position[n, 0] - standoff_distance

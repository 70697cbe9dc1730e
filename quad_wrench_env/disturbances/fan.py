"""A fan at ``(0, y_f(t), z_f)`` blowing along +x whose jet moves along y (McKinnon & Schoellig
2016, Sec. V, Figs. 6-7).

Velocity field (``docs/physics.md``, "Fan"): a round turbulent jet with Gaussian radial profile
``u = u_c·exp(-(r/b)²)``, ``b(x) = sqrt((D/2)² + (c·x)²)``, where ``r`` is the distance from the jet
axis, and a centre-line speed that conserves the outlet's axial momentum flux: the profile carries
``ρ·u_c²·π·b²/2``, the outlet ``ρ·U0²·π·D²/4``, so ``u_c(x) = U0·min(1, D/(√2·b(x)))``. The core, where
``u_c = U0``, ends at ``x_c = D/(2c)``. The air at distance x left the fan
``t_transit(x) = ∫₀ˣ dξ/u_c(ξ)`` earlier (closed form in :meth:`FanJet.transit_time`), so the axis
there sits at the fan's *retarded* position ``y_f(t - t_transit(x))``. Turbulence multiplies the
local mean speed by ``I·n(t)`` in each component, ``n`` a unit-variance Ornstein-Uhlenbeck process
with time scale ``b/u_c`` at the vehicle
(:func:`~quad_wrench_env.disturbances.jet_kernels.turbulence_step`; Hentzen et al.'s (2019) fixed jet,
:mod:`.jet`, takes the same model with a length scale of its own).
Before ``t = 0`` the fan rests where its motion starts.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.disturbances.base import CompiledForm, Outlet
from quad_wrench_env.disturbances.drag import QuadraticDrag
from quad_wrench_env.disturbances.jet_kernels import jet_axis_y
from quad_wrench_env.vehicle import VehicleParams


class FanMotion(Protocol):
    """Lateral position of the fan over time."""

    def y(self, t: np.ndarray) -> np.ndarray:
        """Fan y (m) at times ``t`` (s, array); times before 0 give the start position."""

    def table(self) -> np.ndarray:
        """The motion as numbers for the compiled kernels, ``[y0, amplitude, frequency, K, starts
        (K), positions (K), velocities (K)]``: for ``t' = max(t, 0)``, ``y = y0 + amplitude·sin(2π
        frequency t') + positions[k] + velocities[k]·(t' - starts[k])`` with ``k`` the last start
        ``<= t'`` (no such term when K = 0)."""


def _table(y0: float = 0.0, amplitude: float = 0.0, frequency: float = 0.0, segments=()) -> np.ndarray:
    columns = np.asarray(segments, dtype=float).reshape(-1, 3).T
    starts, positions, velocities = columns
    return np.concatenate(((y0, amplitude, frequency, len(starts)), starts, positions, velocities))


@dataclass(frozen=True)
class Static:
    y0: float = 0.0

    def y(self, t: np.ndarray) -> np.ndarray:
        return np.full(np.shape(t), self.y0)

    def table(self) -> np.ndarray:
        return _table(self.y0)


@dataclass(frozen=True)
class ConstantSpeed:
    speed: float = 0.1
    y0: float = 0.0

    def y(self, t: np.ndarray) -> np.ndarray:
        return self.y0 + self.speed * np.maximum(t, 0.0)

    def table(self) -> np.ndarray:
        return _table(self.y0, segments=[(0.0, 0.0, self.speed)])


@dataclass(frozen=True)
class Sine:
    amplitude: float = 0.5
    frequency: float = 1.0 / 30.0
    y0: float = 0.0

    def y(self, t: np.ndarray) -> np.ndarray:
        return self.y0 + self.amplitude * np.sin(2.0 * math.pi * self.frequency * np.maximum(t, 0.0))

    def table(self) -> np.ndarray:
        return _table(self.y0, self.amplitude, self.frequency)


@dataclass(frozen=True)
class PiecewiseVelocity:
    """Constant velocity over consecutive segments ``(duration s, velocity m/s)``; still afterwards."""

    segments: tuple[tuple[float, float], ...] = ((10.0, 0.1), (10.0, 0.0), (10.0, -0.1))
    y0: float = 0.0

    def __post_init__(self) -> None:
        segments = tuple((float(d), float(v)) for d, v in self.segments)
        if not segments or any(d <= 0 or not math.isfinite(d) or not math.isfinite(v) for d, v in segments):
            raise ValueError(
                f"segments={self.segments!r} must be a non-empty list of (duration > 0, velocity)"
            )
        object.__setattr__(self, "segments", segments)
        durations = np.array([d for d, _ in segments])
        velocities = np.array([v for _, v in segments])
        object.__setattr__(self, "_starts", np.concatenate(([0.0], np.cumsum(durations))))
        object.__setattr__(self, "_velocities", np.append(velocities, 0.0))
        object.__setattr__(
            self, "_positions", self.y0 + np.concatenate(([0.0], np.cumsum(durations * velocities)))
        )

    def y(self, t: np.ndarray) -> np.ndarray:
        t = np.maximum(t, 0.0)
        k = np.searchsorted(self._starts, t, side="right") - 1  # type: ignore[attr-defined]
        return self._positions[k] + self._velocities[k] * (t - self._starts[k])  # type: ignore[attr-defined]

    def table(self) -> np.ndarray:
        rows = zip(self._starts, self._positions, self._velocities, strict=True)  # type: ignore[attr-defined]
        return _table(segments=list(rows))


def half_width(x: np.ndarray, radius2: float, spread: float) -> np.ndarray:
    """``b(x) = sqrt(R² + (c·x)²)`` of a round jet of outlet radius² ``radius2`` and spread ``c``."""
    return np.sqrt(radius2 + (spread * x) ** 2)


def centreline_speed(x: np.ndarray, u0: float, radius2: float, spread: float) -> np.ndarray:
    """``u_c = U0·min(1, D/(√2·b))``: the outlet's momentum flux, spread over the profile."""
    return u0 * np.minimum(1.0, np.sqrt(2.0 * radius2) / half_width(x, radius2, spread))


def turbulence_walks(
    config: FanConfig, vehicle: VehicleParams, distance: float, dt: float
) -> tuple[float, float]:
    """``(N, N·m)``: the largest, over the vehicle's lateral offsets from the jet's axis ``distance`` from
    the fan, of the RMS over the three axes of the change in one step ``dt`` of the force and of the
    torque that the fan's turbulence puts on ``vehicle`` level and at rest: what a random walk of the
    external force and torque must take per filter step to follow it anywhere across the jet.

    The air at each drag point ``j`` (:meth:`VehicleParams.drag_points`, body offset ``r_j``) is
    ``s_j·(e_x + I·n)``, ``s_j`` the jet's mean speed there (:meth:`FanJet.velocity_at`) and ``n`` the
    unit-variance Ornstein-Uhlenbeck turbulence of time scale ``b/u_c``, whose new random part per step has sd
    ``sqrt(1 - a²)``, ``a = exp(-dt·u_c/b)`` (its whole change, ``sqrt(2(1 - a))``, is 0.6 % more at the
    stand-off). Linearised about the mean, the point's quadratic drag ``c·|w|·w``
    (:class:`~quad_wrench_env.disturbances.drag.QuadraticDrag`) changes by ``c·s_j²·I·diag(2, 1, 1)·dn``
    and a hub's rotor drag ``k_d·Ω·w`` in the rotor plane (:meth:`~quad_wrench_env.rotors.Rotors.
    drag_forces`, hover speed Ω) by ``k_d·Ω·s_j·I·diag(1, 1, 0)·dn``; the force sums these Jacobians,
    the torque sums ``[r_j]×`` times them. The force's largest change is on the axis, the torque's about
    ``b/2`` off it, where the square of the jet's profile (the quadratic drag) is steepest. The jet
    model: ``docs/physics.md``, "Fan" (McKinnon & Schoellig 2016's fan)."""
    if not distance > 0.0:
        raise ValueError(f"distance={distance!r} must be > 0 (m in front of the fan)")
    if not config.enabled or config.turbulence_intensity == 0.0:
        return 0.0, 0.0
    points = vehicle.drag_points()
    jet = FanJet(dataclasses.replace(config, motion=RANDOM))  # still, its axis at y = 0 (the first motion)
    centre = np.asarray(distance)
    width = float(jet.half_width(centre))
    decay = math.exp(-dt * float(jet.centreline_speed(centre)) / width)
    offsets = np.linspace(0.0, width, 201)
    centres = np.zeros((len(offsets), 1, 3))
    centres[:, 0, 0], centres[:, 0, 1], centres[:, 0, 2] = distance, offsets, config.height
    where = centres + points[None, :, :]  # (O, P, 3): the drag points with the vehicle at each offset
    speeds = jet.velocity_at(where.reshape(1, -1, 3), np.zeros(1), slice(0, 1), mean=True)[0, :, 0]
    speeds = speeds.reshape(len(offsets), len(points))  # the jet's mean speed at each point, each offset
    quadratic = QuadraticDrag(vehicle.drag_area, len(points)).coefficient * np.diag((2.0, 1.0, 1.0))
    rotor = vehicle.rotor_drag_coefficient * vehicle.hover_rotor_speed * np.diag((1.0, 1.0, 0.0))
    hub = np.arange(len(points)) < 4
    jacobians = (speeds**2)[..., None, None] * quadratic + (hub * speeds)[
        ..., None, None
    ] * rotor  # (O, P, 3, 3)
    levers = np.cross(points[:, None, :], np.eye(3)).transpose(0, 2, 1)  # levers[j] @ f = r_j × f
    # the RMS over the axes of each axis's sd, sqrt(Σ_k J_ik²): the Frobenius norm over √3, largest offset
    force = float(np.max(np.linalg.norm(jacobians.sum(axis=1), axis=(1, 2)))) / math.sqrt(3.0)
    torque = float(np.max(np.linalg.norm(np.einsum("pij,opjk->oik", levers, jacobians), axis=(1, 2))))
    torque /= math.sqrt(3.0)
    per_step = config.turbulence_intensity * math.sqrt(1.0 - decay * decay)
    return per_step * force, per_step * torque


RANDOM = "random"
"""The motion name that asks the task to draw each episode's motion (FanTracking's default)."""

MOTIONS: dict[str, type] = {
    "static": Static,
    "constant_speed": ConstantSpeed,
    "sine": Sine,
    "piecewise": PiecewiseVelocity,
}


def make_motion(name: str, **params) -> FanMotion:
    """A fan motion by name with its parameters; unknown names or parameters raise ``ValueError``."""
    if name not in MOTIONS:
        raise ValueError(f"unknown fan motion {name!r}; allowed: {sorted(MOTIONS)}")
    cls = MOTIONS[name]
    allowed = set(cls.__dataclass_fields__)
    unknown = sorted(set(params) - allowed)
    if unknown:
        raise ValueError(
            f"unknown parameter(s) {unknown} for fan motion {name!r}; allowed: {sorted(allowed)}"
        )
    for key, value in params.items():
        if key != "segments" and not (isinstance(value, (int, float)) and math.isfinite(value)):
            raise ValueError(f"fan motion {name!r}: {key}={value!r} must be a finite number")
    return cls(**params)


def _default_motions() -> dict[str, dict]:
    return {
        "static": {},
        "constant_speed": {"speed": 0.1},
        "sine": {"amplitude": 0.5, "frequency": 1.0 / 30.0},
        "piecewise": {"segments": [[10.0, 0.1], [10.0, 0.0], [10.0, -0.1]]},
    }


@dataclass
class FanConfig:
    """Fan and jet parameters (defaults: ``docs/physics.md``, "Fan")."""

    enabled: bool = True
    """False switches the air off (the fan still moves and is reported), e.g. for hover tests."""
    outlet_diameter: float = 0.75
    """``D`` (m): a large drum fan (an estimate, ``docs/physics.md``, "Fan")."""
    outlet_speed: float = 10.0
    """``U0`` (m/s): with ``D``, about 5.1 m/s on the axis 2.3 m away."""
    height: float = 1.0
    spread: float = 0.42
    """Jet growth ``c`` in ``b(x)``; 0.113 is free-jet theory, 0.42 fits McKinnon & Schoellig 2016 Fig. 6."""
    turbulence_intensity: float = 0.15
    motion: str = RANDOM
    """The motion of every episode: a name of :data:`MOTIONS`, or ``"random"`` (the task draws one
    per episode)."""
    motions: dict[str, dict] = field(default_factory=_default_motions)
    """Parameters of each named motion (McKinnon & Schoellig's (2016) cases by default)."""

    def __post_init__(self) -> None:
        check_numbers("fan", self, ("outlet_diameter", "outlet_speed", "spread"))
        if not (0.0 <= self.turbulence_intensity < 1.0):
            raise ValueError(f"fan.turbulence_intensity={self.turbulence_intensity!r} must be in [0, 1)")
        unknown = sorted(set(self.motions) - set(MOTIONS))
        if unknown:
            raise ValueError(f"unknown fan motion(s) {unknown} in fan.motions; allowed: {sorted(MOTIONS)}")
        if self.motion != RANDOM and self.motion not in MOTIONS:
            raise ValueError(f"fan.motion={self.motion!r}; allowed: {[RANDOM, *sorted(MOTIONS)]}")
        for name in self.motions:
            self.make_motion(name)  # validates the parameters

    def make_motion(self, name: str, **overrides) -> FanMotion:
        return make_motion(name, **{**self.motions.get(name, {}), **overrides})


class FanJet:
    """The moving, turbulent jet of a fan, one copy per vehicle (each with its own fan motion and
    turbulence): a :class:`~quad_wrench_env.disturbances.base.WindField`. Switched off
    (``enabled=False``) it blows no air and draws nothing at reset, but still moves and keeps its
    three columns of each step's draws: exactly the random numbers an env without its fan drew before
    the engine took components (same-seed trajectories with the fan off are unchanged)."""

    name = "fan"
    noise_width = 3
    compiled = CompiledForm(
        "quad_wrench_env.disturbances.jet_kernels",
        (("velocity", "fan_velocity"), ("advance", "fan_advance")),
        state="noise",
        table="motion_tables",
    )

    def __init__(self, config: FanConfig, count: int = 1) -> None:
        self.config = config
        self.count = count
        self._u0 = config.outlet_speed
        self._radius2 = (0.5 * config.outlet_diameter) ** 2
        self._core = 0.5 * config.outlet_diameter / config.spread
        """Length ``x_c = D/(2c)`` of the core, where the centre-line speed is still ``U0``."""
        self._kernel = np.array(
            (
                float(config.enabled),
                config.outlet_speed,
                self._core,
                0.5 * config.outlet_diameter,
                config.spread,
                config.height,
                config.turbulence_intensity,
            )
        )
        self.noise = np.zeros((count, 3))
        """(N, 3) unit-variance Ornstein-Uhlenbeck state of each vehicle's turbulence."""
        first = Static() if config.motion == RANDOM else config.make_motion(config.motion)
        self._motions: list[FanMotion] = [first] * count
        """Each vehicle's motion; with ``"random"``, still until its task draws one."""
        self._group_motions: list[FanMotion] = []
        self._group_of = np.zeros(count, dtype=int)
        self.motion_tables = np.zeros((count, 0))
        """(N, W) :meth:`FanMotion.table` of each vehicle's fan, zero-padded (for the kernels)."""
        self._regroup()

    # -- per-vehicle motions ---------------------------------------------------------------------
    def motion(self, index: int) -> FanMotion:
        return self._motions[index]

    def set_motion(self, index: int, motion: FanMotion) -> None:
        self._motions[index] = motion
        self._regroup()

    def _regroup(self) -> None:
        """Vehicles whose fans move alike are evaluated together (usually all of them)."""
        self._group_motions = []
        for i, motion in enumerate(self._motions):
            if motion not in self._group_motions:
                self._group_motions.append(motion)
            self._group_of[i] = self._group_motions.index(motion)
        tables = [motion.table() for motion in self._group_motions]
        width = max(len(t) for t in tables)
        padded = np.array([np.pad(t, (0, width - len(t))) for t in tables])
        self.motion_tables = padded[self._group_of]

    def _y(self, t: np.ndarray, index: np.ndarray | slice) -> np.ndarray:
        """Fan y at times ``t`` (n, ...) of the vehicles ``index``."""
        if len(self._group_motions) == 1:
            return self._group_motions[0].y(t)
        groups = self._group_of[index]
        y = np.empty(np.shape(t))
        for g, motion in enumerate(self._group_motions):
            mask = groups == g
            if np.any(mask):
                y[mask] = motion.y(t[mask])
        return y

    # -- the field --------------------------------------------------------------------------------
    def kernel_parameters(self) -> np.ndarray:
        """The jet as the kernels read it: on (1, or 0 when disabled), outlet speed, core length
        ``x_c``, outlet radius, spread, height, turbulence intensity (each vehicle's motion is in
        :attr:`motion_tables`)."""
        return self._kernel.copy()

    def reset(self, index: int, rng: np.random.Generator) -> None:
        if self.config.enabled:  # a fan switched off draws nothing at reset
            self.noise[index] = rng.standard_normal(3)  # the stationary distribution of the OU process

    def centreline_speed(self, x: np.ndarray) -> np.ndarray:
        return centreline_speed(x, self._u0, self._radius2, self.config.spread)

    def half_width(self, x: np.ndarray) -> np.ndarray:
        return half_width(x, self._radius2, self.config.spread)

    def transit_time(self, x: np.ndarray) -> np.ndarray:
        """``∫₀ˣ dξ / u_c(ξ)``: how long ago the air now at distance x left the fan (s). Beyond the
        core ``1/u_c = √2·b/(U0·D)`` and ``∫ b dξ = F(ξ) = ξ·b/2 + (R²/2c)·asinh(c·ξ/R)``, R = D/2."""
        x = np.maximum(x, 0.0)
        core, u0, c = self._core, self._u0, self.config.spread
        radius = math.sqrt(self._radius2)

        def antiderivative(xi: np.ndarray) -> np.ndarray:
            return 0.5 * xi * self.half_width(xi) + self._radius2 / (2.0 * c) * np.arcsinh(c * xi / radius)

        beyond = (antiderivative(x) - antiderivative(np.asarray(core))) / (math.sqrt(2.0) * u0 * radius)
        return np.where(x <= core, x / u0, core / u0 + beyond)

    def axis_y(self, x: np.ndarray, t: np.ndarray, index: np.ndarray | slice = slice(None)) -> np.ndarray:
        """y of the jet axis at distances ``x`` (n, ...) from the fans of vehicles ``index`` at their
        times ``t`` (broadcast against ``x``): each fan's retarded y."""
        x = np.asarray(x, dtype=float)
        t = np.asarray(t, dtype=float)
        if x.shape == t.shape == (self.count,) and index == slice(None):
            return jet_axis_y(x, t, self.motion_tables, self._kernel)
        return self._y(np.broadcast_to(t, x.shape) - self.transit_time(x), index)

    def fan_y(self, t: np.ndarray, index: np.ndarray | slice = slice(None)) -> np.ndarray:
        """The fans' y (n,) now, at times ``t`` (n,)."""
        t = np.asarray(t, dtype=float)
        if t.shape == (self.count,) and index == slice(None):
            return jet_axis_y(np.zeros(self.count), t, self.motion_tables, self._kernel)
        return self._y(t, index)

    def outlet(self, vehicle: int, time: float, position: np.ndarray) -> Outlet | None:
        """The fan's outlet at its y now, its axis aimed at the retarded jet axis at the vehicle's
        distance (the :class:`~quad_wrench_env.disturbances.base.Visible` seam); None when switched off."""
        c = self.config
        if not c.enabled:
            return None
        t, index = np.array((time,)), slice(vehicle, vehicle + 1)
        origin = np.array((0.0, float(self.fan_y(t, index)[0]), c.height))
        x = max(float(position[0]), 0.1)
        axis = np.array((x, float(self.axis_y(np.array((x,)), t, index)[0]) - origin[1], 0.0))
        facing = np.array((1.0, 0.0, 0.0))
        return Outlet(
            origin, axis / np.linalg.norm(axis), facing, 0.5 * c.outlet_diameter, c.spread, moving=True
        )

    def velocity_at(
        self, points: np.ndarray, t: np.ndarray, index: np.ndarray | slice, mean: bool = False
    ) -> np.ndarray:
        if not self.config.enabled:
            return np.zeros(points.shape)
        x = points[..., 0]
        u_c = self.centreline_speed(x)
        b = self.half_width(x)
        dy = points[..., 1] - self.axis_y(x, np.asarray(t)[:, None], index)
        dz = points[..., 2] - self.config.height
        speed = np.where(x > 0.0, u_c * np.exp(-(dy * dy + dz * dz) / (b * b)), 0.0)
        if mean:
            return speed[..., None] * np.array((1.0, 0.0, 0.0))
        direction = self.config.turbulence_intensity * self.noise[index]
        direction[:, 0] += 1.0
        return speed[..., None] * direction[:, None, :]

"""``QuadWrench/ForceExertion-v0``: press a tool's tip on a wall or a ceiling with a target force.

Aerial physical interaction after Yüksel et al. 2014 (Secs. IV-V). The vehicle carries a
rigid tool (``tool``; by default its spherical tip 0.1 m beyond the hull, ahead and above) and starts
``start_gap`` (5 cm) from a surface with its tip, at rest, facing +x:

=======  ==========================================================================================
surface  the room (world frame, z up)
=======  ==========================================================================================
wall     a wall whose face is at ``wall_x`` (4.5 m), facing -x; the vehicle starts at 1.2 m height
ceiling  a ceiling whose underside is at ``ceiling_height`` (2.2 m) over x in [0.5, 3.0]; the vehicle
         starts under it at x = 1.75
=======  ==========================================================================================

Both surfaces are in every episode's room; ``surface`` (config, or ``reset(options={"surface": ...})``;
``"random"`` by default) picks where the episode starts. The target force ``f*`` is what the tip
should exert *on* the surface, along the surface's normal into it (+x on the wall, +z on the
ceiling), of magnitude drawn per episode in ``target_range`` times the vehicle's weight (0.05-0.1 m·g:
0.5-1 N on the 1 kg ``yuksel1kg``), or ``reset(options={"target_force": N})``. A constant push along
+x (``push``, N; Yüksel et al. 2014 Fig. 6) may act on the centre of mass (option ``push``, 0 by default).

Contact forces come from PyBullet's solver (:meth:`~quad_wrench_env.engine.world.World.add_contact_loads`)
and are in ``wrench_true``; touching with the tip is allowed, touching with the hull is a crash.

Observation (float32, 28; ``env.unwrapped.obs_layout``): the 25 engine values (estimated state,
estimated force and torque, last action), then ``target_force`` (3, world frame, N). Action: the
``wrench`` type by default (collective thrust and body torques), as IDA-PBC outputs.

Reward per step (``info["reward_terms"]``): ``contact = -min(|f_exerted - f*|, c)`` (N), with
``f_exerted = -contact_force`` the force the tip exerts on the surface and ``c = contact_cap`` (2
N); ``alive = +c`` on every step that does not end the episode early, so ``contact + alive`` lies in
[0, c] and ending an episode early never pays (with ``contact`` alone a crash cost 10 against |f*|
for every step not touching, and a policy learned to crash);
``effort = -effort_weight·mean(a²)``; ``crash = -crash_penalty`` on an early end; ``approach =
γ·Φ(s') - Φ(s)`` with ``Φ = -approach_weight·gap`` (the tip's distance to the surface, m):
potential-based shaping (Ng, Harada & Russell 1999), which leaves the optimal policy unchanged for
discount γ (``reward.discount``, the learner's) and gives a signal before the first touch, where
``contact`` is constant (a PPO run without it never learned to touch). Truncated after
``episode_seconds`` (15 s).

``info`` adds ``contact_force`` (3,: the surface's force on the tip, world frame) and ``target_force``
(3,). The harness reports ``mean_contact_force_last_5s`` (|f_exerted| averaged over the last 5 s, N),
``contact_force_error`` (|f_exerted - f*| averaged over the last 5 s, N) and ``longest_contact_loss_s``
(the longest time without tip contact after the first touch, s).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from quad_wrench_env.config import check_numbers
from quad_wrench_env.disturbances.base import BodyState, CompiledForm
from quad_wrench_env.engine.components import Components
from quad_wrench_env.engine.env_config import EnvConfig, ToolConfig
from quad_wrench_env.engine.fleet_view import FleetView
from quad_wrench_env.numerics import njit
from quad_wrench_env.registry import register
from quad_wrench_env.scene import Ceiling, Wall
from quad_wrench_env.tasks import terms
from quad_wrench_env.tasks.base import TaskDefaults, TaskRecord
from quad_wrench_env.vehicle import GRAVITY, VehicleParams

SURFACES = ("wall", "ceiling")
RANDOM = "random"
CONTACT_THRESHOLD = 1e-3
"""N: a tip force above this counts as contact (the solver reports exact zeros without one)."""


@dataclass
class ForceExertionReward:
    effort_weight: float = 0.01
    crash_penalty: float = 10.0
    approach_weight: float = 10.0
    """Φ per metre of gap (module docstring); 0 switches the shaping off."""
    discount: float = 0.99
    """γ of the shaping: the learner's discount."""
    contact_cap: float = 2.0
    """N: the contact term is ``-min(|f_exerted - f*|, contact_cap)`` and ``alive = +contact_cap`` per
    step flown, so a step is never worth less than nothing and ending an episode early never pays
    (module docstring)."""

    def __post_init__(self) -> None:
        check_numbers("reward", self, ("effort_weight", "crash_penalty", "approach_weight"), positive=False)
        check_numbers("reward", self, ("contact_cap",))
        if not 0.0 < self.discount <= 1.0:
            raise ValueError(f"reward.discount={self.discount!r} must be in (0, 1]")


@dataclass
class ForceExertionConfig(EnvConfig):
    vehicle: str = "yuksel1kg"
    estimator: str = "observer"
    action_type: str = "wrench"
    episode_seconds: float = 15.0
    tool: ToolConfig = field(default_factory=lambda: ToolConfig(enabled=True))
    surface: str = RANDOM
    """``"wall"``, ``"ceiling"`` or ``"random"`` (either, per episode)."""
    wall_x: float = 4.5
    ceiling_height: float = 2.2
    roughness: float = 0.0
    """Ridge height (m) of both surfaces (Yüksel et al. 2014 Fig. 5's rough ceiling); 0 is flat."""
    surface_friction: float = 0.5
    start_gap: float | tuple[float, float] = 0.05
    """Distance (m) from the tip to the surface at the start, or ``[low, high]``: drawn per episode (a
    training curriculum that also starts some episodes at the surface)."""
    target_range: tuple[float, float] = (0.05, 0.1)
    """Range of ``|f*|`` in units of the vehicle's weight ``m·g``."""
    push: float = 0.0
    """Constant push along +x (N) on the centre of mass, unless the reset option gives one."""
    reward: ForceExertionReward = field(default_factory=ForceExertionReward)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.surface not in (RANDOM, *SURFACES):
            raise ValueError(f"surface={self.surface!r}; allowed: {[RANDOM, *SURFACES]}")
        if not self.tool.enabled:
            raise ValueError("tool.enabled=False: ForceExertion presses with the tool's tip; enable the tool")
        check_numbers("env", self, ("wall_x", "ceiling_height", "surface_friction"))
        gaps = self.start_gap if isinstance(self.start_gap, (list, tuple)) else (self.start_gap,)
        finite = all(
            isinstance(g, (int, float)) and not isinstance(g, bool) and math.isfinite(g) for g in gaps
        )
        if not (len(gaps) in (1, 2) and finite and 0.0 <= gaps[0] <= gaps[-1]):
            raise ValueError(f"start_gap={self.start_gap!r} must be a distance >= 0 (m) or [low, high]")
        self.start_gap = float(gaps[0]) if len(gaps) == 1 else (float(gaps[0]), float(gaps[1]))
        check_numbers("env", self, ("roughness",), positive=False)
        low, high = self.target_range = tuple(self.target_range)
        if not (0.0 <= low <= high and math.isfinite(high)):
            raise ValueError(f"target_range={[low, high]!r} must be [low, high] with 0 <= low <= high (m·g)")
        if not math.isfinite(self.push):
            raise ValueError(f"push={self.push!r} must be a finite force (N)")


@register("task")
class ForceExertion(TaskDefaults):
    """Press the tool's tip on a wall or a ceiling with the observed target force (module docstring)."""

    env_id: ClassVar[str] = "QuadWrench/ForceExertion-v0"
    config_class: ClassVar[type[EnvConfig]] = ForceExertionConfig
    reset_options: ClassVar[tuple[str, ...]] = ("surface", "target_force", "push")
    observation_blocks: ClassVar[tuple[tuple[str, int, float], ...]] = (("target_force", 3, 100.0),)
    trace_keys: ClassVar[tuple[str, ...]] = ("contact_force", "target_force")
    metric_columns: ClassVar[tuple[tuple[str, str, str], ...]] = (
        ("contact_force_error", "abs(f - f*) over the last 5 s [N]", "{:.3f}"),
        ("mean_contact_force_last_5s", "abs(f) over the last 5 s [N]", "{:.3f}"),
        ("longest_contact_loss_s", "longest contact loss [s]", "{:.2f}"),
    )

    def __init__(self, cfg: ForceExertionConfig, vehicle: VehicleParams, count: int) -> None:
        self.cfg = cfg
        self.vehicle = vehicle
        self.wall = Wall(x=cfg.wall_x, friction=cfg.surface_friction, roughness=cfg.roughness)
        self.ceiling = Ceiling(
            height=cfg.ceiling_height,
            center=(1.75, 0.0),
            size=(2.5, 4.0),
            friction=cfg.surface_friction,
            roughness=cfg.roughness,
        )
        self.push = ConstantPush(count)
        self.surface = np.zeros(count, dtype=int)
        """Each vehicle's surface (index into :data:`SURFACES`)."""
        self.target_force = np.zeros((count, 3))
        """(N, 3) each vehicle's ``f*`` (world frame, N)."""
        self.potential = np.zeros(count)
        """(N,) each vehicle's shaping potential Φ after its last step (or at its start)."""

    def components(self) -> Components:
        return Components(loads=[self.push], scene=[self.wall, self.ceiling])

    def _tip_offset(self) -> np.ndarray:
        offset = self.cfg.tool.offset
        if offset is None:
            v = self.vehicle
            offset = (v.arm + v.rotor_radius + 0.1, 0.0, 0.5 * v.hull_height + 0.1)
        return np.array(offset, dtype=float)

    def reset_vehicle(
        self, index: int, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> tuple[np.ndarray, float]:
        cfg = self.cfg
        surface = options.get("surface", cfg.surface)
        if surface == RANDOM:
            surface = SURFACES[int(rng.integers(len(SURFACES)))]
        if surface not in SURFACES:
            raise ValueError(f"surface={surface!r}; allowed: {[RANDOM, *SURFACES]}")
        weight = self.vehicle.mass * GRAVITY
        if "target_force" in options:
            magnitude = _number(options, "target_force", allow_negative=False)
        else:
            magnitude = float(rng.uniform(*cfg.target_range)) * weight
        push = _number(options, "push", allow_negative=True) if "push" in options else cfg.push
        gap = cfg.start_gap if isinstance(cfg.start_gap, float) else float(rng.uniform(*cfg.start_gap))
        self.surface[index] = SURFACES.index(surface)
        self.push.force[index] = (push, 0.0, 0.0)
        tip, radius = self._tip_offset(), cfg.tool.tip_radius
        if surface == "wall":
            self.target_force[index] = (magnitude, 0.0, 0.0)
            x = cfg.wall_x - gap - radius - tip[0] - cfg.roughness
            position = np.array((x, 0.0, 1.2))
        else:
            self.target_force[index] = (0.0, 0.0, magnitude)
            z = cfg.ceiling_height - gap - radius - tip[2] - cfg.roughness
            position = np.array((1.75, 0.0, z))
        return position, 0.0

    def start(self, view: FleetView, index: np.ndarray) -> TaskRecord:
        """Φ(s₀) from each start's own pose: under a push the trimmed start is tilted, and the tip is
        not ``start_gap`` from the surface."""
        self.potential[index] = -self.cfg.reward.approach_weight * self.gap(view)[index]
        return TaskRecord({}, blocks=self.target_force.copy(), info=self._info(view))

    def gap(self, view: FleetView) -> np.ndarray:
        """(N,) distance (m) from each tip to its surface's face (0 when touching or beyond)."""
        state, cfg = view.state, self.cfg
        tips = state.position + np.einsum("nij,j->ni", state.rotation, self._tip_offset())
        radius = cfg.tool.tip_radius
        gap = np.where(
            self.surface == 0, cfg.wall_x - tips[:, 0] - radius, cfg.ceiling_height - tips[:, 2] - radius
        )
        return np.maximum(gap, 0.0)

    def step(self, view: FleetView, actions: np.ndarray, ended: np.ndarray) -> TaskRecord:
        r = self.cfg.reward
        potential = -r.approach_weight * self.gap(view)
        approach = r.discount * potential - self.potential
        self.potential = potential
        exerted = -view.contact_force
        reward_terms = {
            "contact": terms.capped_cost(np.linalg.norm(exerted - self.target_force, axis=1), r.contact_cap),
            "alive": terms.alive(ended, r.contact_cap),
            "effort": terms.efforts(actions, r.effort_weight),
            "crash": terms.crashes(ended, r.crash_penalty),
            "approach": approach,
        }
        return TaskRecord(reward_terms, blocks=self.target_force.copy(), info=self._info(view))

    def _info(self, view: FleetView) -> dict[str, np.ndarray]:
        return {"contact_force": view.contact_force.copy(), "target_force": self.target_force.copy()}

    @staticmethod
    def metrics(trace: Mapping[str, np.ndarray], window: float = 5.0) -> dict[str, float]:
        """The harness's scores of one episode (module docstring); ``window`` s at the end."""
        t = np.asarray(trace["time"])
        exerted = -np.asarray(trace["contact_force"])
        target = np.asarray(trace["target_force"])
        late = t >= t[-1] - window
        touching = np.linalg.norm(exerted, axis=1) > CONTACT_THRESHOLD
        longest = 0.0
        if touching.any():
            first = int(np.argmax(touching))
            start = None
            for k in range(first, t.size):
                if not touching[k] and start is None:
                    start = t[k - 1]
                elif touching[k] and start is not None:
                    longest, start = max(longest, t[k] - start), None
            if start is not None:
                longest = max(longest, t[-1] - start)
        else:
            longest = float(t[-1] - t[0])
        return {
            "mean_contact_force_last_5s": float(np.mean(np.linalg.norm(exerted[late], axis=1))),
            "contact_force_error": float(np.mean(np.linalg.norm(exerted[late] - target[late], axis=1))),
            "longest_contact_loss_s": float(longest),
        }


def _number(options: Mapping[str, Any], key: str, allow_negative: bool) -> float:
    value = options[key]
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if not (ok and math.isfinite(value) and (allow_negative or value >= 0)):
        raise ValueError(f"{key}={value!r} must be a finite force{'' if allow_negative else ' >= 0'} (N)")
    return float(value)


class ConstantPush:
    """A constant force on each vehicle's centre of mass (world frame): a
    :class:`~quad_wrench_env.disturbances.base.PointLoad` with a per-vehicle table."""

    name = "push"
    compiled = CompiledForm("quad_wrench_env.tasks.force_exertion", (("load", "push_load"),), table="force")

    def __init__(self, count: int) -> None:
        self.force = np.zeros((count, 3))
        """(N, 3) each vehicle's push (N)."""

    def kernel_parameters(self) -> np.ndarray:
        return np.zeros(1)

    def point_load(
        self, t: np.ndarray, body: BodyState, index: np.ndarray | slice = slice(None)
    ) -> tuple[np.ndarray, np.ndarray] | None:
        forces = np.reshape(self.force[index], (-1, 3))
        return np.zeros((forces.shape[0], 1, 3)), forces[:, None, :].copy()


@njit
def push_load(params, force, state, time, position, velocity, angular_velocity, rotation, out):
    """``ConstantPush.point_load``'s resultant added to ``out`` (N, 6)."""
    for n in range(time.shape[0]):
        for i in range(3):
            out[n, i] += force[n, i]

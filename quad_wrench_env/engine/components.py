"""The components a fleet flies with, by seam, in the order the physics step meets them."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from quad_wrench_env.disturbances.base import PointLoad, RotorModifier, WindField, make_load, make_wind
from quad_wrench_env.disturbances.ground_effect import GroundEffect
from quad_wrench_env.disturbances.payload import Payload
from quad_wrench_env.disturbances.wrench_profile import WrenchProfile
from quad_wrench_env.engine.env_config import EnvConfig
from quad_wrench_env.scene import ScenePart, make_scene_part, surface_tops
from quad_wrench_env.vehicle import VehicleParams


@dataclass
class Components:
    """Wind fields, rotor modifiers, point loads and static scene parts (each list in order)."""

    winds: list[WindField] = field(default_factory=list)
    rotors: list[RotorModifier] = field(default_factory=list)
    loads: list[PointLoad] = field(default_factory=list)
    scene: list[ScenePart] = field(default_factory=list)

    def __add__(self, other: Components) -> Components:
        return Components(
            self.winds + other.winds,
            self.rotors + other.rotors,
            self.loads + other.loads,
            self.scene + other.scene,
        )

    def ordered(self) -> list[tuple[str, Any]]:
        """``(kind, component)`` of every physics component in the step's order: the wind fields
        (``"wind"``), the rotor modifiers (``"rotor"``), the point loads (``"load"``)."""
        return (
            [("wind", w) for w in self.winds]
            + [("rotor", r) for r in self.rotors]
            + [("load", p) for p in self.loads]
        )


def assemble(cfg: EnvConfig, vehicle: VehicleParams, count: int, task: Components) -> Components:
    """The task's components followed by those every env takes from its config: ``scene`` parts,
    ``wind`` fields, ``ground_effect`` (over the ground and every horizontal top of the scene, the
    task's included), ``payload`` and ``external_wrench`` (each only when it acts), then ``loads``."""
    scene = task.scene + [make_scene_part(spec, i) for i, spec in enumerate(cfg.scene)]
    winds = task.winds + [make_wind(spec, count, i) for i, spec in enumerate(cfg.wind)]
    rotors = list(task.rotors)
    if cfg.ground_effect:
        rotors.append(GroundEffect(vehicle.rotor_radius, surface_tops(scene)))
    loads = list(task.loads)
    if cfg.payload.mass > 0:
        loads.append(Payload(cfg.payload))
    if cfg.external_wrench:
        loads.append(WrenchProfile(cfg.external_wrench))
    loads += [make_load(spec, count, i) for i, spec in enumerate(cfg.loads)]
    return Components(winds, rotors, loads, scene)

"""Static scene parts: tables, walls and ceilings, as boxes in every vehicle's frame.

A :class:`ScenePart` is the seam for static bodies. The world (:class:`~quad_wrench_env.engine.world.World`)
builds its boxes once per vehicle frame of the vector env (each vehicle flies in a copy of the scene,
as in its own episode). The vehicle's body touching any part ends its episode as a crash (only a
tool's tip may touch, :class:`~quad_wrench_env.engine.env_config.ToolConfig`); a horizontal top
(:meth:`ScenePart.top`) is a surface the ground effect sees under a rotor. Each part has a friction
coefficient (Bullet combines two bodies' coefficients as their product). A wall or a ceiling may be
rough: ``roughness`` > 0 adds ridges across its face over ``rough_length`` m (along y for a wall,
along x for a ceiling, so that a tool sliding along x or y crosses them), ``ridge_spacing`` apart,
each ``roughness·(1 + sin(2.4·k))/2`` high (a fixed, irregular pattern: nothing random). Config:
``scene=[{"kind": "table", "center": [x, y], "size": [sx, sy], "height": h}, {"kind": "wall", "x": 3.0},
{"kind": "ceiling", "height": 2.5, "roughness": 0.01}]``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from quad_wrench_env.config import build_named
from quad_wrench_env.registry import register, registered, resolve

TOUCHES = ("crash", "report")
"""What a vehicle touching a scene part means: ``crash`` (with anything but a tool's tip: the episode
ends as a crash, the default) or ``report`` (never ends an episode by itself: ``info["contacts"]`` says
which vehicle touches which such part, and the task decides, e.g. a perch or a landing pad)."""


@runtime_checkable
class ScenePart(Protocol):
    """A static body of the scene, in a vehicle's frame (m); its ``touch`` is one of :data:`TOUCHES`
    (a part without one: ``crash``)."""

    name: str
    friction: float

    def boxes(self) -> list[tuple[tuple[float, float, float], tuple[float, float, float]]]:
        """``(centre, half extents)`` of each of the part's boxes."""

    def top(self) -> tuple[float, float, float, float, float] | None:
        """``(x_min, x_max, y_min, y_max, z)`` of the part's horizontal top, or None."""


def touch_of(part: Any) -> str:
    """The part's :data:`TOUCHES` entry (``crash`` for a part that declares none); another is refused."""
    touch = getattr(part, "touch", "crash")
    if touch not in TOUCHES:
        raise ValueError(f"scene {part.name}: touch={touch!r} is unknown; allowed: {list(TOUCHES)}")
    return touch


def _check(part: Any, pairs: tuple[str, ...], positive: tuple[str, ...]) -> None:
    """Refuse a scene part whose numbers are not finite, whose ``pairs`` (centre, size) are not two
    numbers, whose ``positive`` fields are not > 0 or whose ``touch`` is unknown, naming the field."""
    touch_of(part)
    for key in dataclasses.fields(part):
        if key.name == "touch":
            continue
        value = getattr(part, key.name)
        numbers = tuple(value) if isinstance(value, (tuple, list)) else (value,)
        if key.name in pairs:
            setattr(part, key.name, numbers)
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in numbers) or (
            key.name in pairs and len(numbers) != 2
        ):
            raise ValueError(
                f"scene {part.name}: {key.name}={value!r} must be finite numbers, 2 for {list(pairs)}"
            )
        if key.name in positive and min(numbers) <= 0:
            raise ValueError(f"scene {part.name}: {key.name}={value!r} must be > 0 (m)")


@register("scene", "table")
@dataclass
class Table:
    """A table: a box on the ground of ``size`` (m, x and y) and ``height`` (m) centred at ``center``."""

    center: tuple[float, float] = (2.0, 0.0)
    size: tuple[float, float] = (1.0, 1.0)
    height: float = 0.75
    friction: float = 0.5
    touch: str = "crash"
    name = "table"

    def __post_init__(self) -> None:
        _check(self, ("center", "size"), ("size", "height", "friction"))

    def boxes(self):
        (x, y), (sx, sy), h = self.center, self.size, self.height
        return [((x, y, 0.5 * h), (0.5 * sx, 0.5 * sy, 0.5 * h))]

    def top(self):
        (x, y), (sx, sy) = self.center, self.size
        return (x - 0.5 * sx, x + 0.5 * sx, y - 0.5 * sy, y + 0.5 * sy, self.height)


@register("scene", "wall")
@dataclass
class Wall:
    """A wall facing -x whose face is at ``x`` (m), ``width`` along y and ``height`` from the ground."""

    x: float = 4.0
    width: float = 8.0
    height: float = 3.0
    thickness: float = 0.2
    friction: float = 0.5
    touch: str = "crash"
    roughness: float = 0.0
    ridge_spacing: float = 0.05
    rough_length: float = 3.0
    name = "wall"

    def __post_init__(self) -> None:
        _check(self, (), ("width", "height", "thickness", "friction", "ridge_spacing", "rough_length"))
        _check_roughness(self)

    def boxes(self):
        half = (0.5 * self.thickness, 0.5 * self.width, 0.5 * self.height)
        ridges = [
            ((self.x - 0.5 * h, y, half[2]), (0.5 * h, 0.25 * self.ridge_spacing, half[2]))
            for y, h in _ridges(self)
        ]
        return [((self.x + half[0], 0.0, half[2]), half), *ridges]

    def top(self):
        return None


@register("scene", "ceiling")
@dataclass
class Ceiling:
    """A ceiling whose underside is at ``height`` (m), ``size`` (m, x and y) centred on ``center``."""

    height: float = 2.5
    center: tuple[float, float] = (3.0, 0.0)
    size: tuple[float, float] = (8.0, 8.0)
    thickness: float = 0.2
    friction: float = 0.5
    touch: str = "crash"
    roughness: float = 0.0
    ridge_spacing: float = 0.05
    rough_length: float = 3.0
    name = "ceiling"

    def __post_init__(self) -> None:
        _check(
            self,
            ("center", "size"),
            ("size", "height", "thickness", "friction", "ridge_spacing", "rough_length"),
        )
        _check_roughness(self)

    def boxes(self):
        (x, y), (sx, sy) = self.center, self.size
        ridges = [
            ((x + offset, y, self.height - 0.5 * h), (0.25 * self.ridge_spacing, 0.5 * sy, 0.5 * h))
            for offset, h in _ridges(self)
        ]
        return [
            ((x, y, self.height + 0.5 * self.thickness), (0.5 * sx, 0.5 * sy, 0.5 * self.thickness)),
            *ridges,
        ]

    def top(self):
        return None


def _check_roughness(part: Any) -> None:
    if not (
        isinstance(part.roughness, (int, float)) and math.isfinite(part.roughness) and part.roughness >= 0
    ):
        raise ValueError(f"scene {part.name}: roughness={part.roughness!r} must be a finite height >= 0 (m)")


def _ridges(part: Any) -> list[tuple[float, float]]:
    """``(offset from the part's centre along the face, height)`` of a rough part's ridges (module
    docstring); none on a smooth one."""
    if part.roughness <= 0.0:
        return []
    count = int(part.rough_length / part.ridge_spacing)
    offsets = (np.arange(count) - 0.5 * (count - 1)) * part.ridge_spacing
    heights = part.roughness * 0.5 * (1.0 + np.sin(2.4 * np.arange(count)))
    return [(float(o), float(h)) for o, h in zip(offsets, heights, strict=True) if h > 1e-4]


def make_scene_part(spec: Mapping[str, Any], position: int = 0) -> ScenePart:
    """A scene part from its config ``{"kind": ..., **fields}``; bad kinds and keys are named."""
    if isinstance(spec, Mapping) and "kind" in spec:
        spec = {**spec, "kind": resolve(spec["kind"])}
    return build_named(spec, "kind", registered("scene"), f"scene[{position}]")[1]


def surface_tops(parts: list[ScenePart]) -> np.ndarray:
    """(K, 5) ``[x_min, x_max, y_min, y_max, z]`` of the parts' horizontal tops."""
    tops = [part.top() for part in parts]
    return np.array([t for t in tops if t is not None], dtype=float).reshape(-1, 5)

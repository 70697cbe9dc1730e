"""A landing pad: a scene part whose touches are reported, not crashes (the task decides what they mean)."""

from __future__ import annotations

from dataclasses import dataclass

from quad_wrench_env.registry import register


@register("scene", "pad")  # gym.make(id, scene=[{"kind": "pad", "center": [2.3, 0.0]}])
@dataclass
class Pad:
    """A square pad of ``size`` (m) and ``height`` (m) on the ground, centred at ``center``."""

    center: tuple[float, float] = (2.3, 0.0)
    size: float = 0.6
    height: float = 0.3
    friction: float = 0.8
    touch: str = "report"  # info["contacts"] says when a vehicle touches it; "crash" would end the episode
    name = "pad"

    def boxes(self):
        (x, y), half = self.center, 0.5 * self.size
        return [((x, y, 0.5 * self.height), (half, half, 0.5 * self.height))]

    def top(self):
        (x, y), half = self.center, 0.5 * self.size
        return (x - half, x + half, y - half, y + half, self.height)
